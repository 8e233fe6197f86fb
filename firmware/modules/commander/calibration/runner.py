"""The calibration work item and MAV_CMD_PREFLIGHT_CALIBRATION's parameters.

PX4's commander runs a calibration inside its own thread and blocks there until the vehicle
has been turned through every side; here the routine is a state machine on a work item of its
own (``wq:lp_default``, every :data:`STEP_US`), so the commander keeps its 100 Hz loop, its
failsafes and its acks while a calibration runs. The work item belongs to the commander
module (its ``work_items``), so stopping the commander ends a calibration too.

Command parameters as MAVLink defines them and PX4 reads them: param1 1 gyro, param2 1
magnetometer, param5 1 accelerometer (six sides), param5 2 level horizon; params 1 to 6 all 0
cancel a running calibration (QGroundControl's Cancel button), and with none running are
ACCEPTED (the end of an RC calibration, which QGC does itself). Other calibrations (baro,
RC trim, airspeed, ESC, quick accel) are UNSUPPORTED. A new request while one runs is DENIED,
as PX4 denies every command during a calibration.
"""

from __future__ import annotations

from typing import Any, Final

from firmware.modules.commander.calibration import messages as msg
from firmware.modules.commander.calibration.common import CRITICAL, RUNNING, Routine, Say
from firmware.platform.workqueue import WorkItem

__all__ = ["ACCEPTED", "DENIED", "UNSUPPORTED", "CalibrationRunner", "request"]

STEP_US: Final = 4_000
ACCEPTED, DENIED, UNSUPPORTED = 0, 2, 3


class CalibrationRunner(WorkItem):
    """Steps the running routine until it ends."""

    def __init__(self, platform: Any) -> None:
        super().__init__(platform, "calibration", "wq:lp_default")
        # on the instance: compiled WorkItem code would not see a class attribute of this
        # ordinary subclass (tests/hil/test_native_attributes.py)
        self.cpu_cost_ns = 20_000
        self.routine: Routine | None = None
        self.results: list[tuple[str, int]] = []

    @property
    def busy(self) -> bool:
        return self.routine is not None

    def start(self, routine: Routine) -> None:
        self.routine = routine
        self.schedule_on_interval(STEP_US)

    def cancel(self) -> None:
        if self.routine is not None:
            self.routine.cancel()
            self.schedule_now()

    def run(self) -> None:
        r = self.routine
        if r is None:
            self.schedule_clear()
            return
        status = r.step(self.platform.time_us())
        if status != RUNNING:
            self.results.append((r.KIND, status))
            self.routine = None
            self.schedule_clear()


def _int(value: float) -> int:
    """A command parameter as PX4 reads it, ``(int)param`` (truncated); NaN, MAVLink's
    "unused", and infinities are 0."""
    if value != value or value in (float("inf"), float("-inf")):
        return 0
    return int(value)


def _routine(params7: list[int], orb: Any, params: Any, say: Say) -> Routine | None:
    p1, p2, _p3, _p4, p5, _p6, _p7 = params7
    if p1 == 1:
        from firmware.modules.commander.calibration.gyro import GyroCalibration
        return GyroCalibration(orb, params, say)
    if p2 == 1:
        from firmware.modules.commander.calibration.mag import MagCalibration
        return MagCalibration(orb, params, say)
    if p5 == 1:
        from firmware.modules.commander.calibration.accel import AccelCalibration
        return AccelCalibration(orb, params, say)
    if p5 == 2:
        from firmware.modules.commander.calibration.level import LevelCalibration
        return LevelCalibration(orb, params, say)
    return None


def _sayer(module: Any) -> Say:
    """PX4's ``mavlink_log_*`` for the calibration texts: a line in dmesg (module commander) and
    a ``log_message`` whose text is exactly the calibration text. The platform's log prefixes
    ``[module] `` to what it sends the GCS, and QGroundControl's sensor page only reads texts
    that *start* with ``[cal] ``."""
    platform = module.platform
    pub = platform.orb.advertise("log_message")
    m = platform.orb.new("log_message")

    def say(severity: int, text: str) -> None:
        t = platform.time_us()
        platform.dmesg.append((t, severity, module.name, text))
        m.timestamp = t
        m.severity = severity
        m.text = text[:126]
        pub.publish(m)

    return say


def request(module: Any, cmd: Any) -> tuple[int, str]:
    """Start, cancel or refuse a calibration for the commander ``module``; (result, reason).
    The armed check is the commander's (TEMPORARILY_REJECTED before this is called)."""
    values = [_int(float(v)) for v in (cmd.param1, cmd.param2, cmd.param3, cmd.param4,
                                       cmd.param5, cmd.param6, cmd.param7)]
    runner = next((w for w in module.work_items if isinstance(w, CalibrationRunner)), None)
    busy = runner is not None and runner.busy

    say = _sayer(module)

    if busy and runner is not None and all(v == 0 for v in values[:6]):
        say(CRITICAL, msg.CANCELLED)
        runner.cancel()
        return ACCEPTED, ""
    if all(v == 0 for v in values):
        return ACCEPTED, ""
    if busy:
        text = f"command denied during calibration: {int(cmd.command)}"
        say(CRITICAL, text)
        return DENIED, text
    params = module.system.params
    routine = _routine(values, module.platform.orb, params, say) if params is not None else None
    if routine is None:
        text = msg.failed("not supported")
        say(4, text)
        return UNSUPPORTED, text
    if runner is None:
        runner = module.add_work_item(CalibrationRunner(module.platform))
    runner.start(routine)
    return ACCEPTED, ""
