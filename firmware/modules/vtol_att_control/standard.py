"""The standard VTOL ("quadplane"): four lift rotors and a plane with a pusher, PX4's way.

The multicopter and fixed-wing controllers both run and publish *virtual* actuator controls
(``actuator_controls_virtual_mc`` and ``_fw``); this state machine decides, each cycle, how much
of each reaches the real outputs: control group 0 (the lift rotors, MAIN through the IO) and
group 1 (surfaces and pusher, AUX on the FMU).

    MC --front transition--> TRANSITION_TO_FW --airspeed >= VT_ARSP_TRANS--> FW
    FW --back transition--> TRANSITION_TO_MC --VT_B_TRANS_DUR--> MC
    TRANSITION_TO_FW --quad-chute (timeout, altitude or attitude lost)--> TRANSITION_TO_MC

Front transition: the pusher ramps to VT_F_TRANS_THR over VT_PSHER_RMP_DT while the rotors keep
the vehicle level; above VT_ARSP_BLEND the rotors' share falls linearly to zero at
VT_ARSP_TRANS; the transition completes at VT_ARSP_TRANS, not before VT_TRANS_MIN_TM. The
surfaces are live throughout both transitions (share 1; both attitude controllers then hold the
same level setpoint): the pusher pitches the nose down (the quadplane's thrust line passes above
its centre of gravity) and the wing trims with up elevator, so with the elevator locked at
neutral the rotors alone would have to hold the nose up, their thrust already taken by the
weight. Without an airspeed reading (VT_ARSP_TRANS needs one) the blend runs
on time instead, over VT_F_TRANS_DUR, as PX4 does when airspeed is disabled. Back transition:
pusher off, the rotors' share ramps back to one over VT_B_TRANS_RAMP, and the vehicle is a
multicopter again after VT_B_TRANS_DUR, when the surfaces are released.

Quad-chute (PX4's name for giving up on the wing): a front transition that takes longer than
VT_TRANS_TIMEOUT, or fixed-wing flight that drops below VT_FW_MIN_ALT above home or exceeds
VT_FW_QC_P / VT_FW_QC_R in pitch / roll, switches back to multicopter at once and latches
``fixed_wing_system_failure``, which the commander turns into a return.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

__all__ = ["Mode", "StandardVtol", "VtolInputs", "VtolParams", "VtolOutputs"]


class Mode(IntEnum):
    """vtol_vehicle_status.VEHICLE_VTOL_STATE_* values."""

    TRANSITION_TO_FW = 1
    TRANSITION_TO_MC = 2
    MC = 3
    FW = 4


@dataclass
class VtolParams:
    arsp_trans_m_s: float = 10.0     # VT_ARSP_TRANS
    arsp_blend_m_s: float = 8.0      # VT_ARSP_BLEND
    trans_min_tm_s: float = 2.0      # VT_TRANS_MIN_TM
    f_trans_dur_s: float = 5.0       # VT_F_TRANS_DUR (no airspeed: the time it takes)
    f_trans_thr: float = 1.0         # VT_F_TRANS_THR: pusher throttle in the transition
    psher_rmp_dt_s: float = 3.0      # VT_PSHER_RMP_DT: pusher ramp up time
    b_trans_dur_s: float = 4.0       # VT_B_TRANS_DUR
    b_trans_ramp_s: float = 3.0      # VT_B_TRANS_RAMP: rotors back to full share
    trans_timeout_s: float = 15.0    # VT_TRANS_TIMEOUT (front transition quad-chute)
    fw_min_alt_m: float = 0.0        # VT_FW_MIN_ALT (0: off)
    fw_qc_pitch_rad: float = 0.0     # VT_FW_QC_P (0: off)
    fw_qc_roll_rad: float = 0.0      # VT_FW_QC_R (0: off)


@dataclass
class VtolInputs:
    t_s: float
    airspeed_m_s: float              # NaN without a valid airspeed
    altitude_above_home_m: float
    roll_rad: float
    pitch_rad: float


@dataclass
class VtolOutputs:
    mode: Mode
    mc_weight: float                 # share of the rotors' controls (0..1)
    fw_weight: float                 # share of the surfaces' controls (0..1)
    pusher: float | None             # pusher throttle override; None: the FW controller's
    quad_chute: str                  # why the wing was given up, "" if it was not


class StandardVtol:
    """The state machine; :meth:`update` once per cycle, :meth:`request` from commands."""

    def __init__(self, params: VtolParams | None = None) -> None:
        self.p = params or VtolParams()
        self.mode = Mode.MC
        self.t_mode_s = 0.0
        self.mc_weight_at_back_s = 1.0
        self.quad_chute = ""
        self._want_fw = False

    def request(self, fixed_wing: bool) -> bool:
        """A transition request (MAV_CMD_DO_VTOL_TRANSITION); False when refused (a front
        transition after a quad-chute, until the vehicle is back in multicopter mode and the
        failure is reset by landing)."""
        if fixed_wing and self.quad_chute:
            return False
        self._want_fw = fixed_wing
        return True

    def reset_failure(self) -> None:
        """Landed: the quad-chute latch is cleared (PX4 clears it on disarm)."""
        self.quad_chute = ""

    def _enter(self, mode: Mode, t_s: float) -> None:
        self.mode = mode
        self.t_mode_s = t_s

    def _chute(self, why: str, t_s: float) -> None:
        self.quad_chute = why
        self._want_fw = False
        self._enter(Mode.TRANSITION_TO_MC, t_s)
        self.mc_weight_at_back_s = 1.0  # the rotors take over at once

    def update(self, i: VtolInputs) -> VtolOutputs:
        p = self.p
        t = i.t_s
        dt = t - self.t_mode_s
        has_airspeed = not math.isnan(i.airspeed_m_s)
        if self.mode is Mode.MC and self._want_fw:
            self._enter(Mode.TRANSITION_TO_FW, t)
            dt = 0.0
        elif self.mode is Mode.FW and not self._want_fw:
            self._enter(Mode.TRANSITION_TO_MC, t)
            self.mc_weight_at_back_s = 0.0
            dt = 0.0
        elif self.mode is Mode.TRANSITION_TO_FW:
            if not self._want_fw:
                self._enter(Mode.TRANSITION_TO_MC, t)
                self.mc_weight_at_back_s = 1.0
                dt = 0.0
            elif p.trans_timeout_s > 0 and dt > p.trans_timeout_s:
                self._chute(f"transition timeout ({p.trans_timeout_s:g} s)", t)
                dt = 0.0
            elif dt >= p.trans_min_tm_s and (
                    (has_airspeed and i.airspeed_m_s >= p.arsp_trans_m_s)
                    or (not has_airspeed and dt >= p.f_trans_dur_s)):
                self._enter(Mode.FW, t)
                dt = 0.0
        elif self.mode is Mode.TRANSITION_TO_MC and dt >= p.b_trans_dur_s:
            self._enter(Mode.MC, t)
            dt = 0.0
        if self.mode is Mode.FW:
            why = ""
            if p.fw_min_alt_m > 0 and i.altitude_above_home_m < p.fw_min_alt_m:
                why = f"altitude {i.altitude_above_home_m:.1f} m below VT_FW_MIN_ALT"
            elif p.fw_qc_pitch_rad > 0 and abs(i.pitch_rad) > p.fw_qc_pitch_rad:
                why = "pitch beyond VT_FW_QC_P"
            elif p.fw_qc_roll_rad > 0 and abs(i.roll_rad) > p.fw_qc_roll_rad:
                why = "roll beyond VT_FW_QC_R"
            if why:
                self._chute(why, t)
                dt = 0.0
        return self._outputs(i, dt)

    def _outputs(self, i: VtolInputs, dt: float) -> VtolOutputs:
        p = self.p
        mode = self.mode
        if mode is Mode.MC:
            return VtolOutputs(mode, 1.0, 0.0, 0.0, self.quad_chute)
        if mode is Mode.FW:
            return VtolOutputs(mode, 0.0, 1.0, None, self.quad_chute)
        if mode is Mode.TRANSITION_TO_FW:
            ramp = min(1.0, dt / p.psher_rmp_dt_s) if p.psher_rmp_dt_s > 0 else 1.0
            pusher = p.f_trans_thr * ramp
            if not math.isnan(i.airspeed_m_s) and p.arsp_trans_m_s > p.arsp_blend_m_s:
                blend = (i.airspeed_m_s - p.arsp_blend_m_s) / (p.arsp_trans_m_s
                                                               - p.arsp_blend_m_s)
            elif math.isnan(i.airspeed_m_s) and p.f_trans_dur_s > 0:
                blend = dt / p.f_trans_dur_s
            else:
                blend = 0.0
            mc = 1.0 - min(1.0, max(0.0, blend))
            return VtolOutputs(mode, mc, 1.0, pusher, self.quad_chute)
        # back transition: pusher off, rotors ramp back in
        ramp = min(1.0, dt / p.b_trans_ramp_s) if p.b_trans_ramp_s > 0 else 1.0
        mc = self.mc_weight_at_back_s + (1.0 - self.mc_weight_at_back_s) * ramp
        return VtolOutputs(mode, mc, 1.0, 0.0, self.quad_chute)
