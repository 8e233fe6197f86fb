"""S.BUS decoder: packing, PX4 scaling, flags, end bytes, gap framing."""

from __future__ import annotations

import pytest

from ioproc.rc.sbus import (
    SBUS_GAP_US_2022,
    SbusDecoder,
    encode_sbus_frame,
    sbus_raw_to_us,
    sbus_raw_to_us_ardupilot,
    sbus_us_to_raw,
)

FRAME_US = 14_000
BYTE_US = 120

# Reference §10.2, computed frames.
ALL_1024 = bytes.fromhex("0F 00 04 20 00 01 08 40 00 02 10 80 00 04 20 00 01 08 40 00 02 10 80 00 00")
MIXED_FS = bytes.fromhex("0F C8 40 38 00 C1 02 6A 00 FC 1F 7D 00 04 20 00 01 08 40 00 02 10 80 0C 00")


def feed_frame(d: SbusDecoder, frame: bytes, t0: int) -> bool:
    """Byte by byte at the 8E2 character time, as the UART would deliver them."""
    got = False
    for i, b in enumerate(frame):
        got |= d.feed_byte(t0 + i * BYTE_US, b)
    return got


def test_reference_frame_all_centre() -> None:
    d = SbusDecoder()
    assert feed_frame(d, ALL_1024, 0)
    assert d.channels == [1514] * 16 + [998, 998]
    assert d.channel_count == 18
    assert not d.failsafe and not d.frame_lost and d.rssi == 100


def test_reference_frame_values_and_failsafe() -> None:
    d = SbusDecoder()
    assert feed_frame(d, MIXED_FS, 0)
    assert d.channels[:8] == [999, 1999, 1514, 1094, 1934, 874, 2153, 1499]
    assert d.raw_channels[:8] == [200, 1800, 1024, 352, 1696, 0, 2047, 1000]
    assert d.failsafe and d.frame_lost and d.frame_drop
    assert d.lost_frames == 1 and d.rssi == 50


def test_encoder_matches_reference_bytes() -> None:
    assert encode_sbus_frame([1024] * 16) == ALL_1024
    raw = [200, 1800, 1024, 352, 1696, 0, 2047, 1000] + [1024] * 8
    assert encode_sbus_frame(raw, frame_lost=True, failsafe=True) == MIXED_FS


@pytest.mark.parametrize("raw,px4,ap", [
    (0, 874, 875), (172, 982, 982), (192, 994, 995), (200, 999, 1000), (352, 1094, 1095),
    (992, 1494, 1495), (1000, 1499, 1500), (1024, 1514, 1515), (1500, 1812, 1812),
    (1696, 1934, 1935), (1792, 1994, 1995), (1800, 1999, 2000), (1811, 2006, 2006),
    (2047, 2153, 2154),
])
def test_scaling_table(raw: int, px4: int, ap: int) -> None:
    assert sbus_raw_to_us(raw) == px4
    assert sbus_raw_to_us_ardupilot(raw) == ap


def test_every_raw_value_round_trips() -> None:
    d = SbusDecoder()
    for k in range(0, 2048, 16):
        raw = [(k + i) % 2048 for i in range(16)]
        assert feed_frame(d, encode_sbus_frame(raw), k * FRAME_US)
        assert d.raw_channels[:16] == raw
        assert d.channels[:16] == [sbus_raw_to_us(r) for r in raw]
    assert sbus_us_to_raw(sbus_raw_to_us(1000)) == 1000


def test_digital_channels_and_frame_lost_only() -> None:
    d = SbusDecoder()
    feed_frame(d, encode_sbus_frame([1024] * 16, ch17=True, ch18=True, frame_lost=True), 0)
    assert d.channels[16:] == [1998, 1998]
    assert d.frame_lost and not d.failsafe and d.rssi == 50
    d2 = SbusDecoder(e14_ch18_bug=True)
    feed_frame(d2, encode_sbus_frame([1024] * 16, ch18=True), 0)
    assert d2.channels[17] == 2998
    d3 = SbusDecoder(max_channels=16)
    feed_frame(d3, ALL_1024, 0)
    assert d3.channel_count == 16


@pytest.mark.parametrize("end", [0x00, 0x04, 0x14, 0x24, 0x34])
def test_sbus2_end_bytes_accepted(end: int) -> None:
    d = SbusDecoder()
    assert feed_frame(d, encode_sbus_frame([1024] * 16, end=end), 0)
    assert d.end_byte == end


def test_unknown_end_byte_rejected_unless_e14() -> None:
    frame = encode_sbus_frame([1024] * 16, end=0x43)
    d = SbusDecoder()
    assert not feed_frame(d, frame, 0)
    assert d.frames == 0 and d.bad_end_bytes == 1 and d.frame_errors == 1
    assert feed_frame(d, ALL_1024, FRAME_US)  # resynchronises on the next header
    e14 = SbusDecoder(check_end_byte=False)
    assert feed_frame(e14, frame, 0)


def test_telemetry_slots_between_frames_are_skipped() -> None:
    d = SbusDecoder()
    t = 0
    for k in range(6):
        feed_frame(d, encode_sbus_frame([1024] * 16, end=0x04), t)
        slot = bytes((0x03, 0xC4, 0x00))
        d.feed(t + 5000, slot)
        t += FRAME_US
    assert d.frames == 6 and d.frame_errors == 0


def test_gap_discards_partial_frame() -> None:
    d = SbusDecoder()
    frame = encode_sbus_frame([500] * 16)
    d.feed(0, frame[:10])
    assert feed_frame(d, ALL_1024, 3001)  # > 3 ms later: the partial is dropped
    assert d.partial_frames == 1 and d.channels[0] == 1514


def test_gap_parameter_by_era() -> None:
    frame = encode_sbus_frame([1024] * 16)
    for gap_us, ok in ((3000, False), (SBUS_GAP_US_2022, True)):
        d = SbusDecoder(gap_us=gap_us)
        d.feed(0, frame[:12])
        assert d.feed(3500, frame[12:]) is ok


def test_chunked_feed_equals_bytewise() -> None:
    frames = [encode_sbus_frame([(i * 97 + k) % 2048 for i in range(16)]) for k in range(5)]
    a, b = SbusDecoder(), SbusDecoder()
    for k, f in enumerate(frames):
        feed_frame(a, f, k * FRAME_US)
        b.feed(k * FRAME_US, f[:7])
        b.feed(k * FRAME_US + 1000, f[7:])
        assert a.channels == b.channels
    assert a.frames == b.frames == 5


def test_offset_recovery_option() -> None:
    """A truncated frame followed directly by a good one: only offset recovery keeps it."""
    good = encode_sbus_frame([700] * 16)
    stream = ALL_1024[:15] + good
    plain, rec = SbusDecoder(), SbusDecoder(offset_recovery=True)
    plain.feed(0, stream)
    rec.feed(0, stream)
    assert plain.frames == 0
    assert rec.frames == 1 and rec.raw_channels[0] == 700
