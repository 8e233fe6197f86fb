"""A PPM-sum (CPPM) receiver: a train of N + 1 markers per frame on one pin, then a sync gap.

The edges come from the IO decoder's own generator (:func:`ioproc.rc.ppm_edges`): a marker
(300–400 µs) starts each channel and the time from one marker's start to the next is the
channel value, so values are whole µs and round-trip exactly. Frames start every
``period_ns`` (22.5 ms by default, the common 8-channel CPPM frame); when the channels would
leave less than ``min_sync_us`` of sync gap (many channels near 2000 µs) that frame is
stretched, as receivers with a variable frame do.

Each edge is a ``pin`` record (level 0/1) stamped with its own time, released as the lockstep
reaches it. ``marker_level`` is the level during a marker: PX4 captures both edges so either
polarity decodes. The receiver drives the line to its idle level when it starts.

Link loss: the receiver repeats the last values for ``failsafe_delay_ns`` and then, per
``on_loss``, stops the pulses with the line held idle (``"no_pulses"``, what most PPM
receivers do and what PX4's 200 ms validity check is for), keeps repeating the last values
(``"hold"``) or sends the failsafe preset (``"failsafe"``). A lost RF frame repeats the last
values.
"""

from __future__ import annotations

from hil.rc.receiver import Receiver
from hil.rc.transmitter import Transmitter
from ioproc.rc.ppm import ppm_edges

__all__ = ["PpmReceiver"]

PPM_PERIOD_NS = 22_500_000
_GLITCH_OFFSET_US = 100
_GLITCH_WIDTH_US = 10


class PpmReceiver(Receiver):
    """PPM-sum receiver on a world port (default ``rc_ppm``)."""

    kind = "ppm"

    def __init__(self, tx: Transmitter, *, port: str = "rc_ppm", channels: int = 8,
                 period_ns: int = PPM_PERIOD_NS, marker_us: int = 400, marker_level: int = 1,
                 min_sync_us: int = 3000, on_loss: str = "no_pulses", **kwargs: object) -> None:
        if on_loss not in ("no_pulses", "hold", "failsafe"):
            raise ValueError(f"PPM on_loss must be 'no_pulses', 'hold' or 'failsafe', "
                             f"not {on_loss!r}")
        if not 1 <= channels <= tx.n_channels:
            raise ValueError(f"PPM channels must be 1..{tx.n_channels}, not {channels}")
        if marker_level not in (0, 1):
            raise ValueError(f"marker_level must be 0 or 1, not {marker_level!r}")
        if period_ns % 1000:
            raise ValueError("PPM period must be whole µs (edges are on the µs grid)")
        super().__init__(tx, port=port, period_ns=period_ns, **kwargs)  # type: ignore[arg-type]
        if self.start_ns % 1000 or self._next_ns % 1000:
            raise ValueError("PPM start_ns and boot_ns must be whole µs (edges are on the µs grid)")
        self.channels = channels
        self.marker_us = marker_us
        self.marker_level = marker_level
        self.idle_level = 1 - marker_level
        self.min_sync_us = min_sync_us
        self.on_loss = on_loss
        #: Frame lengths actually used (start to start, µs), for tests and plots.
        self.last_frame_us = 0
        self._out.append((port, self.start_ns, self.idle_level))

    def frame_edges(self, values: list[int], t0_us: int) -> list[tuple[int, int]]:
        """(t_us, level) edges of one frame starting at ``t0_us``, in this receiver's polarity."""
        edges = ppm_edges(values[:self.channels], t0_us=t0_us, marker_us=self.marker_us)
        if self.marker_level == 1:
            return edges
        return [(t, 1 - lvl) for t, lvl in edges]

    def _emit(self, t_ns: int, k: int, rf_ok: bool) -> int:
        held = self.held
        if held is None:
            return self.period_ns
        values = held
        if not rf_ok and self.in_failsafe(t_ns):
            if self.on_loss == "no_pulses":
                return self.period_ns
            if self.on_loss == "failsafe":
                values = self.tx.failsafe_us
        values = values[:self.channels]
        byte_prob, spike_prob, rng = self.glitches(t_ns, k)
        if rng is not None and rng.random() < spike_prob:
            values = list(values)
            values[rng.randrange(self.channels)] = rng.randrange(500, 2700)
        t0_us = t_ns // 1000
        edges = self.frame_edges(values, t0_us)
        if rng is not None and rng.random() < byte_prob:
            # A spurious short pulse shortly after a marker (interference on the line).
            i = rng.randrange(self.channels)
            t_g = edges[2 * i + 1][0] + _GLITCH_OFFSET_US
            if t_g + _GLITCH_WIDTH_US < edges[2 * i + 2][0]:
                spur = [(t_g, self.marker_level), (t_g + _GLITCH_WIDTH_US, self.idle_level)]
                edges = edges[:2 * i + 2] + spur + edges[2 * i + 2:]
        port = self.port
        self._out.extend((port, t * 1000, lvl) for t, lvl in edges)
        self.frames_sent += 1
        length_us = sum(values) + self.marker_us + self.min_sync_us
        frame_us = max(self.period_ns // 1000, length_us)
        self.last_frame_us = frame_us
        return frame_us * 1000
