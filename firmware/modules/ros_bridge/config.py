"""The ros_bridge topic list, as data: which uORB topics leave for ROS and at what rate, which
ROS may publish into the companion's broker.

``/etc/bridge/ros_topics.yaml`` (firmware/romfs/bridge/ros_topics.yaml) or ``-c FILE``::

    out:                      # companion broker -> ROS (/fmu/out/<topic> and the views)
      - {topic: vehicle_attitude, rate_hz: 50}       # 0 or absent: every update
      - {topic: sensor_combined, rate_hz: 50, instance: 0}
    in:                       # ROS -> companion broker (then uorb_bridge -> FMU)
      - {topic: trajectory_setpoint}

Every topic must be one of the board's message definitions (firmware/msg); a topic listed twice
in one direction, a negative or non-numeric rate, an unknown key or a file that is not such a
mapping is refused with an error naming the entry, so ``ros_bridge start`` fails with the reason
and nothing half-starts.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Final

import yaml

from firmware.platform.msgdef import MessageRegistry

__all__ = ["BridgeTopic", "ConfigError", "DEFAULT_PATH", "RosTopics", "parse_topics"]

#: where the board's ROMFS keeps the list
DEFAULT_PATH: Final = "/etc/bridge/ros_topics.yaml"
_KEYS: Final = frozenset({"topic", "rate_hz", "instance"})
_MAX_INSTANCE: Final = 3  # firmware.platform.uorb.ORB_MULTI_MAX_INSTANCES - 1


class ConfigError(ValueError):
    """The topic list is malformed; the message names the entry and what is wrong."""


@dataclass(frozen=True)
class BridgeTopic:
    topic: str
    instance: int = 0
    rate_hz: float = 0.0  # 0: every update

    @property
    def interval_us(self) -> int:
        return 0 if self.rate_hz <= 0 else int(round(1e6 / self.rate_hz))


@dataclass(frozen=True)
class RosTopics:
    out: tuple[BridgeTopic, ...]
    inbound: tuple[BridgeTopic, ...]

    def inbound_names(self) -> frozenset[str]:
        return frozenset(t.topic for t in self.inbound)


def _entry(item: Any, where: str, registry: MessageRegistry, with_rate: bool) -> BridgeTopic:
    if not isinstance(item, dict):
        raise ConfigError(f"{where}: expected a mapping like {{topic: NAME}}, got {item!r}")
    unknown = sorted(str(k) for k in item if k not in _KEYS or (k == "rate_hz" and not with_rate))
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {', '.join(unknown)}")
    topic = item.get("topic")
    if not isinstance(topic, str) or not topic:
        raise ConfigError(f"{where}: 'topic' must be a topic name, got {topic!r}")
    try:
        registry.topic(topic)
    except KeyError:
        raise ConfigError(f"{where}: no uORB topic {topic!r} (firmware/msg)") from None
    inst = item.get("instance", 0)
    if isinstance(inst, bool) or not isinstance(inst, int) or not 0 <= inst <= _MAX_INSTANCE:
        raise ConfigError(f"{where}: 'instance' must be 0..{_MAX_INSTANCE}, got {inst!r}")
    rate = item.get("rate_hz", 0)
    if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not 0 <= rate < 1e5:
        raise ConfigError(f"{where}: 'rate_hz' must be a number >= 0 (0: every update), "
                          f"got {rate!r}")
    return BridgeTopic(topic, int(inst), float(rate))


def parse_topics(text: str, registry: MessageRegistry, source: str = "<ros_topics>"
                 ) -> RosTopics:
    """The topic list from YAML text; :class:`ConfigError` says what is wrong and where."""
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ConfigError(f"{source}: not YAML: {exc}") from None
    if not isinstance(doc, dict):
        raise ConfigError(f"{source}: expected a mapping with 'out:' and 'in:' lists")
    extra = sorted(str(k) for k in doc if k not in ("out", "in"))
    if extra:
        raise ConfigError(f"{source}: unknown key(s) {', '.join(extra)} (expected out, in)")
    lists: dict[str, tuple[BridgeTopic, ...]] = {}
    for key in ("out", "in"):
        items = doc.get(key) or []
        if not isinstance(items, list):
            raise ConfigError(f"{source}: '{key}' must be a list")
        seen: set[tuple[str, int]] = set()
        got: list[BridgeTopic] = []
        for i, item in enumerate(items):
            t = _entry(item, f"{source}: {key}[{i}]", registry, with_rate=key == "out")
            if (t.topic, t.instance) in seen:
                raise ConfigError(f"{source}: {key}[{i}]: {t.topic}[{t.instance}] listed twice")
            seen.add((t.topic, t.instance))
            got.append(t)
        lists[key] = tuple(got)
    return RosTopics(lists["out"], lists["in"])
