"""Magnetometer calibration with rotations over MAVLink on the jig: with a hard-iron offset on
each compass (a magnet near it: the chips' bias fault, in gauss), the operator puts the vehicle
on each side CAL_MAG_SIDES asks for and spins it once about the vertical when told; the sphere
fit's offsets are the compasses' offsets, and they are saved."""

from __future__ import annotations

from pymavlink.dialects.v20 import common as mav

from hil.calibration_jig import SideTurner

HMC_IRON = (0.12, -0.06, 0.09)
LSM_IRON = (-0.08, 0.05, 0.10)


def test_mag_calibration_on_three_sides(rig):
    gcs, params, board = rig.gcs, rig.params, rig.board
    ids = {"lsm303d": rig.sensor("sensor_mag", 0)["device_id"],
           "hmc5883": rig.sensor("sensor_mag", 1)["device_id"]}
    hmc, lsm = board.devices["hmc5883"], board.devices["lsm303d"]
    params.set("CAL_MAG_SIDES", 38)  # PX4's three sides: front, left, down
    hmc.faults.bias_step, lsm.faults.bias_step = HMC_IRON, LSM_IRON
    try:
        gcs.step(0.3)
        mark = gcs.mark()
        turner = SideTurner(gcs, rig.jig, turn_s=0.5, spin_s=1.5)
        assert rig.calibrate(0, 1).result == mav.MAV_RESULT_ACCEPTED
        turner.run(timeout_s=40.0)
    finally:
        hmc.faults.bias_step = lsm.faults.bias_step = (0.0, 0.0, 0.0)
        rig.jig.hold(0.0, 0.0)
    texts = rig.cal_texts(mark)
    assert texts[0] == "[cal] calibration started: 2 mag"
    # the sides left out are done from the start, as PX4 reports them
    assert texts[1:4] == [f"[cal] {s} side done, rotate to a different side"
                          for s in ("back", "right", "up")]
    assert texts[4] == "[cal] pending: front left down"
    for side in ("front", "left", "down"):
        det = texts.index(f"[cal] {side} orientation detected")
        assert texts[det + 1] == "[cal] Rotate vehicle around the detected orientation"
        assert texts.index(f"[cal] {side} side done, rotate to a different side") > det
    assert texts[-1] == "[cal] calibration done: mag"

    lsm_err = lsm.mag_errors
    expected = {ids["lsm303d"]: [lsm_err.bias[i] + lsm_err.drift[i] + LSM_IRON[i]
                                 for i in range(3)],
                ids["hmc5883"]: [hmc.errors.bias[i] + HMC_IRON[i] for i in range(3)]}
    got = {}
    for slot in range(4):
        dev = params[f"CAL_MAG{slot}_ID"]
        if dev:
            got[dev] = [params[f"CAL_MAG{slot}_{a}OFF"] for a in "XYZ"]
            assert [params[f"CAL_MAG{slot}_{a}SCALE"] for a in "XYZ"] == [1.0] * 3
    assert set(got) == set(expected)
    for dev, off in got.items():
        # noise (~5 mG per LSM303D sample) and the chips' 1 % scale errors (an ellipsoid,
        # not a sphere) leave a few milligauss; the offsets themselves are ~0.1 G
        assert max(abs(off[i] - expected[dev][i]) for i in range(3)) < 1e-2, (dev, off)
    saved = {n: params[n] for n in params.match("CAL_MAG*")}
    params.reset_all()
    assert params.load()
    assert {n: params[n] for n in params.match("CAL_MAG*")} == saved
    params.set("CAL_MAG_SIDES", 63)
