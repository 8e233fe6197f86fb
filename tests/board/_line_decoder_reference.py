"""Reference oracle: the original Fraction-based :class:`LineDecoder`, kept verbatim.

``board/uart_line.py`` now decodes with exact integer arithmetic for speed; this copy of the
first (slow, obviously-exact) implementation is what the differential test
``test_uart_line_equivalence.py`` compares it with, so keep it unchanged. Only the imports below
were added; everything from ``_parity_bit`` on is the original code.
"""

from __future__ import annotations

import math
from fractions import Fraction

from board.uart_line import FE, LBD, NS_PER_S, PE, LineBreak, UartConfig

__all__ = ["LineDecoder", "burst_levels", "frame_levels"]


def _parity_bit(value: int, parity: str) -> int:
    ones = value.bit_count() & 1
    return ones if parity == "E" else ones ^ 1


def frame_levels(config: UartConfig, value: int) -> list[int]:
    """Logical levels (1 = mark) of one frame: start, data LSB first, parity, stop bits.

    Data bits above ``config.data_bits`` are not sent (a 7-bit line drops bit 7).
    """
    value &= (1 << config.data_bits) - 1
    bits = [0]
    bits.extend((value >> k) & 1 for k in range(config.data_bits))
    if config.parity != "N":
        bits.append(_parity_bit(value, config.parity))
    bits.extend([1] * config.stop_bits)
    return bits


def burst_levels(config: UartConfig, data: bytes | LineBreak) -> list[int]:
    """Logical levels of a whole burst, or of a break (a frame of space, then stop bits)."""
    if isinstance(data, LineBreak):
        return [0] * config.bits_per_frame + [1] * config.stop_bits
    levels: list[int] = []
    for b in data:
        levels.extend(frame_levels(config, b))
    return levels


class _Segment:
    """One burst as the receiver sees it: levels already corrected for both inverters."""

    __slots__ = ("baud", "end", "idle", "levels", "t0")

    def __init__(self, t0: int, baud: int, levels: list[int], idle: int) -> None:
        self.t0 = t0
        self.baud = baud
        self.levels = levels
        self.idle = idle
        self.end = t0 + Fraction(len(levels) * NS_PER_S, baud)


class LineDecoder:
    """Bit-level model of an STM32 USART receiver fed with bursts in another line format.

    What it models (RM0090 "USART receiver"): the receiver waits for a falling edge (after its
    own inverter); it samples the centre of the start bit and drops a false start if that sample
    is mark; it samples the centre of each data bit and the parity bit at its own baud, checks
    parity (PE), and checks only the *first* stop bit (FE if sampled as space, as the STM32 does
    even when configured for two stop bits). A frame whose data, parity and stop samples are all
    space is reported as a break (LBD) besides FE. After the first stop bit sample the receiver
    looks for the next falling edge, so a framing error on a line held low is followed by a new
    frame only after the line rises and falls again.

    Simplifications: samples are ideal points (no 16x oversampling, no noise flag, no clock
    tolerance); a sample falling exactly on a bit boundary reads the later bit. A byte's arrival
    time is the end of the receiver's own frame (start + data + parity + its stop bits) after the
    detected edge, matching the fast path when the formats agree.

    Bursts must be fed in time order (one transmitter per line). Outside bursts the line sits at
    the transmitter's idle level. A frame that runs past the end of the known waveform is decoded
    later, when the next burst is fed or when :meth:`decode` is called with ``final=True`` (the
    owner schedules that once the waveform's end is in the past), so back-to-back writes decode
    as one continuous line.
    """

    __slots__ = ("_before", "_pos", "_segs", "pending")

    def __init__(self) -> None:
        self._segs: list[_Segment] = []
        self._pos: Fraction = Fraction(0)
        self._before = 1
        #: True when decoding waits for more of the line (call decode(final=True) eventually).
        self.pending = False

    def feed(self, t_start_ns: int, tx_config: UartConfig, data: bytes | LineBreak,
             rx_config: UartConfig) -> None:
        """Add a burst sent with ``tx_config`` as seen by a receiver using ``rx_config``."""
        flip = int(tx_config.invert != rx_config.invert)
        levels = burst_levels(tx_config, data)
        if flip:
            levels = [lv ^ 1 for lv in levels]
        idle = 1 ^ flip
        if not self._segs:
            self._before = idle
        self._segs.append(_Segment(t_start_ns, tx_config.baud, levels, idle))

    # -- waveform queries -----------------------------------------------------------------------

    def _level(self, t: Fraction, final: bool) -> int | None:
        prev = self._before
        for s in self._segs:
            if t < s.t0:
                return prev
            if t < s.end:
                return s.levels[(t - s.t0) * s.baud // NS_PER_S]
            prev = s.idle
        return prev if final else None

    def _next_edge(self, pos: Fraction, final: bool) -> tuple[Fraction | None, bool]:
        """First falling edge at or after ``pos``; (None, True) if it may lie past the known
        waveform."""
        segs = self._segs
        for i, s in enumerate(segs):
            if s.end < pos:
                continue
            n = len(s.levels)
            if i == 0:
                prev = self._before
            else:
                p = segs[i - 1]
                prev = p.levels[-1] if p.end == s.t0 else p.idle
            b = 0 if pos <= s.t0 else -((-(pos - s.t0) * s.baud) // NS_PER_S)
            levels = s.levels
            while b < n:
                before = prev if b == 0 else levels[b - 1]
                if before == 1 and levels[b] == 0:
                    return s.t0 + Fraction(b * NS_PER_S, s.baud), False
                b += 1
            # Boundary at the end of the segment: last bit -> whatever follows.
            if i + 1 < len(segs):
                if segs[i + 1].t0 == s.end:
                    continue  # handled as boundary 0 of the next segment
                after = s.idle
            elif not final:
                return None, levels[-1] == 1
            else:
                after = s.idle
            if levels[-1] == 1 and after == 0:
                return s.end, False
        return None, False

    # -- decoding -------------------------------------------------------------------------------

    def decode(self, rx_config: UartConfig, final: bool
               ) -> tuple[list[tuple[int, int, int]], int | None, int | None]:
        """Decode every frame the known waveform determines.

        Returns ``(frames, wake_ns, mark_since_ns)``: frames as ``(arrival_ns, value, flags)``;
        ``wake_ns`` is when to call again with ``final=True`` if a frame or edge depends on what
        follows the last burst (else None); ``mark_since_ns`` is, once nothing is pending, the
        time from which the line stays at mark (None if it rests at space, so no IDLE).
        """
        d = rx_config.data_bits
        p = rx_config.parity_bits
        half = Fraction(NS_PER_S, 2 * rx_config.baud)
        frame_len = Fraction((1 + d + p + rx_config.stop_bits) * NS_PER_S, rx_config.baud)
        nsamples = 2 + d + p  # start, data, parity, first stop bit
        frames: list[tuple[int, int, int]] = []
        wake: Fraction | None = None
        last_end = self._segs[-1].end if self._segs else Fraction(0)
        while True:
            edge, unknown = self._next_edge(self._pos, final)
            if edge is None:
                if unknown:
                    wake = last_end
                break
            samples = []
            for j in range(nsamples):
                lv = self._level(edge + (2 * j + 1) * half, final)
                if lv is None:
                    break
                samples.append(lv)
            if len(samples) < nsamples:
                wake = max(last_end, edge + (2 * nsamples - 1) * half)
                break
            if samples[0] == 1:  # false start: line back at mark mid start bit
                self._pos = edge + half
                continue
            value = 0
            for k in range(d):
                value |= samples[1 + k] << k
            flags = 0
            if p and samples[1 + d] != _parity_bit(value, rx_config.parity):
                flags |= PE
            if samples[1 + d + p] == 0:
                flags |= FE
                if value == 0 and (not p or samples[1 + d] == 0):
                    flags |= LBD
            frames.append((math.floor(edge + frame_len), value, flags))
            self._pos = edge + (2 * nsamples - 1) * half
        self.pending = wake is not None
        mark_since = None
        if not self.pending and self._segs:
            last = self._segs[-1]
            if last.idle == 1:
                k = len(last.levels)
                while k and last.levels[k - 1] == 1:
                    k -= 1
                mark_since = math.ceil(last.t0 + Fraction(k * NS_PER_S, last.baud))
            if final:
                self._before = last.idle
                self._segs.clear()
        self._prune()
        return frames, (math.ceil(wake) if wake is not None else None), mark_since

    def _prune(self) -> None:
        segs = self._segs
        while len(segs) > 1 and segs[0].end < self._pos and segs[1].t0 >= segs[0].end:
            self._before = segs[0].idle
            segs.pop(0)
