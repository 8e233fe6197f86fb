"""poll() over several subscriptions, from a task and from a work item."""

from board.kernel import NS_PER_MS, NS_PER_US
from firmware.platform.task import PollWaiter, Task
from firmware.platform.uorb import Subscription
from firmware.platform.workqueue import WorkItem


def test_poll_times_out_at_exactly_its_virtual_deadline(platform, kernel):
    results = []

    def main(task):
        sub = Subscription(platform.orb, "ping_test")
        n = yield task.poll([sub], timeout_ms=100)
        results.append((n, kernel.now_ns))

    kernel.run(3 * NS_PER_MS)
    Task(platform, "poller", main).start()
    kernel.run(NS_PER_MS * 1000)
    assert results == [(0, 103 * NS_PER_MS)]


def test_poll_wakes_on_any_of_several_topics(platform, kernel):
    orb = platform.orb
    results = []

    def main(task):
        a = Subscription(orb, "ping_test")
        b = Subscription(orb, "sensor_baro")
        while len(results) < 3:
            n = yield task.poll([a, b], timeout_ms=50)
            which = ("a" if a.updated() else "") + ("b" if b.updated() else "")
            a.update()
            b.update()
            results.append((n, which, kernel.now_ns // NS_PER_US))

    Task(platform, "poller", main).start()
    pa = orb.advertise("ping_test")
    pb = orb.advertise("sensor_baro")
    kernel.call_at(7 * NS_PER_MS, pb.publish, orb.new("sensor_baro"))
    kernel.call_at(9 * NS_PER_MS, pa.publish, orb.new("ping_test"))
    kernel.run(200 * NS_PER_MS)
    assert results == [(1, "b", 7000), (1, "a", 9000), (0, "", 59000)]


def test_poll_returns_at_once_when_data_is_waiting(platform, kernel):
    orb = platform.orb
    pub = orb.advertise("ping_test")
    pub.publish(orb.new("ping_test"))
    results = []

    def main(task):
        sub = Subscription(orb, "ping_test")
        n = yield task.poll([sub], timeout_ms=1000)
        results.append((n, kernel.now_ns))

    kernel.run(NS_PER_MS)
    Task(platform, "t", main).start()
    kernel.run(2 * NS_PER_MS)
    assert results == [(1, NS_PER_MS)]


def test_task_sleep(platform, kernel):
    times = []

    def main(task):
        for _ in range(3):
            yield task.sleep_us(250)
            times.append(kernel.now_ns // NS_PER_US)
        return "done"

    t = Task(platform, "sleeper", main)
    t.start()
    kernel.run(NS_PER_MS * 10)
    assert times == [250, 500, 750]
    assert t.result == "done" and not t.running


def test_work_item_waits_on_poll_waiter(platform, kernel):
    orb = platform.orb
    log = []

    class Waiter(WorkItem):
        def __init__(self):
            super().__init__(platform, "waiter", "wq:lp_default")
            self.sub = Subscription(orb, "ping_test")
            self.n = None

        def arm(self):
            PollWaiter(platform, [self.sub], 20_000, self._ready)

        def _ready(self, n):
            self.n = n
            self.schedule_now()

        def run(self):
            log.append((self.n, kernel.now_ns // NS_PER_US))
            self.sub.update()

    w = Waiter()
    w.arm()
    pub = orb.advertise("ping_test")
    kernel.call_at(5 * NS_PER_MS, pub.publish, orb.new("ping_test"))
    kernel.run(6 * NS_PER_MS)
    w.arm()
    kernel.run(100 * NS_PER_MS)
    assert log == [(1, 5000), (0, 26000)]
    assert platform.orb.node("ping_test").callbacks == []
