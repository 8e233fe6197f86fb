"""The flight-stack platform layer: what PX4's ``platforms/common`` gives modules.

One :class:`Platform` per board bundles the kernel, the high-resolution timer, the uORB broker,
the work queues and the perf counters. It is passed explicitly to every driver and module, so two
boards can live in one process without sharing any state.
"""

from __future__ import annotations

from board.kernel import Kernel
from firmware.platform.hrt import Hrt
from firmware.platform.msgdef import MessageRegistry
from firmware.platform.perf import PerfRegistry
from firmware.platform.uorb import Broker
from firmware.platform.workqueue import WorkQueueManager

__all__ = ["Platform"]


class Platform:
    def __init__(self, kernel: Kernel, registry: MessageRegistry | None = None) -> None:
        self.kernel = kernel
        self.hrt = Hrt(kernel)
        self.orb = Broker(self.hrt, registry)
        self.wq = WorkQueueManager(kernel)
        self.perf = PerfRegistry(self.hrt)

    def time_us(self) -> int:
        return self.hrt.absolute_time()
