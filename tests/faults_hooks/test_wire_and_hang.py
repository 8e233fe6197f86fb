"""Wire faults at the orchestrator and a halted CPU, on small probe boards (one process)."""

from __future__ import annotations

import pytest

from board.board import Board
from board.kernel import Kernel
from board.wiring import Wire, uart_link
from hil.orchestrator import BoardSpec, Orchestrator

MS = 1_000_000


def _probes(sends, io_sends=()):
    return {"fmu": BoardSpec("board.stock:UartProbeBoard", {"name": "fmu", "sends": sends}),
            "io": BoardSpec("board.stock:UartProbeBoard",
                            {"name": "io", "sends": list(io_sends)})}


def test_a_cut_wire_carries_nothing_one_way_and_mending_restores_it():
    sends = [(t * MS, bytes([t])) for t in range(1, 10)]
    with Orchestrator(_probes(sends, sends), uart_link(("fmu", "uart"), ("io", "uart")),
                      mode="local") as orch:
        orch.run(duration_ns=4 * MS)           # the byte written at 4 ms is on its way
        orch.cut_wire("fmu", "uart")
        assert orch.wire_faults() == ["fmu.uart"]
        orch.run(duration_ns=3 * MS)
        orch.mend_wire("fmu", "uart")
        assert orch.wire_faults() == []
        assert orch._route_outputs == orch._route_all  # the healthy path again
        orch.run(duration_ns=4 * MS)
        at_io = [b for _, b in orch.call("io", "received")]
        at_fmu = [b for _, b in orch.call("fmu", "received")]
    assert at_io == [1, 2, 3, 4, 8, 9]       # sent at 5, 6, 7 ms: lost on the open wire
    assert at_fmu == list(range(1, 10))      # the other conductor is intact
    with pytest.raises(ValueError, match="no wire leaves"):
        orch.cut_wire("fmu", "nowhere")


class _PwmWorld:
    ports = ("esc1",)

    def __init__(self):
        self.inputs = []

    def run_until(self, t):
        pass

    def outputs(self, until):
        return []

    def input(self, port, t, payload):
        self.inputs.append((port, t, payload))


def test_a_cut_pwm_wire_shows_no_pulses_and_mending_restores_the_train():
    world = _PwmWorld()
    specs = {"io": BoardSpec("tests.hil.boards:PwmBoard", {})}
    with Orchestrator(specs, [Wire(("io", "pwm1"), ("world", "esc1"))], world=world,
                      mode="local") as orch:
        orch.run(duration_ns=2 * MS)
        orch.cut_wire("io", "pwm1")
        assert world.inputs[-1] == ("esc1", 2 * MS, (0, 0))
        orch.run(duration_ns=2 * MS)
        orch.mend_wire("io", "pwm1")
    assert world.inputs[-1] == ("esc1", 4 * MS, (1_500_000, 20_000_000))


class _TickBoard(Board):
    """Counts a 1 ms periodic tick and an ISR-priority one-shot; its output is the tick count."""

    def __init__(self, name="fmu", seed=0):
        super().__init__(name, seed)
        self.ticks = []
        self.kernel.call_every(MS, self._tick, first_ns=MS)
        self.shots = []
        self.kernel.call_at(5 * MS + 10, self.shots.append, "shot")
        self.emit_out = self.expose_output("out")

    def _tick(self):
        self.ticks.append(self.kernel.now_ns)
        self.emit_out(self.kernel.now_ns, len(self.ticks))


def test_a_halted_board_runs_nothing_then_serves_its_overdue_events_once_and_keeps_cadence():
    b = _TickBoard()
    b.advance(3 * MS, [])
    assert b.ticks == [MS, 2 * MS, 3 * MS]
    assert b.ctl_hang() == 3 * MS
    assert b.next_event_ns() is None
    assert b.advance(10 * MS, [], 3 * MS) == []
    assert b.ticks == [MS, 2 * MS, 3 * MS] and b.shots == []
    assert b.kernel.now_ns == 10 * MS
    overdue = b.ctl_release()
    assert overdue == 2                      # the periodic tick and the one-shot
    out = b.advance(13 * MS, [])
    # both pending interrupts run at the release time, then the tick keeps its 1 ms cadence
    assert b.ticks == [MS, 2 * MS, 3 * MS, 10 * MS, 11 * MS, 12 * MS, 13 * MS]
    assert b.shots == ["shot"]
    assert [r[1] for r in out] == [10 * MS, 11 * MS, 12 * MS, 13 * MS]
    assert b.ctl_release() == 0              # releasing a running board is harmless


def test_inputs_to_a_halted_board_reach_its_uart_hardware_and_the_rest_wait():
    from board.uart import Uart

    class _B(Board):
        def __init__(self):
            super().__init__("io")
            self.uart = Uart(self.kernel, "USART2")
            self.uarts = {"USART2": self.uart}
            self.expose_uart("link", self.uart)
            self.pins = []
            self.expose_input("button", lambda t, v: self.pins.append((t, v)), kind="pin")

    b = _B()
    b.ctl_hang()
    cfg = (115_200, 8, "N", 1, 0)
    b.advance(2 * MS, [("link", MS, (*cfg, b"ab")), ("button", MS, 1)], 0)
    assert b.pins == []                       # an EXTI handler is firmware: held
    assert b.uart.in_waiting == 2             # the USART received (DMA/hardware)
    b.ctl_release()
    assert b.pins == [(MS, 1)]


def test_resume_at_moves_only_overdue_events():
    k = Kernel()
    order = []
    k.call_at(5, order.append, "late-low", priority=10)
    k.call_at(7, order.append, "late-high", priority=-10)
    k.call_at(50, order.append, "future")
    k.now_ns = 20
    assert k.resume_at(20) == 2
    k.run(100)
    assert order == ["late-high", "late-low", "future"]
