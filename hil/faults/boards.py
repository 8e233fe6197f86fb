"""Board faults: a processor stops, hangs, reboots or resets.

* ``board.crash``: the board's process is killed (a hard fault with no recovery, a lost
  supply). The orchestrator then gives its outputs those of a dead chip: UARTs silent, PWM
  pins without pulses, driven pins released.
* ``board.fmu_hang`` / ``board.io_hang``: the processor stops executing but keeps its pins (a
  deadlock, an endless interrupt, a clock failure with the watchdog disabled): its kernel stops
  dispatching events, nothing more leaves it, every pin stays at the level it had, and the
  process lives on; stopping the fault resumes it (``ctl_hang``/``ctl_release``).
* ``board.servo_rail_brownout``, ``board.fram_write_fail``, ``board.cpu_overload``: a sagging
  servo rail, an FRAM that stops taking writes, a greedy work item on a work queue.
* ``board.fmu_reboot``: the FMU crashes and comes back (the watchdog resets it, or a brown-out):
  power-cycled after ``down_s``, it boots from its own time zero on the same FRAM, as the
  orchestrator's reboot path does for ``reboot`` on the console.
* ``board.io_reset``: the IO coprocessor resets (brown-out, watchdog) and goes through its bootloader
  again; the FMU's px4io driver must notice and reconfigure it.

While a board is dead or hung its control calls fail; the scenario engine reads its
observables as missing.
"""

from __future__ import annotations

from typing import Any

from hil.faults import NS_PER_S, FaultError, Rig, fault_kind, switch_kind
from hil.faults._rig import board_call, number, orchestrator

BOARDS = ("fmu", "io")


def _check_running(orch: Any, target: str, kind: str) -> None:
    if orch is not None and target in orch.dead:
        raise FaultError(f"fault {kind}: board {target} is already dead ({orch.dead[target]})")


@fault_kind("board.crash", level="board", targets=BOARDS,
            doc="The board's processor dies for good (hard fault without recovery, lost "
                "supply). For the FMU: the IO stops receiving controls and, after its FMU-loss "
                "timeout (500 ms in E14), drives the failsafe PWM values, or hands the motors "
                "to the pilot's RC when manual override is allowed. For the IO: the FMU's "
                "px4io driver loses its link and the motors get no pulses.")
def crash_start(rig: Any, target: str, params: dict[str, Any], t_ns: int) -> None:
    orch = orchestrator(rig, "board.crash")
    _check_running(orch, target, "board.crash")
    orch.kill(target)


def _restart(orch: Any, name: str) -> None:
    orch.dead.pop(name, None)
    orch._restart(name)  # the orchestrator's reboot path (a new board, same FRAM)


@fault_kind("board.fmu_reboot", level="board", targets=("fmu",), down_s=0.0,
            doc="The FMU crashes and reboots (watchdog reset, brown-out): dead for ``down_s`` "
                "(0: reset at once), then a new FMU boots from its own time zero on the same "
                "FRAM. The IO meanwhile times out to failsafe (or override). If the IO was "
                "armed with INAIR_RESTART_OK (``px4io recovery``), the rebooted FMU's px4io "
                "driver finds it armed and asks the commander to arm again: the in-air "
                "restart.")
def reboot_start(rig: Any, target: str, params: dict[str, Any], t_ns: int) -> None:
    orch = orchestrator(rig, "board.fmu_reboot")
    down_s = float(params["down_s"])
    if down_s < 0:
        raise FaultError(f"fault board.fmu_reboot: negative down_s {down_s}")
    if down_s == 0:
        _restart(orch, target)
        return
    later = getattr(rig, "later", None)
    if later is None:
        raise FaultError("fault board.fmu_reboot with down_s > 0 needs a rig with timers "
                         "(hil.faults.Injector)")
    if target not in orch.dead:
        orch.kill(target)
    later(t_ns + round(down_s * NS_PER_S), lambda now: _restart(orch, target))


@fault_kind("board.io_reset", level="board", targets=("io",),
            doc="The IO coprocessor resets (brown-out on the servo rail, watchdog): it runs "
                "its bootloader again (200 ms) and restarts with its registers at reset "
                "values, outputs disarmed. The FMU's px4io driver sees the reset in the IO's "
                "status and configures it again; in flight that is a short loss of thrust.")
def io_reset_start(rig: Any, target: str, params: dict[str, Any], t_ns: int) -> None:
    _check_running(rig.orch, target, "board.io_reset")
    board_call(rig, "board.io_reset", "io", "reset")


def _hang(board: str) -> Any:
    def apply(rig: Rig, target: str, params: dict[str, Any], on: bool) -> Any:
        return board_call(rig, f"board.{board}_hang", board, "hang" if on else "release")

    return apply


switch_kind(
    "board.fmu_hang", _hang("fmu"), level="board",
    doc="The FMU's CPU halts (a lock-up with interrupts masked, a hard-fault loop without a "
        "watchdog): no firmware, interrupt or timer callback runs and nothing new is sent, but "
        "the process lives and its pins hold their last levels. The IO stops receiving "
        "CONTROLS and after 500 ms declares the FMU lost (ALARM_FMU_LOST) and drives its "
        "failsafe PWM, or hands the motors to the pilot's RC override when allowed. Stopping "
        "the fault resumes the CPU where it was: the interrupts that fell due run first and the "
        "flight stack catches up from the present time (its estimator sees a gap).")
switch_kind(
    "board.io_hang", _hang("io"), level="board",
    doc="The IO's CPU halts: its timers keep generating the last PWM (hardware), but nothing "
        "answers the FMU, so the px4io driver times out and reports the IO lost after 10 "
        "failed calls; RC input and the safety switch are no longer processed. Stopping the "
        "fault resumes the IO firmware.")


def _servo_rail(rig: Rig, target: str, params: dict[str, Any], on: bool) -> None:
    name = "board.servo_rail_brownout"
    volts = number(params, "volts", name, 0.0, 10.0) if on else 5.0
    board_call(rig, name, "io", "set_servo_rail_v", volts)


switch_kind("board.servo_rail_brownout", _servo_rail, level="board", volts=4.2,
            doc="The IO's servo rail (VSERVO, normally 5 V from the BEC) sags to `volts`, as "
                "when a servo stalls or the BEC fails. The IO measures it on its ADC, reports "
                "it in its STATUS page (px4io_status.voltage_v) and the FMU logs it.")


def _fram_write_fail(rig: Rig, target: str, params: dict[str, Any], on: bool) -> None:
    board_call(rig, "board.fram_write_fail", "fmu", "fault", "fram", "write_fail", on)


switch_kind("board.fram_write_fail", _fram_write_fail, level="board",
            doc="The FMU's FRAM (FM25V01 on SPI2) stops taking writes: its write-enable latch "
                "never sets after WREN (a failed charge pump, a chip at the end of its life). "
                "The FRAM driver checks WEL after each WREN and reports 'write enable latch "
                "did not set'; a parameter save fails and says so ('write to parameter slot n "
                "failed'); the other slot still holds the last good save, so nothing already "
                "saved is lost and the next boot loads it.")


def _cpu_overload(rig: Rig, target: str, params: dict[str, Any], on: bool) -> None:
    name = "board.cpu_overload"
    if not on:
        board_call(rig, name, "fmu", "cpu_load", target, 0.0)
        return
    frac = number(params, "fraction", name, 0.0, 0.99)
    period = int(number(params, "period_us", name, 100, 1_000_000))
    board_call(rig, name, "fmu", "cpu_load", target, frac, period)


switch_kind("board.cpu_overload", _cpu_overload, level="board", fraction=0.8, period_us=1000,
            doc="A work item on a PX4 work queue of the FMU (target the queue, e.g. "
                "'wq:SPI1', 'wq:rate_ctrl', 'wq:INS0') burns `fraction` of every period_us "
                "of CPU time: a runaway module or a driver spinning. The queue's other items "
                "start late by up to that much: sensor samples reach the estimator older, the "
                "rate controller runs late, visible in the perf counters and in the "
                "timestamp - timestamp_sample of what the queue publishes.")


def _sensor_rail(rig: Rig, target: str, params: dict[str, Any], on: bool) -> Any:
    name = "board.sensor_rail_brownout"
    if on:
        _check_running(rig.orch, target, name)
    return board_call(rig, name, "fmu", "sensor_rail", not on)


switch_kind("board.sensor_rail_brownout", _sensor_rail, level="board", targets=("fmu",),
            doc="The FMU's sensor 3.3 V rail (VDD_3V3_SENSORS, switched by PE3 on FMUv2) sags "
                "below the chips' brown-out level while the fault lasts (a short on a sensor "
                "lead, an overloaded regulator): every chip on it (MPU6000, L3GD20, LSM303D, "
                "MS5611; not the GPS module's compass nor the FRAM) loses power, its SPI "
                "reads give 0xFF, its data-ready lines stop; when the rail returns each goes "
                "through its power-on reset. PX4's drivers see the 0xFF answers and lost "
                "configuration, reset and re-initialise their chips; the sensors come back "
                "after the rail with a gap of about 100-200 ms (the MPU6000's 100 ms reset).")
