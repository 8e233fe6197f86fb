"""The bridge's frame format and stream decoder: good frames through, bad ones counted by
cause, resynchronisation after garbage; a fuzz target for the decoder."""

from __future__ import annotations

import random

from hypothesis import given
from hypothesis import strategies as st

from firmware.modules.uorb_bridge.protocol import (
    CRC_NAME,
    HEADER_SIZE,
    HEARTBEAT_ID,
    MAX_PAYLOAD,
    OVERHEAD,
    FrameDecoder,
    Heartbeat,
    crc16,
    encode_frame,
)
from tests.fuzzing import fuzz

A, B = 0x1234ABCD, 0x0BADF00D
SIZES = {A: 8, B: 3}


def frame_a(seq: int, fill: int = 1) -> bytes:
    return encode_frame(A, 0, seq, bytes([fill]) * 8)


def test_crc_is_ccitt_false():
    # the catalogue's check value of CRC-16/CCITT-FALSE
    assert CRC_NAME == "CRC-16/CCITT-FALSE" and crc16(b"123456789") == 0x29B1


def test_frame_layout():
    f = encode_frame(A, 2, 300, b"xyz")
    assert len(f) == OVERHEAD + 3 and f[:2] == b"\xb7\x1d"
    assert int.from_bytes(f[2:4], "little") == 3
    assert int.from_bytes(f[4:8], "little") == A
    assert f[8] == 2 and f[9] == 300 & 0xFF
    assert f[HEADER_SIZE:-2] == b"xyz"
    assert int.from_bytes(f[-2:], "little") == crc16(f[2:-2])


def test_good_frames_in_any_chunks():
    stream = b"".join(frame_a(i, i) for i in range(20))
    rng = random.Random(3)
    for _ in range(20):
        dec = FrameDecoder(SIZES)
        out = []
        pos = 0
        while pos < len(stream):
            n = rng.randint(1, 40)
            out += dec.feed(stream[pos:pos + n])
            pos += n
        assert [f.payload for f in out] == [bytes([i]) * 8 for i in range(20)]
        assert [f.seq for f in out] == list(range(20))
        assert dec.drops.frames == 0 and dec.drops.garbage_bytes == 0 and dec.pending == 0


def test_resync_after_garbage():
    dec = FrameDecoder(SIZES)
    garbage = bytes(random.Random(1).randrange(256) for _ in range(500)).replace(b"\xb7", b"")
    out = dec.feed(garbage + frame_a(0) + b"\xb7\x1d\xff" + frame_a(1))
    assert [f.seq for f in out] == [0, 1]
    assert dec.drops.garbage_bytes >= len(garbage)


def test_corrupt_frame_dropped_and_counted_as_crc():
    dec = FrameDecoder(SIZES)
    bad = bytearray(frame_a(1))
    bad[HEADER_SIZE + 3] ^= 0x10                     # one bit in the payload
    out = dec.feed(frame_a(0) + bytes(bad) + frame_a(2))
    assert [f.seq for f in out] == [0, 2]
    assert dec.drops.crc == 1 and dec.drops.truncated == 0
    assert dec.drops.lost == 1                        # seq 1 never arrived whole


def test_truncated_frame_dropped_and_counted():
    dec = FrameDecoder(SIZES)
    cut = frame_a(1)[:HEADER_SIZE + 3]                # the sender stopped mid-frame
    out = dec.feed(frame_a(0) + cut + frame_a(2) + frame_a(3))
    assert [f.seq for f in out] == [0, 2, 3]
    assert dec.drops.truncated == 1 and dec.drops.crc == 0


def test_cut_frame_does_not_hold_back_the_next_one():
    dec = FrameDecoder(SIZES)
    long_cut = encode_frame(B, 0, 0, b"x" * 40)[:HEADER_SIZE + 2]   # claims 52 bytes
    out = dec.feed(long_cut + frame_a(1))                              # 32 bytes in all
    assert [f.seq for f in out] == [1] and dec.drops.truncated == 1 and dec.pending == 0


def test_truncated_frame_at_the_end_counted_on_flush():
    dec = FrameDecoder(SIZES)
    assert dec.feed(frame_a(0) + frame_a(1)[:7]) and dec.pending == 7
    dec.flush()
    assert dec.drops.truncated == 1 and dec.pending == 0


def test_unknown_id_and_wrong_size_dropped_and_counted():
    dec = FrameDecoder(SIZES)
    out = dec.feed(encode_frame(0x77777777, 0, 0, b"\0" * 8)    # another definition
                   + encode_frame(B, 0, 1, b"\0" * 4)            # B is 3 bytes here
                   + encode_frame(B, 0, 2, b"abc"))
    assert [(f.topic_id, f.payload) for f in out] == [(B, b"abc")]
    assert dec.drops.unknown_id == 1 and dec.drops.bad_size == 1 and dec.drops.crc == 0


def test_heartbeat_is_always_known():
    hb = Heartbeat(123456789, 5, 6, 7, 8)
    (f,) = FrameDecoder({}).feed(encode_frame(HEARTBEAT_ID, 0, 0, hb.pack()))
    back = Heartbeat.unpack(f.payload)
    assert (back.uptime_us, back.tx_frames, back.rx_frames, back.rx_dropped,
            back.tx_dropped) == (123456789, 5, 6, 7, 8)


def test_length_beyond_max_is_garbage_not_a_wait():
    dec = FrameDecoder(SIZES)
    fake = b"\xb7\x1d" + (MAX_PAYLOAD + 1).to_bytes(2, "little") + b"\0" * 6
    out = dec.feed(fake + frame_a(0))
    assert [f.seq for f in out] == [0] and dec.drops.frames == 0


@fuzz(examples=300)
@given(chunks=st.lists(st.one_of(
    st.binary(max_size=60),                                           # noise
    st.builds(lambda s, p: encode_frame(A, 0, s, p), st.integers(0, 255),
              st.binary(min_size=8, max_size=8)),                     # good frames
    st.builds(lambda s, p, cut: encode_frame(B, 1, s, p)[:cut], st.integers(0, 255),
              st.binary(max_size=20), st.integers(0, 40)),            # cut / wrong size
), max_size=30), split=st.integers(1, 64))
def test_fuzz_decoder(chunks, split):
    """Any byte stream, fed in any chunking: no exception, only frames of known ids and sizes
    come out, every byte is accounted for, and the same stream in one piece gives the same
    frames."""
    stream = b"".join(chunks)
    dec = FrameDecoder(SIZES)
    out = []
    for i in range(0, len(stream), split):
        out += dec.feed(stream[i:i + split])
    for f in out:
        assert SIZES[f.topic_id] == len(f.payload)
    assert dec.pending <= MAX_PAYLOAD + OVERHEAD
    whole = FrameDecoder(SIZES)
    assert [(f.topic_id, f.seq, f.payload) for f in whole.feed(stream)] == \
        [(f.topic_id, f.seq, f.payload) for f in out]
    dec.flush()
    assert dec.pending == 0
    # every good frame that was sent whole and not overlapped comes out
    for c in chunks:
        if len(c) == OVERHEAD + 8 and c[:4] == b"\xb7\x1d\x08\x00" \
                and c[4:8] == A.to_bytes(4, "little") and crc16(c[2:-2]) == c[-2] | c[-1] << 8:
            assert any(f.payload == c[HEADER_SIZE:-2] for f in out)
