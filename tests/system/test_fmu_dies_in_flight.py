"""Killing the FMU process in flight: the orchestrator survives, the IO goes to its failsafe
outputs within its timeout, and the world records the fall."""

from __future__ import annotations

import pytest

from hil.system import SystemConfig, build_system

pytestmark = pytest.mark.slow
S = 1_000_000_000
IO_FMU_LOSS_S = 0.5          # E14 FMU_INPUT_DROP_LIMIT_US
FAILSAFE_US = 900            # quad_x mixer-derived failsafe (E14), one tick short on the pin


def test_kill_fmu_in_hover(tmp_path):
    orch, dev = build_system(SystemConfig(
        seed=3, out_dir=str(tmp_path), gcs=True,
        params={"MIS_TAKEOFF_ALT": 10.0, "EKF2_MAG_DECL": 2.6}))
    gcs, world = dev["gcs"], dev["world"].world
    samples: list[tuple[float, float, list[float]]] = []
    orch.on_quantum.append(lambda o: samples.append(
        (o.t_ns / S, world.truth().agl_m, [e.pulse_us for e in world.escs[:4]]))
        if o.t_ns % (10 * 1_000_000) == 0 else None)
    with orch:
        gcs.attach(orch)
        gcs.wait_heartbeat(timeout_s=10)
        gcs.wait_for(lambda: (gp := gcs.last.get("GPS_RAW_INT")) is not None and gp.fix_type >= 3
                     and gcs.last.get("HOME_POSITION") is not None, timeout_s=60)
        dev["safety"].press(orch.t_ns + S // 10, hold_s=1.5)  # once ready, as a pilot does
        gcs.step(2.0)
        assert gcs.arm(timeout_s=5).result == 0
        assert gcs.takeoff(10.0).result == 0
        gcs.wait_for(lambda: world.truth().agl_m > 9.5, timeout_s=30)
        gcs.step(2.0)
        t_kill = orch.t_ns / S
        orch.kill("fmu")
        orch.run(duration_ns=8 * S)
        assert "fmu" in orch.dead and "killed by signal 9" in orch.dead["fmu"]
        assert not orch.dead.get("io")
    after = [s for s in samples if s[0] > t_kill]
    failsafe = next(s for s in after if all(abs(p - FAILSAFE_US) <= 1 for p in s[2]))
    # The IO notices on its first loop pass after 0.5 s without controls, then one PWM period.
    assert failsafe[0] - t_kill <= IO_FMU_LOSS_S + 0.02
    assert min(s[1] for s in after) < 0.5               # the vehicle fell to the ground
    assert after[0][1] > 9.0
