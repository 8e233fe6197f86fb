"""World faults seen by the real FMU through its sensors and its power module's ADC."""

from __future__ import annotations

import pytest

from hil.faults import FaultError

pytestmark = pytest.mark.slow


def test_a_nearly_empty_pack_raises_the_battery_warning_and_a_mag_disturbance_reaches_the_mags(rig):
    orch = rig.orch
    rig.run_s(2.0)
    bat = orch.call("fmu", "topic", "battery_status")
    assert bat["warning"] == 0 and bat["remaining"] > 0.8
    rig.start("vehicle.battery_low", soc=0.02)
    # the pack now rests at ~3.41 V per cell, below BAT_V_EMPTY (3.5): remaining 0; the
    # voltage filter (tau 1 s) lets the estimate down within a few seconds
    took = rig.run_until(lambda: orch.call("fmu", "topic", "battery_status")["warning"] >= 2,
                         timeout_s=8, step_s=0.1)
    bat = orch.call("fmu", "topic", "battery_status")
    assert bat["voltage_v"] == pytest.approx(3 * 3.406, abs=0.15)
    assert bat["remaining"] < 0.07
    assert took > 0.2                      # filtered, not instant
    # the magnetometers: every instance sees the extra body-frame field
    mags = [orch.call("fmu", "topic", "sensor_mag", i) for i in range(2)]
    rig.start("vehicle.mag_interference", field_body_gauss=(0.0, 0.0, 0.3))
    rig.run_s(0.5)
    after = [orch.call("fmu", "topic", "sensor_mag", i) for i in range(2)]
    for before, now in zip(mags, after):
        dz = now["z"] - before["z"]
        # the sensor frames differ from the body frame by the board rotation; the field is
        # 0.3 G along body z: it shows on the sensor's z axis
        assert abs(abs(dz) - 0.3) < 0.05, (before, now)
    with pytest.raises(FaultError, match="three numbers"):
        rig.start("vehicle.mag_interference", field_body_gauss=(1.0, 2.0))
    with pytest.raises(FaultError, match="outside"):
        rig.start("vehicle.battery_low", soc=2.0)
