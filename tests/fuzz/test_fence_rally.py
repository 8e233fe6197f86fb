"""Fuzz targets for fence and rally uploads (issue 21): random and mutated item lists, to
dataman's stores alone and through a booted FMU's MAVLink link. Whatever comes in, nothing
raises, every upload ends with one MISSION_ACK, and the stored fence is always the previous
one or the new one, valid."""

from __future__ import annotations

import math
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st
from pymavlink.dialects.v20 import common as mav

from firmware.modules.dataman import FENCE_MAX_ITEMS, _region
from firmware.modules.dataman.points import FENCE_CMDS, Point, PointStore, fence_problem
from firmware.modules.dataman.store import SaveError, StoreError
from firmware.platform.params import MemoryPartition
from tests.fuzzing import fuzz
from tests.mavlink.conftest import open_session
from tests.mavlink.test_mavlink_fence_rally import PLAN_FENCE, PLAN_RALLY, download, fields

LAT0, LON0 = 473_977_419, 85_455_938
_CMDS = st.sampled_from(sorted(FENCE_CMDS) + [5100, 16, 0, 65535])
_NEAR = st.integers(-30_000, 30_000)
_P1 = st.one_of(st.sampled_from([3.0, 4.0, 5.0, 2.0, 0.0, -1.0, 3.4, 4.6, 25.0, 70000.0,
                                 math.nan, math.inf, -math.inf, 15.0]),
                st.floats(width=32))
_FRAMES = st.sampled_from([mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, mav.MAV_FRAME_GLOBAL_INT,
                           mav.MAV_FRAME_GLOBAL, mav.MAV_FRAME_GLOBAL_RELATIVE_ALT,
                           mav.MAV_FRAME_MISSION, mav.MAV_FRAME_LOCAL_NED])


def _point() -> Any:
    return st.builds(lambda cmd, a, b, n, r: Point(cmd, LAT0 + a, LON0 + b, 0.0, True, n, r),
                     _CMDS, _NEAR, _NEAR, st.integers(0, 8),
                     st.floats(allow_nan=True, allow_infinity=True, width=32))


@fuzz(examples=300)
@given(first=st.lists(_point(), max_size=12), second=st.lists(_point(), max_size=30))
def test_a_fence_store_holds_the_previous_or_a_valid_new_fence(first: list, second: list
                                                                ) -> None:
    """Invariant: PointStore.replace stores a list fence_problem accepts or raises its
    documented error and keeps the previous one, in memory and after a reload. (Lists are
    compared by repr: a field no command reads, a return point's radius, may be NaN, which
    the store keeps as it came but which never equals itself.)"""
    part = MemoryPartition(8192)
    store = PointStore("fence", _region(part, "fence"), b"DMF1", FENCE_MAX_ITEMS, fence_problem)
    kept: tuple = ()
    for points in (first, second):
        problem = fence_problem(points)
        try:
            store.replace(points)
        except (StoreError, SaveError):
            assert repr(store.points) == repr(kept)
            continue
        assert problem is None and len(points) <= store.capacity
        kept = tuple(points)
        assert repr(store.points) == repr(kept)
    again = PointStore("fence", _region(part, "fence"), b"DMF1", FENCE_MAX_ITEMS, fence_problem)
    again.load()
    assert repr(again.points) == repr(kept)


@pytest.fixture(scope="module")
def fmu(tmp_path_factory):
    s = open_session(tmp_path_factory.mktemp("fuzz_fence"))
    s.gcs.wait_heartbeat()
    yield s
    s.close()


def _item(seq: int, mtype: int, cmd: int, frame: int, p1: float, x: int, y: int, z: float,
          as_float: bool) -> Any:
    if as_float:
        return mav.MAVLink_mission_item_message(1, 1, seq, frame, cmd, 0, 0, p1, 0, 0, 0,
                                                x / 1e7, y / 1e7, z, mtype)
    return mav.MAVLink_mission_item_int_message(1, 1, seq, frame, cmd, 0, 0, p1, 0, 0, 0,
                                                x, y, z, mtype)


_ITEM = st.tuples(_CMDS, _FRAMES, _P1, _NEAR, _NEAR,
                  st.one_of(st.just(0.0), st.floats(width=32)), st.booleans())


@fuzz(examples=30)
@given(mtype=st.sampled_from([mav.MAV_MISSION_TYPE_FENCE, mav.MAV_MISSION_TYPE_RALLY]),
       items=st.lists(_ITEM, max_size=8),
       from_plan=st.booleans(), count_extra=st.sampled_from([0, 0, 0, -1, 1, 30]))
def test_fence_and_rally_uploads_end_cleanly(fmu: Any, mtype: int, items: list,
                                            from_plan: bool, count_extra: int) -> None:
    """Invariant: a fence or rally upload of random items (or a valid plan with random items
    spliced in, and a MISSION_COUNT that may not match) raises in no handler, ends with a
    MISSION_ACK (or the vehicle's own cancel after its retries), and leaves the stored list
    either as it was or as the upload, which then downloads identical."""
    gcs = fmu.gcs
    inst = fmu.udp_instance()
    errors, since_us = inst.rx_handler_errors, fmu.dmesg_mark()
    dm = fmu.orch.handles["fmu"].endpoint.board.system.modules.get("dataman")
    store = dm.fence if mtype == mav.MAV_MISSION_TYPE_FENCE else dm.rally
    before = store.points
    msgs = [_item(0, mtype, *it) for it in items]
    if from_plan:
        plan = PLAN_FENCE if mtype == mav.MAV_MISSION_TYPE_FENCE else PLAN_RALLY
        msgs = [_item(0, mtype, p.command, p.frame, p.param1, p.x, p.y, p.z, False)
                for p in plan] + msgs[:2]
    for seq, m in enumerate(msgs):
        m.seq = seq
    count = max(0, len(msgs) + count_extra)
    mark = gcs.mark()
    gcs.send(mav.MAVLink_mission_count_message(1, 1, count, mtype))
    cursor = [mark]

    def serve() -> Any:
        for m in gcs.messages(None, cursor[0]):
            if m.get_type() == "MISSION_REQUEST_INT" and m.seq < len(msgs):
                gcs.send(msgs[m.seq])
            elif m.get_type() == "MISSION_ACK":
                return m
        cursor[0] = gcs.mark()
        return None
    ack = gcs.wait_for(serve, 5.0)
    assert ack.mission_type == mtype
    assert fmu.mavlink_errors(since_us) == [] and inst.rx_handler_errors == errors
    after = store.points
    if ack.type == mav.MAV_MISSION_ACCEPTED:
        # A MISSION_COUNT below the items on offer takes the first ``count`` of them.
        assert len(after) == count <= len(msgs)
        if mtype == mav.MAV_MISSION_TYPE_FENCE:
            assert fence_problem(after) is None
        got = [fields(m) for m in download(gcs, mtype)]
        assert [g[2] for g in got] == [int(m.command) for m in msgs[:count]]
    else:
        assert after == before
