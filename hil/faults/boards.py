"""Board faults: a processor stops, hangs, reboots or resets.

* ``board_crash``: the board's process is killed (a hard fault with no recovery, a lost
  supply). The orchestrator then gives its outputs those of a dead chip: UARTs silent, PWM
  pins without pulses, driven pins released.
* ``board_hang``: the processor stops executing but keeps its pins (a deadlock, an endless
  interrupt, a clock failure with the watchdog disabled): its clock stops, nothing more leaves
  it, and every pin stays at the level it had. The board's process keeps running idle.
* ``fmu_reboot``: the FMU crashes and comes back (the watchdog resets it, or a brown-out):
  power-cycled after ``down_s``, it boots from its own time zero on the same FRAM, as the
  orchestrator's reboot path does for ``reboot`` on the console.
* ``io_reset``: the IO coprocessor resets (brown-out, watchdog) and goes through its bootloader
  again; the FMU's px4io driver must notice and reconfigure it.

While a board is dead or hung its control calls fail; the scenario engine reads its
observables as missing.
"""

from __future__ import annotations

from typing import Any

from board.endpoint import BoardDied
from hil.faults import NS_PER_S, FaultError, fault_kind

BOARDS = ("fmu", "io")


class HungHandle:
    """A board handle whose processor has stopped: advancing it does nothing and produces
    nothing (so its pins keep their last levels), and control calls fail as they would on a
    board that no longer answers its debug port."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        self.name = inner.name
        self.ports = inner.ports

    def post_advance(self, start_ns: int, until_ns: int, inputs: list) -> None:
        pass

    def wait_advance(self) -> tuple[list, None]:
        return [], None

    def call(self, method: str, *args: Any) -> Any:
        raise BoardDied(self.name, "hung")

    def is_alive(self) -> bool:
        return True

    def close(self, timeout_s: float = 2.0) -> None:
        self.inner.close(timeout_s)

    def kill(self) -> None:
        if hasattr(self.inner, "kill"):
            self.inner.kill()


def _check_running(orch: Any, target: str, kind: str) -> None:
    if target in orch.dead:
        raise FaultError(f"fault {kind}: board {target} is already dead ({orch.dead[target]})")


@fault_kind("board_crash", level="board", targets=BOARDS,
            doc="The board's processor dies for good (hard fault without recovery, lost "
                "supply). For the FMU: the IO stops receiving controls and, after its FMU-loss "
                "timeout (500 ms in E14), drives the failsafe PWM values, or hands the motors "
                "to the pilot's RC when manual override is allowed. For the IO: the FMU's "
                "px4io driver loses its link and the motors get no pulses.")
def crash_start(rig: Any, target: str, params: dict[str, Any], t_ns: int) -> None:
    _check_running(rig.orch, target, "board_crash")
    if isinstance(rig.orch.handles[target], HungHandle):
        rig.orch.handles[target] = rig.orch.handles[target].inner
    rig.orch.kill(target)


@fault_kind("board_hang", level="board", targets=BOARDS,
            doc="The processor stops executing but keeps its pins (deadlock, runaway interrupt, "
                "stopped clock): no more UART bytes or pin changes, every pin held where it "
                "was. Unlike a crash nothing tells the other side; it must time out.")
def hang_start(rig: Any, target: str, params: dict[str, Any], t_ns: int) -> None:
    orch = rig.orch
    _check_running(orch, target, "board_hang")
    if not isinstance(orch.handles[target], HungHandle):
        orch.handles[target] = HungHandle(orch.handles[target])


def _restart(orch: Any, name: str) -> None:
    handle = orch.handles[name]
    if isinstance(handle, HungHandle):
        orch.handles[name] = handle.inner
    orch.dead.pop(name, None)
    orch._restart(name)  # the orchestrator's reboot path (a new board, same FRAM)


@fault_kind("fmu_reboot", level="board", targets=("fmu",), down_s=0.0,
            doc="The FMU crashes and reboots (watchdog reset, brown-out): dead for ``down_s`` "
                "(0: reset at once), then a new FMU boots from its own time zero on the same "
                "FRAM. The IO meanwhile times out to failsafe (or override). If the IO was "
                "armed with INAIR_RESTART_OK (``px4io recovery``), the rebooted FMU's px4io "
                "driver finds it armed and asks the commander to arm again: the in-air "
                "restart.")
def reboot_start(rig: Any, target: str, params: dict[str, Any], t_ns: int) -> None:
    orch = rig.orch
    down_s = float(params["down_s"])
    if down_s < 0:
        raise FaultError(f"fault fmu_reboot: negative down_s {down_s}")
    if down_s == 0:
        _restart(orch, target)
        return
    later = getattr(rig, "later", None)
    if later is None:
        raise FaultError("fault fmu_reboot with down_s > 0 needs a rig with timers "
                         "(hil.faults.Injector)")
    if target not in orch.dead:
        if isinstance(orch.handles[target], HungHandle):
            orch.handles[target] = orch.handles[target].inner
        orch.kill(target)
    later(t_ns + round(down_s * NS_PER_S), lambda now: _restart(orch, target))


@fault_kind("io_reset", level="board", targets=("io",),
            doc="The IO coprocessor resets (brown-out on the servo rail, watchdog): it runs "
                "its bootloader again (200 ms) and restarts with its registers at reset "
                "values, outputs disarmed. The FMU's px4io driver sees the reset in the IO's "
                "status and configures it again; in flight that is a short loss of thrust.")
def io_reset_start(rig: Any, target: str, params: dict[str, Any], t_ns: int) -> None:
    _check_running(rig.orch, target, "io_reset")
    rig.orch.call("io", "reset")
