"""Board hardware faults beyond a kill or a reboot: a halted CPU, power rails, memory, load.

They act on the board's chip models through control calls (``orch.call(board, ...)``): the
CPU stops dispatching events but keeps its pins, a rail's devices lose power, the FRAM stops
taking writes, a work queue gets a greedy item. The firmware notices what real PX4 notices.
"""

from __future__ import annotations

from typing import Any

from hil.faults import Rig, fault_kind
from hil.faults._rig import number
from hil.faults.bus import board_call


def _hang(board: str) -> Any:
    def start(rig: Rig, target: str, params: dict[str, Any], t_ns: int) -> Any:
        return board_call(rig, f"board.{board}_hang", board, "hang")

    def stop(rig: Rig, target: str, params: dict[str, Any], t_ns: int, token: Any) -> None:
        board_call(rig, f"board.{board}_hang", board, "release")

    return start, stop


_fmu_start, _fmu_stop = _hang("fmu")
fmu_hang = fault_kind(
    "board.fmu_hang", level="board",
    doc="The FMU's CPU halts (a lock-up with interrupts masked, a hard-fault loop without a "
        "watchdog): no firmware, interrupt or timer callback runs and nothing new is sent, but "
        "the process lives and its pins hold their last levels. The IO stops receiving "
        "CONTROLS and after 500 ms declares the FMU lost (ALARM_FMU_LOST) and drives its "
        "failsafe PWM, or hands the motors to the pilot's RC override when allowed. Stopping "
        "the fault resumes the CPU where it was: the interrupts that fell due run first and the "
        "flight stack catches up from the present time (its estimator sees a gap).")(_fmu_start)
fmu_hang.stopper(_fmu_stop)  # type: ignore[attr-defined]

_io_start, _io_stop = _hang("io")
io_hang = fault_kind(
    "board.io_hang", level="board",
    doc="The IO's CPU halts: its timers keep generating the last PWM (hardware), but nothing "
        "answers the FMU, so the px4io driver times out and reports the IO lost after 10 "
        "failed calls; RC input and the safety switch are no longer processed. Stopping the "
        "fault resumes the IO firmware.")(_io_start)
io_hang.stopper(_io_stop)  # type: ignore[attr-defined]


@fault_kind("board.servo_rail_brownout", level="board", volts=4.2,
            doc="The IO's servo rail (VSERVO, normally 5 V from the BEC) sags to `volts`, as "
                "when a servo stalls or the BEC fails. The IO measures it on its ADC, reports "
                "it in its STATUS page (px4io_status.voltage_v) and the FMU logs it.")
def servo_rail_brownout(rig: Rig, target: str, params: dict[str, Any], t_ns: int) -> Any:
    board_call(rig, "board.servo_rail_brownout", "io", "set_servo_rail_v",
               number(params, "volts", "board.servo_rail_brownout", 0.0, 10.0))
    return None


@servo_rail_brownout.stopper
def _servo_rail_stop(rig: Rig, target: str, params: dict[str, Any], t_ns: int,
                     token: Any) -> None:
    board_call(rig, "board.servo_rail_brownout", "io", "set_servo_rail_v", 5.0)
