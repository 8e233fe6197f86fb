"""Fuzzing the CAN wire and the UAVCAN node's receive decoding with random frames."""

from __future__ import annotations

import can
from hypothesis import given
from hypothesis import strategies as st

from board.can import CanBus, CanController
from board.kernel import Kernel
from firmware.drivers.uavcan.node import parse_node_status
from tests.fuzzing import fuzz


@st.composite
def frames(draw: st.DrawFn) -> can.Message:
    ext = draw(st.booleans())
    rtr = draw(st.integers(0, 5)) == 0
    aid = draw(st.integers(0, 0x1FFFFFFF if ext else 0x7FF) | st.sampled_from(
        [0x1015507D, 0x1015507E, 0x10155001]))  # NodeStatus from nodes 125, 126, 1
    aid &= 0x1FFFFFFF if ext else 0x7FF
    data = b"" if rtr else draw(st.binary(max_size=8) | st.builds(
        lambda up, h, tail: up.to_bytes(4, "little") + bytes((h << 6, 0, 0, tail)),
        st.integers(0, 2 ** 32 - 1), st.integers(0, 3), st.integers(0, 255)))
    dlc = draw(st.integers(0, 8)) if rtr else len(data)
    return can.Message(arbitration_id=aid, data=data, is_extended_id=ext, is_remote_frame=rtr,
                       dlc=dlc)


@fuzz(examples=120)
@given(st.lists(st.tuples(frames(), st.integers(0, 300_000), st.integers(0, 3)), max_size=30))
def test_random_frames_are_carried_and_decoded_without_raising(traffic) -> None:
    """Invariant: any classic CAN frames (ids, DLC 0..8, data, remote frames), sent at random
    times with injected bit errors, are delivered or lost by the bus model without raising,
    the bus keeps running to the end, and the UAVCAN node's NodeStatus decoding of whatever
    arrives returns None or (node 0..127, uptime uint32, health 0..3)."""
    k = Kernel("fmu")
    bus = CanBus(k, "can1")
    tx, rx = CanController(bus, "tx"), CanController(bus, "rx", rx_fifo_depth=64)
    t_ns = 0
    for msg, gap_ns, errors in traffic:
        t_ns += gap_ns
        k.run(t_ns)
        if errors:
            bus.inject_errors(errors)
        tx.send(msg)
    k.run(t_ns + 50_000_000)
    assert k.now_ns == t_ns + 50_000_000
    while (m := rx.recv()) is not None:
        assert 0 <= m.dlc <= 8 and len(m.data) <= 8
        st_ = parse_node_status(m)
        if st_ is not None:
            node, uptime_s, health = st_
            assert 0 <= node <= 127 and 0 <= uptime_s < 2 ** 32 and 0 <= health <= 3
