"""The commander's ESC check: PX4's ``Commander::esc_status_check`` on ``esc_status``.

The output driver (here the uavcan driver with UAVCAN_ENABLE 3) says which of the ESCs it
drives report (``esc_online_flags``). As PX4, the commander warns only when an ESC goes from
online to offline (ESCs that have not reported yet at boot are no news), with a critical
"ESC2 offline" STATUSTEXT naming every ESC now missing, and keeps ``escs_error`` set while
any is missing (what PX4 keeps in ``condition_escs_error`` and its health report). When all
are online again it says "All ESCs online" once (an info message of this tree; PX4 only
clears its flag). The ESCs' failure bits raise ``escs_failure``.

Not modelled: PX4's arming check on offline ESCs (COM_ARM_CHK_ESCS) and the per-failure-bit
messages (DroneCAN's esc.Status carries an error count, no failure bits).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Final

if TYPE_CHECKING:
    from firmware.modules.commander.commander import CommanderModule

__all__ = ["EscCheck", "SEV_CRITICAL"]

#: MAVLink's MAV_SEVERITY_CRITICAL, PX4's mavlink_log_critical
SEV_CRITICAL: Final = 2


class EscCheck:
    """Watches ``esc_status`` for one commander; :meth:`update` runs in its loop."""

    def __init__(self, cmd: CommanderModule) -> None:
        self.cmd = cmd
        self.sub: Any = cmd.subscribe("esc_status")
        self.last_online_flags = 0
        self.escs_error = False
        self.escs_failure = False
        self.offline_reports = 0

    def update(self) -> None:
        if not self.sub.updated():
            return
        m = self.sub.copy()
        count = int(m.esc_count)
        if count <= 0:
            return  # no mixer loaded in the ESC driver yet
        all_online = (1 << count) - 1
        online = int(m.esc_online_flags) & all_online
        if online == all_online:
            if self.escs_error and self.last_online_flags != all_online:
                self.cmd.info("All ESCs online")
            self.escs_error = False
            self.last_online_flags = online
        elif online == self.last_online_flags:
            self.escs_error = True  # unchanged (e.g. missing since boot): no new message
        elif self.last_online_flags & ~online:  # one that was online is gone
            missing = " ".join(f"ESC{i + 1}" for i in range(count) if not online >> i & 1)
            self.cmd.platform.log(SEV_CRITICAL, self.cmd.name, f"{missing} offline")
            self.offline_reports += 1
            self.last_online_flags = online
            self.escs_error = True
        else:  # some came (back) online, others still missing
            self.last_online_flags = online
            self.escs_error = True
        self.escs_failure = any(int(m.esc[i].failures) for i in range(min(count, len(m.esc))))
