"""L1 lateral guidance for fixed-wing aircraft (PX4's ``ECL_L1_Pos_Controller`` in shape).

Park, Deyst and How (2004), "A New Nonlinear Guidance Logic for Trajectory Tracking": a
reference point at the distance ``L1`` ahead on the desired path; the lateral acceleration that
puts the velocity vector onto it is ``a = 2 V^2 / L1 * sin(eta)``, eta the angle from the
velocity to the line of sight. Near a straight line this is a PD law on the cross-track error
with natural period and damping set by ``L1``: PX4 parameterises it by that period
(``FW_L1_PERIOD``) and damping (``FW_L1_DAMPING``) instead, so the reference distance grows
with ground speed and the response in seconds stays the same at any speed::

    L1 = damping * period / pi * V          K = 4 * damping^2          a = K V^2 / L1 sin(eta)

(``K = 2`` at the paper's damping of 1/sqrt(2)). Loiter circles use a PD law on the radial error
with the centripetal term as feed-forward, and plain L1 to capture the circle from outside.

Everything is in a local north-east frame in metres (the module projects latitude and longitude
around the estimator's reference point first), so the library knows nothing of uORB, parameters
or geodesy and is tested alone (tests/firmware/fw/test_l1.py). Sign conventions are PX4's:
a positive lateral acceleration and roll turn right (clockwise seen from above in NED), loiter
direction +1 is clockwise.
"""

from __future__ import annotations

import math
from typing import Final
from common.units import G0_M_S2

__all__ = ["L1Control", "wrap_pi"]

_PI: Final = math.pi
#: below this ground speed the velocity direction means nothing: use the heading instead
_MIN_GS_M_S: Final = 1.0


def wrap_pi(a: float) -> float:
    """An angle wrapped into [-pi, pi)."""
    return (a + _PI) % (2.0 * _PI) - _PI


def _cross(ax: float, ay: float, bx: float, by: float) -> float:
    """2-D cross product (north, east): positive when b is clockwise from a."""
    return ax * by - ay * bx


class L1Control:
    """The guidance state of one aircraft: call one ``navigate_*`` per control step, then read
    :attr:`lateral_accel_m_s2` and :meth:`nav_roll` (PX4: ``nav_lateral_acceleration_demand``,
    ``get_roll_setpoint``)."""

    def __init__(self) -> None:
        self.period_s = 20.0
        self.damping = 0.75
        self.roll_lim_rad = math.radians(50.0)
        self._update_gains()
        #: outputs of the last navigate_* call
        self.lateral_accel_m_s2 = 0.0
        self.nav_bearing_rad = 0.0
        self.target_bearing_rad = 0.0
        self.bearing_error_rad = 0.0
        self.crosstrack_error_m = 0.0
        self.l1_distance_m = 20.0
        self.circle_mode = False

    # -- configuration (PX4: set_l1_period, set_l1_damping, set_l1_roll_limit) ---------------

    def _update_gains(self) -> None:
        self.l1_ratio = self.damping * self.period_s / _PI
        self.k_l1 = 4.0 * self.damping * self.damping

    def set_period(self, period_s: float) -> None:
        self.period_s = max(float(period_s), 1.0)
        self._update_gains()

    def set_damping(self, damping: float) -> None:
        self.damping = min(max(float(damping), 0.1), 1.5)
        self._update_gains()

    def set_roll_limit(self, roll_lim_rad: float) -> None:
        self.roll_lim_rad = min(max(float(roll_lim_rad), 0.0), math.radians(85.0))

    # -- outputs ---------------------------------------------------------------------------------

    def nav_roll(self) -> float:
        """The roll angle (rad) of a coordinated turn giving the lateral acceleration."""
        r = math.atan(self.lateral_accel_m_s2 / G0_M_S2)
        lim = self.roll_lim_rad
        return -lim if r < -lim else (lim if r > lim else r)

    def switch_distance(self, wp_radius_m: float) -> float:
        """The distance to a waypoint at which the navigator should switch to the next: the L1
        point already reaches past a closer waypoint, so waiting longer only overshoots it."""
        return min(wp_radius_m, self.l1_distance_m)

    # -- helpers -----------------------------------------------------------------------------------

    @staticmethod
    def _ground_velocity(vel_ne: tuple[float, float], yaw_rad: float) -> tuple[float, float]:
        vn, ve = vel_ne
        if math.hypot(vn, ve) < _MIN_GS_M_S:
            return _MIN_GS_M_S * math.cos(yaw_rad), _MIN_GS_M_S * math.sin(yaw_rad)
        return vn, ve

    def _accel_from_eta(self, eta: float, gs: float) -> None:
        eta = min(max(eta, -0.5 * _PI), 0.5 * _PI)
        self.bearing_error_rad = eta
        self.lateral_accel_m_s2 = self.k_l1 * gs * gs / self.l1_distance_m * math.sin(eta)

    def _eta_towards(self, vn: float, ve: float, dn: float, de: float) -> float:
        """Angle from the velocity (vn, ve) to the direction (dn, de), positive clockwise."""
        return math.atan2(_cross(vn, ve, dn, de), vn * dn + ve * de)

    # -- guidance ----------------------------------------------------------------------------------

    def navigate_waypoints(self, a_ne: tuple[float, float], b_ne: tuple[float, float],
                           pos_ne: tuple[float, float], vel_ne: tuple[float, float],
                           yaw_rad: float = 0.0) -> None:
        """Follow the line from A to B (toward B).

        Three cases, as PX4: far behind A and flying away from the line's start, head for A
        first; past B (the aircraft beyond B's perpendicular by more than 100 deg of bearing),
        head for B; otherwise L1 on the line, ``eta = eta1 + eta2`` with eta1 from the
        cross-track error and eta2 the angle between the velocity and the line.
        """
        self.circle_mode = False
        vn, ve = self._ground_velocity(vel_ne, yaw_rad)
        gs = math.hypot(vn, ve)
        self.l1_distance_m = max(self.l1_ratio * gs, 1.0)
        pn, pe = pos_ne
        abn, abe = b_ne[0] - a_ne[0], b_ne[1] - a_ne[1]
        ab_len = math.hypot(abn, abe)
        apn, ape = pn - a_ne[0], pe - a_ne[1]
        if ab_len < 1e-6:  # A on B: the line is the one from A to the aircraft
            ap = math.hypot(apn, ape)
            if ap < 1e-6:
                self.navigate_level_flight(yaw_rad)
                return
            abn, abe, ab_len = -apn / ap, -ape / ap, 1.0
        abn, abe = abn / ab_len, abe / ab_len
        self.target_bearing_rad = math.atan2(b_ne[1] - pe, b_ne[0] - pn)
        dist_a = math.hypot(apn, ape)
        along = apn * abn + ape * abe
        bpn, bpe = pn - b_ne[0], pe - b_ne[1]
        dist_b = math.hypot(bpn, bpe)
        bp_bearing = (math.atan2(_cross(bpn, bpe, abn, abe), bpn * abn + bpe * abe)
                      if dist_b > 1e-6 else _PI)
        self.crosstrack_error_m = _cross(apn, ape, abn, abe)
        if dist_a > self.l1_distance_m and along / max(dist_a, 1.0) < -0.7071:
            # behind A, facing away: fly to A
            un, ue = -apn / dist_a, -ape / dist_a
            eta = self._eta_towards(vn, ve, un, ue)
            self.nav_bearing_rad = math.atan2(ue, un)
        elif abs(bp_bearing) < math.radians(100.0):
            # beyond B: fly back to B
            un, ue = -bpn / dist_b, -bpe / dist_b
            eta = self._eta_towards(vn, ve, un, ue)
            self.nav_bearing_rad = math.atan2(ue, un)
        else:
            sin_eta1 = self.crosstrack_error_m / self.l1_distance_m
            sin_eta1 = min(max(sin_eta1, -0.7071), 0.7071)
            eta1 = math.asin(sin_eta1)
            eta2 = self._eta_towards(vn, ve, abn, abe)
            eta = eta1 + eta2
            self.nav_bearing_rad = wrap_pi(math.atan2(abe, abn) + eta1)
        self._accel_from_eta(eta, gs)

    def navigate_loiter(self, center_ne: tuple[float, float], pos_ne: tuple[float, float],
                        radius_m: float, direction: int, vel_ne: tuple[float, float],
                        yaw_rad: float = 0.0) -> None:
        """Circle around the centre, clockwise for ``direction`` +1, counter-clockwise for -1.

        On or near the circle a PD law on the radial error (natural frequency ``2 pi / period``,
        the L1 damping) plus the centripetal acceleration of the tangential speed; far outside,
        or inside/outside circling the wrong way, L1 toward the tangent point captures it.
        """
        d = 1.0 if direction >= 0 else -1.0
        radius = max(abs(radius_m), 1.0)
        vn, ve = self._ground_velocity(vel_ne, yaw_rad)
        gs = math.hypot(vn, ve)
        self.l1_distance_m = max(self.l1_ratio * gs, 1.0)
        omega = 2.0 * _PI / self.period_s
        k_cross = omega * omega
        k_vel = 2.0 * self.damping * omega
        rn, re = pos_ne[0] - center_ne[0], pos_ne[1] - center_ne[1]
        r = math.hypot(rn, re)
        if r < 1e-3:  # on the centre: any direction is radial
            rn, re, r = math.cos(yaw_rad) * 1e-3, math.sin(yaw_rad) * 1e-3, 1e-3
        un, ue = rn / r, re / r
        self.target_bearing_rad = math.atan2(-ue, -un)
        err = r - radius                       # positive outside
        self.crosstrack_error_m = err
        v_radial = vn * un + ve * ue           # positive outward
        v_tangent = _cross(un, ue, vn, ve)     # positive clockwise
        wrong_way = d * v_tangent < 0.0
        if err > 0.0 and (err > self.l1_distance_m or wrong_way):
            # capture: L1 toward the tangent point that turns us the right way round
            self.circle_mode = False
            bearing_c = math.atan2(-ue, -un)
            bearing = bearing_c - d * math.asin(min(radius / r, 1.0))
            eta = self._eta_towards(vn, ve, math.cos(bearing), math.sin(bearing))
            self.nav_bearing_rad = wrap_pi(bearing)
            self._accel_from_eta(eta, gs)
            return
        self.circle_mode = True
        pd = k_cross * err + k_vel * v_radial
        vt = max(d * v_tangent, 0.0)
        centripetal = vt * vt / max(0.5 * radius, r)
        if wrong_way:  # inside the circle the wrong way round: turn hard toward the right way
            centripetal = gs * gs / max(0.5 * radius, r)
        self.lateral_accel_m_s2 = d * (pd + centripetal)
        self.bearing_error_rad = 0.0
        self.nav_bearing_rad = wrap_pi(math.atan2(-ue, -un) - d * 0.5 * _PI)

    def navigate_heading(self, heading_sp_rad: float, yaw_rad: float,
                         vel_ne: tuple[float, float]) -> None:
        """Turn onto a heading (no position): L1 with eta the heading error."""
        self.circle_mode = False
        vn, ve = self._ground_velocity(vel_ne, yaw_rad)
        gs = math.hypot(vn, ve)
        self.l1_distance_m = max(self.l1_ratio * gs, 1.0)
        self.nav_bearing_rad = wrap_pi(heading_sp_rad)
        self.target_bearing_rad = self.nav_bearing_rad
        self.crosstrack_error_m = 0.0
        self._accel_from_eta(wrap_pi(heading_sp_rad - yaw_rad), gs)

    def navigate_level_flight(self, yaw_rad: float) -> None:
        """Wings level on the current heading."""
        self.circle_mode = False
        self.lateral_accel_m_s2 = 0.0
        self.bearing_error_rad = 0.0
        self.crosstrack_error_m = 0.0
        self.nav_bearing_rad = wrap_pi(yaw_rad)
        self.target_bearing_rad = self.nav_bearing_rad
