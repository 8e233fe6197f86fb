"""Six-sided accelerometer calibration and level horizon over MAVLink on the jig: an operator
(hil.calibration_jig.SideTurner) turns the vehicle to a pending side each time the vehicle asks,
the texts arrive in QGroundControl's order, and the offsets and scales written (and saved) are
the ones the accelerometer models were seeded with."""

from __future__ import annotations

import math

from pymavlink.dialects.v20 import common as mav

from hil.calibration_jig import SideTurner
from common.units import G0_M_S2

SIDES = ("back", "front", "left", "right", "up", "down")


class LingeringTurner(SideTurner):
    """Leaves the vehicle on its first side once more after it is done: the vehicle must say
    that side is already completed and ask again."""

    lingered = False

    def choose(self, pending):
        if not self.lingered and any(t.endswith("side done, rotate to a different side")
                                     for t in self.texts):
            self.lingered = True
            return ""
        return super().choose(pending)


def _expected(rig, device: str, topic: str, instance: int):
    model = rig.board.devices[device]
    err = model.engine.accel_err if device == "mpu6000" else model.accel_errors
    temp_c = rig.sensor(topic, instance)["temperature"]
    tc = err.p.temp_coeff * (temp_c - 25.0) if math.isfinite(temp_c) else 0.0
    return [err.bias[i] + err.drift[i] + tc for i in range(3)], [1.0 / s for s in err.scale]


def test_accel_calibration_six_sides(rig):
    gcs, params = rig.gcs, rig.params
    ids = [rig.sensor("sensor_accel", i)["device_id"] for i in range(2)]
    mark = gcs.mark()
    turner = LingeringTurner(gcs, rig.jig, turn_s=0.5)
    assert rig.calibrate(0, 0, 0, 0, 1).result == mav.MAV_RESULT_ACCEPTED
    turner.run(timeout_s=80.0)
    texts = rig.cal_texts(mark)
    assert texts[0] == "[cal] calibration started: 2 accel"
    assert texts[1] == "[cal] pending: back front left right up down"
    assert texts[-1] == "[cal] calibration done: accel"
    assert "[cal] down side already completed" in texts
    # every side: detected, then done, each once, in that order; the pending list shrinks
    for side in SIDES:
        det = texts.index(f"[cal] {side} orientation detected")
        done = texts.index(f"[cal] {side} side done, rotate to a different side")
        assert det < done
        assert texts.count(f"[cal] {side} side done, rotate to a different side") == 1
    pendings = [t.split(":")[1].split() for t in texts if t.startswith("[cal] pending:")]
    assert all(set(b) <= set(a) for a, b in zip(pendings, pendings[1:]))
    assert pendings[-1] and len(pendings[-1]) == 1
    progress = [int(t[len("[cal] progress <"):-1]) for t in texts if "progress <" in t]
    assert progress == sorted(progress) and progress[-1] == 100

    expected = {ids[0]: _expected(rig, "mpu6000", "sensor_accel", 0),
                ids[1]: _expected(rig, "lsm303d", "sensor_accel", 1)}
    got = {}
    for slot in range(3):
        dev = params[f"CAL_ACC{slot}_ID"]
        if dev:
            got[dev] = ([params[f"CAL_ACC{slot}_{a}OFF"] for a in "XYZ"],
                        [params[f"CAL_ACC{slot}_{a}SCALE"] for a in "XYZ"])
    assert set(got) == set(expected)
    for dev, (off, scale) in got.items():
        exp_off, exp_scale = expected[dev]
        for axis in range(3):
            assert abs(off[axis] - exp_off[axis]) < 0.02, (dev, off, exp_off)
            assert abs(scale[axis] - exp_scale[axis]) < 1.5e-3, (dev, scale, exp_scale)
    # the LSM303D's offsets are large (~0.1 m/s^2): a calibration that wrote nothing fails
    assert max(abs(v) for v in got[ids[1]][0]) > 0.05
    # applied: back level on the jig, the calibrated specific force is -g on z
    rig.jig.hold(0.0, 0.0)
    gcs.step(0.5)
    acc = rig.sensor("vehicle_acceleration", 0)["xyz"]
    assert abs(acc[0]) < 0.05 and abs(acc[1]) < 0.05 and abs(acc[2] + G0_M_S2) < 0.05
    # saved
    saved = {n: params[n] for n in params.match("CAL_ACC*")}
    params.reset_all()
    assert params.load()
    assert {n: params[n] for n in params.match("CAL_ACC*")} == saved


def test_level_horizon_folds_the_tilt_into_the_board_trims(rig):
    gcs, params, jig = rig.gcs, rig.params, rig.jig
    jig.hold(3.0, -2.0)
    try:
        gcs.step(1.0)
        mark = gcs.mark()
        assert rig.calibrate(0, 0, 0, 0, 2).result == mav.MAV_RESULT_ACCEPTED
        texts = rig.run_until_end(mark, timeout_s=5.0)
        assert texts[0] == "[cal] calibration started: 2 level"
        assert texts[-1] == "[cal] calibration done: level"
        assert abs(params["SENS_BOARD_X_OFF"] - 3.0) < 0.3
        assert abs(params["SENS_BOARD_Y_OFF"] + 2.0) < 0.3
        gcs.step(0.5)
        acc = rig.sensor("vehicle_acceleration", 0)["xyz"]
        # the tilted vehicle now reads level
        assert abs(acc[0]) < 0.06 and abs(acc[1]) < 0.06
    finally:
        jig.hold(0.0, 0.0)
        params.set("SENS_BOARD_X_OFF", 0.0)
        params.set("SENS_BOARD_Y_OFF", 0.0)
