"""Work queues: run to completion, FIFO, priority between queues, busy time, scheduling."""

import pytest

from board.kernel import NS_PER_US, KernelError
from firmware.platform.workqueue import WQ_CONFIGS, WorkItem


class Recorder(WorkItem):
    def __init__(self, platform, name, wq, log, cost_ns=0):
        super().__init__(platform, name, wq)
        self.log = log
        self.cpu_cost_ns = cost_ns

    def run(self):
        self.log.append((self.name, self.platform.kernel.now_ns))


def test_px4_queue_table():
    assert WQ_CONFIGS["wq:rate_ctrl"].priority == 0
    assert WQ_CONFIGS["wq:SPI1"].priority > WQ_CONFIGS["wq:I2C1"].priority
    assert WQ_CONFIGS["wq:hp_default"].priority > WQ_CONFIGS["wq:lp_default"].priority
    for name in ("wq:rate_ctrl", "wq:SPI1", "wq:I2C1", "wq:hp_default", "wq:lp_default",
                 "wq:nav_and_controllers", "wq:INS0", "wq:ttyS5"):
        assert name in WQ_CONFIGS


def test_unknown_queue_is_an_error(platform):
    with pytest.raises(ValueError, match="unknown work queue 'wq:nope'"):
        Recorder(platform, "x", "wq:nope", [])


def test_higher_priority_queue_runs_first_at_same_instant(platform, kernel):
    log = []
    low = Recorder(platform, "low", "wq:lp_default", log)
    high = Recorder(platform, "high", "wq:rate_ctrl", log)
    mid = Recorder(platform, "mid", "wq:SPI1", log)
    kernel.call_at(100, low.schedule_now)
    kernel.call_at(100, mid.schedule_now)
    kernel.call_at(100, high.schedule_now)
    kernel.run(1000)
    assert [n for n, _ in log] == ["high", "mid", "low"]


def test_items_on_one_queue_run_fifo_and_busy_time_delays_the_next(platform, kernel):
    log = []
    a = Recorder(platform, "a", "wq:hp_default", log, cost_ns=30_000)
    b = Recorder(platform, "b", "wq:hp_default", log, cost_ns=5_000)
    c = Recorder(platform, "c", "wq:lp_default", log)

    def kick():
        a.schedule_now()
        b.schedule_now()
        a.schedule_now()  # already queued: no second run
        c.schedule_now()

    kernel.call_at(1_000, kick)
    kernel.run(1_000_000)
    assert log == [("a", 1_000), ("c", 1_000), ("b", 31_000)]
    assert a.run_count == 1 and a.busy_ns_total == 30_000


def test_bus_time_in_run_keeps_the_queue_busy(platform, kernel):
    log = []

    class Reader(WorkItem):
        def run(self):
            log.append(("r", kernel.now_ns, platform.hrt.absolute_time()))
            kernel.busy_ns += 112_000  # what a 14-byte SPI transfer at 1 MHz adds
            log.append(("r-end", kernel.now_ns, platform.hrt.absolute_time()))

    r = Reader(platform, "reader", "wq:SPI1")
    other = Recorder(platform, "next", "wq:SPI1", log)
    kernel.call_at(0, r.schedule_now)
    kernel.call_at(0, other.schedule_now)
    kernel.run(1_000_000)
    assert log == [("r", 0, 0), ("r-end", 0, 112), ("next", 112_000)]


def test_schedule_delayed_interval_and_clear(platform, kernel):
    log = []
    item = Recorder(platform, "i", "wq:hp_default", log)
    item.schedule_on_interval(2_500)  # 400 Hz
    kernel.run(10_000 * NS_PER_US)
    assert [t // NS_PER_US for _, t in log] == [2500, 5000, 7500, 10000]
    assert item.interval_us == 2500
    item.schedule_clear()
    kernel.run(20_000 * NS_PER_US)
    assert len(log) == 4 and not item.scheduled
    item.schedule_delayed(300)
    kernel.run(30_000 * NS_PER_US)
    assert log[-1][1] == 20_300 * NS_PER_US
    item.schedule_on_interval(1_000, delay_us=50)
    kernel.run(32_100 * NS_PER_US)
    assert [t // NS_PER_US for _, t in log[-3:]] == [30_050, 31_050, 32_050]


def test_item_rescheduling_itself_runs_again(platform, kernel):
    runs = []

    class Twice(WorkItem):
        def run(self):
            runs.append(kernel.now_ns)
            if len(runs) < 3:
                self.schedule_now()

    t = Twice(platform, "twice", "wq:test1")
    t.cpu_cost_ns = 1_000
    t.schedule_now()
    kernel.run(10**6)
    assert runs == [0, 1_000, 2_000]


def test_exception_in_run_names_the_work_item(platform, kernel):
    class Broken(WorkItem):
        def run(self):
            raise RuntimeError("sensor on fire")

    Broken(platform, "mpu6000", "wq:SPI1").schedule_now()
    with pytest.raises(KernelError, match="work item mpu6000 on wq:SPI1 .*sensor on fire"):
        kernel.run(1000)


def test_item_removed_before_its_dispatch_is_skipped(platform, kernel):
    """A module stopped between the queueing of its run and the dispatch (an attitude
    controller swapped from the shell in flight): the dispatch finds an empty queue and the
    queue works on."""
    log = []
    a = Recorder(platform, "a", "wq:rate_ctrl", log)
    kernel.call_at(100, a.schedule_now)
    kernel.call_at(100, a.schedule_clear)         # same instant, before the dispatch runs
    kernel.call_at(200, a.schedule_now)
    kernel.run(1000)
    assert log == [("a", 200)]
