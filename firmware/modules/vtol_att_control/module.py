"""``vtol_att_control``: the standard VTOL's mixer of controllers (PX4's VtolAttitudeControl).

The multicopter rate controller and the fixed-wing attitude controller of a VTOL publish
``actuator_controls_virtual_mc`` and ``actuator_controls_virtual_fw`` instead of group 0; this
module runs when the multicopter's virtual controls arrive (the rate loop's cadence) and
writes the real groups through :class:`StandardVtol`'s shares:

* ``actuator_controls_0`` (lift rotors, the IO's MAIN mixer): the multicopter's roll, pitch,
  yaw and thrust times the rotors' share;
* ``actuator_controls_1`` (surfaces and pusher, the FMU's AUX mixer): the fixed-wing's roll,
  pitch and yaw times the surfaces' share, and the pusher (index 3) from the transition's ramp
  or, in fixed-wing flight, the fixed-wing controller's throttle.

Transitions come as ``vehicle_command`` MAV_CMD_DO_VTOL_TRANSITION (3000; param1 3 = MC,
4 = FW), from a ground station or the navigator; each gets a ``vehicle_command_ack``.
``vtol_vehicle_status`` says the state, which the commander copies into
``vehicle_status.vehicle_type`` and ``in_transition_mode``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, ClassVar, Final

from firmware.modules.vtol_att_control.standard import (
    Mode,
    StandardVtol,
    VtolInputs,
    VtolParams,
)
from firmware.platform.module import WorkItemModule
from firmware.platform.params import ParamDef

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["PARAMS", "VtolAttControlModule"]

CMD_DO_VTOL_TRANSITION: Final = 3000
MAV_VTOL_STATE_MC: Final = 3
MAV_VTOL_STATE_FW: Final = 4
ACK_ACCEPTED: Final = 0
ACK_DENIED: Final = 2
_G: Final = "VTOL Attitude Control"


def _f(name: str, default: float, lo: float, hi: float, short: str, unit: str = "") -> ParamDef:
    return ParamDef(name, "FLOAT", default, min=lo, max=hi, unit=unit, group=_G, short=short)


PARAMS: tuple[ParamDef, ...] = (
    ParamDef("VT_TYPE", "INT32", 2, min=0, max=2, group=_G, short="VTOL type",
             values={0: "tailsitter", 1: "tiltrotor", 2: "standard"},
             long="Only the standard VTOL (lift rotors plus a pusher) is built."),
    _f("VT_ARSP_TRANS", 10.0, 0.0, 30.0, "Airspeed at which the front transition ends", "m/s"),
    _f("VT_ARSP_BLEND", 8.0, 0.0, 30.0, "Airspeed at which the rotors start to hand over", "m/s"),
    _f("VT_TRANS_MIN_TM", 2.0, 0.0, 20.0, "Shortest front transition", "s"),
    _f("VT_F_TRANS_DUR", 5.0, 0.0, 20.0, "Front transition without airspeed", "s"),
    _f("VT_F_TRANS_THR", 1.0, 0.0, 1.0, "Pusher throttle during the front transition"),
    _f("VT_PSHER_RMP_DT", 3.0, 0.0, 20.0, "Pusher ramp-up time", "s"),
    _f("VT_B_TRANS_DUR", 4.0, 0.1, 20.0, "Back transition duration", "s"),
    _f("VT_B_TRANS_RAMP", 3.0, 0.0, 20.0, "Rotors back to full share over", "s"),
    _f("VT_TRANS_TIMEOUT", 15.0, 0.0, 30.0, "Front transition timeout (quad-chute)", "s"),
    _f("VT_FW_MIN_ALT", 0.0, 0.0, 200.0, "Quad-chute below this height (0: off)", "m"),
    _f("VT_FW_QC_P", 0.0, 0.0, 180.0, "Quad-chute beyond this pitch (0: off)", "deg"),
    _f("VT_FW_QC_R", 0.0, 0.0, 180.0, "Quad-chute beyond this roll (0: off)", "deg"),
)


class VtolAttControlModule(WorkItemModule):
    """See the module docstring."""

    NAME: ClassVar[str] = "vtol_att_control"
    DESCRIPTION: ClassVar[str] = "standard VTOL: transitions and the mix of MC and FW controls"
    WQ: ClassVar[str] = "wq:rate_ctrl"
    CPU_COST_NS: ClassVar[int] = 20_000
    PARAMS: ClassVar[tuple[ParamDef, ...]] = PARAMS
    #: answered here, so the commander leaves them (firmware/modules/commander/commands.py)
    VEHICLE_COMMANDS: ClassVar[frozenset[int]] = frozenset({CMD_DO_VTOL_TRANSITION})

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        self.vtol = StandardVtol(self._params())

    def _params(self) -> VtolParams:
        p = self.param
        return VtolParams(
            arsp_trans_m_s=float(p("VT_ARSP_TRANS")), arsp_blend_m_s=float(p("VT_ARSP_BLEND")),
            trans_min_tm_s=float(p("VT_TRANS_MIN_TM")), f_trans_dur_s=float(p("VT_F_TRANS_DUR")),
            f_trans_thr=float(p("VT_F_TRANS_THR")), psher_rmp_dt_s=float(p("VT_PSHER_RMP_DT")),
            b_trans_dur_s=float(p("VT_B_TRANS_DUR")),
            b_trans_ramp_s=float(p("VT_B_TRANS_RAMP")),
            trans_timeout_s=float(p("VT_TRANS_TIMEOUT")),
            fw_min_alt_m=float(p("VT_FW_MIN_ALT")),
            fw_qc_pitch_rad=math.radians(float(p("VT_FW_QC_P"))),
            fw_qc_roll_rad=math.radians(float(p("VT_FW_QC_R"))))

    def _start(self) -> None:
        item = self.work_item
        assert item is not None
        self.sub_mc = self.subscribe_callback(item, "actuator_controls_virtual_mc")
        self.sub_fw = self.subscribe("actuator_controls_virtual_fw")
        self.sub_cmd = self.subscribe("vehicle_command")
        self.sub_att = self.subscribe("vehicle_attitude")
        self.sub_lpos = self.subscribe("vehicle_local_position")
        self.sub_airspeed = self.subscribe("airspeed")
        self.sub_armed = self.subscribe("actuator_armed")
        self.sub_param = self.subscribe("parameter_update")
        self.pub_ac0 = self.advertise("actuator_controls_0")
        self.pub_ac1 = self.advertise("actuator_controls_1")
        self.pub_status = self.advertise("vtol_vehicle_status")
        self.pub_ack = self.advertise("vehicle_command_ack")
        orb = self.platform.orb
        self.msg_ac0 = orb.new("actuator_controls_0")
        self.msg_ac1 = orb.new("actuator_controls_1")
        self.msg_status = orb.new("vtol_vehicle_status")
        self.mc = [0.0] * 8
        self.fw = [0.0] * 8
        self.last_mode = self.vtol.mode
        self.chute_reported = ""
        self.vtol.p = self._params()

    def _commands(self) -> None:
        while (cmd := self.sub_cmd.update()) is not None:
            if cmd.command != CMD_DO_VTOL_TRANSITION:
                continue
            want = int(round(cmd.param1))
            ok = want in (MAV_VTOL_STATE_MC, MAV_VTOL_STATE_FW) and self.vtol.request(
                want == MAV_VTOL_STATE_FW)
            ack = self.platform.orb.new("vehicle_command_ack")
            ack.timestamp = self.platform.hrt.absolute_time()
            ack.command = CMD_DO_VTOL_TRANSITION
            ack.result = ACK_ACCEPTED if ok else ACK_DENIED
            ack.target_system = cmd.source_system
            ack.target_component = cmd.source_component
            self.pub_ack.publish(ack)
            if not ok:
                self.warn("transition to fixed wing refused: quad-chute latched"
                          if want == MAV_VTOL_STATE_FW else f"unknown VTOL state {want}")

    def run(self) -> None:
        if self.sub_param.updated():
            self.sub_param.copy()
            self.vtol.p = self._params()
        self._commands()
        m = self.sub_mc.update()
        if m is not None:
            self.mc = list(m.control)
        f = self.sub_fw.update()
        if f is not None:
            self.fw = list(f.control)
        armed = self.sub_armed.copy()
        if armed is not None and not armed.armed:
            self.vtol.reset_failure()
        att = self.sub_att.copy()
        roll = pitch = 0.0
        if att is not None:
            w, x, y, z = att.q
            roll = math.atan2(2.0 * (w * x + y * z), 1.0 - 2.0 * (x * x + y * y))
            pitch = math.asin(max(-1.0, min(1.0, 2.0 * (w * y - z * x))))
        lpos = self.sub_lpos.copy()
        height = -float(lpos.z) if lpos is not None else 0.0
        asp = self.sub_airspeed.copy()
        airspeed = (float(asp.indicated_airspeed_m_s)
                    if asp is not None and asp.confidence > 0.5 else math.nan)
        now = self.platform.hrt.absolute_time()
        out = self.vtol.update(VtolInputs(now * 1e-6, airspeed, height, roll, pitch))
        if out.mode is not self.last_mode:
            self.info(f"{self.last_mode.name} -> {out.mode.name}")
            self.last_mode = out.mode
        if out.quad_chute and out.quad_chute != self.chute_reported:
            self.emergency(f"quad-chute: {out.quad_chute}")
            self.chute_reported = out.quad_chute
        a0, a1 = self.msg_ac0, self.msg_ac1
        wm, wf = out.mc_weight, out.fw_weight
        for i in range(4):
            a0.control[i] = self.mc[i] * wm
        for i in range(3):
            a1.control[i] = self.fw[i] * wf
        a1.control[3] = self.fw[3] if out.pusher is None else out.pusher
        a0.timestamp = a1.timestamp = now
        self.pub_ac0.publish(a0)
        self.pub_ac1.publish(a1)
        st = self.msg_status
        st.timestamp = now
        st.vehicle_vtol_state = int(out.mode)
        st.fixed_wing_system_failure = bool(out.quad_chute)
        st.mc_weight = wm
        st.pusher_throttle = a1.control[3]
        self.pub_status.publish(st)

    def status_lines(self) -> list[str]:
        v = self.vtol
        return [f"state {v.mode.name}" + (f", quad-chute: {v.quad_chute}" if v.quad_chute else "")]
