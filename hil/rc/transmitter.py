"""The pilot's transmitter: sticks, switches and power as functions of virtual time.

Receivers sample the transmitter at the start of each frame they send, so the transmitter is
not a process with its own clock: it is a timeline. Every command (a step, a ramp, a power
change) is stored with its virtual time, and :meth:`Transmitter.sample` evaluates the timeline
at any instant. That keeps a run deterministic whatever the lockstep quantum is, and lets a
test script the whole flight before the run starts.

Channel numbers are 1-based and are the receiver *output* numbers PX4 sees (RC_MAP_* params):
channel 1 arrives in PX4's slot 0 whatever the protocol puts on the wire (a DSM satellite sends
throttle first; :mod:`hil.rc.dsm` does that reordering). Values are µs as PX4 reports them
(after its protocol scaling), because that is what a test compares against; the different
µs conventions of real receivers' servo outputs are absorbed by RC calibration anyway.
"""

from __future__ import annotations

from bisect import bisect_right
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from math import floor

__all__ = ["NS_PER_S", "ChannelMap", "Transmitter"]

NS_PER_S = 1_000_000_000

#: Widest value a channel may be given: beyond any real transmitter's extended travel.
_ABS_MIN_US = 500
_ABS_MAX_US = 2500


@dataclass(frozen=True)
class ChannelMap:
    """Which channel each stick and switch drives (1-based, as PX4's RC_MAP_* parameters).

    The default is PX4's: roll 1, pitch 2, throttle 3, yaw 4. Switch names are free-form; the
    defaults are only this project's test convention (PX4 maps no switch by default).
    """

    roll: int = 1
    pitch: int = 2
    throttle: int = 3
    yaw: int = 4
    switches: Mapping[str, int] = field(
        default_factory=lambda: {"mode": 5, "kill": 6, "arm": 7})

    def channel(self, name: str) -> int:
        """Channel of a stick or switch name; raises KeyError with the known names."""
        if name in ("roll", "pitch", "throttle", "yaw"):
            return int(getattr(self, name))
        if name in self.switches:
            return int(self.switches[name])
        known = ", ".join(["roll", "pitch", "throttle", "yaw", *self.switches])
        raise KeyError(f"no stick or switch {name!r} (known: {known})")


class _Track:
    """One piecewise-linear signal of time built from step and ramp commands.

    A command starting at ``t0`` overrides whatever was planned after ``t0`` (an unfinished
    ramp stops where it was), like a pilot moving a stick that is already moving. Commands may
    be added in any order; the timeline is rebuilt lazily.
    """

    __slots__ = ("_events", "_ts", "_vs", "initial")

    def __init__(self, initial: float) -> None:
        self.initial = float(initial)
        self._events: list[tuple[int, int, int, float]] = []
        self._ts: list[int] | None = None
        self._vs: list[float] = []

    def add(self, t0_ns: int, t1_ns: int, value: float) -> None:
        if t1_ns < t0_ns:
            raise ValueError(f"ramp ends before it starts ({t0_ns} > {t1_ns} ns)")
        self._events.append((t0_ns, len(self._events), t1_ns, float(value)))
        self._ts = None

    def _build(self) -> list[int]:
        ts: list[int] = []
        vs: list[float] = []
        self._ts, self._vs = ts, vs
        for t0, _, t1, v in sorted(self._events):
            v0 = self.value(t0)
            cut = bisect_right(ts, t0)
            del ts[cut:]
            del vs[cut:]
            ts += (t0, t1)
            vs += (v0, v)
        return ts

    def value(self, t_ns: int) -> float:
        ts = self._ts
        if ts is None:
            ts = self._build()
        i = bisect_right(ts, t_ns) - 1
        if i < 0:
            return self.initial
        vs = self._vs
        if i + 1 < len(ts) and ts[i + 1] > ts[i]:
            t0, t1 = ts[i], ts[i + 1]
            return vs[i] + (vs[i + 1] - vs[i]) * (t_ns - t0) / (t1 - t0)
        return vs[i]


class Transmitter:
    """Channel values (µs) and power of a transmitter, scripted in virtual time.

    ``channels`` is how many proportional channels it has (18 lets S.BUS carry its two digital
    channels as 17 and 18). Sticks are normalised (roll, pitch, yaw in −1…1, throttle 0…1) and
    mapped onto ``min_us``/``center_us``/``max_us``; switches take positions 0…n−1 spread evenly
    from ``min_us`` to ``max_us``. ``failsafe_us`` is the failsafe preset a receiver is bound
    with (centre, throttle low by default).
    """

    def __init__(self, channels: int = 18, *, channel_map: ChannelMap | None = None,
                 min_us: int = 1000, center_us: int = 1500, max_us: int = 2000,
                 initial_us: Sequence[int] | None = None, powered: bool = True) -> None:
        if not 1 <= channels <= 32:
            raise ValueError(f"a transmitter has 1..32 channels, not {channels}")
        self.n_channels = channels
        self.map = channel_map or ChannelMap()
        self.min_us, self.center_us, self.max_us = min_us, center_us, max_us
        for name in ("roll", "pitch", "throttle", "yaw", *self.map.switches):
            ch = self.map.channel(name)
            if not 1 <= ch <= channels:
                raise ValueError(f"{name} mapped to channel {ch}, transmitter has {channels}")
        if initial_us is None:
            init = [center_us] * channels
            init[self.map.throttle - 1] = min_us
            for ch in self.map.switches.values():
                init[ch - 1] = min_us
        else:
            if len(initial_us) != channels:
                raise ValueError(f"initial_us has {len(initial_us)} values for {channels} channels")
            init = [self._check_us(v) for v in initial_us]
        self._tracks = [_Track(v) for v in init]
        self._power = _Track(1.0 if powered else 0.0)
        fs = [center_us] * channels
        fs[self.map.throttle - 1] = min_us
        self.failsafe_us: list[int] = fs

    # -- commands -----------------------------------------------------------------------------

    @staticmethod
    def _check_us(value: float) -> float:
        if not _ABS_MIN_US <= value <= _ABS_MAX_US:
            raise ValueError(f"channel value {value} µs outside {_ABS_MIN_US}..{_ABS_MAX_US}")
        return float(value)

    def _track(self, channel: int) -> _Track:
        if not 1 <= channel <= self.n_channels:
            raise ValueError(f"channel {channel} outside 1..{self.n_channels}")
        return self._tracks[channel - 1]

    def set(self, t_ns: int, channel: int, value_us: float, *, ramp_ns: int = 0) -> None:
        """Channel ``channel`` goes to ``value_us`` at ``t_ns`` (linearly over ``ramp_ns``)."""
        self._track(channel).add(t_ns, t_ns + ramp_ns, self._check_us(value_us))

    def ramp(self, t0_ns: int, t1_ns: int, channel: int, value_us: float) -> None:
        """Move ``channel`` linearly from wherever it is at ``t0_ns`` to ``value_us`` at ``t1_ns``."""
        self._track(channel).add(t0_ns, t1_ns, self._check_us(value_us))

    def stick_us(self, name: str, x: float) -> float:
        """µs for a normalised stick position (throttle 0…1, the others −1…1)."""
        lo, mid, hi = self.min_us, self.center_us, self.max_us
        if name == "throttle":
            if not 0.0 <= x <= 1.0:
                raise ValueError(f"throttle {x} outside 0..1")
            return lo + (hi - lo) * x
        if not -1.0 <= x <= 1.0:
            raise ValueError(f"{name} {x} outside -1..1")
        return mid + (hi - mid) * x if x >= 0 else mid + (mid - lo) * x

    def set_sticks(self, t_ns: int, *, roll: float | None = None, pitch: float | None = None,
                   yaw: float | None = None, throttle: float | None = None,
                   ramp_ns: int = 0) -> None:
        """Move the named sticks (normalised) at ``t_ns``, over ``ramp_ns`` if given."""
        for name, x in (("roll", roll), ("pitch", pitch), ("yaw", yaw), ("throttle", throttle)):
            if x is not None:
                self.set(t_ns, self.map.channel(name), self.stick_us(name, x), ramp_ns=ramp_ns)

    def set_switch(self, t_ns: int, name: str, position: int, *, positions: int = 3) -> None:
        """Flip switch ``name`` to ``position`` (0…positions−1, evenly spread over the range)."""
        if positions < 2 or not 0 <= position < positions:
            raise ValueError(f"switch position {position} of {positions}")
        us = self.min_us + (self.max_us - self.min_us) * position / (positions - 1)
        self.set(t_ns, self.map.channel(name), us)

    def power(self, t_ns: int, on: bool) -> None:
        """Switch the transmitter on or off at ``t_ns`` (off = every receiver loses the link)."""
        self._power.add(t_ns, t_ns, 1.0 if on else 0.0)

    def play(self, steps: Iterable[tuple]) -> None:
        """Load a script of ``(t_s, target, value[, ramp_s])`` steps (times in seconds).

        ``target`` is a stick name (normalised value), a switch name (position), a channel
        number (µs) or ``"power"`` (bool). Example::

            tx.play([(1.0, "throttle", 0.6, 2.0), (4.0, "mode", 2), (6.0, "power", False)])
        """
        for step in steps:
            t_s, target, value, *rest = step
            t_ns = round(t_s * NS_PER_S)
            ramp_ns = round(rest[0] * NS_PER_S) if rest else 0
            if target == "power":
                self.power(t_ns, bool(value))
            elif isinstance(target, int):
                self.set(t_ns, target, value, ramp_ns=ramp_ns)
            elif target in ("roll", "pitch", "yaw", "throttle"):
                self.set(t_ns, self.map.channel(target), self.stick_us(target, value),
                         ramp_ns=ramp_ns)
            elif target in self.map.switches:
                self.set_switch(t_ns, target, int(value))
            else:
                raise ValueError(f"script step {step!r}: unknown target {target!r}")

    # -- what receivers see ---------------------------------------------------------------------

    def powered(self, t_ns: int) -> bool:
        return self._power.value(t_ns) >= 0.5

    def sample(self, t_ns: int) -> list[int]:
        """All channel values at ``t_ns``, whole µs (a receiver's resolution is coarser)."""
        return [floor(tr.value(t_ns) + 0.5) for tr in self._tracks]

    def value(self, t_ns: int, channel: int) -> int:
        return floor(self._track(channel).value(t_ns) + 0.5)
