"""The IO's manual override end to end: the FMU dies in a hover and the pilot's sticks reach
the motors through the IO's own mixer within the IO's FMU-loss timeout (override allowed on
this multicopter with IO_OVERRIDE_EN, as E14 allows it for fixed wing)."""

from __future__ import annotations

import pytest

from hil.system import SystemConfig, build_system

pytestmark = pytest.mark.slow
S = 1_000_000_000
MS = 1_000_000


def test_pilot_sticks_reach_the_motors_when_the_fmu_dies(tmp_path):
    orch, dev = build_system(SystemConfig(
        seed=5, out_dir=str(tmp_path), gcs=True,
        params={"MIS_TAKEOFF_ALT": 10.0, "EKF2_MAG_DECL": 2.6, "IO_OVERRIDE_EN": 1}))
    gcs, world, tx = dev["gcs"], dev["world"].world, dev["rc"].tx
    with orch:
        gcs.attach(orch)
        gcs.wait_heartbeat(timeout_s=10)
        gcs.wait_for(lambda: (gp := gcs.last.get("GPS_RAW_INT")) is not None and gp.fix_type >= 3
                     and gcs.last.get("HOME_POSITION") is not None, timeout_s=60)
        dev["safety"].press(orch.t_ns + S // 10, hold_s=1.5)
        gcs.step(2.0)
        assert gcs.arm(timeout_s=5).result == 0
        assert gcs.takeoff(10.0).result == 0
        gcs.wait_for(lambda: world.truth().agl_m > 9.5, timeout_s=30)
        io = orch.call("io", "status")
        assert "MANUAL_OVERRIDE_OK" in io["arming_names"]
        # The pilot holds the sticks centred, throttle at 70 %.
        tx.set_sticks(orch.t_ns, roll=0.0, pitch=0.0, yaw=0.0, throttle=0.7)
        gcs.step(1.0)
        t_kill = orch.t_ns
        orch.kill("fmu")
        orch.run(duration_ns=int(0.52 * S))
        io = orch.call("io", "status")
        assert io["source"] == "override", io["source"]
        high = [e.pulse_us for e in world.escs[:4]]
        assert all(p > 1500 for p in high), high          # 70 % throttle, not the failsafe
        # The pilot pulls the throttle down: the motors follow through the IO.
        tx.set_sticks(orch.t_ns, throttle=0.2)
        orch.run(duration_ns=200 * MS)
        low = [e.pulse_us for e in world.escs[:4]]
        assert all(lo < hi - 200 for lo, hi in zip(low, high)), (low, high)
        assert (orch.t_ns - t_kill) < 1 * S
