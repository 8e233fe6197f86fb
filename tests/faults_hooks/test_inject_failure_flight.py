"""A GPS and a motor failure injected over MAVLink in flight, and the vehicle's reaction.

The ground station sends MAV_CMD_INJECT_FAILURE as MAVSDK's failure plugin does (pymavlink
COMMAND_LONG); the FMU's failure_injector asks the orchestrator, whose injector (installed by
the pytest plugin's ``hil_vehicle``) starts the catalogue fault: ``gps.absent`` silences the
GPS module on its UART, ``vehicle.motor_failure`` stops motor 1 in the world. The flight
stack learns of each only through its drivers and sensors, and reacts as PX4 does: EKF2
stops fusing GPS after its 5 s timeout and the commander, unable to hold position, lands;
a quad-X with a dead rotor rolls over and the failure detector flags the attitude.
"""

from __future__ import annotations

import pytest
from pymavlink.dialects.v20 import common as mav

pytestmark = pytest.mark.slow

CMD = mav.MAV_CMD_INJECT_FAILURE


def _inject(v, unit: int, ftype: int, instance: int = 0):
    return v.gcs.command_long(CMD, [unit, ftype, instance], timeout_s=2.0, retries=0)


@pytest.mark.parametrize("hil_vehicle", [{"seed": 1, "params": {
    "SYS_FAILURE_EN": 1, "MIS_TAKEOFF_ALT": 5.0}}], indirect=True)
def test_gps_off_lands_and_motor_off_tumbles(hil_vehicle):
    v = hil_vehicle
    v.wait_for("home_set", within=40)
    v.wait_for("gps_fix >= 3", within=10)
    v.press_safety()
    v.wait_for("io.flags contains SAFETY_OFF", within=10)
    v.run(0.5)
    assert v.gcs.arm(timeout_s=5).result == mav.MAV_RESULT_ACCEPTED
    assert v.gcs.takeoff(5.0).result == mav.MAV_RESULT_ACCEPTED
    v.wait_for("alt_agl_m > 4.5", within=30)
    v.run(1.0)
    assert v.read("nav_state") == "Hold"
    v.read("gcs.text")  # from here on, only new STATUSTEXTs

    # GPS off: the module falls silent on its wire
    ack = _inject(v, mav.FAILURE_UNIT_SENSOR_GPS, mav.FAILURE_TYPE_OFF)
    assert ack.result == mav.MAV_RESULT_ACCEPTED
    fi = v.injector.failure_injection
    assert [a.kind.name for a in v.injector.history if a.active] == ["gps.absent"]
    assert fi.history[-1][1:5] == (mav.FAILURE_UNIT_SENSOR_GPS, mav.FAILURE_TYPE_OFF, 0, 0)
    v.wait_for("gps_age_s > 0.9", within=1.5)      # no more sensor_gps from the driver
    # dead reckoning until EKF2's GPS timeout (5 s), then Hold is impossible: Land
    assert v.check("nav_state == Hold") and not v.check("failsafe")
    v.run(3.0)
    assert v.read("nav_state") == "Hold", "left Hold before the estimator's GPS timeout"
    v.wait_for("nav_state == Land", within=3.5)
    texts = v.read("gcs.all_text")
    assert any("GPS fusion stopped" in t for t in texts), texts
    assert any("Hold not possible, Land instead" in t for t in texts), texts
    v.wait_for("alt_agl_m < 4.0", within=5)           # descending under control
    assert v.read("tilt_deg") < 10

    # GPS ok clears the fault; motor 1 off in the world, still 3-4 m up
    assert _inject(v, mav.FAILURE_UNIT_SENSOR_GPS, mav.FAILURE_TYPE_OK).result == \
        mav.MAV_RESULT_ACCEPTED
    assert not any(a.active for a in v.injector.history)
    ack = _inject(v, mav.FAILURE_UNIT_SYSTEM_MOTOR, mav.FAILURE_TYPE_OFF, 1)
    assert ack.result == mav.MAV_RESULT_ACCEPTED
    active = [(a.kind.name, a.target) for a in v.injector.history if a.active]
    assert active == [("vehicle.motor_failure", "motor1")]
    assert v.wait_for("tilt_deg > 45", within=0.6) < 0.6   # a quad-X cannot fly on three
    v.wait_for("topic.vehicle_status.failure_detector_status != 0", within=1.0)
