"""PPM-sum (CPPM) decoder fed with edge times from the IO's TIM1 channel-1 input capture.

On the IO, TIM1 counts freely at 1 MHz with a 16-bit counter; after every capture the ISR flips
the capture polarity, so both edges of the signal are timestamped and the receiver's polarity
does not matter. Widths are differences of 16-bit capture values modulo 65536. The decoder is
PX4's HRT one: markers 200..600 µs, channels 800..2200 µs (start of one marker to the start of
the next), a gap ≥ 2300 µs ends a frame, 5..20 channels, and a new channel count is only
accepted after it has repeated for PPM_CHANNEL_LOCK more frames. Any error (missed edge, bad
marker, bad channel) desynchronises *and* forgets the accepted count, so the lock has to run
again: a receiver needs about 7 frames before the first output.

Two entry points: :meth:`PpmDecoder.feed_capture` takes the raw 16-bit CCR value (what the
ISR reads), :meth:`PpmDecoder.feed_edge` takes an absolute µs time (for receiver models that
work in time; differences are then exact, no 16-bit aliasing).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Final

PPM_MIN_PULSE_WIDTH: Final = 200
PPM_MAX_PULSE_WIDTH: Final = 600
PPM_MIN_CHANNEL_VALUE: Final = 800
PPM_MAX_CHANNEL_VALUE: Final = 2200
PPM_MIN_START: Final = 2300
PPM_MIN_CHANNELS: Final = 5
PPM_MIN_CHANNELS_E14: Final = 6
PPM_MAX_CHANNELS: Final = 20
PPM_CHANNEL_LOCK: Final = 4
#: The IO consumes a decode only if it is younger than this (§6.4).
PPM_VALID_US: Final = 200_000

_UNSYNCH, _ARM, _ACTIVE, _INACTIVE = range(4)


def ppm_edges(channels_us: Sequence[int], *, t0_us: int = 0,
              marker_us: int = 400) -> list[tuple[int, int]]:
    """(t_us, level) edges of one PPM frame whose first marker starts at ``t0_us``.

    Models what a receiver puts on PA8 (N + 1 high-going markers); the sync gap is whatever
    time passes before the caller starts the next frame.
    """
    edges: list[tuple[int, int]] = []
    t = t0_us
    for v in list(channels_us) + [None]:
        edges.append((t, 1))
        edges.append((t + marker_us, 0))
        if v is not None:
            t += int(v)
    return edges


class PpmDecoder:
    """PX4's edge-driven PPM state machine with its channel-count lock.

    ``channels``/``channel_count`` hold the last frame whose channel count matched the accepted
    count; ``frame_len_us`` the time between the first markers of successive frames (what the
    IO puts in RAW_RC DATA). ``frame_errors`` counts decode errors (each resets the lock),
    ``missed_edges`` captures flagged as overcaptured or arriving with an unchanged level.
    """

    protocol = "ppm"
    min_us = PPM_MIN_CHANNEL_VALUE
    max_us = PPM_MAX_CHANNEL_VALUE

    def __init__(self, *, min_channels: int = PPM_MIN_CHANNELS) -> None:
        self.min_channels = min_channels
        self.channels: list[int] = []
        self.raw_channels: list[int] = []
        self.channel_count = 0
        self.failsafe = False
        self.frame_lost = False
        self.rssi: int | None = None
        self.frames = 0
        self.frame_errors = 0
        self.missed_edges = 0
        self.bad_crc = 0
        self.lost_frames = 0
        self.last_frame_us: int | None = None
        self.frame_len_us = 0
        #: Channel count the lock has accepted (0 = none yet / after an error).
        self.accepted_count = 0
        self._state = _UNSYNCH
        self._buf: list[int] = []
        self._candidate = 0
        self._holdoff = 0
        self._last_edge: int | None = None
        self._last_level: int | None = None
        self._last_mark = 0
        self._frame_start: int | None = None
        self._last_count: int | None = None
        self._ext = 0

    def feed_capture(self, count: int, level: int | None = None, *, overflow: bool = False,
                     t_us: int | None = None) -> bool:
        """One input capture: ``count`` is the 16-bit CCR1 value, ``overflow`` the CC1OF flag.

        ``t_us`` is the HRT time of the capture for the validity stamp; if omitted the decoder
        extends the 16-bit counter itself (correct while edges are < 65.5 ms apart).
        """
        count &= 0xFFFF
        if self._last_count is None:
            width = 0
        else:
            width = (count - self._last_count) & 0xFFFF
        self._last_count = count
        self._ext += width
        return self._edge(self._ext, width, t_us if t_us is not None else self._ext,
                          level, overflow)

    def feed_edge(self, t_us: int, level: int | None = None, *, overflow: bool = False) -> bool:
        """One edge at absolute time ``t_us`` (exact widths); True if a frame was output."""
        last = self._last_edge
        width = 0 if last is None else t_us - last
        return self._edge(t_us, width, t_us, level, overflow)

    def _error(self) -> None:
        self.frame_errors += 1
        self._state = _UNSYNCH
        self.accepted_count = 0
        self._buf = []

    def _edge(self, t: int, width: int, now_us: int, level: int | None, overflow: bool) -> bool:
        """Process one edge; ``t`` is on the decoder's own timeline, ``width`` since last edge."""
        first = self._last_edge is None
        prev = self._last_edge
        self._last_edge = t
        if level is not None:
            if level == self._last_level:
                overflow = True  # the opposite edge in between was never captured
            self._last_level = level
        if overflow:
            self.missed_edges += 1
            self._error()
            return False
        if first:
            return False
        out = False
        if width >= PPM_MIN_START:
            n = len(self._buf)
            if n != self.accepted_count:
                if n != self._candidate:
                    self._candidate = n
                    self._holdoff = PPM_CHANNEL_LOCK
                elif self._holdoff > 0:
                    self._holdoff -= 1
                else:
                    self.accepted_count = n
                    self._candidate = 0
            elif n >= self.min_channels and self._state != _UNSYNCH:
                self.channels = list(self._buf)
                self.raw_channels = self.channels
                self.channel_count = n
                self.frames += 1
                self.last_frame_us = now_us
                out = True
            self._buf = []
            self._state = _ARM
            return out
        st = self._state
        if st == _UNSYNCH:
            return False
        if st == _ARM:
            if not PPM_MIN_PULSE_WIDTH <= width <= PPM_MAX_PULSE_WIDTH:
                self._error()
                return False
            if prev is None:  # unreachable: the first edge returned above
                return False
            if self._frame_start is not None:
                self.frame_len_us = prev - self._frame_start
            self._frame_start = prev
            self._last_mark = prev
            self._state = _ACTIVE
            return False
        if st == _ACTIVE:
            interval = t - self._last_mark
            self._last_mark = t
            if not PPM_MIN_CHANNEL_VALUE <= interval <= PPM_MAX_CHANNEL_VALUE:
                self._error()
                return False
            if len(self._buf) >= PPM_MAX_CHANNELS:
                self._error()
                return False
            self._buf.append(interval)
            self._state = _INACTIVE
            return False
        if not PPM_MIN_PULSE_WIDTH <= width <= PPM_MAX_PULSE_WIDTH:
            self._error()
            return False
        self._state = _ACTIVE
        return False
