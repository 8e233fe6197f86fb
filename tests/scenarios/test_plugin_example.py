"""An example test written only with the hil pytest plugin's fixtures (hil.pytest_plugin)."""

from __future__ import annotations

import pytest


@pytest.mark.parametrize("hil_vehicle", [{"seed": 2}], indirect=True)
def test_primary_imu_failure_fails_over_within_100_ms(hil_vehicle):
    v = hil_vehicle
    v.wait_for("imu_healthy[0:2]", within=3.0)
    v.run(0.5)
    assert v.read("imu_primary") == 0
    v.fault("sensor.absent", "mpu6000")
    took = v.wait_for("imu_primary == 1", within=0.1, step=0.005)
    assert took < 0.1
    assert v.read("imu_failovers") >= 1
    assert not v.check("estimator_fault")


def test_transmitter_off_is_seen_by_the_fmu_as_receiver_failsafe(hil_vehicle):
    v = hil_vehicle
    v.wait_for("not rc_lost", within=3.0)
    v.sticks(throttle=0.2)
    v.wait_for("rc_channels_us[2] == 1200 +- 2", within=0.5)
    v.fault("rc.tx_off")
    took = v.wait_for("rc_failsafe", within=1.5)
    assert 0.9 < took < 1.3  # the S.BUS receiver's ~1 s failsafe delay
