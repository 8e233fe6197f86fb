"""uORB: the publish/subscribe message bus of the flight stack, one broker per board.

The shape follows PX4's uORB: a topic may have several instances (one per redundant sensor);
each instance is a node holding the latest message, a generation counter, and for queued topics
a ring of the last ``ORB_QUEUE_LENGTH`` messages. Subscribers keep the generation they last
read, so ``updated()`` is one comparison and nothing is copied per subscriber.

Publishing takes a snapshot (``msg.copy()``), so a publisher may reuse its message object as PX4
code reuses its struct. Subscribers receive the stored snapshot and must treat it as read-only.
"""

from __future__ import annotations

from functools import partial
from typing import TYPE_CHECKING, Any, Callable, Final

from firmware.platform.msgdef import MessageDef, MessageRegistry, default_registry

if TYPE_CHECKING:
    from firmware.platform.hrt import Hrt
    from firmware.platform.workqueue import WorkItem

__all__ = ["Broker", "TopicNode", "Publication", "Subscription", "SubscriptionInterval",
           "SubscriptionCallback", "ORB_MULTI_MAX_INSTANCES"]

ORB_MULTI_MAX_INSTANCES: Final = 4


class TopicNode:
    """One instance of one topic: latest message, generation, optional queue, callbacks."""

    __slots__ = ("meta", "name", "instance", "generation", "queue_len", "buf", "last",
                 "callbacks", "advertised", "last_publish_ns", "lost",
                 "_kernel")

    def __init__(self, meta: MessageDef, name: str, instance: int, hrt: Hrt) -> None:
        self.meta = meta
        self.name = name
        self.instance = instance
        self.generation = 0
        self.queue_len = meta.queue_length
        self.buf: list[Any] = [None] * self.queue_len
        self.last: Any = None
        self.callbacks: list[Callable[[], None]] = []
        self.advertised = False
        self.last_publish_ns = 0
        self.lost = 0
        self._kernel = hrt.kernel

    def publish(self, msg: Any) -> None:
        # One copy per publication (the snapshot subscribers share); the ring slot and
        # ``last`` hold the same object. ``publish_count`` is the generation, so one counter
        # is updated, not two.
        self.last = snap = msg.copy()
        self.generation = gen = self.generation + 1
        self.buf[gen % self.queue_len] = snap
        k = self._kernel
        self.last_publish_ns = k.now_ns + k.busy_ns
        if self.callbacks:
            for cb in self.callbacks:
                cb()

    @property
    def publish_count(self) -> int:
        """Messages published on this instance since boot (the generation counter)."""
        return self.generation


class Publication:
    """The handle a publisher gets from :meth:`Broker.advertise`."""

    __slots__ = ("node", "publish")

    def __init__(self, node: TopicNode) -> None:
        self.node = node
        #: publish(msg): store a snapshot and notify subscribers (bound for speed).
        self.publish = node.publish

    @property
    def instance(self) -> int:
        return self.node.instance

    def unadvertise(self) -> None:
        self.node.advertised = False


class Broker:
    """The uORB broker of one board: topic nodes by (name, instance)."""

    def __init__(self, hrt: Hrt, registry: MessageRegistry | None = None) -> None:
        self.hrt = hrt
        self.registry = registry or default_registry()
        self._nodes: dict[tuple[str, int], TopicNode] = {}
        #: counts advertisements, so a subscriber to every instance (the logger) can tell
        #: cheaply whether a new one may have appeared
        self.advertisements = 0

    def node(self, topic: str, instance: int = 0) -> TopicNode:
        """The node for (topic, instance), created (unadvertised) if needed."""
        key = (topic, instance)
        node = self._nodes.get(key)
        if node is None:
            if not 0 <= instance < ORB_MULTI_MAX_INSTANCES:
                raise ValueError(f"uORB {topic}: instance {instance} out of range "
                                 f"0..{ORB_MULTI_MAX_INSTANCES - 1}")
            meta = self.registry.topic(topic)
            node = TopicNode(meta, topic, instance, self.hrt)
            self._nodes[key] = node
        return node

    def advertise(self, topic: str, instance: int = 0) -> Publication:
        node = self.node(topic, instance)
        node.advertised = True
        self.advertisements += 1
        return Publication(node)

    def advertise_multi(self, topic: str) -> Publication:
        """Advertise the first free instance of a multi-instance topic (redundant sensors)."""
        for i in range(ORB_MULTI_MAX_INSTANCES):
            node = self.node(topic, i)
            if not node.advertised:
                node.advertised = True
                self.advertisements += 1
                return Publication(node)
        raise RuntimeError(f"uORB {topic}: all {ORB_MULTI_MAX_INSTANCES} instances in use")

    def exists(self, topic: str, instance: int = 0) -> bool:
        node = self._nodes.get((topic, instance))
        return node is not None and node.advertised

    def group_count(self, topic: str) -> int:
        return sum(1 for i in range(ORB_MULTI_MAX_INSTANCES) if self.exists(topic, i))

    def nodes(self) -> list[TopicNode]:
        return sorted(self._nodes.values(), key=lambda n: (n.name, n.instance))

    def new(self, topic: str, **fields: Any) -> Any:
        """A new message object of a topic's type."""
        return self.registry.cls(topic)(**fields)


class Subscription:
    """A subscriber's view of one topic instance.

    A new subscription sees the latest message already published (if any) as updated, as in
    PX4. ``update()`` returns the next unread message or None; on a queued topic it walks the
    queue in order, skipping (and counting in ``lost``) messages that were overwritten.
    """

    __slots__ = ("node", "last_gen")

    def __init__(self, broker: Broker, topic: str, instance: int = 0) -> None:
        self.node = broker.node(topic, instance)
        g = self.node.generation
        self.last_gen = g - 1 if g > 0 else 0

    def updated(self) -> bool:
        return self.node.generation != self.last_gen

    def update(self) -> Any:
        node = self.node
        g = node.generation
        last = self.last_gen
        if g == last:
            return None
        qlen = node.queue_len
        if qlen == 1:
            self.last_gen = g
            return node.last
        nxt = last + 1
        if g - nxt >= qlen:
            node.lost += g - qlen + 1 - nxt
            nxt = g - qlen + 1
        self.last_gen = nxt
        return node.buf[nxt % qlen]

    def update_all(self) -> list[Any]:
        """Every unread message, oldest first, as repeated :meth:`update` calls would return
        them (losses counted the same way), in one call: a consumer that walks a 1 kHz queue
        saves a call per sample."""
        node = self.node
        g = node.generation
        last = self.last_gen
        if g == last:
            return []
        self.last_gen = g
        qlen = node.queue_len
        if qlen == 1:
            return [node.last]
        nxt = last + 1
        if g - nxt >= qlen:
            node.lost += g - qlen + 1 - nxt
            nxt = g - qlen + 1
        buf = node.buf
        return [buf[i % qlen] for i in range(nxt, g + 1)]

    def copy(self) -> Any:
        """The latest message (or None), marking everything as read."""
        self.last_gen = self.node.generation
        return self.node.last

    @property
    def advertised(self) -> bool:
        return self.node.advertised

    @property
    def instance(self) -> int:
        return self.node.instance


class SubscriptionInterval(Subscription):
    """A subscription that reports an update at most once per ``interval_us``.

    This is the notification limit a slow consumer (a 10 Hz logger of a 1 kHz topic) uses to
    avoid waking for every message. The reference time advances by whole intervals so the rate
    does not alias down when messages arrive slightly early or late.
    """

    __slots__ = ("interval_us", "last_update_us", "_hrt", "_kernel")

    def __init__(self, broker: Broker, topic: str, interval_us: int, instance: int = 0) -> None:
        super().__init__(broker, topic, instance)
        if interval_us < 0:
            raise ValueError(f"interval must be >= 0 us, got {interval_us}")
        self.interval_us = interval_us
        self._hrt = broker.hrt
        self._kernel = broker.hrt.kernel
        self.last_update_us = -(1 << 62)

    def updated(self) -> bool:
        if self.node.generation == self.last_gen:
            return False
        k = self._kernel
        return (k.now_ns + k.busy_ns) // 1000 - self.last_update_us >= self.interval_us

    def update(self) -> Any:
        node = self.node
        if node.generation == self.last_gen:  # nothing new: no time read at all
            return None
        k = self._kernel
        now = (k.now_ns + k.busy_ns) // 1000  # hrt_absolute_time(), read once
        iv = self.interval_us
        last = self.last_update_us
        if now - last < iv:
            return None
        nxt = last + iv
        # Keep the cadence when this update came at most one interval late (so the rate does
        # not alias down by jitter); otherwise restart the cadence from now.
        self.last_update_us = nxt if now - iv < nxt <= now else now
        self.last_gen = node.generation
        return node.last


class SubscriptionCallback(Subscription):
    """A subscription that schedules a work item whenever the topic is published.

    With ``interval_us`` the item is scheduled at most once per interval. With
    ``required_updates`` n > 1 (PX4's ``set_required_updates``) it is scheduled only once n
    messages are unread, so a consumer of a queued 1 kHz topic can wake at a fraction of the
    rate and walk the queue: the way PX4 limits ``vehicle_angular_velocity`` to
    IMU_GYRO_RATEMAX without losing a sample.
    """

    __slots__ = ("work_item", "interval_us", "last_call_us", "_hrt", "_registered",
                 "required_updates", "_cb")

    def __init__(self, work_item: WorkItem, broker: Broker, topic: str, instance: int = 0,
                 interval_us: int = 0) -> None:
        super().__init__(broker, topic, instance)
        self.work_item = work_item
        self.interval_us = interval_us
        self.last_call_us = -(1 << 62)
        self._hrt = broker.hrt
        self._registered = False
        self.required_updates = 1
        self._cb: Callable[[], None] | None = None

    def set_required_updates(self, n: int) -> None:
        """Schedule the item only when ``n`` messages are unread (clamped to the queue)."""
        n = max(1, min(int(n), self.node.queue_len))
        if n == self.required_updates:
            return
        registered = self._registered
        if registered:
            self.unregister_callback()
        self.required_updates = n
        if registered:
            self.register_callback()

    def _choose(self) -> Callable[[], None]:
        if self.interval_us:
            return self._call
        if self.required_updates > 1:
            return self._call_required
        # The common case: queue the item directly (a C-level partial, no Python frame for
        # schedule_now per publication).
        item = self.work_item
        return partial(item.wq.add, item)

    def register_callback(self) -> bool:
        if not self._registered:
            self._cb = cb = self._choose()
            self.node.callbacks.append(cb)
            self._registered = True
        return True

    def unregister_callback(self) -> None:
        if self._registered:
            if self._cb is not None:
                self.node.callbacks.remove(self._cb)
            self._cb = None
            self._registered = False

    @property
    def registered(self) -> bool:
        return self._registered

    def _call(self) -> None:
        now = self._hrt.absolute_time()
        if now - self.last_call_us >= self.interval_us:
            self.last_call_us = now
            self.work_item.schedule_now()

    def _call_required(self) -> None:
        if self.node.generation - self.last_gen >= self.required_updates:
            self.work_item.schedule_now()
