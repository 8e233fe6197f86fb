"""Geofence and rally point storage: PX4's DM_KEY_FENCE_POINTS and DM_KEY_SAFE_POINTS.

Each list is replaced whole (the MAVLink mission protocol with mission_type FENCE or RALLY
collects a complete upload first, as PX4 writes into the inactive DM_KEY_*_0/1 and switches
only when the upload is complete) and saved in a :class:`~.records.RecordPair` of its own, so a
power cut at any byte of a save brings back the old or the new list. A list becomes active
only once it is saved (:class:`~.store.SaveError` otherwise), and a fence is checked whole
(:func:`fence_problem`) before it is stored, so the stored fence is always a valid one.

Items are PX4's ``mission_fence_point_s`` reduced to what is used: the command, the position
(degE7, what MISSION_ITEM_INT carries, so an uploaded item downloads identical), the altitude
and whether it is above home, the polygon's vertex count or the circle's radius.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Iterable, Sequence
from typing import Final, NamedTuple

from firmware.modules.dataman.records import Partition, RecordPair

__all__ = ["FENCE_CIRCLE_EXCLUSION", "FENCE_CIRCLE_INCLUSION", "FENCE_CMDS",
           "FENCE_POLYGON_EXCLUSION", "FENCE_POLYGON_INCLUSION", "FENCE_RETURN_POINT",
           "FenceProblem", "Point", "PointStore", "lat_lon_deg", "RALLY_POINT", "fence_problem",
           "polygons_and_circles", "self_intersecting"]

#: MAV_CMD_NAV_FENCE_* and MAV_CMD_NAV_RALLY_POINT (MAVLink common)
FENCE_RETURN_POINT: Final = 5000
FENCE_POLYGON_INCLUSION: Final = 5001
FENCE_POLYGON_EXCLUSION: Final = 5002
FENCE_CIRCLE_INCLUSION: Final = 5003
FENCE_CIRCLE_EXCLUSION: Final = 5004
RALLY_POINT: Final = 5100
FENCE_CMDS: Final = frozenset({FENCE_RETURN_POINT, FENCE_POLYGON_INCLUSION,
                               FENCE_POLYGON_EXCLUSION, FENCE_CIRCLE_INCLUSION,
                               FENCE_CIRCLE_EXCLUSION})
_POLYGON: Final = frozenset({FENCE_POLYGON_INCLUSION, FENCE_POLYGON_EXCLUSION})
_CIRCLE: Final = frozenset({FENCE_CIRCLE_INCLUSION, FENCE_CIRCLE_EXCLUSION})

#: nav_cmd, lat degE7, lon degE7, alt m, relative, vertex count, radius m
_ITEM: Final = struct.Struct("<HiifBHf")


class Point(NamedTuple):
    """One fence or rally item as dataman stores it."""
    nav_cmd: int
    lat_e7: int
    lon_e7: int
    alt_m: float
    relative: bool       # altitude above home (MAV_FRAME_GLOBAL_RELATIVE_ALT[_INT])
    vertex_count: int = 0  # polygon vertices (param1 of a vertex), else 0
    radius_m: float = 0.0  # circle radius (param1 of a circle), else 0

    @property
    def lat(self) -> float:
        return self.lat_e7 / 1e7

    @property
    def lon(self) -> float:
        return self.lon_e7 / 1e7

    def pack(self) -> bytes:
        return _ITEM.pack(self.nav_cmd, self.lat_e7, self.lon_e7, self.alt_m,
                          int(self.relative), self.vertex_count, self.radius_m)

    @staticmethod
    def unpack(data: bytes) -> Point:
        cmd, lat, lon, alt, rel, n, r = _ITEM.unpack(data)
        return Point(int(cmd), int(lat), int(lon), float(alt), bool(rel), int(n), float(r))


def lat_lon_deg(p: Point) -> tuple[float, float]:
    """``(p.lat, p.lon)``: a point's position in degrees, as one value."""
    return p.lat, p.lon


class FenceProblem(NamedTuple):
    """Why a fence list is not valid: the item it shows at, a kind (``vertex_count``,
    ``too_few``, ``self_intersecting``, ``radius``, ``command``) and a sentence."""
    seq: int
    kind: str
    text: str


def _cross(ax: float, ay: float, bx: float, by: float, cx: float, cy: float) -> float:
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


def _on_segment(ax: float, ay: float, bx: float, by: float, px: float, py: float) -> bool:
    return min(ax, bx) <= px <= max(ax, bx) and min(ay, by) <= py <= max(ay, by)


def _segments_touch(a: tuple[float, float], b: tuple[float, float], c: tuple[float, float],
                    d: tuple[float, float]) -> bool:
    """Whether segments ab and cd share a point (crossing, touching or overlapping)."""
    d1 = _cross(c[0], c[1], d[0], d[1], a[0], a[1])
    d2 = _cross(c[0], c[1], d[0], d[1], b[0], b[1])
    d3 = _cross(a[0], a[1], b[0], b[1], c[0], c[1])
    d4 = _cross(a[0], a[1], b[0], b[1], d[0], d[1])
    if ((d1 > 0) != (d2 > 0)) and d1 != 0 and d2 != 0 and \
            ((d3 > 0) != (d4 > 0)) and d3 != 0 and d4 != 0:
        return True
    return (d1 == 0 and _on_segment(c[0], c[1], d[0], d[1], a[0], a[1])) or \
        (d2 == 0 and _on_segment(c[0], c[1], d[0], d[1], b[0], b[1])) or \
        (d3 == 0 and _on_segment(a[0], a[1], b[0], b[1], c[0], c[1])) or \
        (d4 == 0 and _on_segment(a[0], a[1], b[0], b[1], d[0], d[1]))


def self_intersecting(vertices: Sequence[tuple[int, int]]) -> bool:
    """Whether a closed polygon (degE7 vertices, exact integer geometry) is not simple: two
    edges that are not neighbours share a point, neighbours overlap or fold back, or a vertex
    repeats. PX4's point-in-polygon test (PNPOLY) "only supports non-complex polygons", so
    such a fence would not mean what its author drew."""
    n = len(vertices)
    pts = [(float(x), float(y)) for x, y in vertices]
    if len(set(vertices)) != n:
        return True
    edges = [(pts[i], pts[(i + 1) % n]) for i in range(n)]
    for i in range(n):
        a, b = edges[i]
        for j in range(i + 1, n):
            c, d = edges[j]
            if j == i + 1 or (i == 0 and j == n - 1):
                # neighbours share one vertex; they must not fold back over each other
                shared, p, q = (b, a, d) if j == i + 1 else (a, b, c)
                if _cross(shared[0], shared[1], p[0], p[1], q[0], q[1]) == 0 and \
                        (p[0] - shared[0]) * (q[0] - shared[0]) + \
                        (p[1] - shared[1]) * (q[1] - shared[1]) > 0:
                    return True
                continue
            if _segments_touch(a, b, c, d):
                return True
    area2 = sum(pts[i][0] * pts[(i + 1) % n][1] - pts[(i + 1) % n][0] * pts[i][1]
                for i in range(n))
    return area2 == 0


def fence_problem(points: Sequence[Point], complete: bool = True) -> FenceProblem | None:
    """The first structural problem of a fence list, or None. ``complete=False`` checks an
    upload in progress: a polygon still open at the end is not (yet) a problem.

    PX4's rules (mavlink_mission.cpp, geofence.cpp): a polygon is ``vertex_count`` items in a
    row with the same command, each carrying the count in param1; fewer than 3 vertices is
    refused (MAV_MISSION_ERROR). The emulator also refuses what PX4 would store and then
    misread: a count the following vertices do not repeat, a polygon cut short, a
    self-intersecting polygon, and a circle whose radius is not a positive finite number."""
    i, n = 0, len(points)
    while i < n:
        p = points[i]
        if p.nav_cmd in _POLYGON:
            count = p.vertex_count
            if count < 3:
                return FenceProblem(i, "too_few", f"Fence polygon at item {i}: {count} "
                                    "vertices, at least 3 needed")
            end = i + count
            for k in range(i + 1, min(end, n)):
                q = points[k]
                if q.nav_cmd != p.nav_cmd or q.vertex_count != count:
                    return FenceProblem(k, "vertex_count",
                                        f"Fence polygon at item {i} has {k - i} of its "
                                        f"{count} vertices; item {k} does not continue it")
            if end > n:
                if complete:
                    return FenceProblem(n - 1, "vertex_count",
                                        f"Fence polygon at item {i} has {n - i} of its "
                                        f"{count} vertices")
                return None
            if self_intersecting([(q.lat_e7, q.lon_e7) for q in points[i:end]]):
                return FenceProblem(end - 1, "self_intersecting",
                                    f"Fence polygon at item {i} is self-intersecting")
            i = end
        elif p.nav_cmd in _CIRCLE:
            if not (math.isfinite(p.radius_m) and p.radius_m > 0.0):
                return FenceProblem(i, "radius", f"Fence circle at item {i}: radius "
                                    f"{p.radius_m} m")
            i += 1
        elif p.nav_cmd == FENCE_RETURN_POINT:
            i += 1
        else:
            return FenceProblem(i, "command", f"Fence item {i}: command {p.nav_cmd}")
    return None


def polygons_and_circles(points: Sequence[Point]) -> tuple[
        list[tuple[int, list[tuple[float, float]]]], list[tuple[int, float, float, float]]]:
    """A valid fence list as (command, [(lat, lon), ...]) polygons and (command, lat, lon,
    radius_m) circles, in list order (the return point is not an area)."""
    polygons: list[tuple[int, list[tuple[float, float]]]] = []
    circles: list[tuple[int, float, float, float]] = []
    i = 0
    while i < len(points):
        p = points[i]
        if p.nav_cmd in _POLYGON and p.vertex_count > 0:
            polygons.append((p.nav_cmd, [(q.lat, q.lon) for q in points[i:i + p.vertex_count]]))
            i += p.vertex_count
            continue
        if p.nav_cmd in _CIRCLE:
            circles.append((p.nav_cmd, p.lat, p.lon, p.radius_m))
        i += 1
    return polygons, circles


class PointStore:
    """One list (fence or rally) in memory, saved to ``partition`` if given.

    ``max_items`` is PX4's bound for the list (DM_KEY_FENCE_POINTS_MAX 64,
    DM_KEY_SAFE_POINTS_MAX 32); :attr:`capacity` is the smaller of it and what one record
    holds. ``validate`` (the fence's :func:`fence_problem`) is applied to every new list."""

    def __init__(self, name: str, partition: Partition | None, magic: bytes, max_items: int,
                 validate: Callable[[Sequence[Point]], FenceProblem | None] | None = None
                 ) -> None:
        self.name = name
        self.max_items = max_items
        self.validate = validate
        #: after the magic and save number: item count, update counter
        self.records = RecordPair(partition, magic, "HH", self._body_len)
        self.points: tuple[Point, ...] = ()
        self.update_counter = 0
        #: called after the active list changed
        self.listeners: list[Callable[[], None]] = []

    @property
    def partition(self) -> Partition | None:
        """Where the list is saved (None: memory only); the records' partition."""
        return self.records.part

    @partition.setter
    def partition(self, part: Partition | None) -> None:
        self.records.part = part

    def _body_len(self, meta: tuple[int, ...]) -> int:
        return meta[0] * _ITEM.size

    @property
    def capacity(self) -> int:
        if self.partition is None:
            return self.max_items
        return max(0, min(self.max_items, self.records.body_room() // _ITEM.size))

    @property
    def count(self) -> int:
        return len(self.points)

    def replace(self, points: Iterable[Point]) -> None:
        """Make ``points`` the active list once saved. :class:`~.store.StoreError` for a list
        that is too long or (a fence) not valid, :class:`~.store.SaveError` if the save
        failed; either way the previous list stays active and stored."""
        from firmware.modules.dataman.store import SaveError, StoreError

        new = tuple(points)
        if len(new) > self.capacity:
            raise StoreError(f"dataman: {len(new)} {self.name} items, storage holds "
                             f"{self.capacity}")
        if self.validate is not None:
            problem = self.validate(new)
            if problem is not None:
                raise StoreError(f"dataman: {problem.text}")
        counter = (self.update_counter + 1) & 0xFFFF
        try:
            body = b"".join(p.pack() for p in new)
        except (struct.error, OverflowError):
            raise StoreError(f"dataman: a {self.name} item the storage cannot hold") from None
        if not self.records.write((len(new), counter), body):
            raise SaveError(f"dataman: the {self.name} could not be written to storage; "
                            f"the previous one stays active")
        self.points = new
        self.update_counter = counter
        for fn in self.listeners:
            fn()

    def clear(self) -> None:
        self.replace(())

    def load(self) -> str:
        """The newest valid list saved in the partition; what happened, in words."""
        if self.partition is None:
            return f"no {self.name} storage"
        got = self.records.load()
        note = self.records.note()
        if got is None:
            return f"no {self.name} stored{note}"
        (count, counter), body = got
        size = _ITEM.size
        points = tuple(Point.unpack(body[i * size:(i + 1) * size]) for i in range(count))
        if self.validate is not None and self.validate(points) is not None:
            return f"{self.name} stored is not valid, ignored{note}"
        self.points, self.update_counter = points, counter
        return f"{self.name} of {count} items loaded{note}"
