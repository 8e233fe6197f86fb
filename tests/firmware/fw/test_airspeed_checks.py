"""The airspeed validator's checks (firmware/modules/sensors/airspeed.py) on a blocked pitot:
PX4's ASPD_DO_CHECKS bits, the load factor check, and the rule that the consistency and load
factor checks failing together invalidate the airspeed at once (else after ASPD_FS_T_STOP).

The Airspeed part is fed through stand-in subscriptions: each test sets what the topics hold
(the MS4525DO's differential pressure, the ground speed, the specific force, the vehicle's
state) and steps it at the sensor's 100 Hz."""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import pytest

from firmware.modules.sensors.airspeed import AIRSPEED_PARAMS, Airspeed, LoadFactorCheck

RHO0 = 1.225


class _Sub:
    def __init__(self) -> None:
        self.msg: Any = None
        self.fresh = False

    def set(self, **fields: Any) -> None:
        self.msg = SimpleNamespace(**fields)
        self.fresh = True

    def updated(self) -> bool:
        return self.fresh

    def copy(self) -> Any:
        self.fresh = False
        return self.msg


class _Pub:
    def __init__(self) -> None:
        self.last: Any = None

    def publish(self, m: Any) -> None:
        self.last = SimpleNamespace(**vars(m))


class Rig:
    def __init__(self, checks: int) -> None:
        self.subs: dict[str, _Sub] = {}
        self.pub = _Pub()
        self.asp = Airspeed(self._subscribe, lambda topic: self.pub, SimpleNamespace())
        defaults = {d.name: d.default for d in AIRSPEED_PARAMS}
        defaults["ASPD_DO_CHECKS"] = checks
        self.asp.set_params(lambda name: defaults[name])
        self.t_us = 1_000_000
        self.subs["vehicle_air_data"].set(baro_pressure_pa=101325.0, baro_temp_celcius=20.0)
        self.subs["vehicle_status"].set(arming_state=2, vehicle_type=2)
        self.subs["vehicle_land_detected"].set(landed=False)
        self.subs["vehicle_acceleration"].set(xyz=[0.0, 0.0, -9.81])     # level flight: 1 g
        self.subs["vehicle_local_position"].set(v_xy_valid=True, vx=16.0, vy=0.0)

    def _subscribe(self, topic: str) -> _Sub:
        return self.subs.setdefault(topic, _Sub())

    def run(self, seconds: float, airspeed_m_s: float) -> list[float]:
        """Samples of a pitot that reads ``airspeed_m_s``; the confidences published."""
        dp = 0.5 * RHO0 * airspeed_m_s ** 2
        out = []
        for i in range(round(seconds * 100)):
            self.t_us += 10_000
            # a little noise, so the data-stuck check does not see equal values
            noisy = dp + (0.01 if i % 2 else -0.01)
            self.subs["differential_pressure"].set(
                differential_pressure_raw_pa=noisy, differential_pressure_filtered_pa=noisy,
                error_count=0, temperature=20.0)
            self.asp.update(self.t_us)
            out.append(self.pub.last.confidence)
        return out


@pytest.mark.parametrize("checks, invalid_within_s", [(7, 2.1), (15, 0.2)])
def test_a_blocked_pitot_is_invalid_at_once_only_when_both_checks_fail(checks, invalid_within_s):
    """PX4's default ASPD_DO_CHECKS 7 (no load factor check): invalid after ASPD_FS_T_STOP
    (2 s); with bit 3 the load factor 1 g at ~0 m/s fails too, and both at once invalidate."""
    rig = Rig(checks)
    assert min(rig.run(5.0, 16.0)) > 0.9 and not rig.asp.load_factor.failed
    conf = rig.run(3.0, 0.0)
    first_invalid_s = next(i for i, c in enumerate(conf) if c == 0.0) / 100.0
    assert first_invalid_s <= invalid_within_s
    if checks == 7:
        assert first_invalid_s > 1.9 and rig.asp.load_factor.ratio == 0.5


def test_load_factor_check_passes_a_steep_turn_and_runs_only_in_fixed_wing_flight():
    rig = Rig(15)
    # a 60 deg bank at 16 m/s (2 g) with ASPD_STALL 10 m/s: ratio 2 / 2.56, passes
    rig.subs["vehicle_acceleration"].set(xyz=[0.0, 0.0, -2.0 * 9.81])
    assert min(rig.run(10.0, 16.0)) > 0.9 and 0.7 < rig.asp.load_factor.ratio < 0.85
    # hovering (a VTOL's multicopter mode): ~0 m/s at 1 g is no airspeed fault
    rig.subs["vehicle_acceleration"].set(xyz=[0.0, 0.0, -9.81])
    rig.subs["vehicle_status"].set(arming_state=2, vehicle_type=1)
    rig.subs["vehicle_local_position"].set(v_xy_valid=True, vx=0.0, vy=0.0)
    assert min(rig.run(5.0, 0.0)) > 0.9 and not rig.asp.load_factor.failed


def test_load_factor_filter_has_px4s_time_constant_at_any_sample_rate():
    a, b = LoadFactorCheck(), LoadFactorCheck()
    for _ in range(20):                     # 1 s at PX4's 20 Hz
        a.update(0.05, 12.0, 9.81, 10.0, True)
    for _ in range(100):                    # 1 s at the sensor's 100 Hz
        b.update(0.01, 12.0, 9.81, 10.0, True)
    assert abs(a.ratio - b.ratio) < 0.01
