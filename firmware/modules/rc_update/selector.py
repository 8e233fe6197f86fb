"""Which manual-control input flies: RC or a MAVLink joystick (PX4's ManualControlSelector).

Each input (rc_update's own RC sticks, each MAVLink link's MANUAL_CONTROL on
``manual_control_input``) is offered as it arrives; the selector says whether it is the one
to publish on ``manual_control_setpoint``. PX4's rules (``COM_RC_IN_MODE``):

* 0 RC only, 1 MAVLink only;
* 2 RC and MAVLink with fallback: any valid input; the chosen one is kept while it is valid,
  and another takes over once it has timed out;
* 3 RC or MAVLink, keep first: only the source that was valid first, ever (since boot);
* 4 stick input disabled: nothing is selected.

An input is valid while its sample is newer than ``COM_RC_LOSS_T`` (PX4 uses the same timeout
for the selector and the commander's loss check), so the commander's manual-control loss
applies to the selected source: when it stops, the setpoint stops.
"""

from __future__ import annotations

from typing import Any, Final

__all__ = ["ManualControlSelector"]

SOURCE_UNKNOWN: Final = 0
SOURCE_RC: Final = 1
SOURCE_MAVLINK_0: Final = 2
SOURCE_MAVLINK_LAST: Final = 7


class ManualControlSelector:
    def __init__(self) -> None:
        self.rc_in_mode = 3
        self.timeout_us = 500_000
        self.source = SOURCE_UNKNOWN    # data_source of the chosen input
        self.chosen_us = -1             # sample time of the chosen input's newest sample
        self.first_source = SOURCE_UNKNOWN

    def _valid(self, source: int, sample_us: int, now_us: int) -> bool:
        if not (sample_us <= now_us < sample_us + self.timeout_us):
            return False
        mode = self.rc_in_mode
        if mode == 0:
            return source == SOURCE_RC
        if mode == 1:
            return SOURCE_MAVLINK_0 <= source <= SOURCE_MAVLINK_LAST
        if mode == 2:
            return True
        if mode == 3:
            return self.first_source in (SOURCE_UNKNOWN, source)
        return False

    def chosen_valid(self, now_us: int) -> bool:
        return self.source != SOURCE_UNKNOWN and self._valid(self.source, self.chosen_us, now_us)

    def offer(self, m: Any, now_us: int) -> bool:
        """True if ``m`` (a manual_control_setpoint-shaped input) is now the selected input."""
        source, sample_us = int(m.data_source), int(m.timestamp_sample)
        if not m.valid or not self._valid(source, sample_us, now_us):
            return False
        if self.chosen_valid(now_us) and source != self.source:
            return False  # the chosen input is still good: keep it
        self.source, self.chosen_us = source, sample_us
        if self.first_source == SOURCE_UNKNOWN:
            self.first_source = source
        return True
