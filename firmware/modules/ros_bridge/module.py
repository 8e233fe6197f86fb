"""ros_bridge: the companion's uORB topics to and from ROS, through the board's "ros" port.

On a PX4 companion this is what the micro XRCE-DDS agent and px4_ros_com do for ROS 2, and what
a MAVROS node does for ROS 1: selected topics leave for the robot's software, setpoints and
commands come back. Here the module stays firmware (deterministic, in virtual time): it only
turns uORB messages into records ``(topic, instance, packed bytes)`` on the board's
:class:`~firmware.modules.ros_bridge.port.RosPort` and back. The ROS node itself (rospy, threads,
``/clock``) is the host edge, ``hil/ros/``.

Out: one callback subscription per listed topic (at most once per ``1/rate_hz``), so the module
runs when something is due; a run sends every listed topic that was updated and whose interval
has passed. In: a record that is not a ``(str, int, bytes)`` triple, names a topic that is not
in the ``in:`` list, or whose payload is not the topic's packed size is dropped and counted by
cause (``ros_bridge status``); a good one is unpacked and published on the companion's broker
(advertised at its first message), from where the uorb_bridge carries it to the FMU.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Final

from firmware.modules.ros_bridge.config import DEFAULT_PATH, ConfigError, RosTopics, parse_topics
from firmware.platform.module import ModuleError, UsageError, WorkItemModule
from firmware.platform.uorb import Publication, SubscriptionCallback

if TYPE_CHECKING:
    from firmware.modules.ros_bridge.port import RosPort
    from firmware.system import System

__all__ = ["DROP_CAUSES", "RosBridgeModule", "check_record"]

#: why an incoming record was dropped (the status line's order)
DROP_CAUSES: Final[tuple[str, ...]] = ("malformed", "unknown_topic", "bad_instance", "wrong_size")


def check_record(record: Any, sizes: dict[str, int]) -> tuple[str, int, bytes] | str:
    """``(topic, instance, payload)`` if ``record`` is a well-formed record of a topic in
    ``sizes`` (topic -> packed size), else the drop cause (one of :data:`DROP_CAUSES`)."""
    if not isinstance(record, (tuple, list)) or len(record) != 3:
        return "malformed"
    topic, instance, payload = record
    if not isinstance(topic, str) or isinstance(instance, bool) or not isinstance(instance, int) \
            or not isinstance(payload, (bytes, bytearray)):
        return "malformed"
    size = sizes.get(topic)
    if size is None:
        return "unknown_topic"
    if not 0 <= instance <= 3:
        return "bad_instance"
    if len(payload) != size:
        return "wrong_size"
    return topic, instance, bytes(payload)


class RosBridgeModule(WorkItemModule):
    NAME = "ros_bridge"
    DESCRIPTION = "uORB topics to and from ROS over the board's ros port (list: -c FILE)"
    USAGE = (f"start [-c FILE]   topic list (default {DEFAULT_PATH})",)
    WQ = "wq:hp_default"
    CPU_COST_NS = 20_000

    def __init__(self, system: System, args: Sequence[str] = (), path: str = DEFAULT_PATH
                 ) -> None:
        super().__init__(system, args)
        self.path = path
        self.topics: RosTopics | None = None
        self.port: RosPort | None = None
        self._out: list[tuple[str, int, int, SubscriptionCallback]] = []
        self._last_sent_us: list[int] = []
        self._sizes: dict[str, int] = {}
        self._pubs: dict[tuple[str, int], Publication] = {}
        self.sent: dict[str, int] = {}
        self.received: dict[str, int] = {}
        self.dropped: dict[str, int] = {c: 0 for c in DROP_CAUSES}

    @classmethod
    def instantiate(cls, system: System, args: Sequence[str]) -> RosBridgeModule:
        path = DEFAULT_PATH
        rest = list(args)
        while rest:
            opt = rest.pop(0)
            if opt == "-c" and rest:
                path = rest.pop(0)
            else:
                raise UsageError(f"unknown option {opt!r}")
        return cls(system, args, path)

    # -- life cycle -------------------------------------------------------------------------------

    def _start(self) -> None:
        port = getattr(self.system.hw, "ros_port", None) if self.system.hw is not None else None
        if port is None:
            raise ModuleError(f"{self.name}: this board has no ros port")
        try:
            text = self.system.resolve_path(self.path).read_text()
        except OSError as exc:
            raise ModuleError(f"{self.name}: cannot read {self.path}: {exc}") from None
        registry = self.platform.orb.registry
        try:
            topics = parse_topics(text, registry, self.path)
        except ConfigError as exc2:
            raise ModuleError(f"{self.name}: {exc2}") from None
        self.topics = topics
        self.port = port
        item = self.work_item
        assert item is not None
        for t in topics.out:
            sub = SubscriptionCallback(item, self.platform.orb, t.topic, t.instance,
                                       t.interval_us)
            sub.register_callback()
            self.subscriptions.append(sub)
            self._out.append((t.topic, t.instance, t.interval_us, sub))
            self._last_sent_us.append(-(1 << 62))
            self.sent[t.topic] = 0
        self._sizes = {t.topic: registry.topic(t.topic).size for t in topics.inbound}
        self.received = {t.topic: 0 for t in topics.inbound}
        port.listener = item.schedule_now
        if port.inbox:
            item.schedule_now()

    def _stop(self) -> None:
        if self.port is not None:
            self.port.listener = None
        self._out.clear()
        self._last_sent_us.clear()
        self._pubs.clear()

    # -- the work ---------------------------------------------------------------------------------

    def run(self) -> None:
        port = self.port
        if port is None:
            return
        if port.inbox:
            self._receive(port)
        k = self.platform.kernel
        now_ns = k.now_ns + k.busy_ns
        now_us = now_ns // 1000
        last = self._last_sent_us
        for i, (topic, instance, interval_us, sub) in enumerate(self._out):
            if not sub.updated() or now_us - last[i] < interval_us:
                continue
            msg = sub.copy()
            if msg is None:
                continue
            last[i] = now_us
            port.send(now_ns, topic, instance, msg.pack())
            self.sent[topic] += 1

    def _receive(self, port: RosPort) -> None:
        orb = self.platform.orb
        sizes = self._sizes
        for _t_ns, record in port.take():
            checked = check_record(record, sizes)
            if isinstance(checked, str):
                self.dropped[checked] += 1
                continue
            topic, instance, payload = checked
            msg = orb.registry.cls(topic).unpack(payload)  # type: ignore[attr-defined]
            key = (topic, instance)
            pub = self._pubs.get(key)
            if pub is None:
                pub = self._pubs[key] = self.advertise(topic, instance)
            pub.publish(msg)
            self.received[topic] += 1

    # -- status -----------------------------------------------------------------------------------

    def status_lines(self) -> list[str]:
        port = self.port
        out = [f"topic list: {self.path}"]
        if self.topics is not None:
            out.append("out: " + ", ".join(
                f"{t.topic}[{t.instance}] {t.rate_hz:g} Hz {self.sent.get(t.topic, 0)} sent"
                if t.rate_hz else f"{t.topic}[{t.instance}] every update "
                f"{self.sent.get(t.topic, 0)} sent" for t in self.topics.out))
            out.append("in: " + ", ".join(f"{t.topic} {self.received.get(t.topic, 0)} received"
                                          for t in self.topics.inbound))
        out.append("dropped: " + ", ".join(f"{c} {self.dropped[c]}" for c in DROP_CAUSES))
        if port is not None:
            out.append(f"port: {port.records_in} records in, {port.records_out} out, "
                       f"{port.overflow} lost to a full inbox")
        return out
