"""Analog-to-digital converter: channels fed by voltages from the outside world.

The world (battery model through its divider, a current sensor, the 5 V rail monitor) sets
each channel's source; firmware reads counts, the only thing the real ADC gives it. A source is
a constant float or a callable ``(t_ns) -> volts`` evaluated at the sample time, so a changing
voltage needs no events.

Counts = clamp(floor(v / vref_v * (2**bits - 1) + 0.5), 0, 2**bits - 1): rounding half up
(Python's ``round`` rounds half to even, which no ADC does), and inputs beyond the rails clip
the way the converter saturates.

A conversion may take time: ``conversion_ns`` (default 0) is added to ``kernel.busy_ns`` per
:meth:`Adc.read`, and the input is sampled at ``kernel.context_ns`` before it. On the STM32F4
it is (sampling cycles + 12) / ADCCLK, e.g. (15 + 12) / 21 MHz = 1285 ns; use
:func:`conversion_time_ns` to compute it.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from board.kernel import Kernel

__all__ = ["Adc", "VoltageSource", "conversion_time_ns"]

#: A channel's input: a fixed voltage or a function of virtual time.
VoltageSource = float | int | Callable[[int], float]


def conversion_time_ns(sample_cycles: int, resolution_cycles: int, adc_clock_hz: int) -> int:
    """STM32-style conversion time: (sampling + resolution cycles) / ADCCLK, in whole ns."""
    if adc_clock_hz <= 0 or sample_cycles < 0 or resolution_cycles < 0:
        raise ValueError(f"conversion_time_ns: bad arguments ({sample_cycles}, "
                         f"{resolution_cycles}, {adc_clock_hz})")
    return (sample_cycles + resolution_cycles) * 1_000_000_000 // adc_clock_hz


class Adc:
    """One ADC with ``channels`` inputs of ``bits`` resolution against ``vref_v``."""

    def __init__(self, kernel: Kernel, name: str, bits: int = 12, vref_v: float = 3.3,
                 channels: int = 16, conversion_ns: int = 0) -> None:
        if type(bits) is not int or not 1 <= bits <= 24:
            raise ValueError(f"ADC {name}: bits must be an int 1..24, got {bits!r}")
        if not vref_v > 0 or math.isinf(vref_v):
            raise ValueError(f"ADC {name}: vref_v must be a positive voltage, got {vref_v!r}")
        if type(channels) is not int or channels <= 0:
            raise ValueError(f"ADC {name}: channels must be a positive int, got {channels!r}")
        if type(conversion_ns) is not int or conversion_ns < 0:
            raise ValueError(f"ADC {name}: conversion_ns must be an int >= 0, "
                             f"got {conversion_ns!r}")
        self.kernel = kernel
        self.name = name
        self.bits = bits
        self.vref_v = float(vref_v)
        self.full_scale = (1 << bits) - 1
        self.conversion_ns = conversion_ns
        self._sources: list[VoltageSource | None] = [None] * channels
        #: Conversions done, and how many clipped at a rail (a wiring or model problem).
        self.conversions = 0
        self.clipped = 0

    @property
    def channels(self) -> int:
        return len(self._sources)

    def _check_ch(self, ch: object, where: str) -> int:
        if type(ch) is not int or not 0 <= ch < len(self._sources):
            raise ValueError(f"ADC {self.name}.{where}: channel must be 0..{len(self._sources) - 1}"
                             f", got {ch!r}")
        return ch  # type: ignore[return-value]

    def set_source(self, ch: int, source: VoltageSource | None) -> None:
        """Feed channel ``ch`` from a voltage or a ``(t_ns) -> volts`` callable (None: open
        input, reads 0)."""
        self._check_ch(ch, "set_source")
        if source is not None and not callable(source):
            if isinstance(source, bool) or not isinstance(source, (int, float)) \
                    or math.isnan(source):
                raise ValueError(f"ADC {self.name}.set_source({ch}): source must be volts or "
                                 f"a callable (t_ns) -> volts, got {source!r}")
            source = float(source)
        self._sources[ch] = source

    def voltage(self, ch: int, t_ns: int | None = None) -> float:
        """The input voltage on ``ch`` at ``t_ns`` (default: now in the running context)."""
        self._check_ch(ch, "voltage")
        if t_ns is None:
            t_ns = self.kernel.context_ns
        src = self._sources[ch]
        if src is None:
            return 0.0
        v = src(t_ns) if callable(src) else src
        if not isinstance(v, (int, float)) or math.isnan(v):
            raise ValueError(f"ADC {self.name}: source of channel {ch} gave {v!r} at "
                             f"t={t_ns} ns, not a voltage")
        return float(v)

    def counts_for(self, volts: float) -> int:
        """The conversion result for ``volts`` (no time, no counters): the transfer function."""
        fs = self.full_scale
        x = volts / self.vref_v * fs + 0.5
        if x >= fs:
            return fs
        if x < 0:
            return 0
        return math.floor(x)

    def read(self, ch: int) -> int:
        """Convert channel ``ch`` now: the input is sampled at ``kernel.context_ns``, then the
        conversion time blocks the caller."""
        kernel = self.kernel
        v = self.voltage(ch, kernel.now_ns + kernel.busy_ns)
        kernel.busy_ns += self.conversion_ns
        self.conversions += 1
        counts = self.counts_for(v)
        if (counts == self.full_scale and v > self.vref_v) or (counts == 0 and v < 0):
            self.clipped += 1
        return counts

    def read_u16(self, ch: int) -> int:
        """MicroPython ``ADC.read_u16``: the result scaled to 0..65535."""
        return self.read(ch) * 0xFFFF // self.full_scale

    def __repr__(self) -> str:
        return f"<Adc {self.name} {self.bits} bit vref={self.vref_v} V>"
