"""Fuzzing the DroneCAN reassembler (what the FMU and every node model run on frames from the
bus) with random frames and with valid transfers cut, reordered, duplicated or bit-flipped."""

from __future__ import annotations

import can
import dronecan
from hypothesis import given
from hypothesis import strategies as st

from firmware.lib.uavcan.ids import message_id, service_id
from firmware.lib.uavcan.transfer import Reassembler, encode
from tests.fuzzing import fuzz

U = dronecan.uavcan


def _transfer(kind: int, src: int, tid: int) -> list[can.Message]:
    if kind == 0:
        r = U.protocol.GetNodeInfo.Response()
        r.name = "org.hil.fuzz"
        return encode(r, src, tid, dest=1)
    if kind == 1:
        f = U.equipment.gnss.Fix2(latitude_deg_1e8=4739774290, sats_used=12, status=3)
        f.covariance = [1.0] * 6
        return encode(f, src, tid)
    return encode(U.protocol.NodeStatus(uptime_sec=tid), src, tid)


@st.composite
def random_frame(draw: st.DrawFn) -> can.Message:
    aid = draw(st.integers(0, 0x1FFFFFFF) | st.sampled_from(
        [message_id(16, 341, 5), message_id(16, 1063, 5), service_id(16, 1, False, 1, 5),
         service_id(16, 1, True, 1, 5), 0x1E000100]))
    return can.Message(arbitration_id=aid, is_extended_id=draw(st.integers(0, 9)) > 0,
                       data=draw(st.binary(max_size=8)))


@st.composite
def mutated_transfer(draw: st.DrawFn) -> list[can.Message]:
    frames = _transfer(draw(st.integers(0, 2)), draw(st.integers(1, 3)), draw(st.integers(0, 31)))
    op = draw(st.sampled_from(["none", "flip", "drop", "dup", "swap", "cut"]))
    i = draw(st.integers(0, len(frames) - 1))
    if op == "flip":
        d = bytearray(frames[i].data)
        d[draw(st.integers(0, len(d) - 1))] ^= 1 << draw(st.integers(0, 7))
        frames[i] = can.Message(arbitration_id=frames[i].arbitration_id, data=bytes(d))
    elif op == "drop":
        del frames[i]
    elif op == "dup":
        frames.insert(i, frames[i])
    elif op == "swap" and i + 1 < len(frames):
        frames[i], frames[i + 1] = frames[i + 1], frames[i]
    elif op == "cut":
        frames[i] = can.Message(arbitration_id=frames[i].arbitration_id,
                                data=bytes(frames[i].data[:draw(st.integers(0, 7))]))
    return frames


@fuzz(examples=150)
@given(st.lists(st.tuples(random_frame().map(lambda f: [f]) | mutated_transfer(),
                          st.integers(0, 3_000_000_000)), max_size=12))
def test_reassembler_counts_and_drops_bad_input_without_raising(traffic) -> None:
    """Invariant: whatever frames arrive, in whatever order and timing, push() returns None or
    a decoded transfer from a node 0..127, never raises; every frame is accounted for at most
    once (a transfer, a counted drop, or not addressed to us; unfinished transfers given up are
    counted apart); and after the noise a clean
    transfer still decodes to what was sent."""
    r = Reassembler(node_id=1)
    t_ns = 0
    pushed = 0
    for frames, gap in traffic:
        t_ns += gap
        for f in frames:
            pushed += 1
            tr = r.push(f, t_ns)
            if tr is not None:
                assert 0 <= tr.source <= 127 and tr.payload is not None
    assert r.frames == pushed
    e = r.errors
    abandoned = e["timeouts"] + e["evicted"]  # transfers given up, not frames
    assert r.transfers + r.error_count - abandoned + r.not_for_us <= pushed
    clean = _transfer(0, 9, 7)
    out = [r.push(f, t_ns + 3_000_000_000) for f in clean]
    assert out[-1] is not None and out[-1].payload.name.decode() == "org.hil.fuzz"
