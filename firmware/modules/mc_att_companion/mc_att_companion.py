"""Multicopter attitude law on the companion computer, the FMU's law as fallback
(``mc_att_companion``, issue 24).

The companion computer runs the attitude controller (``mc_att_control`` on its own board, fed
over the uORB bridge on TELEM2); its ``vehicle_rates_setpoint`` arrives here as
``companion_rates_setpoint``. This module sits where the FMU's attitude controller sits and
decides, on every attitude update, who flies:

- the companion's rates and thrust, published as ``vehicle_rates_setpoint``, while its latest
  message is fresh (arrived at most ``MC_CMP_TIMEOUT`` ms ago) and inside the safety envelope
  (``envelope.py``: finite, rates within ``MC_*RATE_MAX``, thrust 0..1, and the tilt error
  against the attitude setpoint beyond ``MC_CMP_ERR_MAX`` for no longer than
  ``MC_CMP_ERR_TM``);
- otherwise PX4's law (the superclass, ``mc_att_control``), which runs on every update anyway
  (warm standby), so it takes over at once. The fallback is latched: a companion that failed
  once does not get the vehicle back by itself (a flapping source is worse than either).
  It ends when the module restarts (``mc_att_companion stop; mc_att_companion start``, or
  ``MC_ATT_IMPL`` set to another controller and back to 2). A warning names the reason.

Before the companion's first message it flies the FMU's law (it does not wait: the companion
may boot later than the FMU, or never), and says so. Disarmed or landed it is
``mc_att_control``: no checks, no latching (a companion booting or restarting on the ground
is no fault); in the air again, the companion's rates are taken while fresh, else it falls
back at once.

Bumpless both ways: at a switch the output continues from the last rate setpoint published
and the difference fades with ``HANDOVER_TAU_S`` (``mc_att_control/handover.py``), so the
rate controller sees no step whichever side was ahead. Freshness is measured by the FMU's
clock (when the bridge published the message here), never by the companion's timestamps.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Final

from firmware.modules.mc_att_companion.envelope import rates_violation, tilt_error_rad
from firmware.modules.mc_att_control.handover import Handover
from common.quaternion import Quat
from firmware.modules.mc_att_control.mc_att_control import PARAMS as MC_ATT_PARAMS
from firmware.modules.mc_att_control.mc_att_control import McAttControlModule
from firmware.platform.params import ParamDef

if TYPE_CHECKING:
    from firmware.system import System

__all__ = ["PARAMS", "McAttCompanionModule"]

_G: Final = "Multicopter Attitude Control"

PARAMS: tuple[ParamDef, ...] = (
    ParamDef("MC_CMP_TIMEOUT", "INT32", 20, min=1, max=1000, unit="ms", group=_G,
             short="Companion attitude law: rate setpoint timeout",
             long="The FMU's attitude law takes over (latched) when the companion's latest "
                  "rate setpoint is older than this in flight. 20 ms is five attitude periods "
                  "at 250 Hz."),
    ParamDef("MC_CMP_ERR_MAX", "FLOAT", 30.0, min=1.0, max=180.0, unit="deg", group=_G,
             decimals=1, short="Companion attitude law: max tilt error",
             long="The FMU's attitude law takes over (latched) when the tilt differs from the "
                  "attitude setpoint by more than this for longer than MC_CMP_ERR_TM."),
    ParamDef("MC_CMP_ERR_TM", "INT32", 200, min=0, max=5000, unit="ms", group=_G,
             short="Companion attitude law: max time beyond the tilt error",
             long="How long the tilt error may stay beyond MC_CMP_ERR_MAX (a step in the "
                  "setpoint gives any law a large error for a moment)."),
) + MC_ATT_PARAMS   # the rate limits, gains of the fallback law, manual tilt, throttle curve

#: what the output is now (status and log)
_WAITING: Final = "FMU law (waiting for the companion's first rate setpoint)"
_GROUND: Final = "FMU law (disarmed or landed)"
_COMPANION: Final = "companion"
_FALLBACK: Final = "FMU law (fallback, latched)"


class McAttCompanionModule(McAttControlModule):
    """``mc_att_companion``: companion_rates_setpoint while fresh and safe, else PX4's law ->
    vehicle_rates_setpoint."""

    NAME = "mc_att_companion"
    DESCRIPTION = "multicopter attitude law on the companion computer, FMU law as fallback"
    #: the FMU's law (warm standby) plus the envelope checks, ~110 us per run
    CPU_COST_NS = 110_000
    PARAMS = PARAMS
    ATT_IMPL = 2

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        self.source = _WAITING
        self.fallback_reason = ""
        self.fallback_us = 0
        self.cmp: Any = None               # the companion's latest rate setpoint
        self.fmu_thrust = self.thrust_body  # the FMU's own (its setpoint's) thrust
        self.cmp_thrust = [0.0, 0.0, 0.0]   # the companion's, while forwarded
        self.engage = Handover()            # the fade into the companion's rates
        self.tilt_since_us = -1             # beyond MC_CMP_ERR_MAX since (-1: not)
        self.received = 0
        self.forwarded = 0
        self.fmu_outputs = 0
        self.age_max_us = 0                 # largest age of a forwarded setpoint
        self.tilt_max_rad = 0.0             # largest tilt error while forwarding

    def _start(self) -> None:
        super()._start()
        self.sub_cmp = self.subscribe("companion_rates_setpoint")
        node = self.sub_cmp.node
        if node.last is not None and self._age_us(self.platform.hrt.absolute_time()) \
                > self.timeout_us:
            # from before this start (a restart after a fallback, the companion silent
            # since): not a first message, and no reason to fall back again at once
            self.sub_cmp.update()
        self.info("flying the FMU law until the companion's first rate setpoint")

    def _age_us(self, now: int) -> int:
        """How long ago (FMU clock) the companion's latest rate setpoint arrived."""
        return now - self.sub_cmp.node.last_publish_ns // 1000

    def _load_params(self) -> None:
        super()._load_params()
        p = self.param
        self.timeout_us = int(p("MC_CMP_TIMEOUT")) * 1000
        self.err_max = float(p("MC_CMP_ERR_MAX")) * math.pi / 180.0
        self.err_time_us = int(p("MC_CMP_ERR_TM")) * 1000

    def _poll(self) -> None:
        # the setpoint's thrust goes to the FMU's own list, whatever was forwarded last time
        self.thrust_body = self.fmu_thrust
        super()._poll()

    # -- the choice ----------------------------------------------------------------------------

    def _law(self, q: Quat, dt: float, now: int) -> tuple[float, float, float]:
        """The FMU's law always (warm standby); the companion's rates instead while fresh and
        inside the envelope, in the air, until the first failure."""
        fmu = super()._law(q, dt, now)
        sub = self.sub_cmp
        if sub.updated():
            if self.cmp is None:
                self.info("first rate setpoint from the companion: it flies while fresh "
                          f"(MC_CMP_TIMEOUT {self.timeout_us // 1000} ms) and inside the "
                          "envelope")
            self.received += sub.node.generation - sub.last_gen
            self.cmp = sub.copy()         # the latest: any before it is superseded
        if self.source == _FALLBACK or self.cmp is None:
            self.fmu_outputs += 1
            return fmu
        if not self.armed or self.landed:
            self.source = _GROUND
            self.tilt_since_us = -1
            self.fmu_outputs += 1
            return fmu
        reason = self._check(q, now)
        if reason:
            return self._fall_back(reason, fmu, now)
        c = self.cmp
        rates = (float(c.roll), float(c.pitch), float(c.yaw))
        if self.source != _COMPANION:
            self.source = _COMPANION
            self._start_fade(self.engage, rates, now)
        tb, ct = self.cmp_thrust, c.thrust_body
        tb[0], tb[1], tb[2] = float(ct[0]), float(ct[1]), float(ct[2])
        self.thrust_body = tb
        self.forwarded += 1
        if self.engage.active:
            return self.engage.apply(rates[0], rates[1], rates[2], now)
        return rates

    def _check(self, q: Quat, now: int) -> str:
        """Why the companion may not fly now ("" if it may): stale, or outside the envelope."""
        age_us = self._age_us(now)
        if age_us > self.timeout_us:
            return (f"stale: no companion rate setpoint for {age_us / 1000:.1f} ms "
                    f"(MC_CMP_TIMEOUT {self.timeout_us // 1000} ms)")
        self.age_max_us = max(self.age_max_us, age_us)
        c = self.cmp
        why = rates_violation((float(c.roll), float(c.pitch), float(c.yaw)),
                              (float(c.thrust_body[0]), float(c.thrust_body[1]),
                               float(c.thrust_body[2])), self.rate_max)
        if why is not None:
            return f"envelope: {why}"
        tilt = tilt_error_rad(q, self.qd)
        self.tilt_max_rad = max(self.tilt_max_rad, tilt)
        if tilt <= self.err_max:
            self.tilt_since_us = -1
            return ""
        if self.tilt_since_us < 0:
            self.tilt_since_us = now
        if now - self.tilt_since_us <= self.err_time_us:
            return ""
        return (f"envelope: tilt error {math.degrees(tilt):.1f} deg beyond MC_CMP_ERR_MAX "
                f"({math.degrees(self.err_max):.0f} deg) for "
                f"{(now - self.tilt_since_us) / 1000:.0f} ms")

    def _fall_back(self, reason: str, fmu: tuple[float, float, float], now: int
                   ) -> tuple[float, float, float]:
        """Latch the FMU's law, say why, and continue from the last output (bumpless)."""
        self.source = _FALLBACK
        self.fallback_reason = reason
        self.fallback_us = now
        self.fmu_outputs += 1
        # short: the log's message (log_message.text) holds 127 characters with the prefix
        self.warn(f"FMU law flies (latched): {reason}")
        self.engage.active = False
        ho = self.handover
        # the superclass's fade (a swap at start) may still run: take it out, then fade from
        # the last output to the bare FMU law with the superclass's own fade
        cur = ho.apply(0.0, 0.0, 0.0, now) if ho.active else (0.0, 0.0, 0.0)
        raw = (fmu[0] - cur[0], fmu[1] - cur[1], fmu[2] - cur[2])
        if not self._start_fade(ho, raw, now):
            ho.active = False
            return raw
        return ho.apply(raw[0], raw[1], raw[2], now)

    def _start_fade(self, fade: Handover, new: tuple[float, float, float], now: int) -> bool:
        """Start ``fade`` from the last published rate setpoint to ``new`` if that one is
        recent (else there is no step to avoid); returns whether it started."""
        last = self.pub_rates.node.last
        if not fade.take(last, now):
            return False
        dr, dp, dy = fade.difference(new[0], new[1], new[2])
        fade.start_offset((dr, dp, dy), now)
        return True

    # -- status --------------------------------------------------------------------------------

    def status_lines(self) -> list[str]:
        now = self.platform.hrt.absolute_time()
        age = (f"{self._age_us(now) / 1000:.1f} ms" if self.cmp is not None
               else "none yet")
        src = self.source
        if src == _FALLBACK:
            src += f" at {self.fallback_us / 1e6:.3f} s: {self.fallback_reason}"
        return [f"source: {src}",
                f"companion rate setpoints: {self.received} received, latest age {age}; "
                f"outputs: {self.forwarded} forwarded, {self.fmu_outputs} by the FMU law",
                f"in flight while forwarding: max age {self.age_max_us / 1000:.1f} ms "
                f"(MC_CMP_TIMEOUT {self.timeout_us // 1000} ms), max tilt error "
                f"{math.degrees(self.tilt_max_rad):.1f} deg (MC_CMP_ERR_MAX "
                f"{math.degrees(self.err_max):.0f} deg)",
                f"fallbacks: {1 if self.fallback_reason else 0}"
                + (f" ({self.fallback_reason.split(':')[0]})" if self.fallback_reason else "")
                ] + super().status_lines()
