"""SUMD and ST24 decoders: CRCs, layouts, scaling, re-ordering, error counting."""

from __future__ import annotations

import pytest

from ioproc.rc.common import crc8_07, crc16_xmodem
from ioproc.rc.st24 import ST24_TO_US, ST24_TO_US_E14, St24Decoder, encode_st24_frame
from ioproc.rc.sumd import SumdDecoder, encode_sumd_frame


def test_crc_check_values() -> None:
    assert crc16_xmodem(b"123456789") == 0x31C3
    assert crc8_07(b"123456789") == 0xF4


def test_sumd_round_trip_and_reorder() -> None:
    us = [1100, 1200, 1300, 1400, 1500, 1600, 1700, 1800]
    d = SumdDecoder()
    assert d.feed(0, encode_sumd_frame(us))
    assert d.channels == [1200, 1300, 1100, 1400, 1500, 1600, 1700, 1800]
    assert d.raw_channels[0] == 1200 * 8
    assert d.channel_count == 8 and not d.failsafe and d.rssi == 100


def test_sumd_failsafe_status() -> None:
    d = SumdDecoder()
    assert d.feed(0, encode_sumd_frame([1500] * 8, failsafe=True))
    assert d.failsafe and d.status == 0x81


def test_sumd_bad_crc_counted_and_next_frame_ok() -> None:
    frame = bytearray(encode_sumd_frame([1500] * 8))
    frame[5] ^= 0x10
    d = SumdDecoder()
    assert not d.feed(0, bytes(frame))
    assert d.bad_crc == 1 and d.frames == 0
    assert d.feed(10_000, encode_sumd_frame([1500] * 8))


def test_sumd_bad_status_and_count() -> None:
    d = SumdDecoder()
    d.feed(0, bytes((0xA8, 0x55)))
    d.feed(0, bytes((0xA8, 0x01, 40)))
    d.feed(0, bytes((0xA8, 0x01, 1)))
    assert d.frame_errors == 3 and d.frames == 0
    # A header where a status was expected restarts the frame instead of losing it.
    assert d.feed(0, b"\xa8" + encode_sumd_frame([1500] * 4))


def test_sumh_checksum() -> None:
    words = [1500 * 8] * 4
    body = bytearray((0xA8, 0x00, 4))
    for w in words:
        body += bytes((w >> 8, w & 0xFF))
    frame = bytes(body) + bytes((0, 0, 0x42, sum(body) & 0xFF))
    d = SumdDecoder()
    assert d.feed(0, frame) and d.channels == [1500] * 4
    assert not d.feed(0, frame[:-1] + bytes(((frame[-1] + 1) & 0xFF,)))
    assert d.bad_crc == 1


@pytest.mark.parametrize("raw,us", [(500, 999), (2000, 1499), (3500, 1999), (0, 832), (4095, 2197)])
def test_st24_scaling(raw: int, us: int) -> None:
    assert ST24_TO_US[raw] == us


def test_st24_e14_scaling() -> None:
    assert ST24_TO_US_E14[0] == 999 and ST24_TO_US_E14[2048] == 1499
    d = St24Decoder(scaling="e14")
    d.feed(0, encode_st24_frame([2048] * 12))
    assert d.channels == [1499] * 12


@pytest.mark.parametrize("n", [12, 24])
def test_st24_round_trip(n: int) -> None:
    raw = [500 + 97 * i for i in range(n)]
    d = St24Decoder()
    assert d.feed(0, encode_st24_frame(raw, rssi=204, lost=2, counter=0x1234))
    assert d.raw_channels == raw and d.channel_count == n
    assert d.channels == [ST24_TO_US[v] for v in raw]
    assert d.rssi == 80 and d.lost_count == 2 and d.counter == 0x1234


def test_st24_bad_crc_gps_and_unknown_types() -> None:
    frame = bytearray(encode_st24_frame([2000] * 12))
    frame[10] ^= 1
    d = St24Decoder()
    assert not d.feed(0, bytes(frame))
    assert d.bad_crc == 1
    body = bytes((3, 2, 0))
    assert not d.feed(0, b"\x55\x55" + body + bytes((crc8_07(body),)))
    body = bytes((3, 7, 0))
    assert not d.feed(0, b"\x55\x55" + body + bytes((crc8_07(body),)))
    assert d.gps_packets == 1 and d.unknown_packets == 1 and d.frames == 0
    body = bytes((3, 0, 0))  # channel packet too short for its type
    assert not d.feed(0, b"\x55\x55" + body + bytes((crc8_07(body),)))
    assert d.frame_errors == 1
    d.feed(0, bytes((0x55, 0x55, 67)))
    assert d.frame_errors == 2
    assert d.feed(0, encode_st24_frame([2000] * 12))


def test_bad_st24_scaling_name() -> None:
    with pytest.raises(ValueError):
        St24Decoder(scaling="x")
