"""uORB throughput: publish -> callback subscription -> work item scheduled and run -> update().

This is the path of every sensor sample into the flight stack, so it is measured whole: the
publisher's kernel event, the snapshot copy, the callback, the work queue dispatch event and
the subscriber's update().
"""

from __future__ import annotations

from bench._util import median_rate
from board.kernel import Kernel
from firmware.platform import Platform
from firmware.platform.uorb import SubscriptionCallback
from firmware.platform.workqueue import WorkItem

N_PUBLISH = 100_000


class _Consumer(WorkItem):
    def __init__(self, platform: Platform) -> None:
        super().__init__(platform, "bench_consumer", "wq:rate_ctrl")
        self.sub = SubscriptionCallback(self, platform.orb, "sensor_gyro")
        self.sub.register_callback()
        self.received = 0

    def run(self) -> None:
        if self.sub.update() is not None:
            self.received += 1


def _run() -> int:
    k = Kernel("bench")
    p = Platform(k)
    consumer = _Consumer(p)
    pub = p.orb.advertise("sensor_gyro")
    msg = p.orb.new("sensor_gyro")
    left = [N_PUBLISH]

    def produce() -> None:
        msg.timestamp = k.now_ns // 1000
        msg.x += 0.001
        pub.publish(msg)
        left[0] -= 1
        if left[0]:
            k.call_later(125_000, produce)

    k.call_later(0, produce)
    k.run(1 << 62)
    assert consumer.received == N_PUBLISH
    return N_PUBLISH


def bench_uorb_publish_callback_per_s() -> float:
    return median_rate(_run)


if __name__ == "__main__":
    print(f"uorb_publish_callback_per_s: {bench_uorb_publish_callback_per_s():,.0f}")
