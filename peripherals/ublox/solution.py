"""The navigation solution: truth from the environment plus a seeded GNSS error model.

What a flight stack cares about in a GPS is not the satellites but how the reported position
moves around the truth: a slowly wandering error of about a metre (multipath, atmosphere,
satellite geometry), a little white noise on top, velocity noise of a few cm/s, an accuracy
estimate (hAcc, vAcc, sAcc) that matches the error, a time to first fix, and what happens when
the sky is lost or jammed. The horizontal and vertical errors are first-order Gauss-Markov
processes (bounded random walks), which is the usual way to model GNSS position error for
estimator testing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from peripherals.physics import Environment

__all__ = [
    "LEAP_SECONDS",
    "START_UTC_NS",
    "GnssErrorParams",
    "GnssFaults",
    "Satellite",
    "Solution",
    "SolutionModel",
]

NS_PER_MS = 1_000_000
NS_PER_S = 1_000_000_000
#: UTC at power-on by default (2024-06-01 12:00:00 UTC): fixed so that runs are reproducible.
#: ``hil fly`` passes the host's UTC instead (``utc_start_ns``), read at the edge in hil/.
START_UTC_NS = 1_717_243_200 * NS_PER_S
#: GPS - UTC in seconds since 2017.
LEAP_SECONDS = 18
_GPS_EPOCH_UNIX_S = 315_964_800  # 1980-01-06 00:00:00 UTC
_WEEK_MS = 7 * 86_400_000
_M_PER_DEG_LAT = 111_320.0
_HACC_UNKNOWN_M = 4_294_967.295  # what a receiver reports before its first fix (U4 max in mm)


@dataclass
class GnssFaults:
    """GNSS-specific faults (the generic ones, like ``absent``, are in FaultState)."""

    no_fix: bool = False                          # the fix is lost as if the sky were blocked
    degraded: float = 1.0                         # error and hAcc/vAcc/sAcc scale by this
    jump_m: tuple[float, float, float] = (0.0, 0.0, 0.0)  # offset N, E, D added to the position
    jamming: int = 0                              # jamming indicator 0..255 (MON-HW jamInd)

    def clear(self) -> None:
        self.__init__()  # type: ignore[misc]


@dataclass
class GnssErrorParams:
    """Figures of a u-blox M8 in open sky (datasheet class: ~2.5 m CEP, 0.05 m/s)."""

    sigma_h_m: float = 0.6        # Gauss-Markov horizontal error, per axis
    sigma_v_m: float = 1.2
    tau_s: float = 30.0           # correlation time of the wandering error
    white_m: float = 0.02         # white noise on top of the wandering error
    vel_sigma_m_s: float = 0.05   # velocity noise per axis (vertical x1.5)
    h_acc_m: float = 1.2          # reported hAcc with 12 satellites (vAcc is 1.7x)
    s_acc_m_s: float = 0.15
    geoid_sep_m: float = 47.4     # ellipsoid height - MSL height at the default place
    ttff_s: float = 2.0           # time to first fix after power-on with sky view
    reacquire_s: float = 1.0      # time to get the fix back after the sky returns


@dataclass
class Satellite:
    gnss_id: int
    svid: int
    elev_deg: int
    azim_deg: int
    cno_dbhz: int = 0
    used: bool = False


@dataclass
class Solution:
    """One navigation epoch, in SI units; message encoders turn it into UBX/NMEA."""

    t_ns: int = 0
    utc_ns: int = START_UTC_NS
    fix_type: int = 0
    fix_ok: bool = False
    time_valid: bool = False
    num_sv: int = 0
    lat_deg: float = 0.0
    lon_deg: float = 0.0
    hmsl_m: float = 0.0
    height_m: float = 0.0
    h_acc_m: float = _HACC_UNKNOWN_M
    v_acc_m: float = _HACC_UNKNOWN_M
    vel_ned_m_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    s_acc_m_s: float = 20.0
    head_acc_deg: float = 180.0
    pdop: float = 99.99
    hdop: float = 99.99
    vdop: float = 99.99
    ttff_ms: int = 0
    noise_per_ms: int = 90
    agc_cnt: int = 5000
    jam_ind: int = 3
    sats: list[Satellite] = field(default_factory=list)

    @property
    def gps_ns(self) -> int:
        return self.utc_ns - _GPS_EPOCH_UNIX_S * NS_PER_S + LEAP_SECONDS * NS_PER_S

    @property
    def itow_ms(self) -> int:
        return (self.gps_ns // NS_PER_MS) % _WEEK_MS

    @property
    def ground_speed_m_s(self) -> float:
        return math.hypot(self.vel_ned_m_s[0], self.vel_ned_m_s[1])

    @property
    def heading_deg(self) -> float:
        """Course over ground, 0..360 deg."""
        return math.degrees(math.atan2(self.vel_ned_m_s[1], self.vel_ned_m_s[0])) % 360.0


class SolutionModel:
    """Turns the environment into a solution per navigation epoch (seeded, deterministic)."""

    def __init__(self, env: Environment, rng: np.random.Generator,
                 params: GnssErrorParams | None = None,
                 utc_start_ns: int = START_UTC_NS) -> None:
        self.env = env
        #: UTC (ns since 1970) at kernel time 0: configuration, never the host clock.
        self.utc_start_ns = utc_start_ns
        self.rng = rng
        self.p = params or GnssErrorParams()
        self.faults = GnssFaults()
        self.err_ned = [float(x) for x in rng.normal(0.0, 1.0, 3)
                        * (self.p.sigma_h_m, self.p.sigma_h_m, self.p.sigma_v_m)]
        self.constellation = self._make_constellation()
        self.num_sv_target = int(rng.integers(10, 15))
        self.power_on_ns = 0
        self._sky_since_ns: int | None = 0
        self._had_fix = False
        self._ttff_ms = 0
        self._last_t_ns: int | None = None
        self._last = Solution()
        self._lost_at_ns = 0
        self._lost_acc_m = (_HACC_UNKNOWN_M, _HACC_UNKNOWN_M)

    def _make_constellation(self) -> list[Satellite]:
        rng = self.rng
        sats = []
        for svid in (2, 5, 6, 9, 12, 13, 15, 17, 19, 20, 24, 25, 28, 29, 30, 32):
            sats.append(Satellite(0, svid, int(rng.integers(15, 85)), int(rng.integers(0, 360))))
        return sats

    def restart(self, t_ns: int, cold: bool = True) -> None:
        """After a reset: the fix must be acquired again (cold: full TTFF)."""
        self.power_on_ns = t_ns
        self._sky_since_ns = t_ns
        if cold:
            self._had_fix = False

    def step(self, t_ns: int) -> Solution:
        """The solution of the navigation epoch at kernel time ``t_ns``."""
        env, p, f, rng = self.env, self.p, self.faults, self.rng
        dt = 0.0 if self._last_t_ns is None else (t_ns - self._last_t_ns) / NS_PER_S
        self._last_t_ns = t_ns
        jam = max(0, min(255, int(f.jamming)))
        degrade = max(1.0, float(f.degraded)) * (1.0 + jam / 64.0)
        # The wandering error evolves whether or not there is a fix.
        if dt > 0:
            a = math.exp(-dt / p.tau_s)
            b = math.sqrt(1.0 - a * a)
            n = rng.standard_normal(3)
            sig = (p.sigma_h_m, p.sigma_h_m, p.sigma_v_m)
            for i in range(3):
                self.err_ned[i] = a * self.err_ned[i] + b * sig[i] * float(n[i])
            if rng.random() < dt / 20.0:  # a satellite rises or sets now and then
                self.num_sv_target = int(np.clip(self.num_sv_target + rng.choice((-1, 1)),
                                                  10, 14))
        sky = env.gps_available and not f.no_fix and jam < 230
        if not sky:
            self._sky_since_ns = None
        elif self._sky_since_ns is None:
            self._sky_since_ns = t_ns
        need_s = p.reacquire_s if self._had_fix else p.ttff_s
        fix = sky and t_ns - self._sky_since_ns >= int(need_s * NS_PER_S)
        sol = Solution(t_ns=t_ns, utc_ns=self.utc_start_ns + t_ns)
        sol.time_valid = self._had_fix or fix
        num_sv = max(0, self.num_sv_target - jam // 40) if sky else int(rng.integers(0, 3))
        sol.jam_ind = jam if jam else int(rng.integers(1, 6))
        sol.noise_per_ms = 85 + int(rng.integers(0, 10)) + jam
        sol.agc_cnt = max(0, 5200 - 12 * jam + int(rng.integers(-40, 40)))
        self._fill_sats(sol, num_sv if fix else 0, jam, sky)
        if fix:
            if not self._had_fix:
                self._ttff_ms = (t_ns - self.power_on_ns) // NS_PER_MS
            self._had_fix = True
            self._fill_fix(sol, env, num_sv, degrade, rng)
        else:
            self._fill_no_fix(sol, t_ns)
        sol.ttff_ms = self._ttff_ms if self._had_fix else 0
        self._last = sol
        return sol

    def _fill_fix(self, sol: Solution, env: Environment, num_sv: int, degrade: float,
                  rng: np.random.Generator) -> None:
        p, f = self.p, self.faults
        w = rng.standard_normal(6)
        en, ee, ed = (e * degrade + p.white_m * float(x) for e, x in zip(self.err_ned, w[:3]))
        en += f.jump_m[0]
        ee += f.jump_m[1]
        ed += f.jump_m[2]
        lat = env.lat_deg + en / _M_PER_DEG_LAT
        lon = env.lon_deg + ee / (_M_PER_DEG_LAT * max(1e-6, math.cos(math.radians(lat))))
        geometry = math.sqrt(12.0 / max(num_sv, 4))
        vn, ve, vd = env.vel_ned_m_s
        vs = p.vel_sigma_m_s * degrade
        sol.fix_type, sol.fix_ok = 3, True
        sol.num_sv = sum(s.used for s in sol.sats)
        sol.lat_deg, sol.lon_deg = lat, lon
        sol.hmsl_m = env.alt_m - ed
        sol.height_m = sol.hmsl_m + p.geoid_sep_m
        sol.h_acc_m = p.h_acc_m * degrade * geometry * (1.0 + 0.05 * float(w[3]) ** 2)
        sol.v_acc_m = 1.7 * sol.h_acc_m
        sol.vel_ned_m_s = (vn + vs * float(w[4]), ve + vs * float(w[5]),
                           vd + 1.5 * vs * float(rng.standard_normal()))
        sol.s_acc_m_s = p.s_acc_m_s * degrade
        speed = sol.ground_speed_m_s
        sol.head_acc_deg = min(180.0, math.degrees(sol.s_acc_m_s / max(speed, 1e-3)))
        sol.hdop = 0.9 * geometry * degrade
        sol.vdop = 1.3 * geometry * degrade
        sol.pdop = math.hypot(sol.hdop, sol.vdop)

    def _fill_no_fix(self, sol: Solution, t_ns: int) -> None:
        last = self._last
        if last.fix_ok:
            self._lost_at_ns = t_ns
            self._lost_acc_m = (last.h_acc_m, last.v_acc_m)
        if self._had_fix:
            # The receiver keeps its last position with an accuracy that grows (coasting).
            grow = 10.0 * (t_ns - self._lost_at_ns) / NS_PER_S
            sol.lat_deg, sol.lon_deg = last.lat_deg, last.lon_deg
            sol.hmsl_m, sol.height_m = last.hmsl_m, last.height_m
            sol.h_acc_m = min(_HACC_UNKNOWN_M, self._lost_acc_m[0] + grow)
            sol.v_acc_m = min(_HACC_UNKNOWN_M, self._lost_acc_m[1] + grow)
        sol.num_sv = 0

    def _fill_sats(self, sol: Solution, used: int, jam: int, sky: bool) -> None:
        rng = self.rng
        visible = [s for s in self.constellation if s.elev_deg > 10]
        order = sorted(visible, key=lambda s: -s.elev_deg)
        out = []
        for i, s in enumerate(order):
            cno = 0
            if sky:
                cno = max(0, int(28 + s.elev_deg / 5 + rng.integers(-2, 3) - jam // 12))
            out.append(Satellite(s.gnss_id, s.svid, s.elev_deg, s.azim_deg, cno,
                                 i < used and cno > 0))
        sol.sats = out
