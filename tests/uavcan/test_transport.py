"""The shared DroneCAN transport (firmware/lib/uavcan): CAN IDs against the dronecan package's
own, transfers split and reassembled, every kind of bad frame counted and dropped, the TX
queue's order and deadlines. The reference for framing is the ``dronecan`` package itself
(``Transfer.to_frames`` / ``from_frames``), used here independently of our reassembler."""

from __future__ import annotations

import can
import dronecan
import dronecan.transport as dt
import pytest

from board.can import CanBus, CanController
from firmware.lib.uavcan.ids import anonymous_id, message_id, parse_id, service_id
from firmware.lib.uavcan.transfer import Reassembler, TransferIds, decode_single, encode
from firmware.lib.uavcan.txqueue import TxQueue

U = dronecan.uavcan
S = 1_000_000_000


def node_info(name="org.hil.test"):
    r = U.protocol.GetNodeInfo.Response()
    r.name = name
    r.software_version.major = 3
    r.hardware_version.unique_id = list(range(16))
    return r


def test_can_ids_match_the_package_and_parse_back():
    t = dt.Transfer(payload=U.protocol.NodeStatus(), source_node_id=42, transfer_priority=16)
    assert message_id(16, 341, 42) == t.message_id == 0x10015500 | 42
    t = dt.Transfer(payload=U.protocol.GetNodeInfo.Request(), source_node_id=10,
                    dest_node_id=99, service_not_message=True, request_not_response=True,
                    transfer_priority=30)
    assert service_id(30, 1, True, 99, 10) == t.message_id
    c = parse_id(t.message_id)
    assert (c.service, c.request, c.dest, c.source, c.data_type_id, c.priority) == (
        True, True, 99, 10, 1, 30)
    a = parse_id(anonymous_id(31, 1, 0x1234))
    assert a.anonymous and a.discriminator == 0x1234 and a.data_type_id == 1
    with pytest.raises(ValueError, match="source node ID"):
        message_id(16, 341, 0)
    with pytest.raises(ValueError, match="destination"):
        service_id(16, 1, False, 128, 1)


def test_multi_frame_transfer_round_trip_and_the_package_agrees():
    frames = encode(node_info(), 7, 5, dest=9)
    assert len(frames) > 3 and all(len(f.data) == 8 for f in frames[:-1])
    # the package decodes our frames
    ref = dt.Transfer()
    ref.from_frames([dt.Frame(f.arbitration_id, f.data) for f in frames])
    assert ref.payload.name.decode() == "org.hil.test"
    r = Reassembler(node_id=9)
    out = [r.push(f, i * 1000) for i, f in enumerate(frames)]
    assert out[:-1] == [None] * (len(frames) - 1)
    tr = out[-1]
    assert (tr.source, tr.dest, tr.service, tr.request, tr.transfer_id) == (7, 9, True, False, 5)
    assert tr.payload.name.decode() == "org.hil.test" and tr.payload.software_version.major == 3
    assert list(tr.payload.hardware_version.unique_id) == list(range(16))
    assert r.transfers == 1 and r.error_count == 0
    # not addressed to this node: ignored, not an error
    other = Reassembler(node_id=10)
    assert all(other.push(f, 0) is None for f in frames) and other.error_count == 0
    assert other.not_for_us == len(frames)


def test_interleaved_transfers_from_two_sources_both_complete():
    a = encode(node_info("a"), 3, 1, dest=1)
    b = encode(node_info("bb"), 4, 1, dest=1)
    r = Reassembler(node_id=1)
    got = []
    for fa, fb in zip(a, b):
        got += [x for x in (r.push(fa, 0), r.push(fb, 0)) if x is not None]
    got += [x for f in a[len(b):] + b[len(a):] if (x := r.push(f, 0)) is not None]
    assert sorted(t.payload.name.decode() for t in got) == ["a", "bb"]


def _flip(msg, i, mask):
    d = bytearray(msg.data)
    d[i] ^= mask
    return can.Message(arbitration_id=msg.arbitration_id, is_extended_id=True, data=bytes(d))


def test_bad_frames_are_counted_by_cause_and_dropped():
    frames = encode(node_info(), 7, 5, dest=9)
    r = Reassembler(node_id=9)
    # bad CRC: a payload byte of the second frame changed
    for f in [frames[0], _flip(frames[1], 2, 0x10)] + frames[2:]:
        assert r.push(f, 0) is None
    # bad toggle: the second frame's toggle bit flipped
    assert r.push(frames[0], 0) is None
    assert r.push(_flip(frames[1], 7, 0x20), 0) is None
    # a continuation whose transfer was just dropped: no start seen
    assert r.push(frames[2], 0) is None
    # wrong length: a middle frame cut short
    short = can.Message(arbitration_id=frames[1].arbitration_id, is_extended_id=True,
                        data=bytes(frames[1].data[:4]) + bytes(frames[1].data[-1:]))
    r.push(frames[0], 0)
    assert r.push(short, 0) is None
    # unknown data type, an empty frame, a standard-ID frame, a single frame with toggle set
    assert r.push(can.Message(arbitration_id=message_id(16, 60000, 3), data=b"\xc0"), 0) is None
    assert r.push(can.Message(arbitration_id=message_id(16, 341, 3), data=b""), 0) is None
    assert r.push(can.Message(arbitration_id=0x123, is_extended_id=False, data=b"\xc0"), 0) \
        is None
    st = encode(U.protocol.NodeStatus(uptime_sec=9), 3, 0)[0]
    assert r.push(_flip(st, 7, 0x20), 0) is None
    # a NodeStatus too short for its fields
    assert r.push(can.Message(arbitration_id=st.arbitration_id, data=b"\x01\x02\xc1"), 0) is None
    e = r.errors
    assert (e["bad_crc"], e["bad_toggle"], e["missed_start"], e["unknown_type"],
            e["bad_payload"]) == (1, 2, 1, 1, 1)
    assert e["bad_length"] == 3 and r.transfers == 0
    # and a good one still gets through afterwards
    assert r.push(st, 0).payload.uptime_sec == 9


def test_unfinished_transfer_times_out_after_two_seconds():
    frames = encode(node_info(), 7, 5, dest=9)
    r = Reassembler(node_id=9)
    r.push(frames[0], 0)
    assert r.push(frames[1], 2 * S + 1) is None
    assert r.errors["timeouts"] == 1 and r.errors["missed_start"] == 1


def test_anonymous_allocation_request_round_trip():
    a = U.protocol.dynamic_node_id.Allocation(node_id=0, first_part_of_unique_id=True,
                                              unique_id=list(b"\x01\x02\x03\x04\x05\x06"))
    (f,) = encode(a, 0, 3, priority=31)
    c = parse_id(f.arbitration_id)
    assert c.anonymous and c.priority == 31
    tr = decode_single(f)
    assert tr.source == 0 and bytes(tr.payload.unique_id) == b"\x01\x02\x03\x04\x05\x06"
    assert tr.payload.first_part_of_unique_id
    with pytest.raises(ValueError, match="anonymous"):
        encode(U.protocol.dynamic_node_id.Allocation(unique_id=list(range(16))), 0, 0)


def test_transfer_ids_count_per_type_and_destination():
    t = TransferIds()
    assert [t.next(341) for _ in range(3)] == [0, 1, 2]
    assert t.next(1, True, 5) == 0 and t.next(1, True, 6) == 0 and t.next(1, True, 5) == 1
    for _ in range(29):
        t.next(341)
    assert t.next(341) == 0  # modulo 32


def test_tx_queue_keeps_frame_order_and_drops_late_transfers(kernel):
    bus = CanBus(kernel, "can1")
    a, b = CanController(bus, "a"), CanController(bus, "b", rx_fifo_depth=64)
    q = TxQueue(a)
    a.on_tx_complete(lambda t, m, ok: q.tx_done(m, ok))
    frames = encode(node_info(), 7, 5, dest=9)
    st = encode(U.protocol.NodeStatus(), 7, 0)
    q.push(frames, S, 0)
    q.push(st, S, 0)  # a higher-priority ID queued behind: still after the transfer
    kernel.run(10_000_000)
    got = []
    while (m := b.recv()) is not None:
        got.append(bytes(m.data))
    assert got == [bytes(f.data) for f in frames + st]
    assert q.transfers_tx == 2 and q.frames_tx == len(frames) + 1
    # alone on the bus: nobody ACKs, the deadline passes, the transfer is dropped
    b.disable()
    q.push(st, 20_000_000, kernel.now_ns)
    kernel.run(30_000_000)
    q.expire(kernel.now_ns)
    assert q.tx_timeouts == 1 and len(q) == 0 and a.tx_pending == 0
