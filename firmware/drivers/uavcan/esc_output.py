"""CAN ESC output of the uavcan driver (``UAVCAN_ENABLE`` 3): the airframe's mixer run on the
FMU and its outputs sent as ``uavcan.equipment.esc.RawCommand``, as PX4's uavcan ESC
controller does (PX4 mixes CAN ESC outputs on the FMU: ``mixer load /dev/uavcan/esc FILE``,
which the ROMFS runs when ``UAVCAN_ENABLE`` is 3).

The mixer is PX4's mixer library as the IO runs it (:mod:`ioproc.mixer`, the same text
format and multirotor geometry, idle speed included), fed by ``actuator_controls_0``. An
output in -1..1 becomes the RawCommand value ``UAVCAN_EC_MIN + (out + 1) / 2 x (UAVCAN_EC_MAX
- UAVCAN_EC_MIN)`` (the CAN counterpart of PWM_MIN/PWM_MAX: an airframe that idles its motors
on PWM sets UAVCAN_EC_MIN to the same fraction of 8191); disarmed (or with no mixer) every ESC
gets 0, which stops it. Commands go out at most every
5 ms (PX4's uavcan ESC controller runs at up to 200 Hz). esc.Status from the ESC nodes is kept
per ESC index (``uavcan status``) and published as ``esc_status`` at 10 Hz (:meth:`EscOutput.fill_status`):
an ESC is online while its esc.Status arrives within ``ESC_STATUS_TIMEOUT_US`` (1.2 s, a dozen
missed 10 Hz reports, as PX4's uavcan ESC controller), which the commander watches for a lost
ESC (firmware/modules/commander/esc_check.py).
"""

from __future__ import annotations

from typing import Any, Final

from ioproc.mixer import MixerGroup, parse_mixer_text

__all__ = ["EscOutput", "EscReport", "RAW_MAX", "ESC_STATUS_PERIOD_US", "ESC_STATUS_TIMEOUT_US"]

RAW_MAX: Final = 8191
MAX_ESCS: Final = 8
COMMAND_INTERVAL_US: Final = 5_000
ESC_STATUS_PERIOD_US: Final = 100_000
ESC_STATUS_TIMEOUT_US: Final = 1_200_000
#: esc_status.esc_connectiontype of ESCs on CAN (PX4's ESC_CONNECTION_TYPE_CAN)
CONNECTION_TYPE_CAN: Final = 4


class EscReport:
    """The latest esc.Status of one ESC index."""

    __slots__ = ("node_id", "last_us", "count", "error_count", "voltage_v", "current_a",
                 "temperature_c", "rpm", "power_pct")

    def __init__(self, node_id: int) -> None:
        self.node_id = node_id
        self.last_us = 0
        self.count = 0
        self.error_count = 0
        self.voltage_v = 0.0
        self.current_a = 0.0
        self.temperature_c = 0.0
        self.rpm = 0
        self.power_pct = 0


class EscOutput:
    """Mixer and command state of the CAN ESC output."""

    def __init__(self, raw_min: int = 1, raw_max: int = RAW_MAX) -> None:
        self.raw_min = raw_min
        self.raw_max = max(raw_min, raw_max)
        self.group = MixerGroup()
        self.mixer_path = ""
        self.commands_tx = 0
        self.last_raw: list[int] = []
        self.status_published = 0
        self.reports: dict[int, EscReport] = {}
        self._controls: list[float] = [0.0] * 8

    def load_mixer(self, text: str, path: str) -> int:
        """Replace the mixer with the one in ``text``; returns its output count (raises
        ``MixerParseError`` naming the line, as ``mixer load`` reports it)."""
        mixers = parse_mixer_text(text)
        group = MixerGroup()
        for m in mixers:
            group.add(m)
        self.group = group
        self.mixer_path = path
        return min(group.output_count, MAX_ESCS)

    def _source(self, group: int, index: int) -> float | None:
        return self._controls[index] if group == 0 and 0 <= index < 8 else None

    def command(self, controls: Any, armed: bool) -> list[int]:
        """The RawCommand array for these controls (``actuator_controls_0.control``)."""
        n = min(self.group.output_count, MAX_ESCS)
        if not armed or n == 0:
            return [0] * n
        self._controls = [float(c) for c in controls]
        outs = self.group.mix(self._source, n)
        raw = []
        for o in outs:
            if o != o:  # NaN from the controllers: stop rather than guess
                raw.append(0)
                continue
            o = -1.0 if o < -1.0 else 1.0 if o > 1.0 else o
            raw.append(round(self.raw_min + (o + 1.0) * 0.5 * (self.raw_max - self.raw_min)))
        return raw

    def on_status(self, node_id: int, s: Any, now_us: int) -> None:
        idx = int(s.esc_index)
        r = self.reports.get(idx)
        if r is None or r.node_id != node_id:
            r = self.reports[idx] = EscReport(node_id)
        r.last_us = now_us
        r.count += 1
        r.error_count = int(s.error_count)
        r.voltage_v = float(s.voltage)
        r.current_a = float(s.current)
        r.temperature_c = float(s.temperature) - 273.15
        r.rpm = int(s.rpm)
        r.power_pct = int(s.power_rating_pct)

    def esc_count(self) -> int:
        """The ESCs this output drives: the mixer's outputs (0 before ``mixer load``)."""
        return min(self.group.output_count, MAX_ESCS)

    def online_flags(self, now_us: int) -> int:
        """Bit i set while ESC index i's esc.Status arrives within ESC_STATUS_TIMEOUT_US."""
        flags = 0
        for idx, r in self.reports.items():
            if idx < MAX_ESCS and now_us - r.last_us < ESC_STATUS_TIMEOUT_US:
                flags |= 1 << idx
        return flags

    def fill_status(self, m: Any, now_us: int) -> None:
        """``esc_status`` from the latest esc.Status of each ESC index (PX4's field meanings;
        zero for an index never heard)."""
        m.timestamp = now_us
        self.status_published += 1
        m.counter = self.status_published & 0xFFFF
        m.esc_count = self.esc_count()
        m.esc_connectiontype = CONNECTION_TYPE_CAN
        m.esc_online_flags = self.online_flags(now_us)
        m.esc_armed_flags = sum(1 << i for i, raw in enumerate(self.last_raw[:MAX_ESCS]) if raw > 0)
        for idx in range(MAX_ESCS):
            e = m.esc[idx]
            r = self.reports.get(idx)
            if r is None:
                continue
            e.timestamp = r.last_us
            e.esc_errorcount = r.error_count & 0xFFFFFFFF
            e.esc_rpm = r.rpm
            e.esc_voltage = r.voltage_v
            e.esc_current = r.current_a
            e.esc_temperature = r.temperature_c
            e.esc_address = r.node_id
            e.esc_state = r.power_pct
            e.esc_power = min(r.power_pct, 100)
