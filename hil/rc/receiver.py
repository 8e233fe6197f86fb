"""What every RC receiver model shares: frame clock, link state, fault windows, record queue.

A receiver is a world device with the orchestrator's port interface: ``run_until(t_ns)``
produces every frame that *starts* by ``t_ns``, ``outputs(until_ns)`` hands over the stamped
records ``(port, t_ns, payload)`` up to ``until_ns``. A UART frame is one record stamped with
the leading edge of its first start bit (the receiving UART works out each byte's arrival, as
for a board's own transmitter); a PPM frame is one ``pin`` record per edge, released as the
quantum reaches it.

Everything runs on virtual time: frame k starts at a time computed from the previous frame,
the transmitter is sampled at that instant, and random faults draw from a generator seeded by
``(seed, k)``, so a run is the same whatever the quantum and however often it is polled.

Link model per frame: the RF frame is received when the transmitter is powered, the receiver
is not out of range, and the frame is not dropped (a ``drop_frames`` window or the random
``frame_loss_prob``). A receiver that never had a link since it was powered sends nothing, as
real receivers do before they first bind to the transmitter. What it sends while the link is
lost is protocol-specific (subclasses).
"""

from __future__ import annotations

import random
from typing import Any

from hil.rc.transmitter import Transmitter

__all__ = ["Receiver", "Record"]

#: (port, t_ns, payload), as board records.
Record = tuple[str, int, Any]


class _Windows:
    """Time windows ``[t0, t1)`` (``t1`` None: until the end of the run) with a payload."""

    __slots__ = ("items",)

    def __init__(self) -> None:
        self.items: list[tuple[int, int | None, Any]] = []

    def add(self, t0_ns: int, t1_ns: int | None, payload: Any = True) -> None:
        if t1_ns is not None and t1_ns < t0_ns:
            raise ValueError(f"fault window ends before it starts ({t0_ns} > {t1_ns} ns)")
        self.items.append((t0_ns, t1_ns, payload))

    def at(self, t_ns: int) -> Any:
        """Payload of the last-added window containing ``t_ns``, or None."""
        for t0, t1, payload in reversed(self.items):
            if t0 <= t_ns and (t1 is None or t_ns < t1):
                return payload
        return None


class Receiver:
    """Base of the receiver models; a subclass implements :meth:`_emit` for one frame.

    ``start_ns`` is when the receiver is powered (the board's rail), ``boot_ns`` the delay to
    its first frame slot (binding, start-up); both keep the first records clear of t = 0 for
    protocols that need a quiet line first. ``failsafe_delay_ns`` is how long a receiver holds
    the last values after losing the link before its failsafe action (≈1 s on common Futaba
    and FrSky receivers; the exact figure varies by model and is not from a datasheet).
    """

    #: Protocol name for reports.
    kind = "?"

    def __init__(self, tx: Transmitter, *, port: str, period_ns: int, start_ns: int = 0,
                 boot_ns: int | None = None, seed: int = 0, frame_loss_prob: float = 0.0,
                 failsafe_delay_ns: int = 1_000_000_000) -> None:
        if period_ns <= 0:
            raise ValueError(f"frame period must be positive, got {period_ns} ns")
        self.tx = tx
        self.port = port
        self.period_ns = int(period_ns)
        self.start_ns = start_ns
        self.seed = seed
        self.frame_loss_prob = frame_loss_prob
        self.failsafe_delay_ns = failsafe_delay_ns
        self._next_ns = start_ns + (self.period_ns if boot_ns is None else boot_ns)
        self._t_ns = start_ns
        self._out: list[Record] = []
        self._k = 0
        #: Values of the last RF frame received (None before the first link).
        self.held: list[int] | None = None
        #: Virtual time of the last RF frame received.
        self.last_rf_ns: int | None = None
        #: RF frames lost since the last good one, and in total.
        self.lost_run = 0
        self.lost_total = 0
        #: Frames (records or PPM trains) actually put on the wire.
        self.frames_sent = 0
        self._out_of_range = _Windows()
        self._dropped = _Windows()
        self._glitch = _Windows()
        self._forced_failsafe = _Windows()
        self._unplugged = _Windows()

    # -- faults ---------------------------------------------------------------------------------

    def out_of_range(self, t0_ns: int, t1_ns: int | None = None) -> None:
        """No RF link in ``[t0, t1)`` although the transmitter is on (range, antenna, jamming)."""
        self._out_of_range.add(t0_ns, t1_ns)

    def drop_frames(self, t0_ns: int, t1_ns: int | None = None) -> None:
        """A burst of lost RF frames: the receiver misses every frame in ``[t0, t1)``."""
        self._dropped.add(t0_ns, t1_ns)

    def glitch(self, t0_ns: int, t1_ns: int | None = None, *, byte_prob: float = 0.0,
               spike_prob: float = 0.0) -> None:
        """Seeded corruption in ``[t0, t1)``: per frame, with ``byte_prob`` one byte (PPM: one
        spurious edge pair) is damaged on the wire, with ``spike_prob`` one channel carries a
        random value in a well-formed frame."""
        self._glitch.add(t0_ns, t1_ns, (byte_prob, spike_prob))

    def force_failsafe(self, t0_ns: int, t1_ns: int | None = None) -> None:
        """Receiver reports failsafe in ``[t0, t1)`` with a good link (S.BUS failsafe bit)."""
        self._forced_failsafe.add(t0_ns, t1_ns)

    def unplug(self, t0_ns: int, t1_ns: int | None = None) -> None:
        """Unplugged from its connector in ``[t0, t1)``: unpowered, nothing on the wire; plugged
        back it powers up again and sends nothing until its first RF frame (re-bind)."""
        self._unplugged.add(t0_ns, t1_ns)

    def link_ok(self, t_ns: int) -> bool:
        """True when the RF link exists at ``t_ns`` (transmitter on, in range)."""
        return self.tx.powered(t_ns) and self._out_of_range.at(t_ns) is None

    # -- lockstep interface ---------------------------------------------------------------------

    #: A receiver only drives its line; nothing comes back (no telemetry modelled).
    input_ports: tuple[str, ...] = ()

    @property
    def ports(self) -> tuple[str, ...]:
        """World output ports this device drives."""
        return (self.port,)

    @property
    def t_ns(self) -> int:
        return self._t_ns

    def next_event_ns(self) -> int | None:
        """Stamp of the next record this receiver will output, if it can tell."""
        if self._out:
            return self._out[0][1]
        return self._next_ns

    def run_until(self, t_ns: int) -> None:
        """Produce every frame whose first edge is at or before ``t_ns``."""
        while self._next_ns <= t_ns:
            t = self._next_ns
            self._next_ns = t + self._frame(t)
        self._t_ns = max(self._t_ns, t_ns)

    def outputs(self, until_ns: int) -> list[Record]:
        """Records stamped at or before ``until_ns``, in time order (the rest stay queued)."""
        out = self._out
        n = len(out)
        if n and out[-1][1] <= until_ns:
            self._out = []
            return out
        i = 0
        while i < n and out[i][1] <= until_ns:
            i += 1
        ready = out[:i]
        del out[:i]
        return ready

    def input(self, port: str, t_ns: int, payload: Any) -> None:
        raise ValueError(f"{self.kind} receiver has no input port {port!r}")

    # -- per frame ------------------------------------------------------------------------------

    def rng(self, k: int, stream: str = "loss") -> random.Random:
        """Generator for frame ``k``: depends only on the seed, the stream and the frame index
        (a string seed is hashed with SHA-512, so it is the same in every process)."""
        return random.Random(f"{self.seed}/{self.port}/{stream}/{k}")

    def _frame(self, t_ns: int) -> int:
        k = self._k
        self._k = k + 1
        if self._unplugged.items and self._unplugged.at(t_ns) is not None:
            self.held = None  # unpowered: it forgets the link
            self.last_rf_ns = None
            self.lost_run = 0
            return self.period_ns
        rf = self.link_ok(t_ns) and self._dropped.at(t_ns) is None
        if rf and self.frame_loss_prob > 0.0:
            rf = self.rng(k).random() >= self.frame_loss_prob
        if rf:
            self.held = self.tx.sample(t_ns)
            self.last_rf_ns = t_ns
            self.lost_run = 0
        elif self.held is not None:
            self.lost_run += 1
            self.lost_total += 1
        return self._emit(t_ns, k, rf)

    def in_failsafe(self, t_ns: int) -> bool:
        """Lost the link for longer than the failsafe delay (only meaningful after a loss)."""
        return self.last_rf_ns is not None and t_ns - self.last_rf_ns >= self.failsafe_delay_ns

    def glitches(self, t_ns: int, k: int) -> tuple[float, float, random.Random | None]:
        """(byte_prob, spike_prob, rng) active for frame ``k``; rng None when none is."""
        g = self._glitch.at(t_ns)
        if g is None or (g[0] <= 0.0 and g[1] <= 0.0):
            return 0.0, 0.0, None
        return g[0], g[1], self.rng(k, "glitch")

    def forced_failsafe(self, t_ns: int) -> bool:
        return self._forced_failsafe.at(t_ns) is not None

    def _emit(self, t_ns: int, k: int, rf_ok: bool) -> int:  # pragma: no cover - abstract
        """Put frame ``k`` on the wire (or not); return the time to the next frame slot."""
        raise NotImplementedError
