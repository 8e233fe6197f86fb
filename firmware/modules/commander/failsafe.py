"""Failsafe decisions: which reaction (hold, return, land, ...) overrides the pilot's mode.

Shaped like PX4's failsafe state machine (2022+), reduced to the causes this stack has:

* a *latched* cause (RC loss, data-link loss, low battery) triggers once while armed and in the
  air, and its reaction stays until it is cleared: a Hold reaction clears when the condition
  does; Return/Land clear only when the condition is gone *and* the pilot selects a mode (or on
  disarm), so a flickering link does not yank the vehicle back and forth;
* the battery cause escalates with the warning level and re-triggers only at a higher level;
* COM_FAIL_ACT_T: before a Return/Land/Descend reaction the vehicle holds that long;
* position loss is not latched: :func:`fallback` replaces a mode that cannot run with the best
  one that can (position -> altitude, auto -> land -> descend), every loop.

The most severe active reaction wins (FAILSAFE_ACTION_* are ordered by severity).
"""

from __future__ import annotations

from typing import Final

from firmware.modules.commander import modes

__all__ = ["ACTION_NAMES_LOWER", "A_DESCEND", "A_DISARM", "A_HOLD", "A_LAND", "A_NONE", "A_RTL", "A_TERMINATE",
           "Failsafe", "action_from_param", "fallback", "offboard_loss_nav"]

A_NONE, A_HOLD, A_RTL, A_LAND, A_DESCEND, A_DISARM, A_TERMINATE = range(7)
#: names of the actions, for messages ("Failsafe: manual control lost, return")
ACTION_NAMES_LOWER: Final[tuple[str, ...]] = ("none", "hold", "return", "land", "descend", "disarm", "terminate")

#: NAV_RCL_ACT / NAV_DLL_ACT value -> action
_PARAM_ACTION: Final = {0: A_NONE, 1: A_HOLD, 2: A_RTL, 3: A_LAND, 4: A_RTL, 5: A_TERMINATE,
                 6: A_DISARM}


def action_from_param(value: int) -> int:
    return _PARAM_ACTION.get(int(value), A_RTL)


def battery_action(com_low_bat_act: int, warning: int) -> int:
    """COM_LOW_BAT_ACT at a battery warning level (1 low, 2 critical, 3 emergency)."""
    if warning < 2 or com_low_bat_act == 0:
        return A_NONE
    if com_low_bat_act == 1:
        return A_RTL
    if com_low_bat_act == 2:
        return A_LAND
    return A_RTL if warning == 2 else A_LAND


def fallback(nav: int, ok: dict[str, bool]) -> int:
    """The mode to fly instead of ``nav`` when its requirements are not met (``ok`` says which
    are). Returns ``nav`` itself when it can run."""
    for _ in range(4):  # a short chain: e.g. RTL -> Land -> Descend
        req = modes.REQUIREMENTS.get(nav, frozenset())
        if all(ok.get(r, False) for r in req):
            return nav
        if nav == modes.POSCTL:
            nav = modes.ALTCTL if ok.get("manual") and ok.get("alt") else modes.DESCEND
        elif nav == modes.ALTCTL:
            nav = modes.STAB if ok.get("manual") else modes.DESCEND
        elif nav == modes.AUTO_MISSION and ok.get("gpos") and ok.get("lpos"):
            nav = modes.AUTO_LOITER
        elif nav == modes.AUTO_RTL and ok.get("gpos") and ok.get("lpos"):
            nav = modes.AUTO_LAND
        elif nav in (modes.MANUAL, modes.STAB, modes.ACRO):
            nav = modes.AUTO_LOITER if ok.get("gpos") and ok.get("lpos") else modes.DESCEND
        elif nav == modes.AUTO_LAND or "never" in req:
            nav = modes.DESCEND if "never" not in req else modes.AUTO_LOITER
        else:
            nav = modes.AUTO_LAND if ok.get("gpos") and ok.get("alt") else modes.DESCEND
    return modes.DESCEND


#: COM_OBL_RC_ACT value -> the mode to fly (None: disarm), PX4's fromOffboardLossActParam
_OBL_NAV: Final[dict[int, int | None]] = {
    0: modes.POSCTL, 1: modes.ALTCTL, 2: modes.STAB, 3: modes.AUTO_RTL, 4: modes.AUTO_LAND,
    5: modes.AUTO_LOITER, 6: modes.TERMINATION, 7: None}


def offboard_loss_nav(com_obl_rc_act: int, ok: dict[str, bool]) -> int | None:
    """The mode that replaces Offboard when its signal is lost (None: disarm).

    As PX4 1.14's Failsafe::checkModeFallback: COM_OBL_RC_ACT names the mode (unknown values:
    Position); a manual mode that cannot run (no manual control, no position) falls to the next
    (Position -> Altitude -> Stabilized, COM_POSCTL_NAVL 0), and one that still cannot run
    becomes Return; :func:`fallback` then takes Return -> Land -> Descend as usual. So with RC
    the default flies Position mode, without RC it returns."""
    nav = _OBL_NAV.get(int(com_obl_rc_act), modes.POSCTL)
    if nav is None or nav == modes.TERMINATION:
        return nav

    def can_run(n: int) -> bool:
        return all(ok.get(r, False) for r in modes.REQUIREMENTS.get(n, frozenset()))

    if nav == modes.POSCTL and not can_run(nav):
        nav = modes.ALTCTL
    if nav == modes.ALTCTL and not can_run(nav):
        nav = modes.STAB
    if not can_run(nav) and nav in (modes.STAB, modes.ALTCTL, modes.POSCTL):
        nav = modes.AUTO_RTL
    return nav


def action_nav(action: int) -> int | None:
    """Navigation state of a reaction (None: the reaction is not a mode, e.g. disarm)."""
    return {A_HOLD: modes.AUTO_LOITER, A_RTL: modes.AUTO_RTL, A_LAND: modes.AUTO_LAND,
            A_DESCEND: modes.DESCEND, A_TERMINATE: modes.TERMINATION}.get(action)


class _Cause:
    """One latched failsafe cause."""

    __slots__ = ("action", "level", "name", "t_trigger_us")

    def __init__(self, name: str) -> None:
        self.name = name
        self.action = A_NONE
        self.t_trigger_us = 0
        self.level = 0          # battery: the warning level already acted on


class Failsafe:
    """The latched causes and the resulting reaction."""

    def __init__(self) -> None:
        self.causes = {n: _Cause(n) for n in ("rc", "datalink", "battery", "quad_chute")}
        self.user_took_over = False

    def update(self, name: str, condition: bool, action: int, now_us: int,
               in_air: bool, level: int = 1) -> bool:
        """Feed one cause's condition; True when it newly triggered (to report it)."""
        c = self.causes[name]
        if not condition:
            if c.action == A_HOLD:
                c.action = A_NONE
            if name != "battery":  # a new loss of the link may trigger again
                c.level = 0
            return False
        if action == A_NONE or not in_air:
            return False
        if level > c.level and (c.action == A_NONE or action > c.action):
            c.action = action
            c.level = level
            c.t_trigger_us = now_us
            self.user_took_over = False
            return True
        return False

    def user_mode_change(self, conditions: dict[str, bool]) -> None:
        """The pilot selected a mode: clear reactions whose condition has gone."""
        for name, c in self.causes.items():
            if c.action != A_NONE and not conditions.get(name, False):
                c.action = A_NONE
                self.user_took_over = True
            elif name == "battery" and c.action != A_NONE:
                c.action = A_NONE     # the pilot takes over; only a higher level re-triggers
                self.user_took_over = True

    def clear(self) -> None:
        """Disarmed: every reaction ends."""
        for c in self.causes.values():
            c.action = A_NONE
            c.level = 0
        self.user_took_over = False

    def active(self, now_us: int, delay_us: int) -> tuple[int, bool]:
        """(the most severe reaction, whether it is still in its hold delay)."""
        best, t = A_NONE, 0
        for c in self.causes.values():
            if c.action > best:
                best, t = c.action, c.t_trigger_us
        delayed = (best in (A_RTL, A_LAND, A_DESCEND) and delay_us > 0
                   and now_us - t < delay_us)
        return best, delayed

    def active_causes(self) -> list[str]:
        return [c.name for c in self.causes.values() if c.action != A_NONE]
