"""The uORB bridge's topic list (data, like PX4's dds_topics.yaml) and the topic ids.

The list is a YAML file (default ``/etc/bridge/topics.yaml``, the ROMFS)::

    link_timeout_ms: 500          # quiet this long: the link is reported lost
    heartbeat_hz: 2               # the link's heartbeat frame (carries the sender's counters)
    fmu_to_companion:
      - {topic: vehicle_attitude, rate_hz: 0}      # 0: every update
      - {topic: battery_status, rate_hz: 2}        # at most 2 Hz
    companion_to_fmu:
      - {topic: vehicle_rates_setpoint, rate_hz: 0, as: companion_rates_setpoint}

``as:`` renames a topic on the receiving side: the receiver publishes it under that topic,
which must carry the same message type. ``instance:`` (default 0) picks a topic instance.

Both sides load the same file. A topic's id on the wire is derived from its name and its
message layout (:func:`topic_id`), so a frame is only accepted by a side whose ``.msg``
definition has the same fields in the same order with the same types; a side built from other
definitions counts the frame as an unknown id instead of reading garbage. Two topics of the
list with the same id are refused when the list is loaded.

Everything wrong with the file (bad YAML, unknown keys or topics, a rename to another type, a
topic both sent and received) is a :class:`BridgeConfigError` naming the file and the entry.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass
from typing import Any, Final

import yaml

from firmware.modules.uorb_bridge.protocol import MAX_PAYLOAD
from firmware.platform.msgdef import MessageDef, MessageRegistry

__all__ = ["BridgeConfig", "BridgeConfigError", "ROLES", "Route", "layout_text", "topic_id"]

#: the two ends of the link and the list each one sends
ROLES: Final = {"fmu": "fmu_to_companion", "companion": "companion_to_fmu"}
_TOP_KEYS: Final = ("link_timeout_ms", "heartbeat_hz", "fmu_to_companion", "companion_to_fmu")
_ENTRY_KEYS: Final = ("topic", "rate_hz", "as", "instance")
#: an instance byte on the wire, and uORB's own limit
_MAX_INSTANCE: Final = 9


class BridgeConfigError(ValueError):
    """The topic list cannot be used; the message says where and why."""


def layout_text(mdef: MessageDef, registry: MessageRegistry) -> str:
    """The message's field layout as text: its ULog format and those of the types nested in
    it, which is what both sides must agree on for the packed bytes to mean the same."""
    parts = [mdef.ulog_format()]
    seen = {mdef.name}
    todo = [f.type for f in mdef.fields if not f.is_primitive]
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        sub = registry.messages[name]
        parts.append(sub.ulog_format())
        todo.extend(f.type for f in sub.fields if not f.is_primitive)
    return "\n".join([parts[0]] + sorted(parts[1:]))


def topic_id(topic: str, mdef: MessageDef, registry: MessageRegistry) -> int:
    """The 32-bit id of ``topic`` on the wire: CRC-32 of its name and its layout."""
    return zlib.crc32(f"{topic}\n{layout_text(mdef, registry)}".encode()) & 0xFFFFFFFF


@dataclass(frozen=True)
class Route:
    """One bridged topic in one direction."""

    topic: str            # the sender's topic (and the name the id is derived from)
    instance: int
    rate_hz: float        # 0: every update
    publish_as: str       # the receiver's topic (``as:``, default the same name)
    topic_id: int
    size: int             # payload bytes (the packed message)

    @property
    def interval_us(self) -> int:
        """The shortest time between two frames of this topic (0: every update)."""
        return 0 if self.rate_hz <= 0 else int(round(1e6 / self.rate_hz))


@dataclass(frozen=True)
class BridgeConfig:
    """The loaded topic list."""

    source: str
    link_timeout_ms: int
    heartbeat_hz: float
    fmu_to_companion: tuple[Route, ...]
    companion_to_fmu: tuple[Route, ...]

    def sends(self, role: str) -> tuple[Route, ...]:
        """What the ``role`` side (fmu or companion) sends."""
        return self.fmu_to_companion if role == "fmu" else self.companion_to_fmu

    def receives(self, role: str) -> tuple[Route, ...]:
        """What the ``role`` side receives (and publishes as each route's ``publish_as``)."""
        return self.companion_to_fmu if role == "fmu" else self.fmu_to_companion

    @classmethod
    def load_file(cls, path: str, host_path: Any, registry: MessageRegistry) -> BridgeConfig:
        """Load from ``host_path`` (a pathlib.Path); errors name ``path`` (the FMU's path)."""
        try:
            text = host_path.read_text()
        except (OSError, UnicodeDecodeError) as exc:
            raise BridgeConfigError(f"{path}: cannot read: {exc}") from None
        return cls.parse(text, registry, path)

    @classmethod
    def parse(cls, text: str, registry: MessageRegistry, source: str = "<text>"
              ) -> BridgeConfig:
        try:
            data = yaml.safe_load(text)
        except yaml.YAMLError as exc:
            raise BridgeConfigError(f"{source}: not valid YAML: {_one_line(str(exc))}"
                                    ) from None
        if not isinstance(data, dict):
            raise BridgeConfigError(f"{source}: expected a mapping with "
                                    f"{', '.join(_TOP_KEYS)}")
        extra = sorted(str(k) for k in data if k not in _TOP_KEYS)
        if extra:
            raise BridgeConfigError(f"{source}: unknown key(s) {', '.join(extra)} (known: "
                                    f"{', '.join(_TOP_KEYS)})")
        timeout = data.get("link_timeout_ms", 500)
        if type(timeout) is not int or not 10 <= timeout <= 60_000:
            raise BridgeConfigError(f"{source}: link_timeout_ms must be an integer in "
                                    f"10..60000, got {timeout!r}")
        hb = data.get("heartbeat_hz", 2)
        if type(hb) not in (int, float) or not 0.1 <= hb <= 100:
            raise BridgeConfigError(f"{source}: heartbeat_hz must be a number in 0.1..100, "
                                    f"got {hb!r}")
        lists: dict[str, tuple[Route, ...]] = {}
        for key in ("fmu_to_companion", "companion_to_fmu"):
            lists[key] = _routes(data.get(key) or [], key, registry, source)
        cfg = cls(source, timeout, float(hb), lists["fmu_to_companion"],
                  lists["companion_to_fmu"])
        _check_ids(cfg)
        _check_loops(cfg)
        return cfg


def _one_line(text: str) -> str:
    return " ".join(text.split())


def _routes(items: Any, key: str, registry: MessageRegistry, source: str
            ) -> tuple[Route, ...]:
    if not isinstance(items, list):
        raise BridgeConfigError(f"{source}: {key} must be a list of {{topic: NAME, ...}}")
    out: list[Route] = []
    seen: set[tuple[str, int]] = set()
    for i, item in enumerate(items):
        where = f"{source}: {key}[{i}]"
        if not isinstance(item, dict):
            raise BridgeConfigError(f"{where}: expected {{topic: NAME, rate_hz: R}}, "
                                    f"got {item!r}")
        extra = sorted(str(k) for k in item if k not in _ENTRY_KEYS)
        if extra:
            raise BridgeConfigError(f"{where}: unknown key(s) {', '.join(extra)} (known: "
                                    f"{', '.join(_ENTRY_KEYS)})")
        topic = item.get("topic")
        if not isinstance(topic, str):
            raise BridgeConfigError(f"{where}: 'topic' must be a topic name, got {topic!r}")
        mdef = registry.topics.get(topic)
        if mdef is None:
            raise BridgeConfigError(f"{where}: unknown uORB topic {topic!r}")
        rate = item.get("rate_hz", 0)
        if type(rate) not in (int, float) or not 0 <= rate <= 10_000:
            raise BridgeConfigError(f"{where} ({topic}): rate_hz must be a number in "
                                    f"0..10000 (0: every update), got {rate!r}")
        inst = item.get("instance", 0)
        if type(inst) is not int or not 0 <= inst <= _MAX_INSTANCE:
            raise BridgeConfigError(f"{where} ({topic}): instance must be an integer in "
                                    f"0..{_MAX_INSTANCE}, got {inst!r}")
        as_topic = item.get("as", topic)
        if not isinstance(as_topic, str):
            raise BridgeConfigError(f"{where} ({topic}): 'as' must be a topic name, "
                                    f"got {as_topic!r}")
        as_def = registry.topics.get(as_topic)
        if as_def is None:
            raise BridgeConfigError(f"{where} ({topic}): 'as' names unknown uORB topic "
                                    f"{as_topic!r}")
        if as_def is not mdef:
            raise BridgeConfigError(
                f"{where}: {topic} ({mdef.name}) cannot be published as {as_topic}: that "
                f"topic carries {as_def.name}, not the same message type")
        if mdef.size > MAX_PAYLOAD:
            raise BridgeConfigError(f"{where}: {topic} packs to {mdef.size} bytes, more than "
                                    f"a frame carries ({MAX_PAYLOAD})")
        if (topic, inst) in seen:
            raise BridgeConfigError(f"{where}: {topic} instance {inst} listed twice")
        seen.add((topic, inst))
        out.append(Route(topic, inst, float(rate), as_topic, topic_id(topic, mdef, registry),
                         mdef.size))
    return tuple(out)


def _check_ids(cfg: BridgeConfig) -> None:
    by_id: dict[int, str] = {}
    for r in cfg.fmu_to_companion + cfg.companion_to_fmu:
        if r.topic_id == 0:
            raise BridgeConfigError(f"{cfg.source}: topic {r.topic} has id 0, the heartbeat's")
        other = by_id.setdefault(r.topic_id, r.topic)
        if other != r.topic:
            raise BridgeConfigError(f"{cfg.source}: topics {other} and {r.topic} have the same "
                                    f"id 0x{r.topic_id:08x}; rename one of them")


def _check_loops(cfg: BridgeConfig) -> None:
    """A topic one side receives and also sends back would echo for ever."""
    for a, b in (("fmu_to_companion", "companion_to_fmu"),
                 ("companion_to_fmu", "fmu_to_companion")):
        sent_back = {(r.topic, r.instance) for r in getattr(cfg, b)}
        for r in getattr(cfg, a):
            if (r.publish_as, r.instance) in sent_back:
                raise BridgeConfigError(
                    f"{cfg.source}: {r.topic} in {a} is published as {r.publish_as}, which "
                    f"{b} sends back: the bridge would echo it; rename it with 'as:'")
