"""UART line format and the bit-level receiver used when two ends disagree on it.

A UART link carries *bursts*: a transmitter hands its link ``(t_start_ns, config, data)`` once
per write, where ``t_start_ns`` is the leading edge of the first start bit and the bytes follow
back to back. When the receiver's format matches the transmitter's, the receiving
:class:`~board.uart.Uart` computes byte arrival times directly (fast path). When it does not
(baud, data bits, parity or inversion differ), :class:`LineDecoder` rebuilds the line waveform
from the transmitter's format and samples it the way an STM32 USART does, so a wrong baud rate
or a missing inverter shows up as the same wrong bytes and error flags as on the bench.

Error flags use the bit positions of the STM32 ``USART_SR`` register so that firmware code can
test them as it would on the chip.

All times are integer nanoseconds at the API. Inside the decoder, bit boundaries and sample
points are exact rationals, held as integers in units of ``1/q`` ns where ``q`` is the smallest
scale that makes every transmitter bit and every half receiver bit a whole number of units
(usually a single digit); they are floored to ns only when a byte's arrival is reported. Exact
arithmetic keeps runs deterministic; integers instead of :class:`fractions.Fraction` keep the
GPS driver's baud scan (seconds of traffic at the wrong baud) cheap.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache
from typing import Final

__all__ = [
    "BREAK",
    "FE",
    "LBD",
    "NF",
    "ORE",
    "PE",
    "LineBreak",
    "LineDecoder",
    "UartConfig",
    "burst_levels",
    "frame_levels",
]

NS_PER_S: Final = 1_000_000_000

#: Parity error (USART_SR.PE).
PE: Final = 0x01
#: Framing error: the first stop bit was sampled as space (USART_SR.FE).
FE: Final = 0x02
#: Noise flag (USART_SR.NF); never set by this model.
NF: Final = 0x04
#: Overrun: a byte arrived while the receive buffer was full and was lost (USART_SR.ORE).
ORE: Final = 0x08
#: Break: an all-space character (data, parity and stop bit all space) (USART_SR.LBD position).
LBD: Final = 0x100

_PARITIES: Final[tuple[str, ...]] = ("N", "E", "O")
_MAX_BAUD: Final = 100_000_000


@dataclass(frozen=True, slots=True)
class UartConfig:
    """Line format of one UART end: what the USART_BRR/CR1/CR2 registers and an inverter set.

    ``data_bits`` counts data bits only; a parity bit, if any, comes on top (a "8E2" line has
    12 bits per frame). ``invert`` models the line inverter in front of the pin (S.BUS): with it,
    the idle line is low and a start bit is high.
    """

    baud: int = 115_200
    data_bits: int = 8
    parity: str = "N"
    stop_bits: int = 1
    invert: bool = False
    #: Bits per frame: start + data + parity + stop (derived).
    bits_per_frame: int = field(init=False, repr=False, compare=False)
    #: What must match for the fast path: (baud, data_bits, parity, invert) (derived).
    line_format: tuple = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        if type(self.baud) is not int or not 0 < self.baud <= _MAX_BAUD:
            raise ValueError(
                f"UartConfig.baud must be an int in 1..{_MAX_BAUD}, got {self.baud!r}")
        if self.data_bits not in (7, 8, 9) or type(self.data_bits) is not int:
            raise ValueError(f"UartConfig.data_bits must be 7, 8 or 9, got {self.data_bits!r}")
        if self.parity not in _PARITIES:
            raise ValueError(f"UartConfig.parity must be 'N', 'E' or 'O', got {self.parity!r}")
        if self.stop_bits not in (1, 2) or type(self.stop_bits) is not int:
            raise ValueError(f"UartConfig.stop_bits must be 1 or 2, got {self.stop_bits!r}")
        if type(self.invert) is not bool:
            raise ValueError(f"UartConfig.invert must be a bool, got {self.invert!r}")
        bpf = 1 + self.data_bits + (self.parity != "N") + self.stop_bits
        object.__setattr__(self, "bits_per_frame", bpf)
        object.__setattr__(self, "line_format",
                           (self.baud, self.data_bits, self.parity, self.invert))

    @property
    def parity_bits(self) -> int:
        return 0 if self.parity == "N" else 1

    @property
    def frame_ns_ceil(self) -> int:
        """One character time rounded up: the line must be idle this long for IDLE."""
        return -((-self.bits_per_frame * NS_PER_S) // self.baud)

    def byte_end_ns(self, t_start_ns: int, index: int) -> int:
        """End of the last stop bit of byte ``index`` of a burst starting at ``t_start_ns``.

        Computed from the burst start, never by accumulating a rounded per-byte time, so a long
        burst at 1.5 Mbaud does not drift.
        """
        return t_start_ns + ((index + 1) * self.bits_per_frame * NS_PER_S) // self.baud

    def burst_ns(self, nbytes: int) -> int:
        """Duration of ``nbytes`` back-to-back frames (floored to ns)."""
        return (nbytes * self.bits_per_frame * NS_PER_S) // self.baud

    def __str__(self) -> str:
        inv = " inverted" if self.invert else ""
        return f"{self.baud} {self.data_bits}{self.parity}{self.stop_bits}{inv}"


class LineBreak:
    """Marker sent in place of data for a break (STM32 SBK): the line at space for a whole
    frame, then stop bits at mark. Use the module singleton :data:`BREAK`."""

    __slots__ = ()

    def __repr__(self) -> str:
        return "BREAK"


#: The break marker a transmitter passes as ``data`` in ``link.transmit``.
BREAK: Final = LineBreak()


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


_FLIP: Final = bytes([1, 0]) + bytes(254)  # translate table: level 0 <-> 1
_FALL: Final = b"\x01\x00"  # a mark bit followed by a space bit: a falling edge between them


@lru_cache(maxsize=64)
def _frame_table(data_bits: int, parity: str, stop_bits: int) -> tuple[bytes, ...]:
    """Frame levels of every byte value as ``bytes``, so a burst is one ``join``."""
    cfg = UartConfig(9600, data_bits, parity, stop_bits)
    return tuple(bytes(frame_levels(cfg, v)) for v in range(256))


def _burst_bytes(config: UartConfig, data: bytes | LineBreak) -> bytes:
    """:func:`burst_levels` as ``bytes`` (one level per byte), built from cached frames."""
    if isinstance(data, LineBreak):
        return bytes(config.bits_per_frame) + b"\x01" * config.stop_bits
    table = _frame_table(config.data_bits, config.parity, config.stop_bits)
    return b"".join(map(table.__getitem__, data))


def _scale(rate: int) -> int:
    """Smallest ``q`` for which ``NS_PER_S * q`` is a multiple of ``rate`` (so ``1/rate`` s is
    a whole number of ``1/q`` ns)."""
    return rate // math.gcd(rate, NS_PER_S)


@lru_cache(maxsize=256)
def _sample_offsets(tx_baud: int, rx_baud: int, nsamples: int) -> tuple[int, ...]:
    """Transmitter bit index, relative to the edge's bit, of each receiver sample point.

    Sample ``j`` lies ``(2j+1)/(2 rx_baud)`` s after an edge on a transmitter bit boundary, so
    within the same burst it reads bit ``b + floor((2j+1) tx_baud / (2 rx_baud))``: exact, and
    free of any time arithmetic per sample.
    """
    return tuple((2 * j + 1) * tx_baud // (2 * rx_baud) for j in range(nsamples))


class _Segment:
    """One burst as the receiver sees it: levels already corrected for both inverters.

    ``levels`` holds one byte (0 or 1) per transmitter bit, so edges are found by
    ``bytes.find``. ``t0q``/``endq``/``unit`` are the start, end and bit time in the decoder's
    current ``1/q`` ns units (rescaled when ``q`` grows).
    """

    __slots__ = ("baud", "endq", "idle", "levels", "t0", "t0q", "unit")

    def __init__(self, t0: int, baud: int, levels: bytes, idle: int, q: int) -> None:
        self.t0 = t0
        self.baud = baud
        self.levels = levels
        self.idle = idle
        self.unit = NS_PER_S * q // baud
        self.t0q = t0 * q
        self.endq = self.t0q + len(levels) * self.unit


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

    Implementation: the results are exactly those of the original Fraction-based decoder (kept
    as the oracle in ``tests/board/_line_decoder_reference.py``), including its handling of
    bursts that overlap by a fraction of a ns (``Uart.write`` floors burst ends) and of pruning.
    Times are integers in ``1/q`` ns. A frame whose samples all fall inside the burst holding its
    start edge (nearly all of them) is read by precomputed bit offsets; anything else goes
    through the general per-sample walk over the bursts.
    """

    __slots__ = ("_before", "_lo", "_pos", "_q", "_segs", "pending")

    def __init__(self) -> None:
        self._segs: list[_Segment] = []
        #: Where the receiver resumes looking for a falling edge, in 1/_q ns.
        self._pos = 0
        self._q = 1
        #: Every segment before index _lo ends before _pos (skipped by every query).
        self._lo = 0
        self._before = 1
        #: True when decoding waits for more of the line (call decode(final=True) eventually).
        self.pending = False

    def feed(self, t_start_ns: int, tx_config: UartConfig, data: bytes | LineBreak,
             rx_config: UartConfig) -> None:
        """Add a burst sent with ``tx_config`` as seen by a receiver using ``rx_config``."""
        flip = tx_config.invert != rx_config.invert
        levels = _burst_bytes(tx_config, data)
        if flip:
            levels = levels.translate(_FLIP)
        idle = 0 if flip else 1
        if not self._segs:
            self._before = idle
        self._rescale(_scale(tx_config.baud))
        self._segs.append(_Segment(t_start_ns, tx_config.baud, levels, idle, self._q))

    def _rescale(self, need: int) -> None:
        """Make ``_q`` a multiple of ``need``, scaling every stored time (exact: integer factor)."""
        q = self._q
        if q % need == 0:
            return
        f = math.lcm(q, need) // q
        self._q = q * f
        self._pos *= f
        for s in self._segs:
            s.t0q *= f
            s.endq *= f
            s.unit *= f

    # -- waveform queries (general path; times in 1/_q ns) ---------------------------------------

    def _level(self, t: int, final: bool) -> int | None:
        """Line level at ``t`` (>= _pos); None if past the known waveform and not final."""
        segs = self._segs
        lo = self._lo
        prev = segs[lo - 1].idle if lo else self._before
        for i in range(lo, len(segs)):
            s = segs[i]
            if t < s.t0q:
                return prev
            if t < s.endq:
                return s.levels[(t - s.t0q) // s.unit]
            prev = s.idle
        return prev if final else None

    def _next_edge(self, pos: int, final: bool) -> tuple[int | None, bool, int, int]:
        """First falling edge at or after ``pos`` as ``(time, False, segment, bit)``;
        ``(None, True, -1, 0)`` if it may lie past the known waveform, ``(None, False, -1, 0)``
        if there is none. ``bit`` is the segment's length for an edge at its end."""
        segs = self._segs
        nseg = len(segs)
        i = self._lo
        while i < nseg:
            s = segs[i]
            endq = s.endq
            if endq < pos:
                i += 1
                continue
            levels = s.levels
            t0q = s.t0q
            if pos <= t0q:
                if i == 0:
                    prev = self._before
                else:
                    p = segs[i - 1]
                    prev = p.levels[-1] if p.endq == t0q else p.idle
                if prev == 1 and levels[0] == 0:
                    return t0q, False, i, 0
                b = 1
            else:
                b = -((t0q - pos) // s.unit)  # ceil: first boundary at or after pos
            n = len(levels)
            if b < n:
                j = levels.find(_FALL, b - 1)
                if j >= 0:
                    return t0q + (j + 1) * s.unit, False, i, j + 1
            # Boundary at the end of the segment: last bit -> whatever follows.
            i += 1
            if i < nseg:
                if segs[i].t0q == endq:
                    continue  # handled as boundary 0 of the next segment
            elif not final:
                return None, levels[-1] == 1, -1, 0
            if levels[-1] == 1 and s.idle == 0:
                return endq, False, i - 1, n
        return None, False, -1, 0

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
        rx_baud = rx_config.baud
        self._rescale(_scale(2 * rx_baud))
        q = self._q
        half = NS_PER_S * q // (2 * rx_baud)
        frame_len = (1 + d + p + rx_config.stop_bits) * 2 * half
        nsamples = 2 + d + p  # start, data, parity, first stop bit
        span = (2 * nsamples - 1) * half  # edge to the first stop bit sample
        want_odd = int(rx_config.parity == "O")
        data_idx = range(1, 1 + d)
        segs = self._segs
        frames: list[tuple[int, int, int]] = []
        wake: int | None = None
        last_end = segs[-1].endq if segs else 0
        pos = self._pos
        lo = self._lo
        nseg = len(segs)
        while True:
            while lo < nseg and segs[lo].endq < pos:
                lo += 1
            self._lo = lo
            edge, unknown, k, b = self._next_edge(pos, final)
            if edge is None:
                if unknown:
                    wake = last_end
                break
            s = segs[k]
            levels = s.levels
            offs = _sample_offsets(s.baud, rx_baud, nsamples)
            if b + offs[-1] < len(levels) and (k == lo or all(
                    segs[i].endq <= edge for i in range(lo, k))):
                # Fast path: every sample lies in this segment, which nothing before covers.
                if levels[b + offs[0]]:
                    pos = edge + half  # false start
                    continue
                value = 0
                for bit in data_idx:
                    value |= levels[b + offs[bit]] << (bit - 1)
                par = levels[b + offs[1 + d]]
                stop = levels[b + offs[-1]]
            else:
                samples = []
                for j in range(nsamples):
                    lv = self._level(edge + (2 * j + 1) * half, final)
                    if lv is None:
                        break
                    samples.append(lv)
                if len(samples) < nsamples:
                    wake = max(last_end, edge + span)
                    break
                if samples[0] == 1:  # false start: line back at mark mid start bit
                    pos = edge + half
                    continue
                value = 0
                for bit in data_idx:
                    value |= samples[bit] << (bit - 1)
                par = samples[1 + d]
                stop = samples[-1]
            flags = 0
            if p and par != (value.bit_count() & 1) ^ want_odd:
                flags |= PE
            if stop == 0:
                flags |= FE
                if value == 0 and (not p or par == 0):
                    flags |= LBD
            frames.append(((edge + frame_len) // q, value, flags))
            pos = edge + span
        self._pos = pos  # (_lo is already up to date: pos has not moved since it was set)
        self.pending = wake is not None
        mark_since = None
        if not self.pending and segs:
            last = segs[-1]
            if last.idle == 1:
                k = len(last.levels.rstrip(b"\x01"))
                mark_since = last.t0 - ((-k * NS_PER_S) // last.baud)
            if final:
                self._before = last.idle
                segs.clear()
                self._lo = 0
        self._prune()
        return frames, (-((-wake) // q) if wake is not None else None), mark_since

    def _prune(self) -> None:
        segs = self._segs
        pos = self._pos
        while len(segs) > 1 and segs[0].endq < pos and segs[1].t0q >= segs[0].endq:
            self._before = segs[0].idle
            segs.pop(0)
            self._lo -= 1
