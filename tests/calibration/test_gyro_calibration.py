"""Gyro calibration over MAVLink (pymavlink, QGroundControl's protocol) on the jig: refused
while armed, runs to completion with QGC's texts in order, writes the offsets the gyro models
were seeded with and saves them, and fails as PX4 does when cancelled or moved."""

from __future__ import annotations

from pymavlink.dialects.v20 import common as mav

from tests.calibration.conftest import CAL


def _expected_offset(rig, device: str, errors_attr: str, topic: str, instance: int):
    """The board-frame offset a gyro model produces at rest: its seeded bias, its bias drift so
    far and its temperature coefficient at the die temperature its driver reports (neither
    model is mounted rotated on the FMUv2, so chip and board axes agree)."""
    model = rig.board.devices[device]
    err = getattr(model, errors_attr) if errors_attr else model.engine.gyro_err
    temp_c = rig.sensor(topic, instance)["temperature"]
    tc = err.p.temp_coeff * (temp_c - 25.0)
    return [err.bias[i] + err.drift[i] + tc for i in range(3)]


def test_calibration_refused_while_armed(rig):
    gcs = rig.gcs
    assert gcs.arm(force=True).result == mav.MAV_RESULT_ACCEPTED
    try:
        mark = gcs.mark()
        assert rig.calibrate(1).result == mav.MAV_RESULT_TEMPORARILY_REJECTED
        gcs.step(0.1)
        assert not any(t.startswith("[cal] calibration started") for t in rig.texts(mark))
    finally:
        assert gcs.disarm(force=True).result == mav.MAV_RESULT_ACCEPTED


def test_unsupported_calibration_is_said(rig):
    mark = rig.gcs.mark()
    assert rig.calibrate(0, 0, 0, 0, 0, 0, 1).result == mav.MAV_RESULT_UNSUPPORTED  # ESC
    rig.gcs.step(0.1)
    assert "[cal] calibration failed: not supported" in rig.texts(mark)


def test_gyro_calibration_writes_the_seeded_offsets_and_saves_them(rig):
    params, gcs = rig.params, rig.gcs
    gyro_ids = [rig.sensor("sensor_gyro", i)["device_id"] for i in range(2)]
    mark = gcs.mark()
    assert rig.calibrate(1).result == mav.MAV_RESULT_ACCEPTED
    texts = rig.run_until_end(mark, timeout_s=5.0)
    assert texts[0] == "[cal] calibration started: 2 gyro"
    assert texts[-1] == "[cal] calibration done: gyro"
    progress = [int(t[len("[cal] progress <"):-1]) for t in texts if "progress <" in t]
    assert progress == sorted(progress) and progress[0] < 10 and progress[-1] == 100, "\n".join(texts)
    # each gyro in a slot of its own, by device id, with the offsets its model was seeded with
    expected = {gyro_ids[0]: _expected_offset(rig, "mpu6000", "", "sensor_gyro", 0),
                gyro_ids[1]: _expected_offset(rig, "l3gd20", "errors", "sensor_gyro", 1)}
    got = {}
    for slot in range(3):
        dev = params[f"CAL_GYRO{slot}_ID"]
        if dev:
            got[dev] = [params[f"CAL_GYRO{slot}_{a}OFF"] for a in "XYZ"]
    assert set(got) == set(expected)
    # the averages' noise: the MPU6000 delivers 20-sample averages (~1e-4 rad/s left after
    # 250), the L3GD20 single samples of ~1e-2 rad/s (~5e-4 left after ~470)
    tolerance = {gyro_ids[0]: 3e-4, gyro_ids[1]: 2e-3}
    for dev, off in got.items():
        exp = expected[dev]
        err = [off[i] - exp[i] for i in range(3)]
        assert max(abs(e) for e in err) < tolerance[dev], (dev, off, exp)
        # and far closer to the seeded offset than no calibration would be
        assert sum(e * e for e in err) < 0.1 * sum(v * v for v in exp), (dev, off, exp)
    # applied by the sensors module: the rate the controllers see at rest is ~0 now
    rate = rig.sensor("vehicle_angular_velocity", 0)["xyz"]
    assert max(abs(v) for v in rate) < 2e-3
    # saved: they survive a reload of the parameters from FRAM
    saved = {n: params[n] for n in params.match("CAL_GYRO*")}
    params.reset_all()
    assert params.load()
    assert {n: params[n] for n in params.match("CAL_GYRO*")} == saved


def test_gyro_calibration_cancelled(rig):
    gcs = rig.gcs
    before = {n: rig.params[n] for n in rig.params.match("CAL_GYRO*")}
    mark = gcs.mark()
    assert rig.calibrate(1).result == mav.MAV_RESULT_ACCEPTED
    gcs.step(0.2)
    assert rig.calibrate(1).result == mav.MAV_RESULT_DENIED  # one at a time
    assert rig.calibrate(0, 0, 0, 0, 0, 0, 0).result == mav.MAV_RESULT_ACCEPTED  # QGC's Cancel
    texts = rig.run_until_end(mark, timeout_s=1.0)
    assert texts[0] == "[cal] calibration started: 2 gyro"
    assert texts[-1] == "[cal] calibration cancelled"
    assert "[cal] calibration done: gyro" not in texts
    assert {n: rig.params[n] for n in rig.params.match("CAL_GYRO*")} == before


def test_gyro_calibration_fails_when_the_vehicle_moves(rig):
    gcs, jig = rig.gcs, rig.jig
    before = {n: rig.params[n] for n in rig.params.match("CAL_GYRO*")}
    mark = gcs.mark()
    jig.shake(amplitude_rad_s=0.3, freq_hz=2.0, duration_s=30.0)
    try:
        assert rig.calibrate(1).result == mav.MAV_RESULT_ACCEPTED
        texts = rig.run_until_end(mark, timeout_s=30.0)
    finally:
        jig.hold(0.0, 0.0)
    assert texts[0] == "[cal] calibration started: 2 gyro"
    retries = texts.count("[cal] motion, retrying..")
    assert retries == 19  # PX4: 20 tries
    assert texts[-1] == "[cal] calibration failed: motion"
    assert {n: rig.params[n] for n in rig.params.match("CAL_GYRO*")} == before
