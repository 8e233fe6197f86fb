"""HRT: absolute time in us and callouts in interrupt context."""

import pytest

from board.kernel import NS_PER_US


def test_absolute_time_in_microseconds(platform, kernel):
    kernel.run(2_500_999)
    assert platform.hrt.absolute_time() == 2_500


def test_callouts_fire_at_exact_times_in_isr_context(platform, kernel):
    hrt = platform.hrt
    seen = []

    def isr(tag):
        seen.append((tag, kernel.now_ns // NS_PER_US, kernel.in_isr))

    hrt.call_after(150, isr, "once")
    every = hrt.call_every(100, 250, isr, "every")
    hrt.call_at(400, isr, "at")
    kernel.run(700 * NS_PER_US)
    assert seen == [("every", 100, True), ("once", 150, True), ("every", 350, True),
                    ("at", 400, True), ("every", 600, True)]
    assert kernel.in_isr is False
    every.cancel()
    kernel.run(2000 * NS_PER_US)
    assert len(seen) == 5


def test_call_at_in_the_past_fires_now(platform, kernel):
    kernel.run(1000 * NS_PER_US)
    seen = []
    platform.hrt.call_at(10, lambda: seen.append(kernel.now_ns))
    kernel.run(2000 * NS_PER_US)
    assert seen == [1000 * NS_PER_US]


def test_cancel_before_firing(platform, kernel):
    seen = []
    call = platform.hrt.call_after(100, seen.append, 1)
    assert call.pending
    platform.hrt.cancel(call)
    kernel.run(10**6)
    assert seen == [] and not call.fired


def test_bad_arguments(platform):
    with pytest.raises(ValueError):
        platform.hrt.call_after(-1, print)
    with pytest.raises(ValueError):
        platform.hrt.call_every(0, 0, print)
