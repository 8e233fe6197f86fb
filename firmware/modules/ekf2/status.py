"""Filling estimator_status: what the filter fuses, how well, and what went wrong.

Bit meanings follow PX4 so that tools reading PX4 logs read ours:

* ``control_mode_flags``: CS_TILT_ALIGN (0), CS_YAW_ALIGN (1), CS_GPS (2), CS_MAG_HDG (4),
  CS_BARO_HGT (7);
* ``innovation_check_flags``: velocity NE (0), velocity D (1), position NE (2), height (3),
  yaw (7) -- set while the latest measurement of that kind is rejected;
* ``solution_status_flags``: attitude (0), horizontal velocity (1), vertical velocity (2),
  relative horizontal position (3), absolute horizontal position (4), vertical position (5),
  height above ground (6), constant position mode (7), GPS glitch (10);
* ``filter_fault_flags``: 1 a negative variance was repaired, 2 a non-finite covariance was
  re-initialised (since the previous status);
* ``health_flags`` / ``timeout_flags``: velocity (0), position (1), height (2).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Final

if TYPE_CHECKING:
    from firmware.modules.ekf2.module import Ekf2Module

__all__ = ["fill_estimator_status"]

CS_TILT_ALIGN: Final = 0
CS_YAW_ALIGN: Final = 1
CS_GPS: Final = 2
CS_MAG_HDG: Final = 4
CS_BARO_HGT: Final = 7


def fill_estimator_status(mod: Ekf2Module, m: Any, t: int) -> None:
    ekf = mod.ekf
    P = ekf.P
    tout = mod.p["EKF2_NOAID_TOUT"]
    m.timestamp = mod.platform.time_us()
    m.timestamp_sample = t
    m.gps_check_fail_flags = mod.gps_checks.fail_flags
    cs = 0
    if mod.tilt_aligned:
        cs |= 1 << CS_TILT_ALIGN
    if mod.yaw_aligned:
        cs |= 1 << CS_YAW_ALIGN
    if mod.gps_in_use:
        cs |= 1 << CS_GPS
    if mod.src_yaw.active:
        cs |= 1 << CS_MAG_HDG
    if mod.src_hgt.active and t - mod._last_baro_us < 1_000_000:
        cs |= 1 << CS_BARO_HGT
    m.control_mode_flags = cs
    m.filter_fault_flags = mod._faults
    d = P.diagonal().tolist()
    m.pos_horiz_accuracy = math.sqrt(d[6] + d[7])
    m.pos_vert_accuracy = math.sqrt(d[8])
    m.mag_test_ratio = mod.src_yaw.test_ratio
    m.vel_test_ratio = max(mod.src_vel.test_ratio, mod.src_vel_d.test_ratio)
    m.pos_test_ratio = mod.src_pos.test_ratio
    m.hgt_test_ratio = mod.src_hgt.test_ratio
    m.tas_test_ratio = m.hagl_test_ratio = m.beta_test_ratio = 0.0
    m.innovation_check_flags = mod.innov_flags
    sol = 0
    if mod.tilt_aligned:
        sol |= 1
    if mod.gps_in_use:
        sol |= 2 | 8 | 16
    if mod.tilt_aligned and t - mod._last_baro_us < 1_000_000:
        sol |= 4 | 32 | 64
    if not mod.gps_in_use:
        sol |= 128
    if mod.src_pos.rejected:
        sol |= 1024
    m.solution_status_flags = sol
    r = mod.resets
    m.reset_count_vel_ne = r["vel_ne"] & 0xFF
    m.reset_count_vel_d = r["vel_d"] & 0xFF
    m.reset_count_pos_ne = r["pos_ne"] & 0xFF
    m.reset_count_pod_d = r["pos_d"] & 0xFF
    m.reset_count_quat = r["quat"] & 0xFF
    m.time_slip = 0.0
    pf = mod.preflight
    m.pre_flt_fail_innov_heading = pf.fail_heading
    m.pre_flt_fail_innov_vel_horiz = pf.fail_vel_ne
    m.pre_flt_fail_innov_vel_vert = pf.fail_vel_d
    m.pre_flt_fail_innov_height = pf.fail_hgt
    m.pre_flt_fail_mag_field_disturbed = mod.mag_disturbed
    m.accel_device_id, m.gyro_device_id, m.baro_device_id, m.mag_device_id = mod._ids
    health = 0
    if mod.src_vel.rejected or mod.src_vel_d.rejected:
        health |= 1
    if mod.src_pos.rejected:
        health |= 2
    if mod.src_hgt.rejected:
        health |= 4
    m.health_flags = health
    to = 0
    if mod.gps_in_use and mod.src_vel.since_fused_us(t) > tout:
        to |= 1
    if mod.gps_in_use and mod.src_pos.since_fused_us(t) > tout:
        to |= 2
    if mod.tilt_aligned and mod._last_baro_us >= 0 and t - mod._last_baro_us > 1_000_000:
        to |= 4
    m.timeout_flags = to
