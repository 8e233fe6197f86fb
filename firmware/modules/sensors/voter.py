"""Redundant-sensor health and selection (PX4's voted sensors, reduced to what a Pixhawk needs).

Each sensor kind (gyro, accel, mag, baro) is a :class:`SensorGroup` over the uORB instances of
its topic. The group looks at every instance a few hundred times a second, cheaply: the latest
message of each node (no queue walking; the module walks only the selected sensor's queue), its
publication time and generation.

An instance is unhealthy when it

* stops publishing (no message for ``timeout_us``: a chip off the bus, a dead driver),
* freezes (``freeze_count`` consecutive identical readings, as observed by the group: real
  sensor noise makes that impossible, a stuck register or a saturated axis makes it certain),
* keeps reporting errors (its driver's ``error_count`` grows by more than one per observation
  on average: a chip the driver finds stuck, NAKing or returning garbage), or
* disagrees strongly with the others for a second. With three or more sensors the one far from
  the median is out. With two there is no majority, so the group keeps the selected one unless
  only the other is sane by its own account (the selected one clips); the other is then marked
  unusable as a failover target and the disagreement is reported.

Selection: the best healthy instance by (not previously failed, priority, lower index), so
the primary (instance 0) wins at start-up even if a secondary publishes first. A switch away from a sensor that turned unhealthy is a failover: counted and
returned to the module, which says so in dmesg. A sensor that failed once ranks below all
sensors that never failed, so a flaky sensor does not win the selection back.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Final

from firmware.modules.sensors.calibration import Calibration
from firmware.platform.uorb import TopicNode

__all__ = ["Event", "SensorGroup", "SensorInstance"]

#: (kind of event, old index, new index, reason): "failover" or "select"
Event = tuple[str, int, int, str]

#: filter weight of one observation in the inconsistency average (~0.1 s at 250 Hz)
_ALPHA: Final = 0.04
#: errors per observation (low-passed) above which a sensor is unhealthy
ERROR_RATE_LIMIT: Final = 1.0
#: how long a disagreement must last before it counts, us
_INCONSISTENT_US: Final = 1_000_000
#: a sensor that clipped within this time is not trusted in a two-sensor disagreement, us
_CLIP_HOLD_US: Final = 1_000_000


class SensorInstance:
    """What the group knows about one uORB instance."""

    __slots__ = (
        "cal",
        "device_id",
        "equal_count",
        "error_count",
        "error_rate",
        "failed_once",
        "fault",
        "fx",
        "fy",
        "fz",
        "healthy",
        "inconsistency",
        "inconsistent_since_us",
        "index",
        "last_clip_us",
        "last_gen",
        "last_raw",
        "node",
        "priority",
        "seen",
        "seen_errors",
        "value",
    )

    def __init__(self, index: int, node: TopicNode, cal: Calibration) -> None:
        self.index = index
        self.node = node
        self.cal = cal
        self.device_id = 0
        self.seen = False
        self.last_gen = 0
        self.last_raw: tuple = ()
        self.equal_count = 0
        self.fx = self.fy = self.fz = 0.0
        self.healthy = False
        self.fault = "no data"
        self.failed_once = False
        self.inconsistency = 0.0
        self.inconsistent_since_us = -1
        self.last_clip_us = -(1 << 62)
        self.error_count = 0
        self.error_rate = 0.0
        self.seen_errors = False
        self.value = (0.0, 0.0, 0.0)
        self.priority = cal.priority


class SensorGroup:
    """Health and selection of the instances of one sensor topic.

    ``read(msg)`` returns the raw reading as a tuple (compared for freezes);
    ``to_vec(cal, raw)`` the calibrated 3-vector (or (value, 0, 0)) compared for consistency.
    ``angle_limit``: compare directions (magnetometers, whose magnitude varies with mounting
    and hard iron) instead of differences.
    """

    def __init__(self, name: str, nodes: list[TopicNode], cals: list[Calibration],
                 read: Callable[[object], tuple], timeout_us: int, freeze_count: int,
                 inconsistency_limit: float, angle_limit: bool = False) -> None:
        self.name = name
        self.instances = [SensorInstance(i, n, c) for i, (n, c) in enumerate(zip(nodes, cals))]
        self.read = read
        self.timeout_us = timeout_us
        self.freeze_count = freeze_count
        self.limit = inconsistency_limit
        self.angle = angle_limit
        self.selected = -1
        self.failover_count = 0
        self.reported_inconsistent = False
        #: a device was seen for the first time: its calibration slot must be looked up
        self.new_device = False

    # -- observation -------------------------------------------------------------------------

    def observe(self, now_us: int, clip: Callable[[object], bool] | None = None) -> None:
        """Take in the latest message of every instance and update its health."""
        for s in self.instances:
            node = s.node
            gen = node.generation
            if gen == 0 or not node.advertised:
                if s.seen:
                    s.healthy, s.fault = False, "unadvertised"
                continue
            if gen != s.last_gen:
                msg = node.last
                s.last_gen = gen
                if not s.seen:
                    s.seen = True
                    s.device_id = msg.device_id
                    s.cal.device_id = msg.device_id
                    s.cal.external = bool(getattr(msg, "is_external", False))
                    self.new_device = True
                errors = msg.error_count
                if s.seen_errors:
                    s.error_rate += 0.2 * (max(0, errors - s.error_count) - s.error_rate)
                s.seen_errors = True
                s.error_count = errors
                raw = self.read(msg)
                if raw == s.last_raw:
                    s.equal_count += 1
                else:
                    s.equal_count = 0
                    s.last_raw = raw
                if clip is not None and clip(msg):
                    s.last_clip_us = now_us
                v = s.cal.apply(raw[0], raw[1], raw[2]) if len(raw) == 3 else \
                    (raw[0] - s.cal.pressure_offset_pa, 0.0, 0.0)
                s.value = v
                if s.fx == 0.0 and s.fy == 0.0 and s.fz == 0.0:
                    s.fx, s.fy, s.fz = v
                else:
                    s.fx += _ALPHA * (v[0] - s.fx)
                    s.fy += _ALPHA * (v[1] - s.fy)
                    s.fz += _ALPHA * (v[2] - s.fz)
            if not s.seen:
                continue
            s.priority = s.cal.priority
            age = now_us - node.last_publish_ns // 1000
            if age > self.timeout_us:
                s.healthy, s.fault = False, f"timeout ({age / 1000:.0f} ms)"
            elif s.equal_count >= self.freeze_count:
                s.healthy, s.fault = False, f"frozen ({s.equal_count + 1} identical readings)"
            elif s.error_rate > ERROR_RATE_LIMIT:
                s.healthy, s.fault = False, f"errors ({s.error_count} reported by the driver)"
            elif s.priority == 0:
                s.healthy, s.fault = False, "disabled"
            elif s.fault.startswith("inconsistent"):
                pass  # sticky: a sensor voted out stays out
            else:
                s.healthy, s.fault = True, ""
        self._consistency(now_us)

    def _distance(self, a: SensorInstance, rx: float, ry: float, rz: float) -> float:
        if self.angle:
            na = math.sqrt(a.fx * a.fx + a.fy * a.fy + a.fz * a.fz)
            nr = math.sqrt(rx * rx + ry * ry + rz * rz)
            if na < 1e-9 or nr < 1e-9:
                return 0.0
            c = (a.fx * rx + a.fy * ry + a.fz * rz) / (na * nr)
            return math.acos(max(-1.0, min(1.0, c)))
        dx, dy, dz = a.fx - rx, a.fy - ry, a.fz - rz
        return math.sqrt(dx * dx + dy * dy + dz * dz)

    def _consistency(self, now_us: int) -> None:
        live = [s for s in self.instances if s.healthy]
        if len(live) < 2:
            for s in self.instances:
                s.inconsistency = 0.0
                s.inconsistent_since_us = -1
            return
        if len(live) >= 3:
            xs = sorted(s.fx for s in live)
            ys = sorted(s.fy for s in live)
            zs = sorted(s.fz for s in live)
            m = len(live) // 2
            ref = (xs[m], ys[m], zs[m])
        else:
            ref = (sum(s.fx for s in live) / 2, sum(s.fy for s in live) / 2,
                   sum(s.fz for s in live) / 2)
        for s in live:
            # Against the median (3+) or, for two, their full mutual difference.
            d = self._distance(s, *ref)
            s.inconsistency = d * 2.0 if len(live) == 2 else d
            if s.inconsistency > self.limit:
                if s.inconsistent_since_us < 0:
                    s.inconsistent_since_us = now_us
            else:
                s.inconsistent_since_us = -1
        bad = [s for s in live if s.inconsistent_since_us >= 0
               and now_us - s.inconsistent_since_us >= _INCONSISTENT_US]
        if not bad:
            self.reported_inconsistent = False
            return
        if len(live) >= 3:
            worst = max(bad, key=lambda s: s.inconsistency)
        else:
            sel = next((s for s in live if s.index == self.selected), live[0])
            other = live[1] if live[0] is sel else live[0]
            sel_clips = now_us - sel.last_clip_us < _CLIP_HOLD_US
            other_clips = now_us - other.last_clip_us < _CLIP_HOLD_US
            worst = sel if sel_clips and not other_clips else other
        worst.healthy = False
        worst.fault = f"inconsistent ({worst.inconsistency:.3g})"
        self.reported_inconsistent = True

    # -- selection ---------------------------------------------------------------------------

    def select(self) -> Event | None:
        """Re-evaluate the selection; the event if it changed."""
        best = None
        best_key: tuple = ()
        for s in self.instances:
            if not s.healthy:
                continue
            key = (not s.failed_once, s.priority, -s.index)
            if best is None or key > best_key:
                best, best_key = s, key
        old = self.selected
        if best is None:
            if old >= 0 and not self.instances[old].healthy:
                cur = self.instances[old]
                if not cur.failed_once:
                    cur.failed_once = True
                    self.failover_count += 1
                    return ("failover", old, -1, cur.fault)
            return None
        if best.index == old:
            return None
        self.selected = best.index
        if old >= 0 and not self.instances[old].healthy:
            cur = self.instances[old]
            if not cur.failed_once:
                self.failover_count += 1
            cur.failed_once = True
            return ("failover", old, best.index, cur.fault)
        return ("select", old, best.index, "")

    @property
    def current(self) -> SensorInstance | None:
        return self.instances[self.selected] if self.selected >= 0 else None
