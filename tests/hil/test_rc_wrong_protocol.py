"""rc.wrong_protocol: another receiver on the IO's RC connector, on the wire.

The kind unplugs the fitted receiver and plugs one of another protocol (bound to the same
transmitter) into the same world port, so its frames reach the IO's UART in their own line
format; the UART's bit-level decoder turns them into what an STM32 would read.
"""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from board.board import Board
from board.uart import Uart, UartConfig
from board.wiring import WORLD, Wire
from hil.devices import DeviceHub
from hil.faults import FaultError, get_kind
from hil.orchestrator import BoardSpec, Orchestrator
from hil.rc import RcRig, Transmitter
from ioproc.rc import SbusDecoder

MS = 1_000_000


class SbusSink(Board):
    """The IO's S.BUS input only: USART3 100 kbit/s 8E2 inverted, bytes and flags recorded."""

    def __init__(self, name: str = "io", seed: int = 0) -> None:
        super().__init__(name, seed)
        self.rx: list[tuple[int, int, int]] = []
        uart = Uart(self.kernel, "USART3", UartConfig(100_000, 8, "E", 2, True))
        uart.on_rx(lambda t, b, f: self.rx.append((t, b, f)))
        self.expose_uart("sbus_in", uart)


def _system():
    rig = RcRig(Transmitter())
    rig.add("sbus")
    orch = Orchestrator({"io": BoardSpec("tests.hil.test_rc_wrong_protocol:SbusSink")},
                        [Wire((WORLD, "rc_sbus"), ("io", "sbus_in"))], world=DeviceHub(rig),
                        quantum_ns=MS, mode="local")
    return orch, SimpleNamespace(orch=orch, dev={"rc": rig}), rig


def _frames(rx, t0, t1):
    dec = SbusDecoder()
    return sum(bool(dec.feed_byte(t // 1000, b)) for t, b, _f in rx if t0 <= t < t1)


def test_dsm_satellite_on_the_sbus_input_gives_errors_and_no_frame_then_sbus_returns():
    orch, rig, rc = _system()
    kind = get_kind("rc.wrong_protocol")
    params = kind.check("sbus", {})
    assert params == {"protocol": "dsm"}
    with orch:
        orch.run(500 * MS)
        t_swap = orch.t_ns
        token = kind.start(rig, "sbus", params, t_swap)
        assert [r.kind for r in rc.receivers] == ["sbus", "dsm"]
        orch.run(1000 * MS)
        t_back = orch.t_ns
        kind.stop(rig, "sbus", params, t_back, token)
        orch.run(500 * MS)
        rx = orch.handles["io"].board.rx
    assert rc.receivers[0].kind == "sbus" and len(rc.receivers) == 1
    assert _frames(rx, 0, t_swap) >= 30
    # one quantum of slack: the rig runs ahead of the board by one quantum
    during = [(t, b, f) for t, b, f in rx if t_swap + 2 * MS <= t < t_back]
    assert len(during) > 100 and sum(1 for *_x, f in during if f) > 20  # FE/PE on the line
    assert _frames(rx, t_swap + 2 * MS, t_back) == 0
    assert _frames(rx, t_back + 2 * MS, t_back + 500 * MS) >= 30


def test_unplugged_receiver_sends_nothing_and_rebinds():
    tx = Transmitter()
    rig = RcRig(tx)
    rx = rig.add("dsm")
    rx.unplug(100 * MS, 300 * MS)
    rig.run_until(600 * MS)
    times = [t for _p, t, _pl in rig.outputs(600 * MS)]
    assert times and not any(100 * MS <= t < 300 * MS for t in times)
    assert any(t >= 300 * MS for t in times) and rx.held is not None


def test_bad_parameters_are_fault_errors():
    orch, rig, _rc = _system()
    kind = get_kind("rc.wrong_protocol")
    with pytest.raises(FaultError, match="what the sbus input expects"):
        kind.start(rig, "sbus", kind.check("sbus", {"protocol": "sbus"}), 0)
    with pytest.raises(FaultError, match="PPM pulse train"):
        kind.start(rig, "sbus", kind.check("sbus", {"protocol": "ppm"}), 0)
    with pytest.raises(FaultError, match="no dsm receiver"):
        kind.start(rig, "dsm", kind.check("dsm", {"protocol": "sbus"}), 0)
    with pytest.raises(FaultError, match="not one of"):
        kind.check("ppm", {})
