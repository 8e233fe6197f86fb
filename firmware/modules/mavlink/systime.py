"""SYSTEM_TIME (#2): the vehicle's UTC and boot time out, the GCS's UTC in.

PX4 streams SYSTEM_TIME at 1 Hz (``configure_streams_to_default``, normal, onboard and config
modes) with ``time_unix_usec`` from CLOCK_REALTIME and ``time_boot_ms`` from the boot clock.
PX4's realtime clock is set by the GPS driver once the receiver reports a valid UTC, and by
the MAVLink receiver (``handle_message_system_time``) from a GCS's SYSTEM_TIME when the clock
is not yet valid (before PX4_EPOCH_SECS, 2009-02-13) and the GCS's time is.

The emulator's firmware has no wall clock (it is deterministic): its "realtime clock" is an
offset from UTC to the virtual boot clock. The GPS's offset (``sensor_gps.time_utc_usec``
minus the fix's timestamp, as the logger anchors its file names) wins when a fix carries UTC;
else the offset a GCS set; else the time is unknown and ``time_unix_usec`` is 0, which the
MAVLink definition gives for "unknown". A GCS time before PX4's epoch, or one arriving after
the clock is valid, is ignored as PX4 ignores it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Final

from firmware.modules.mavlink.dialect import mav

if TYPE_CHECKING:
    from firmware.modules.mavlink.instance import MavlinkInstance

__all__ = ["PX4_EPOCH_US", "SystemTimeService", "system_time", "utc_offset_us"]

#: PX4_EPOCH_SECS (1234567890, 2009-02-13): a realtime clock before it is "not set"
PX4_EPOCH_US: Final = 1_234_567_890 * 1_000_000
_UINT64_MAX: Final = (1 << 64) - 1


def utc_offset_us(inst: MavlinkInstance) -> int:
    """UTC minus the boot clock in µs: from the GPS when it has UTC, else from a GCS, else 0
    (unknown)."""
    gps = inst.latest("sensor_gps")
    if gps is not None and int(gps.time_utc_usec) > PX4_EPOCH_US:
        return int(gps.time_utc_usec) - int(gps.timestamp)
    return inst.module.gcs_utc_offset_us


def system_time(inst: MavlinkInstance) -> Any:
    """The SYSTEM_TIME stream's message: UTC (0 if unknown) and the boot time in ms."""
    now = inst.time_us()
    offset = utc_offset_us(inst)
    unix_us = now + offset if offset else 0
    return mav.MAVLink_system_time_message(max(0, min(unix_us, _UINT64_MAX)), inst.boot_ms())


class SystemTimeService:
    """SYSTEM_TIME from the GCS: sets the module's UTC offset when the clock is not set."""

    def __init__(self, inst: MavlinkInstance) -> None:
        self.inst = inst
        #: GCS times taken (tests and ``mavlink status`` read it)
        self.clock_sets = 0

    def handlers(self) -> dict[int, Callable[[Any], None]]:
        return {mav.MAVLINK_MSG_ID_SYSTEM_TIME: self._on_system_time}

    def _on_system_time(self, m: Any) -> None:
        inst = self.inst
        gcs_us = int(m.time_unix_usec)
        if utc_offset_us(inst) != 0 or gcs_us <= PX4_EPOCH_US:
            return  # the clock is valid already (GPS or a GCS before), or the GCS's is not
        inst.module.gcs_utc_offset_us = gcs_us - inst.time_us()
        self.clock_sets += 1

    def update(self, now_us: int) -> None:
        pass
