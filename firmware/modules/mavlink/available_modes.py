"""The mode protocol of the development dialect: AVAILABLE_MODES, CURRENT_MODE, the monitor.

As PX4 1.15 (streams/AVAILABLE_MODES.hpp, CURRENT_MODE.hpp, lib/modes), following
https://mavlink.io/en/services/standard_modes.html:

* REQUEST_MESSAGE(AVAILABLE_MODES, param2 = index): index 0 sends one AVAILABLE_MODES per mode
  the commander implements, numbered 1..n in navigation-state order; index k sends the k-th
  only; an index beyond n (or not a number) is DENIED, as PX4's ``request_message`` returning
  false. Each carries PX4's custom mode (the HEARTBEAT's), the MAVLink standard mode where one
  matches (Position is POSITION_HOLD on a multicopter, Altitude ALTITUDE_HOLD, Mission, Return
  SAFE_RECOVERY, Takeoff, Land), PX4's mode name for the others, ``MAV_MODE_PROPERTY_ADVANCED``
  for every mode but Altitude and Position (PX4's ``isAdvanced``) and NOT_USER_SELECTABLE for
  a mode the commander can never enter here (precision landing);
* CURRENT_MODE: the active and the intended mode (the user's choice a failsafe overrides), at
  0.5 Hz and at once when either changes, so a ground station never shows a stale mode;
* AVAILABLE_MODES_MONITOR: only once the set of modes (or whether one is selectable) has
  changed since boot, then at the AVAILABLE_MODES stream's rate (0.3 Hz) with a sequence
  number that counts the changes, so a ground station knows to fetch the list again. PX4's
  set changes when external (ROS 2) modes register; this stack has none, so it is sent only
  if the commander's set changes.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Final

from firmware.modules.commander import modes as nav
from firmware.modules.mavlink.dialect import mav
from firmware.modules.mavlink.streams import custom_mode

if TYPE_CHECKING:
    from firmware.modules.mavlink.instance import MavlinkInstance

__all__ = ["AvailableModesService", "standard_mode"]

VEHICLE_TYPE_ROTARY_WING: Final = 1
VEHICLE_TYPE_FIXED_WING: Final = 2
_STANDARD_ALWAYS: Final = {
    nav.AUTO_RTL: mav.MAV_STANDARD_MODE_SAFE_RECOVERY,
    nav.AUTO_MISSION: mav.MAV_STANDARD_MODE_MISSION,
    nav.AUTO_LAND: mav.MAV_STANDARD_MODE_LAND,
    nav.AUTO_TAKEOFF: mav.MAV_STANDARD_MODE_TAKEOFF,
}
#: not advanced in PX4's ``isAdvanced`` (every other mode is)
_BASIC: Final = frozenset({nav.ALTCTL, nav.POSCTL})


def standard_mode(nav_state: int, vehicle_type: int, is_vtol: bool) -> int:
    """MAV_STANDARD_MODE of a navigation state (PX4's getStandardModeFromNavState)."""
    std = _STANDARD_ALWAYS.get(nav_state)
    if std is not None:
        return std
    plane_or_copter = is_vtol or vehicle_type in (VEHICLE_TYPE_ROTARY_WING,
                                                  VEHICLE_TYPE_FIXED_WING)
    if nav_state == nav.ALTCTL and plane_or_copter:
        return mav.MAV_STANDARD_MODE_ALTITUDE_HOLD
    if nav_state == nav.POSCTL and not is_vtol:
        if vehicle_type == VEHICLE_TYPE_ROTARY_WING:
            return mav.MAV_STANDARD_MODE_POSITION_HOLD
        if vehicle_type == VEHICLE_TYPE_FIXED_WING:
            return mav.MAV_STANDARD_MODE_CRUISE
    return mav.MAV_STANDARD_MODE_NON_STANDARD


def _vehicle(inst: MavlinkInstance) -> tuple[int, bool]:
    st = inst.latest("vehicle_status")
    if st is None:
        return VEHICLE_TYPE_ROTARY_WING, False
    return int(st.vehicle_type), bool(st.is_vtol)


class AvailableModesService:
    """Answers AVAILABLE_MODES requests and sends CURRENT_MODE when the mode changes."""

    def __init__(self, inst: MavlinkInstance) -> None:
        self.inst = inst
        #: the modes offered and those selectable (PX4's valid/can_set_nav_states_mask)
        self.valid: tuple[int, ...] = nav.VALID_NAV_STATES
        self.selectable: frozenset[int] = nav.SELECTABLE_NAV_STATES
        self._last_sets = (self.valid, self.selectable)
        self.had_dynamic_update = False
        self.update_seq = 0
        self._last_mode: tuple[int, int] | None = None

    def handlers(self) -> dict[int, Callable[[Any], None]]:
        return {}

    def current_mode(self) -> Any:
        """CURRENT_MODE from vehicle_status (None before the commander's first status)."""
        st = self.inst.latest("vehicle_status")
        if st is None:
            return None
        return mav.MAVLink_current_mode_message(
            standard_mode(int(st.nav_state), int(st.vehicle_type), bool(st.is_vtol)),
            custom_mode(int(st.nav_state)), custom_mode(int(st.nav_state_user_intention)))

    def monitor(self) -> Any:
        """AVAILABLE_MODES_MONITOR, or None while the set of modes has not changed."""
        if not self.had_dynamic_update:
            return None
        return mav.MAVLink_available_modes_monitor_message(self.update_seq)

    def _mode_message(self, index: int, nav_state: int) -> Any:
        vtype, vtol = _vehicle(self.inst)
        std = standard_mode(nav_state, vtype, vtol)
        props = 0 if nav_state in _BASIC else mav.MAV_MODE_PROPERTY_ADVANCED
        if nav_state not in self.selectable:
            props |= mav.MAV_MODE_PROPERTY_NOT_USER_SELECTABLE
        name = b"" if std != mav.MAV_STANDARD_MODE_NON_STANDARD else \
            nav.NAV_NAMES.get(nav_state, str(nav_state)).encode()
        return mav.MAVLink_available_modes_message(len(self.valid), index, std,
                                                   custom_mode(nav_state), props, name)

    def request(self, index_param: float) -> int:
        """REQUEST_MESSAGE(AVAILABLE_MODES): the MAV_RESULT (PX4: DENIED if nothing sent)."""
        if not math.isfinite(index_param):
            return mav.MAV_RESULT_DENIED
        # C's roundf (halves away from zero), as PX4 rounds param2
        index = int(math.copysign(math.floor(abs(index_param) + 0.5), index_param))
        if index == 0:
            for i, nav_state in enumerate(self.valid, start=1):
                self.inst.send(self._mode_message(i, nav_state))
            return mav.MAV_RESULT_ACCEPTED
        if 1 <= index <= len(self.valid):
            self.inst.send(self._mode_message(index, self.valid[index - 1]))
            return mav.MAV_RESULT_ACCEPTED
        return mav.MAV_RESULT_DENIED

    def update(self, now_us: int) -> None:
        sets = (self.valid, self.selectable)
        if sets != self._last_sets:
            self._last_sets = sets
            self.had_dynamic_update = True
            self.update_seq = (self.update_seq + 1) & 0xFF
        st = self.inst.latest("vehicle_status")
        if st is None:
            return
        mode = (int(st.nav_state), int(st.nav_state_user_intention))
        if mode != self._last_mode and not self.inst.silent():
            msg = self.current_mode()
            if msg is not None and self.inst.send(msg):
                self._last_mode = mode
