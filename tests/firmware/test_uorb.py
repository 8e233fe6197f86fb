"""uORB: publish/subscribe, multi-instance, queues, interval and callback subscriptions."""

import pytest

from board.kernel import NS_PER_MS, NS_PER_US
from firmware.platform.uorb import (
    Subscription,
    SubscriptionCallback,
    SubscriptionInterval,
)
from firmware.platform.workqueue import WorkItem


def test_publish_then_update_and_copy(platform):
    orb = platform.orb
    sub = Subscription(orb, "ping_test")
    assert not sub.updated() and sub.update() is None and sub.copy() is None
    pub = orb.advertise("ping_test")
    msg = orb.new("ping_test", seq=1)
    pub.publish(msg)
    msg.seq = 2  # the publisher reuses its struct: the published snapshot must not change
    assert sub.updated()
    got = sub.update()
    assert got.seq == 1
    assert not sub.updated() and sub.update() is None
    pub.publish(msg)
    assert sub.copy().seq == 2 and not sub.updated()


def test_late_subscriber_sees_latest_message_as_updated(platform):
    pub = platform.orb.advertise("ping_test")
    pub.publish(platform.orb.new("ping_test", seq=7))
    late = Subscription(platform.orb, "ping_test")
    assert late.updated() and late.update().seq == 7


def test_multi_instance_topics(platform):
    orb = platform.orb
    p0 = orb.advertise_multi("sensor_gyro")
    p1 = orb.advertise_multi("sensor_gyro")
    assert (p0.instance, p1.instance) == (0, 1)
    assert orb.group_count("sensor_gyro") == 2
    s1 = Subscription(orb, "sensor_gyro", instance=1)
    p0.publish(orb.new("sensor_gyro", device_id=10))
    assert not s1.updated()
    p1.publish(orb.new("sensor_gyro", device_id=11))
    assert s1.update().device_id == 11
    with pytest.raises(ValueError, match="instance"):
        Subscription(orb, "sensor_gyro", instance=9)


def test_queued_topic_delivers_every_message_up_to_queue_length(platform):
    orb = platform.orb
    sub = Subscription(orb, "vehicle_command")  # ORB_QUEUE_LENGTH = 8
    pub = orb.advertise("vehicle_command")
    cmd = orb.new("vehicle_command")
    for i in range(5):
        cmd.command = 100 + i
        pub.publish(cmd)
    got = []
    while (m := sub.update()) is not None:
        got.append(m.command)
    assert got == [100, 101, 102, 103, 104]


def test_queued_topic_overflow_keeps_newest_and_counts_lost(platform):
    orb = platform.orb
    sub = Subscription(orb, "vehicle_command")
    pub = orb.advertise("vehicle_command")
    cmd = orb.new("vehicle_command")
    for i in range(11):
        cmd.command = i
        pub.publish(cmd)
    got = []
    while (m := sub.update()) is not None:
        got.append(m.command)
    assert got == list(range(3, 11))
    assert sub.node.lost == 3


def test_unknown_topic_is_a_clear_error(platform):
    with pytest.raises(KeyError, match="unknown uORB topic 'no_such_topic'"):
        platform.orb.advertise("no_such_topic")


def test_interval_subscription_delivers_at_most_one_update_per_interval(platform, kernel):
    orb = platform.orb
    pub = orb.advertise("ping_test")
    sub = SubscriptionInterval(orb, "ping_test", interval_us=10_000)
    msg = orb.new("ping_test")
    delivered = []

    def publish_1khz():
        msg.seq += 1
        pub.publish(msg)
        m = sub.update()
        if m is not None:
            delivered.append((kernel.now_ns // NS_PER_US, m.seq))

    kernel.call_every(NS_PER_MS, publish_1khz, first_ns=NS_PER_MS)
    kernel.run(100 * NS_PER_MS)
    times = [t for t, _ in delivered]
    assert times[0] == 1000
    assert all(b - a >= 10_000 for a, b in zip(times, times[1:]))
    assert len(delivered) == 10  # 100 ms of 1 kHz data at 100 Hz
    assert [s for _, s in delivered] == [t // 1000 for t in times]


def test_callback_subscription_schedules_work_item(platform, kernel):
    orb = platform.orb
    runs = []

    class Consumer(WorkItem):
        def __init__(self):
            super().__init__(platform, "consumer", "wq:hp_default")
            self.sub = SubscriptionCallback(self, orb, "ping_test")
            self.sub.register_callback()

        def run(self):
            m = self.sub.update()
            runs.append((kernel.now_ns, m.seq))

    c = Consumer()
    pub = orb.advertise("ping_test")
    kernel.call_at(5000, pub.publish, orb.new("ping_test", seq=1))
    kernel.call_at(9000, pub.publish, orb.new("ping_test", seq=2))
    kernel.run(20_000)
    assert runs == [(5000, 1), (9000, 2)]
    c.sub.unregister_callback()
    kernel.call_at(30_000, pub.publish, orb.new("ping_test", seq=3))
    kernel.run(40_000)
    assert len(runs) == 2


def test_callback_subscription_with_interval_limits_scheduling(platform, kernel):
    orb = platform.orb
    runs = []

    class Slow(WorkItem):
        def run(self):
            runs.append(kernel.now_ns // NS_PER_US)

    item = Slow(platform, "slow", "wq:lp_default")
    sub = SubscriptionCallback(item, orb, "ping_test", interval_us=5000)
    sub.register_callback()
    pub = orb.advertise("ping_test")
    msg = orb.new("ping_test")
    kernel.call_every(NS_PER_MS, pub.publish, msg, first_ns=NS_PER_MS)
    kernel.run(20 * NS_PER_MS)
    assert runs == [1000, 6000, 11000, 16000]


def test_callback_subscription_with_required_updates_walks_the_queue(platform, kernel):
    """PX4's set_required_updates: wake once n messages are unread, none lost (sensor_gyro
    queues 8)."""
    orb = platform.orb
    runs = []

    class Batch(WorkItem):
        def __init__(self):
            super().__init__(platform, "batch", "wq:rate_ctrl")
            self.sub = SubscriptionCallback(self, orb, "sensor_gyro")
            self.sub.register_callback()
            self.sub.set_required_updates(3)

        def run(self):
            runs.append((kernel.now_ns // NS_PER_US,
                         [m.timestamp for m in iter(self.sub.update, None)]))

    b = Batch()
    assert b.sub.required_updates == 3 and b.sub.registered
    pub = orb.advertise("sensor_gyro")
    msg = orb.new("sensor_gyro")

    def publish():
        msg.timestamp = kernel.now_ns // NS_PER_US
        pub.publish(msg)

    kernel.call_every(NS_PER_MS, publish, first_ns=NS_PER_MS)
    kernel.run(10 * NS_PER_MS)
    assert runs == [(3000, [1000, 2000, 3000]), (6000, [4000, 5000, 6000]),
                    (9000, [7000, 8000, 9000])]
    b.sub.set_required_updates(100)  # clamped to the queue length
    assert b.sub.required_updates == 8
    b.sub.unregister_callback()
    kernel.run(30 * NS_PER_MS)
    assert len(runs) == 3
