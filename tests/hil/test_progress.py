"""The progress lines of ``hil run`` (hil.progress): from the first second, each says what the
run is doing, at which virtual time, with the real-time factor since the start."""

from __future__ import annotations

import io
from types import SimpleNamespace

from hil.progress import Progress


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


def test_activity_is_printed_at_once_and_repeated_while_it_lasts() -> None:
    clock, out = FakeClock(), io.StringIO()
    p = Progress(every_wall_s=5.0, out=out, clock=clock)
    p.doing("booting")
    assert out.getvalue().splitlines() == ["  [   0.00 s] booting   (real-time factor 0.0)"]
    orch = SimpleNamespace(t_ns=0)
    for k in range(1, 41):  # 4 virtual s over 8 wall s: one repeat, at the 5th wall second
        clock.now += 0.2
        orch.t_ns = k * 100_000_000
        p(orch)
    lines = out.getvalue().splitlines()
    assert len(lines) == 2
    assert lines[1] == "  [   2.50 s] booting   (real-time factor 0.5)"


def test_event_keeps_the_activity_and_rtf_counts_from_the_start() -> None:
    clock, out = FakeClock(), io.StringIO()
    p = Progress(every_wall_s=5.0, out=out, clock=clock)
    clock.now += 4.0  # wall time before the first quantum (spawning the boards) counts too
    p(SimpleNamespace(t_ns=2_000_000_000))
    p.doing("waiting for a GPS fix")
    p(SimpleNamespace(t_ns=6_000_000_000))
    p.event("estimator ready")
    assert p.activity == "waiting for a GPS fix"
    assert out.getvalue().splitlines()[-1] == \
        "  [   6.00 s] estimator ready   (real-time factor 1.5)"


def test_disabled_prints_nothing() -> None:
    out = io.StringIO()
    p = Progress(enabled=False, out=out)
    p.doing("booting")
    p.event("armed")
    p(SimpleNamespace(t_ns=10**12))
    assert out.getvalue() == ""
