"""``px4io status`` text: what the driver last read from the IO, decoded into bit names."""

from __future__ import annotations

from enum import IntFlag
from typing import TYPE_CHECKING

from ioproc.protocol import Alarms, ArmingA, StatusFlags

if TYPE_CHECKING:
    from firmware.drivers.px4io.driver import Px4ioDriver

__all__ = ["bit_names", "status_lines"]


def bit_names(value: int, flags: type[IntFlag]) -> str:
    """Set bits of ``value`` by name, in bit order (unknown bits in hex)."""
    names = [m.name or "" for m in flags if value & m.value]
    rest = value & ~sum(m.value for m in flags)
    if rest:
        names.append(f"0x{rest:X}")
    return " ".join(names) if names else "-"


def status_lines(d: Px4ioDriver) -> list[str]:
    c = d.config
    lines = [f"state: {d.state}" + (f" ({d.fail_reason})" if d.fail_reason else "")]
    if c:
        lines.append(f"IO: protocol {c.get('protocol', '?')}, hardware {c.get('hardware', '?')}, "
                     f"bootloader {c.get('bootloader', '?')}, {c.get('actuators', '?')} "
                     f"outputs, {c.get('controls', '?')} controls, {c.get('relays', '?')} "
                     f"relays, {c.get('rc_inputs', '?')} RC inputs, max transfer "
                     f"{c.get('max_transfer', '?')} bytes, {d.freemem} bytes free")
    lines += [
        f"mixer: {d.mixer_name or 'none'} ({'MIXER_OK' if d.mixer_ok else 'not loaded'})",
        f"status 0x{d.status_flags:04X}: {bit_names(d.status_flags, StatusFlags)}",
        f"alarms 0x{d.alarms:04X}: {bit_names(d.alarms, Alarms)}",
        f"arming 0x{d.arming:04X}: {bit_names(d.arming, ArmingA)}",
        f"vservo {d.vservo_mv / 1000:.2f} V, vrssi {d.vrssi_mv / 1000:.2f} V",
        f"rc: {d.rc_count} channels, flags 0x{d.rc_flags:02X}: "
        + " ".join(str(v) for v in d.rc_values),
        "servos: " + " ".join(str(v) for v in d.servos),
        "disarmed: " + " ".join(str(v) for v in d.pwm_disarmed),
        "failsafe: " + " ".join(str(v) for v in d.pwm_failsafe),
        (f"update limit {d.update_rate_hz} Hz (interval "
        f"{d.sub_controls[0].interval_us // 1000} ms), status poll every 20 ms"),
        (f"link: {d.link.failed_attempts} failed attempts, "
        f"{'LOST' if d.link.lost else 'ok'} (lost {d.link.lost_count} times), "
        f"{d.io_reboots} IO reboots, last error: {d.link.last_error or '-'}"),
    ]
    return lines
