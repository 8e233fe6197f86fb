"""Total energy control (TECS) for fixed-wing altitude and airspeed (PX4's ``TECS`` in shape).

Lambregts' idea, as PX4 and ArduPilot use it: the aircraft's specific energies, potential
``SPE = g h`` and kinetic ``SKE = V^2 / 2`` (J/kg), are controlled as two combinations:

* the **total** ``STE = SPE + SKE`` is what the propeller changes: throttle comes from the total
  energy error and rate (feed-forward from the demanded rate between the cruise throttle and the
  throttle limits, ``FW_T_CLMB_MAX`` and ``FW_T_SINK_MIN`` scaling it; P with time constant
  ``FW_T_THRO_CONST``, damping ``FW_T_THR_DAMP``, integrator ``FW_T_INTEG_GAIN``, and the extra
  drag of a banked turn, ``FW_T_RLL2THR``);
* the **balance** ``SEB = SPE w_p - SKE w_k`` is what the elevator trades: pitch comes from
  the balance error and rate (time constant ``FW_T_TIME_CONST``), so climbing with the same
  energy means slowing down, and the pitch loop never fights the throttle loop.
  ``FW_T_SPDWEIGHT`` (0..2) sets the weights: 0 controls height only with pitch, 2 speed only.

Demands are shaped before use: the height setpoint is followed at most at the climb and sink
limits and gives a height rate demand with time constant ``FW_T_ALT_TC`` plus the ramp's rate
times ``FW_T_HRATE_FF``; the airspeed setpoint is kept between ``FW_AIRSPD_MIN`` and
``FW_AIRSPD_MAX`` and followed with time constant ``FW_T_TAS_TC``, its rate limited by what the
throttle range can give (half the total energy rate range, all of it kinetic).

Protections: underspeed (true airspeed below 90 % of the minimum while the throttle is at its
maximum) puts the throttle at maximum and the pitch on speed only; climb-out (a large height
error, or the caller's takeoff) flies full throttle and pitch on speed only at the minimum
airspeed, with a minimum pitch: the steepest climb the aircraft has.
Without a valid airspeed (``airspeed_valid = False``) the speed is taken as ``FW_AIRSPD_TRIM``
and TECS flies PX4's airspeed-less mode (PX4 ``TECSControl``: the speed weight is 0, underspeed
is not detected, the throttle integrator is frozen and only a positive one is still added): the
pitch controls height only and the throttle is ``FW_THR_CRUISE`` plus the feed-forward of the
height rate demand and its damping, so no loop depends on the speed it cannot see. A negative
throttle integrator (wound up while the airspeed still read too high or too low) is dropped at
the switch, and the pitch integrator alone never asks for more than the pitch limits: a height
error that the cruise throttle cannot fly off must not walk the nose up to the stall.

A measured airspeed the aircraft's own acceleration cannot explain is not used either: each
sample further than ``TAS_INNOV_GATE_M_S`` from the complementary filter's prediction (a pitot
that blocks reads 0 within a few hundred milliseconds while the airframe does not decelerate)
is rejected, the filter dead-reckons on the longitudinal acceleration and TECS flies that step
as without airspeed, for up to ``TAS_GATE_TIMEOUT_S``; a difference that persists longer is
taken as real and the filter restarts on the measurement. The airspeed module's validator
(ASPD_FS_T_STOP) declares such a pitot invalid within that time, so a blocked pitot still
counted as valid never reaches the underspeed logic, which would otherwise dive at the pitch
limit to "regain" a speed the aircraft has not lost. (PX4 reaches the same end in its airspeed
selector when its load factor check is on, ASPD_DO_CHECKS bit 3: a load factor the measured
airspeed cannot carry together with a failing innovation check invalidates the airspeed at
once; the airspeed module here has it too, but PX4's default leaves it off, hence this guard.)

Pure computation on floats, no uORB or parameters: fw_pos_control_l1 hands it the estimator's
state and its setpoints; tests/firmware/fw/test_tecs.py flies a point-mass energy model with it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final
from common.mathlib import constrain
from common.units import G0_M_S2

__all__ = ["TAS_GATE_TIMEOUT_S", "TAS_INNOV_GATE_M_S", "Tecs", "TecsParams", "TecsStatus"]

#: an airspeed sample this far from the filter's acceleration-based prediction is implausible
#: (the same figure as ASPD_FS_INNOV's default: more than gust and sensor noise)
TAS_INNOV_GATE_M_S: Final = 5.0
#: the longest the filter dead-reckons past implausible samples before believing them
TAS_GATE_TIMEOUT_S: Final = 3.0


@dataclass
class TecsParams:
    """The FW_T_* and FW_AIRSPD_* values TECS needs (SI units; PX4 defaults)."""

    time_const_s: float = 5.0          # FW_T_TIME_CONST
    throttle_time_const_s: float = 8.0  # FW_T_THRO_CONST
    alt_error_tc_s: float = 5.0        # FW_T_ALT_TC
    tas_error_tc_s: float = 2.0        # FW_T_TAS_TC
    hgt_rate_ff: float = 0.3           # FW_T_HRATE_FF
    climb_max_m_s: float = 5.0         # FW_T_CLMB_MAX
    sink_min_m_s: float = 2.0          # FW_T_SINK_MIN
    sink_max_m_s: float = 5.0          # FW_T_SINK_MAX
    throttle_damp: float = 0.1         # FW_T_THR_DAMP
    pitch_damp: float = 0.1            # FW_T_PTCH_DAMP
    integ_gain: float = 0.1            # FW_T_INTEG_GAIN
    vert_accel_max_m_s2: float = 7.0   # FW_T_VERT_ACC
    speed_weight: float = 1.0          # FW_T_SPDWEIGHT
    roll_to_throttle: float = 15.0     # FW_T_RLL2THR
    spd_omega: float = 2.0             # FW_T_SPD_OMEGA (airspeed complementary filter)
    airspeed_min_m_s: float = 10.0     # FW_AIRSPD_MIN
    airspeed_trim_m_s: float = 15.0    # FW_AIRSPD_TRIM
    airspeed_max_m_s: float = 20.0     # FW_AIRSPD_MAX


@dataclass
class TecsStatus:
    """What one update computed (logged as tecs_status)."""

    altitude_sp_m: float = 0.0
    altitude_filtered_m: float = 0.0
    height_rate_sp_m_s: float = 0.0
    height_rate_m_s: float = 0.0
    tas_sp_m_s: float = 0.0
    tas_filtered_m_s: float = 0.0
    tas_rate_sp_m_s2: float = 0.0
    tas_rate_m_s2: float = 0.0
    ste_error: float = 0.0
    ste_rate_error: float = 0.0
    seb_error: float = 0.0
    seb_rate_error: float = 0.0
    throttle_integ: float = 0.0
    pitch_integ: float = 0.0
    throttle_sp: float = 0.0
    pitch_sp_rad: float = 0.0
    underspeed: bool = False
    climbout: bool = False
    airspeed_valid: bool = True
    airspeed_gated: bool = False


class Tecs:
    """TECS state: call :meth:`update` at the position control rate; :meth:`reset` when the
    controller was not in charge (manual modes, on the ground), so no stale integrator or
    demand is carried into the next flight phase."""

    def __init__(self, params: TecsParams | None = None) -> None:
        self.p = params if params is not None else TecsParams()
        self.status = TecsStatus()
        #: airspeed samples the gate rejected since start (not cleared by reset: a count for
        #: the module's status, so a pitot that misbehaves is visible after the fact)
        self.gated_samples = 0
        self.reset()

    def reset(self) -> None:
        self.initialised = False
        self.hgt_sp_adj = 0.0
        self.hgt_sp_adj_prev = 0.0
        self.tas_state = 0.0
        self.tas_rate_state = 0.0
        self.tas_sp_adj = 0.0
        self.throttle_integ = 0.0
        self.pitch_integ = 0.0
        self.last_pitch_sp = 0.0
        self.last_throttle = 0.0
        self.underspeed = False
        self.throttle_sp = 0.0
        self.pitch_sp = 0.0
        self.gated_s = 0.0              # how long samples have been rejected in a row
        self.gated = False              # this step's sample was rejected
        self.used_airspeed = True       # the last step flew on a measured airspeed

    # -- state estimates ---------------------------------------------------------------------------

    def _update_airspeed(self, dt: float, tas: float, accel_x: float, valid: bool,
                         eas2tas: float) -> None:
        """Complementary filter of true airspeed and longitudinal acceleration (less noise and
        lag than either alone; crossover ``FW_T_SPD_OMEGA``), with the innovation gate of the
        module doc: :attr:`gated` says this step's sample was rejected."""
        p = self.p
        self.gated = False
        if not valid or not math.isfinite(tas):
            self.tas_state = p.airspeed_trim_m_s * eas2tas
            self.tas_rate_state = 0.0
            self.gated_s = 0.0
            return
        if not self.initialised:
            self.tas_state = max(tas, 0.0)
            self.tas_rate_state = 0.0
            return
        err = tas - self.tas_state
        if abs(err) > TAS_INNOV_GATE_M_S:
            if self.gated_s < TAS_GATE_TIMEOUT_S:
                # implausible: the speed follows the aircraft's own acceleration only
                self.gated_s += dt
                self.gated = True
                self.gated_samples += 1
                self.tas_state = max(self.tas_state + (self.tas_rate_state + accel_x) * dt, 0.0)
                return
            # persisted past the timeout: believed, the filter restarts on it
            self.tas_state = max(tas, 0.0)
            self.tas_rate_state = 0.0
            self.gated_s = 0.0
            return
        self.gated_s = 0.0
        w = p.spd_omega
        self.tas_rate_state += err * w * w * dt
        self.tas_state = max(self.tas_state + (err * 2.0 * w + self.tas_rate_state + accel_x)
                             * dt, 0.0)

    # -- the update --------------------------------------------------------------------------------

    def update(self, dt: float, *, altitude_m: float, height_rate_m_s: float, tas_m_s: float,
               airspeed_valid: bool, accel_x_m_s2: float, pitch_rad: float, roll_rad: float,
               hgt_sp_m: float, tas_sp_m_s: float, throttle_min: float, throttle_max: float,
               throttle_cruise: float, pitch_min_rad: float, pitch_max_rad: float,
               climbout: bool = False, climbout_pitch_min_rad: float = 0.0,
               speed_weight: float | None = None, alt_tc_s: float | None = None,
               eas2tas: float = 1.0) -> None:
        """One step: :attr:`throttle_sp` (0..1) and :attr:`pitch_sp` (rad) from the state and
        the demands. ``speed_weight`` and ``alt_tc_s`` override the parameters for one call
        (the landing flare trades speed for height with its own time constant).

        Airspeeds: ``tas_m_s`` is true airspeed (the kinetic energy's), while the setpoint and
        the FW_AIRSPD_* limits are equivalent airspeeds, as a pilot and PX4 give them (the
        stall speed is one): they are multiplied by ``eas2tas`` (the airspeed module's true
        over indicated) before use."""
        p = self.p
        dt = constrain(dt, 0.001, 0.2)
        k = eas2tas if math.isfinite(eas2tas) and 0.5 < eas2tas < 2.0 else 1.0
        self._update_airspeed(dt, tas_m_s, accel_x_m_s2, airspeed_valid, k)
        # fly on the measured airspeed only while it is valid and plausible
        measured = airspeed_valid and not self.gated
        if self.initialised and self.used_airspeed and not measured:
            # into airspeed-less flight: the throttle integrator is frozen from here on, and a
            # negative one (wound up against a false airspeed) would hold the throttle below
            # cruise, so it goes (PX4 adds only a positive integrator without airspeed)
            self.throttle_integ = max(self.throttle_integ, 0.0)
        if self.initialised and not self.used_airspeed and measured:
            # back on the airspeed: the speed demand restarts from the speed flown
            self.tas_sp_adj = self.tas_state
        self.used_airspeed = measured
        if not self.initialised:
            self.hgt_sp_adj = self.hgt_sp_adj_prev = altitude_m
            self.tas_sp_adj = self.tas_state if measured else p.airspeed_trim_m_s * k
            self.last_pitch_sp = pitch_rad
            self.last_throttle = throttle_cruise
            self.throttle_integ = 0.0
            self.pitch_integ = 0.0
            self.initialised = True
        tas = max(self.tas_state, 1.0)
        ste_rate_max = G0_M_S2 * p.climb_max_m_s
        ste_rate_min = -G0_M_S2 * p.sink_min_m_s

        # airspeed demand: limits, climb-out at the minimum, rate limited by the throttle range
        v_min, v_max = p.airspeed_min_m_s * k, max(p.airspeed_max_m_s, p.airspeed_min_m_s) * k
        tas_sp = constrain((tas_sp_m_s if math.isfinite(tas_sp_m_s) else p.airspeed_trim_m_s) * k,
                        v_min, v_max)
        if climbout:
            tas_sp = v_min
        if not measured:
            tas_sp = self.tas_state if airspeed_valid else p.airspeed_trim_m_s * k
        vel_rate_max = 0.5 * ste_rate_max / tas
        vel_rate_min = 0.5 * ste_rate_min / tas
        self.tas_sp_adj = constrain(tas_sp, self.tas_sp_adj + vel_rate_min * dt,
                                 self.tas_sp_adj + vel_rate_max * dt)
        tas_rate_sp = constrain((self.tas_sp_adj - self.tas_state) / max(p.tas_error_tc_s, 0.1),
                             vel_rate_min, vel_rate_max)

        # height demand: followed at most at the climb/sink limits
        prev = self.hgt_sp_adj
        self.hgt_sp_adj = constrain(hgt_sp_m, prev - p.sink_max_m_s * dt, prev + p.climb_max_m_s * dt)
        # never further ahead of the aircraft than one time constant at the rate limits: a
        # demand the aircraft cannot follow must not build up an energy error it cannot fly
        tc_h = alt_tc_s if alt_tc_s is not None else p.alt_error_tc_s
        self.hgt_sp_adj = constrain(self.hgt_sp_adj, altitude_m - p.sink_max_m_s * tc_h,
                                 altitude_m + p.climb_max_m_s * tc_h)
        if climbout and hgt_sp_m > altitude_m:
            # climbing out faster than the ramp: the demand keeps up with the aircraft, so
            # that the end of the climb-out does not find it far below and push the nose down
            self.hgt_sp_adj = max(self.hgt_sp_adj, altitude_m)
        ramp_rate = (self.hgt_sp_adj - prev) / dt
        hgt_rate_sp = constrain((self.hgt_sp_adj - altitude_m) / max(tc_h, 0.1)
                             + p.hgt_rate_ff * ramp_rate, -p.sink_max_m_s, p.climb_max_m_s)

        # underspeed: not enough energy to keep flying at any pitch
        # (PX4: only with an airspeed; here also only with a plausible one)
        self.underspeed = (measured and self.tas_state < 0.9 * v_min
                           and self.last_throttle >= 0.95 * throttle_max)

        # energies and their rates
        spe_sp, spe = G0_M_S2 * self.hgt_sp_adj, G0_M_S2 * altitude_m
        spe_rate_sp, spe_rate = G0_M_S2 * hgt_rate_sp, G0_M_S2 * height_rate_m_s
        ske_sp, ske = 0.5 * self.tas_sp_adj * self.tas_sp_adj, 0.5 * tas * tas
        ske_rate_sp, ske_rate = tas * tas_rate_sp, tas * self.tas_rate_state

        # weights: 0 = height only, 2 = speed only
        sw = constrain(speed_weight if speed_weight is not None else p.speed_weight, 0.0, 2.0)
        if not measured:
            sw = 0.0
        if self.underspeed or (climbout and measured):
            sw = 2.0     # pitch on speed only: climb as steeply as the minimum speed allows
        w_spe, w_ske = min(2.0 - sw, 1.0), min(sw, 1.0)

        self._throttle(dt, spe_sp + ske_sp - spe - ske, spe_rate_sp + ske_rate_sp,
                       spe_rate + ske_rate, ste_rate_max, ste_rate_min, roll_rad,
                       throttle_min, throttle_max, throttle_cruise, climbout, measured)
        self._pitch(dt, w_spe * spe_sp - w_ske * ske_sp - (w_spe * spe - w_ske * ske),
                    w_spe * spe_rate_sp - w_ske * ske_rate_sp,
                    w_spe * spe_rate - w_ske * ske_rate, tas, pitch_min_rad, pitch_max_rad,
                    climbout, climbout_pitch_min_rad)

        s = self.status
        s.altitude_sp_m, s.altitude_filtered_m = self.hgt_sp_adj, altitude_m
        s.height_rate_sp_m_s, s.height_rate_m_s = hgt_rate_sp, height_rate_m_s
        s.tas_sp_m_s, s.tas_filtered_m_s = self.tas_sp_adj, self.tas_state
        s.tas_rate_sp_m_s2, s.tas_rate_m_s2 = tas_rate_sp, self.tas_rate_state
        s.throttle_integ, s.pitch_integ = self.throttle_integ, self.pitch_integ
        s.throttle_sp, s.pitch_sp_rad = self.throttle_sp, self.pitch_sp
        s.underspeed, s.climbout, s.airspeed_valid = self.underspeed, climbout, airspeed_valid
        s.airspeed_gated = self.gated

    def _throttle(self, dt: float, ste_error: float, ste_rate_sp: float, ste_rate: float,
                  ste_rate_max: float, ste_rate_min: float, roll: float, thr_min: float,
                  thr_max: float, thr_cruise: float, climbout: bool, measured: bool) -> None:
        p = self.p
        s = self.status
        # the extra drag of a banked turn (load factor - 1) wants more total energy rate
        cos_r = max(math.cos(roll), 0.1)
        ste_rate_sp = constrain(ste_rate_sp, ste_rate_min, ste_rate_max) \
            + p.roll_to_throttle * (1.0 / cos_r - 1.0)
        ste_rate_error = ste_rate_sp - ste_rate
        s.ste_error, s.ste_rate_error = ste_error, ste_rate_error
        if self.underspeed or climbout:
            thr = thr_max
            self.throttle_integ = 0.0
        else:
            k = 1.0 / (max(p.throttle_time_const_s, 0.1) * (ste_rate_max - ste_rate_min))
            if ste_rate_sp >= 0.0:
                ff = thr_cruise + ste_rate_sp / ste_rate_max * (thr_max - thr_cruise)
            else:
                ff = thr_cruise + ste_rate_sp / ste_rate_min * (thr_min - thr_cruise)
            unc = (ste_error + ste_rate_error * p.throttle_damp) * k + ff
            if measured:
                # integrator bounded by the room the P and feed-forward terms leave (PX4's)
                integ = self.throttle_integ + ste_error * p.integ_gain * dt * k
                self.throttle_integ = constrain(integ, thr_min - unc, max(thr_max - unc,
                                                                       thr_min - unc))
            # without airspeed the integrator is frozen (PX4 TECSControl): the throttle is the
            # cruise throttle and the height's feed-forward and feedback, nothing that winds up
            thr = unc + self.throttle_integ
        self.throttle_sp = constrain(thr, thr_min, thr_max)
        self.last_throttle = self.throttle_sp

    def _pitch(self, dt: float, seb_error: float, seb_rate_sp: float, seb_rate: float,
               tas: float, pitch_min: float, pitch_max: float, climbout: bool,
               climbout_pitch_min: float) -> None:
        p = self.p
        s = self.status
        seb_rate_error = seb_rate_sp - seb_rate
        s.seb_error, s.seb_rate_error = seb_error, seb_rate_error
        tc = max(p.time_const_s, 0.1)
        gain_inv = tas * tc * G0_M_S2           # SEB per radian of pitch over one time constant
        integ_lo, integ_hi = pitch_min * gain_inv, pitch_max * gain_inv
        if climbout:
            pitch_min = max(pitch_min, min(climbout_pitch_min, pitch_max))
        correction = seb_error + seb_rate_error * p.pitch_damp + seb_rate_sp * tc
        integ = self.pitch_integ + seb_error * p.integ_gain * dt
        # anti-windup: the integrator may not push the setpoint further past a limit
        unc = (correction + integ) / gain_inv
        if unc > pitch_max:
            integ = min(integ, max(self.pitch_integ, pitch_max * gain_inv - correction))
        elif unc < pitch_min:
            integ = max(integ, min(self.pitch_integ, pitch_min * gain_inv - correction))
        # and alone it never asks for more than the pitch limits
        self.pitch_integ = constrain(integ, integ_lo, integ_hi)
        integ = self.pitch_integ
        pitch = constrain((correction + integ) / gain_inv, pitch_min, pitch_max)
        # pitch rate limit from the vertical acceleration limit
        d = p.vert_accel_max_m_s2 / tas * dt
        pitch = constrain(pitch, self.last_pitch_sp - d, self.last_pitch_sp + d)
        self.pitch_sp = constrain(pitch, pitch_min, pitch_max)
        self.last_pitch_sp = self.pitch_sp
