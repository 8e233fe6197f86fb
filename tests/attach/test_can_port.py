"""The host's adapter node on an emulated CAN bus (fmu/can_port.py) and the TCP record format
(hil/can_interface_wire.py): what a tool's frames do on the wire, and bad input from outside."""

from __future__ import annotations

import can
from hypothesis import given
from hypothesis import strategies as st

from board.board import Board
from board.can import CanBus, CanController, frame_length_bits
from fmu.can_port import TX_QUEUE_MAX, CanHostPort
from hil.can_interface_wire import KIND_FRAME, RECORD, WireFrame, decode, encode
from tests.fuzzing import fuzz

MS = 1_000_000


def _rig() -> tuple[Board, CanBus, CanController, CanHostPort]:
    board = Board("fmu")
    bus = CanBus(board.kernel, "CAN1")
    fmu = CanController(bus, "fmu.CAN1")
    return board, bus, fmu, CanHostPort(board, bus, "can1")


def _outputs(board: Board, until_ns: int, inputs: list | None = None) -> list:
    return board.advance(until_ns, inputs or [])


def test_adapter_is_off_the_bus_until_a_tool_attaches():
    board, bus, fmu, port = _rig()
    fmu.send(can.Message(arbitration_id=0x123, is_extended_id=False, data=b"\x01"))
    out = _outputs(board, 2 * MS)
    assert out == [] and fmu.tx_errors > 0, "nobody should ACK: the adapter is not attached"
    assert ("can1", "can", "inout") in board.ctl_ports()
    out = _outputs(board, 3 * MS, [("can1_host", 2 * MS, True)])
    assert fmu.tx_frames == 1
    (rec,) = out
    assert rec[0] == "can1" and rec[2] == (0x123, False, False, b"\x01", 0)
    assert port.received == 1


def test_tool_frames_are_sent_in_order_acked_and_confirmed_at_their_wire_time():
    board, bus, fmu, port = _rig()
    frames = [(0x300, False, False, b"\xAA" * 8, 7), (0x100, False, False, b"", 7),
              (0x1ABCDE, True, True, bytes(2), 7)]
    out = _outputs(board, 5 * MS, [("can1_host", 0, True)] +
                   [("can1", 1 * MS, f) for f in frames])
    got = []
    while (m := fmu.recv()) is not None:
        got.append(m)
    # FIFO like SocketCAN/slcan adapters: 0x300 first although 0x100 would win arbitration
    assert [m.arbitration_id for m in got] == [0x300, 0x100, 0x1ABCDE]
    assert got[2].is_remote_frame and got[2].dlc == 2 and got[2].is_extended_id
    assert [r[2] for r in out] == frames
    first = can.Message(arbitration_id=0x300, is_extended_id=False, data=b"\xAA" * 8)
    assert out[0][1] == 1 * MS + frame_length_bits(first) * 1000  # 1 Mbit/s: 1 us a bit
    assert port.sent == 3 and fmu.tx_errors == 0


def test_bad_records_from_the_host_are_counted_and_dropped():
    board, bus, fmu, port = _rig()
    bad = [(0x800, False, False, b"", 1),        # 11-bit id out of range
           (0x1, False, False, b"123456789", 1),  # 9 data bytes
           ("x", False, False, b"", 1), (1, 2), None]
    _outputs(board, 2 * MS, [("can1_host", 0, True)] + [("can1", MS, p) for p in bad])
    assert port.rejected == len(bad) and port.sent == 0 and fmu.rx_frames == 0
    flood = [("can1", 3 * MS, (0x10, False, False, b"\0", 1))] * (TX_QUEUE_MAX + 10)
    _outputs(board, 3 * MS, flood)
    assert port.dropped >= 9


def test_wire_records_round_trip():
    f = WireFrame(KIND_FRAME, 0x1FFFFFFF, True, False, b"\x01\x02\x03", 12.5)
    buf = bytearray(encode(f) + encode(f)[:10])
    frames, bad = decode(buf)
    assert frames == [f] and bad == 0 and len(buf) == 10  # the partial record waits


@fuzz(examples=300)
@given(st.binary(max_size=RECORD.size * 6))
def test_fuzz_wire_decode_never_raises_and_returns_only_valid_frames(data):
    buf = bytearray(data)
    frames, bad = decode(buf)
    assert len(frames) + bad == len(data) // RECORD.size
    assert len(buf) == len(data) % RECORD.size
    for f in frames:
        assert len(f.data) <= 8
        assert f.arbitration_id <= (0x1FFFFFFF if f.is_extended else 0x7FF)


@fuzz(examples=200)
@given(st.lists(st.one_of(
    st.tuples(st.integers(-5, 1 << 30), st.booleans(), st.booleans(), st.binary(max_size=10),
              st.integers(0, 5)),
    st.none(), st.integers(), st.tuples(st.text(max_size=3))), max_size=8))
def test_fuzz_host_records_never_crash_the_adapter(payloads):
    board, bus, fmu, port = _rig()
    _outputs(board, 3 * MS, [("can1_host", 0, True)] + [("can1", MS, p) for p in payloads])
    assert port.sent + port.rejected + port.dropped + len(port._queue) + \
        (port._in_mailbox is not None) == len(payloads)
