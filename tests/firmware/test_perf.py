"""Perf counters: counts, elapsed and interval statistics in virtual time."""

import pytest

from board.kernel import NS_PER_US
from firmware.platform.perf import PC_COUNT, PC_ELAPSED, PC_INTERVAL


def test_count(platform):
    pc = platform.perf.alloc(PC_COUNT, "mpu6000: bad register")
    for _ in range(3):
        pc.count()
    assert pc.events == 3
    assert platform.perf.find("mpu6000: bad register") is pc
    assert "3 events" in platform.perf.report()


def test_elapsed_statistics(platform, kernel):
    pc = platform.perf.alloc(PC_ELAPSED, "read")
    for dur in (100, 200, 300):
        pc.begin()
        kernel.busy_ns += dur * NS_PER_US
        pc.end()
    assert pc.events == 3
    assert pc.total_us == 600
    assert pc.min_us == 100 and pc.max_us == 300
    assert pc.mean_us == pytest.approx(200)
    assert pc.stddev_us == pytest.approx((20000 / 3) ** 0.5)


def test_interval_statistics(platform, kernel):
    pc = platform.perf.alloc(PC_INTERVAL, "gyro interval")
    for t in (0, 125, 250, 400):
        kernel.run(t * NS_PER_US)
        pc.count()
    assert pc.events == 4
    assert pc.min_us == 125 and pc.max_us == 150
    assert pc.mean_us == pytest.approx(400 / 3)
    assert pc.total_us == 400


def test_unknown_kind_rejected(platform):
    with pytest.raises(ValueError):
        platform.perf.alloc("bogus", "x")
