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


@fault_kind("board.fram_write_fail", level="board",
            doc="The FMU's FRAM (FM25V01 on SPI2) stops taking writes: its write-enable latch "
                "never sets after WREN (a failed charge pump, a chip at the end of its life). "
                "The FRAM driver checks WEL after each WREN and reports 'write enable latch "
                "did not set'; a parameter save fails and says so ('write to parameter slot n "
                "failed'); the other slot still holds the last good save, so nothing already "
                "saved is lost and the next boot loads it.")
def fram_write_fail(rig: Rig, target: str, params: dict[str, Any], t_ns: int) -> Any:
    board_call(rig, "board.fram_write_fail", "fmu", "fault", "fram", "write_fail", True)
    return None


@fram_write_fail.stopper
def _fram_write_fail_stop(rig: Rig, target: str, params: dict[str, Any], t_ns: int,
                          token: Any) -> None:
    board_call(rig, "board.fram_write_fail", "fmu", "fault", "fram", "write_fail", False)


@fault_kind("board.cpu_overload", level="board", fraction=0.8, period_us=1000,
            doc="A work item on a PX4 work queue of the FMU (target the queue, e.g. "
                "'wq:SPI1', 'wq:rate_ctrl', 'wq:INS0') burns `fraction` of every period_us "
                "of CPU time: a runaway module or a driver spinning. The queue's other items "
                "start late by up to that much: sensor samples reach the estimator older, the "
                "rate controller runs late, visible in the perf counters and in the "
                "timestamp - timestamp_sample of what the queue publishes.")
def cpu_overload(rig: Rig, target: str, params: dict[str, Any], t_ns: int) -> Any:
    name = "board.cpu_overload"
    frac = number(params, "fraction", name, 0.0, 0.99)
    period = int(number(params, "period_us", name, 100, 1_000_000))
    board_call(rig, name, "fmu", "cpu_load", target, frac, period)
    return None


@cpu_overload.stopper
def _cpu_overload_stop(rig: Rig, target: str, params: dict[str, Any], t_ns: int,
                       token: Any) -> None:
    board_call(rig, "board.cpu_overload", "fmu", "cpu_load", target, 0.0)


@fault_kind("sensor.bias_drift", level="sensor", rate=(0.01, 0.0, 0.0),
            doc="A sensor's bias drifts at `rate` SI units per second per axis (target the FMU "
                "device: mpu6000 gyro rad/s/s, l3gd20, lsm303d accel m/s^2/s, hmc5883 gauss/s, "
                "ms5611 Pa/s on the first axis): a temperature-driven or aging drift, a part "
                "slowly magnetised. The chip's output ramps (updated every 10 ms); the "
                "estimator's bias states follow a slow drift, a fast one shows as growing "
                "innovations and, between redundant sensors, as inconsistency in the voter. "
                "Stopping leaves the bias where it got to.")
def bias_drift(rig: Rig, target: str, params: dict[str, Any], t_ns: int) -> Any:
    from hil.faults._rig import vector

    rate = vector(params, "rate", "sensor.bias_drift")
    board_call(rig, "sensor.bias_drift", "fmu", "sensor_drift", target, rate)
    return None


@bias_drift.stopper
def _bias_drift_stop(rig: Rig, target: str, params: dict[str, Any], t_ns: int,
                     token: Any) -> None:
    board_call(rig, "sensor.bias_drift", "fmu", "sensor_drift", target, (0.0, 0.0, 0.0))
