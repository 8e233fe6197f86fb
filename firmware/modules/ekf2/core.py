"""The estimator proper: a 15-state error-state (multiplicative) extended Kalman filter.

Nominal state (plain floats, propagated at the IMU rate, 250 Hz):
    q      attitude, body -> NED (PX4's vehicle_attitude.q)
    v, p   velocity and position, NED, m/s and m
    bg     gyro bias, rad/s          ba  accelerometer bias, m/s^2

Error state (numpy, 15): dtheta (3, attitude error in NED: R_true = (I + [dtheta x]) R), dv (3),
dp (3), dbg (3), dba (3). The covariance is predicted at 100 Hz (``predict_covariance``) from the
IMU deltas accumulated since the last prediction, as PX4 runs its EKF at 100 Hz.

Every measurement this filter uses observes one error-state component directly (position,
velocity, height, and yaw: a rotation about NED down adds exactly to the yaw angle), so each is
a scalar update with a one-hot H: ``S = P[i, i] + R``, ``K = P[:, i] / S``. Measurements of one
sensor are fused in sequence (later ones see the corrections of earlier ones), then the error
is injected into the nominal state and reset to zero.

Delayed measurements (GPS solutions arrive ~0.1 s after their epoch, the baro average is
centred half an averaging period back) are compared with the nominal state at their own time,
kept in a short history ring; the correction is applied to the current state. This is the
cheap alternative to PX4's delayed-horizon filter with an output predictor: for errors that
change slowly over the delay it gives the same result.
"""

from __future__ import annotations

import math
from typing import Final

import numpy as np

from common.quaternion import Quat, dcm, q_from_rotvec, q_mul, q_norm, q_yaw
from common.units import G0_M_S2

__all__ = ["N_STATES", "Ekf", "NoiseParams"]

N_STATES: Final = 15
I_THETA: Final = 0
I_VEL: Final = 3
I_POS: Final = 6
I_BG: Final = 9
I_BA: Final = 12
HISTORY: Final = 128                 # entries of the state history ring (0.5 s at 250 Hz)
# flat indices of the entries of F that change per prediction: -R dt (theta/gyro bias and
# v/accel bias blocks), -[dv x] (v/theta block), dt (p/v block)
_F_IDX: Final = np.array([r * 15 + c for r in range(3) for c in range(9, 12)]
                  + [r * 15 + c for r in range(3, 6) for c in range(12, 15)]
                  + [3 * 15 + 1, 3 * 15 + 2, 4 * 15 + 0, 4 * 15 + 2, 5 * 15 + 0, 5 * 15 + 1]
                  + [6 * 15 + 3, 7 * 15 + 4, 8 * 15 + 5])


class NoiseParams:
    """Process noise and initial uncertainty (EKF2_* parameters, SI units)."""

    __slots__ = (
        "accel",
        "accel_bias",
        "accel_bias_init",
        "accel_bias_max",
        "gyro",
        "gyro_bias",
        "gyro_bias_init",
        "gyro_bias_max",
        "hgt_init",
        "pos_init",
        "tilt_init",
        "vel_init",
        "yaw_init",
    )

    def __init__(self) -> None:
        self.gyro = 0.015             # rad/s          EKF2_GYR_NOISE
        self.accel = 0.35             # m/s^2          EKF2_ACC_NOISE
        self.gyro_bias = 0.001        # rad/s^2        EKF2_GYR_B_NOISE
        self.accel_bias = 0.003       # m/s^3          EKF2_ACC_B_NOISE
        self.gyro_bias_init = 0.1     # rad/s          EKF2_GBIAS_INIT
        self.accel_bias_init = 0.2    # m/s^2          EKF2_ABIAS_INIT
        self.tilt_init = 0.1          # rad
        self.yaw_init = 0.3           # rad
        self.vel_init = 0.5           # m/s
        self.pos_init = 0.5           # m
        self.hgt_init = 1.0           # m
        self.gyro_bias_max = 0.3      # rad/s, estimates are clamped to this
        self.accel_bias_max = 1.5     # m/s^2


class Ekf:
    """State, covariance, prediction and scalar fusion; no uORB, no parameters by name."""

    def __init__(self, noise: NoiseParams | None = None) -> None:
        self._q_dt: float = -1.0
        self.set_noise(noise or NoiseParams())
        self.q: Quat = (1.0, 0.0, 0.0, 0.0)
        self.R = dcm(self.q)
        self.vn = self.ve = self.vd = 0.0
        self.pn = self.pe = self.pd = 0.0
        self.bgx = self.bgy = self.bgz = 0.0
        self.bax = self.bay = self.baz = 0.0
        #: NED kinematic acceleration of the last IMU step, m/s^2
        self.acc_ned = (0.0, 0.0, 0.0)
        self.P = np.zeros((N_STATES, N_STATES))
        self.dx = np.zeros(N_STATES)
        self._F = np.eye(N_STATES)
        self._n_predict = 0
        self._acc_dt = 0.0
        self._acc_dvn = self._acc_dve = self._acc_dvd = 0.0
        self.fault = 0            # filter_fault_flags bits seen since the last read
        #: a fusion changed P since the last :meth:`condition` (the module conditions only then)
        self.fused = False
        # history ring: time and the nominal p, v, yaw at that time
        self._h_t = [0] * HISTORY
        self._h = [(0.0,) * 7] * HISTORY
        self._h_i = 0
        self._h_n = 0
        self.init_covariance()

    # -- initialisation ------------------------------------------------------------------------

    def init_covariance(self) -> None:
        n = self.noise
        d = ([n.tilt_init ** 2, n.tilt_init ** 2, n.yaw_init ** 2] + [n.vel_init ** 2] * 3
             + [n.pos_init ** 2] * 2 + [n.hgt_init ** 2] + [n.gyro_bias_init ** 2] * 3
             + [n.accel_bias_init ** 2] * 3)
        self.P = np.diag(np.array(d, dtype=float))
        self.dx[:] = 0.0

    def set_attitude(self, q: Quat) -> None:
        self.q = q_norm(q)
        self.R = dcm(self.q)

    # -- prediction ------------------------------------------------------------------------------

    def propagate(self, gx: float, gy: float, gz: float, ax: float, ay: float, az: float,
                  dt: float, t_us: int) -> None:
        """Nominal state over one IMU interval: mean rates (rad/s) and specific force (m/s^2)."""
        wx, wy, wz = (gx - self.bgx) * dt, (gy - self.bgy) * dt, (gz - self.bgz) * dt
        dvx, dvy, dvz = (ax - self.bax) * dt, (ay - self.bay) * dt, (az - self.baz) * dt
        # rotate the velocity increment with the mid-interval attitude (sculling, first order)
        cx = dvx + 0.5 * (wy * dvz - wz * dvy)
        cy = dvy + 0.5 * (wz * dvx - wx * dvz)
        cz = dvz + 0.5 * (wx * dvy - wy * dvx)
        r = self.R
        dn = r[0] * cx + r[1] * cy + r[2] * cz
        de = r[3] * cx + r[4] * cy + r[5] * cz
        dd = r[6] * cx + r[7] * cy + r[8] * cz
        self.q = q = q_norm(q_mul(self.q, q_from_rotvec(wx, wy, wz)))
        self.R = dcm(q)
        vn0, ve0, vd0 = self.vn, self.ve, self.vd
        gdt = G0_M_S2 * dt
        self.vn = vn = vn0 + dn
        self.ve = ve = ve0 + de
        self.vd = vd = vd0 + dd + gdt
        h = 0.5 * dt
        self.pn += (vn0 + vn) * h
        self.pe += (ve0 + ve) * h
        self.pd += (vd0 + vd) * h
        inv = 1.0 / dt if dt > 0.0 else 0.0
        self.acc_ned = (dn * inv, de * inv, dd * inv + G0_M_S2)
        self._acc_dt += dt
        self._acc_dvn += dn
        self._acc_dve += de
        self._acc_dvd += dd
        # history
        i = (self._h_i + 1) % HISTORY
        self._h_i = i
        self._h_t[i] = t_us
        self._h[i] = (self.pn, self.pe, self.pd, vn, ve, vd, q_yaw(q))
        if self._h_n < HISTORY:
            self._h_n += 1

    @property
    def pending_dt(self) -> float:
        return self._acc_dt

    def predict_covariance(self) -> None:
        """P = F P F' + Q over the IMU time accumulated since the last call.

        Written as a handful of whole-array numpy operations (the 27 entries of F that change
        are written with one indexed store): at 15 states a numpy call costs about as much as
        the arithmetic in it, so the number of calls is what matters.
        """
        dt = self._acc_dt
        if dt <= 0.0:
            return
        r0, r1, r2, r3, r4, r5, r6, r7, r8 = self.R
        m = -dt
        a0, a1, a2, a3, a4, a5, a6, a7, a8 = (r0 * m, r1 * m, r2 * m, r3 * m, r4 * m, r5 * m,
                                              r6 * m, r7 * m, r8 * m)
        dvn, dve, dvd = self._acc_dvn, self._acc_dve, self._acc_dvd
        F = self._F
        F.flat[_F_IDX] = (a0, a1, a2, a3, a4, a5, a6, a7, a8,
                          a0, a1, a2, a3, a4, a5, a6, a7, a8,
                          dvd, -dve, -dvd, dvn, dve, -dvn, dt, dt, dt)
        P = F @ self.P @ F.T
        if dt != self._q_dt:
            self._q_dt = dt
            self._q = self._q_rate * (dt * dt)
        P.flat[::N_STATES + 1] += self._q
        self.P = P
        self._acc_dt = 0.0
        self._acc_dvn = self._acc_dve = self._acc_dvd = 0.0
        self._n_predict += 1
        self.condition(self._n_predict % 10 == 0)

    def set_noise(self, noise: NoiseParams) -> None:
        """Take new process noise figures (parameter change)."""
        self.noise = n = noise
        self._q_rate = np.array([n.gyro ** 2] * 3 + [n.accel ** 2] * 3 + [0.0] * 3
                                + [n.gyro_bias ** 2] * 3 + [n.accel_bias ** 2] * 3)
        self._q_dt = -1.0
        self._bias_var_max = np.array([n.gyro_bias_init ** 2] * 3 + [n.accel_bias_init ** 2] * 3)

    def condition(self, full: bool = True) -> None:
        """Keep P symmetric and its variances in range; flag what had to be repaired.

        ``full``: also symmetrise and bound the bias variances. Every tenth prediction is
        plenty: rounding asymmetry and bias variances grow slowly, and each numpy call costs
        microseconds on the host.
        """
        P = self.P
        self.fused = False
        if full:
            P += P.T
            P *= 0.5
        d = P.diagonal()
        lo = float(d.min())  # NaN if anything is NaN
        if not lo >= 0.0:
            if not math.isfinite(lo) or not math.isfinite(float(d.max())):
                self.fault |= 2
                self.init_covariance()
                return
            self.fault |= 1
            idx = np.nonzero(d < 1e-12)[0]
            P[idx, :] = 0.0
            P[:, idx] = 0.0
            P[idx, idx] = 1e-12
        if not full:
            return
        # a bias variance must not grow without bound while it is unobservable
        big = d[9:15] > self._bias_var_max
        if big.any():
            for j in (np.nonzero(big)[0] + 9).tolist():
                s = math.sqrt(self._bias_var_max[j - 9] / P[j, j])
                P[j, :] *= s
                P[:, j] *= s

    # -- history -----------------------------------------------------------------------------------

    def at(self, t_us: int) -> tuple[float, ...]:
        """(pn, pe, pd, vn, ve, vd, yaw) of the nominal state at (or just before) ``t_us``."""
        i = self._h_i
        ts = self._h_t
        for _ in range(self._h_n):
            if ts[i] <= t_us:
                return self._h[i]
            i = (i - 1) % HISTORY
        j = (self._h_i - self._h_n + 1) % HISTORY
        return self._h[j] if self._h_n else (self.pn, self.pe, self.pd, self.vn, self.ve,
                                             self.vd, q_yaw(self.q))

    def clear_history(self) -> None:
        self._h_n = 0

    # -- fusion --------------------------------------------------------------------------------------

    def test_ratio(self, i: int, innov: float, var: float, gate: float) -> float:
        s = float(self.P[i, i]) + var
        return innov * innov / (gate * gate * s) if s > 0.0 else math.inf

    def fuse(self, i: int, innov: float, var: float) -> None:
        """One scalar observation of error-state component ``i`` (call :meth:`inject` after)."""
        P = self.P
        innov -= float(self.dx[i])  # what earlier observations of this batch corrected
        s = float(P[i, i]) + var
        if s < var:  # a negative variance: numerical trouble
            self.fault |= 1
            return
        pht = P[:, i].copy()
        k = pht * (1.0 / s)
        self.dx += k * innov
        P -= np.outer(k, pht)
        self.fused = True

    def inject(self) -> None:
        """Apply the accumulated error estimate to the nominal state and zero it."""
        dx = self.dx
        (tx, ty, tz, dvn, dve, dvd, dpn, dpe, dpd, dgx, dgy, dgz, dax, day, daz) = dx.tolist()
        if tx or ty or tz:
            self.q = q_norm(q_mul(q_from_rotvec(tx, ty, tz), self.q))
            self.R = dcm(self.q)
        self.vn += dvn
        self.ve += dve
        self.vd += dvd
        self.pn += dpn
        self.pe += dpe
        self.pd += dpd
        gm, am = self.noise.gyro_bias_max, self.noise.accel_bias_max
        self.bgx = max(-gm, min(gm, self.bgx + dgx))
        self.bgy = max(-gm, min(gm, self.bgy + dgy))
        self.bgz = max(-gm, min(gm, self.bgz + dgz))
        self.bax = max(-am, min(am, self.bax + dax))
        self.bay = max(-am, min(am, self.bay + day))
        self.baz = max(-am, min(am, self.baz + daz))
        dx.fill(0.0)
        if not all(map(math.isfinite, (self.vn, self.ve, self.vd, self.pn, self.pe, self.pd))):
            self.fault |= 2

    # -- resets ----------------------------------------------------------------------------------------

    def _reset_block(self, i: int, n: int, var: float) -> None:
        P = self.P
        P[i:i + n, :] = 0.0
        P[:, i:i + n] = 0.0
        for j in range(i, i + n):
            P[j, j] = var

    def reset_velocity_ne(self, vn: float, ve: float, var: float) -> None:
        self.vn, self.ve = vn, ve
        self._reset_block(I_VEL, 2, var)
        self.clear_history()

    def reset_velocity_d(self, vd: float, var: float) -> None:
        self.vd = vd
        self._reset_block(I_VEL + 2, 1, var)
        self.clear_history()

    def reset_position_ne(self, pn: float, pe: float, var: float) -> None:
        self.pn, self.pe = pn, pe
        self._reset_block(I_POS, 2, var)
        self.clear_history()

    def reset_height(self, pd: float, var: float) -> None:
        self.pd = pd
        self._reset_block(I_POS + 2, 1, var)
        self.clear_history()

    def reset_yaw(self, yaw: float, var: float) -> Quat:
        """Rotate about NED down to ``yaw``; returns the delta quaternion applied."""
        d = yaw - q_yaw(self.q)
        dq = q_from_rotvec(0.0, 0.0, d)
        self.q = q_norm(q_mul(dq, self.q))
        self.R = dcm(self.q)
        self._reset_block(I_THETA + 2, 1, var)
        self.clear_history()
        return dq

    # -- output ------------------------------------------------------------------------------------------

    def variances(self) -> list[float]:
        return self.P.diagonal().tolist()
