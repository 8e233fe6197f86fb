"""DSM decoder: word decoding, scaling, resolution guess, channel merging, drops, RSSI."""

from __future__ import annotations

import pytest

from ioproc.rc.dsm import (
    DSM10_TO_US,
    DSM10_TO_US_E14,
    DSM11_TO_US,
    DSM11_TO_US_E14,
    DsmDecoder,
    decode_word10,
    decode_word11,
    dsm_rssi_percent,
    dsm_word,
    encode_dsm_frame,
)

BYTE_US = 87

# Reference §10.3, computed frames.
FRAME11 = bytes.fromhex("00 B2 01 56 0C 00 14 00 1C 00 21 56 2E AA 34 00")
FRAME10 = bytes.fromhex("00 01 00 AB 06 00 0A 00 0E 00 10 AB 17 55 1A 00")


def feed_frames(d: DsmDecoder, frames: list[bytes], period_us: int, t0: int = 0,
                repeat: int = 1) -> list[tuple[int, list[int]]]:
    """Frames back to back with ``period_us`` between starts; returns (frame index, output)."""
    out = []
    k = 0
    for _ in range(repeat):
        for f in frames:
            t = t0 + k * period_us
            for i, b in enumerate(f):
                if d.feed_byte(t + i * BYTE_US, b):
                    out.append((k, list(d.channels)))
            k += 1
    return out


def test_encoder_matches_reference() -> None:
    pairs = [(0, 342), (1, 1024), (2, 1024), (3, 1024), (4, 342), (5, 1706), (6, 1024)]
    assert encode_dsm_frame([dsm_word(c, p) for c, p in pairs], system=0xB2) == FRAME11
    pairs10 = [(0, 171), (1, 512), (2, 512), (3, 512), (4, 171), (5, 853), (6, 512)]
    assert encode_dsm_frame([dsm_word(c, p, bits=10) for c, p in pairs10], system=0x01) == FRAME10


def test_11bit_detection_and_values() -> None:
    d = DsmDecoder()
    out = feed_frames(d, [FRAME11], 11_000, repeat=40)
    assert d.dsm_11bit and d.mode == 11 and d.learned_count == 7
    assert out[-1][1] == [1500, 1500, 1102, 1500, 1102, 1898, 1500]
    # 15 frames to guess, the guess-frame quirk drop, 15 more, then output.
    assert d.frame_errors == 1
    assert out[0][0] == 29


def test_10bit_detection_and_values() -> None:
    d = DsmDecoder()
    out = feed_frames(d, [FRAME10], 22_000, repeat=40)
    assert d.mode == 10 and not d.dsm_11bit
    assert out[-1][1] == [1500, 1500, 1102, 1500, 1102, 1898, 1500]
    e14 = DsmDecoder(scaling="e14")
    feed_frames(e14, [FRAME10], 22_000, repeat=40)
    assert e14.channels == [1500, 1500, 1099, 1500, 1099, 1901, 1500]


def test_without_count_quirk_first_guess_is_used() -> None:
    d = DsmDecoder(px4_count_quirk=False)
    out = feed_frames(d, [FRAME11], 11_000, repeat=20)
    assert d.frame_errors == 0 and out[0][0] == 14


@pytest.mark.parametrize("pos,us2021,use14", [(0, 903, 898), (342, 1102, 1099), (1024, 1500, 1500),
                                              (1706, 1898, 1901), (2047, 2096, 2101)])
def test_scaling_11bit(pos: int, us2021: int, use14: int) -> None:
    assert DSM11_TO_US[pos] == us2021
    assert DSM11_TO_US_E14[pos] == use14


@pytest.mark.parametrize("pos,us2021,use14", [(0, 903, 898), (171, 1102, 1099), (342, 1302, 1300),
                                              (512, 1500, 1500), (853, 1898, 1901),
                                              (1023, 2096, 2101)])
def test_scaling_10bit(pos: int, us2021: int, use14: int) -> None:
    assert DSM10_TO_US[pos] == us2021
    assert DSM10_TO_US_E14[pos] == use14


def test_word_decoding() -> None:
    assert decode_word11(0xFFFF)[0] == -1  # blank slot
    assert decode_word11(dsm_word(13, 5))[0] == -2  # IDs 13, 14 invalid
    # X-Plus: ID 12, sub-channel in bits 10..9, phase adds 4, 9-bit position × 4.
    assert decode_word11(0x6000 | (2 << 9) | 100) == (14, 400)
    assert decode_word11(0xE000 | (3 << 9) | 1) == (19, 4)
    assert decode_word10(0xFFFF)[0] == -1
    assert decode_word10((20 << 10) | 5)[0] == -2
    assert decode_word10((19 << 10) | 5) == (19, 5)


def test_channels_merged_over_alternating_frames() -> None:
    ids_a, ids_b = range(7), range(7, 12)
    fa = encode_dsm_frame([dsm_word(c, 100 + 50 * c) for c in ids_a])
    fb = encode_dsm_frame([dsm_word(c, 100 + 50 * c) for c in ids_b])
    d = DsmDecoder()
    out = feed_frames(d, [fa, fb], 11_000, repeat=30)
    assert d.learned_count == 12 and d.channel_count == 12
    expect = [DSM11_TO_US[100 + 50 * c] for c in range(12)]
    expect[0], expect[1], expect[2] = expect[1], expect[2], expect[0]
    assert out[-1][1] == expect
    assert d.raw_channels[2] == 100  # throttle (Spektrum ID 0) in slot 2


def test_sync_by_gap_when_started_mid_frame() -> None:
    d = DsmDecoder()
    d.feed(0, FRAME11[5:])  # tail of a frame: starts a bogus frame
    out = feed_frames(d, [FRAME11], 11_000, t0=20_000, repeat=40)
    assert out and out[-1][1] == [1500, 1500, 1102, 1500, 1102, 1898, 1500]


def test_duplicate_and_out_of_range_ids_drop_and_reguess() -> None:
    d = DsmDecoder()
    feed_frames(d, [FRAME11], 11_000, repeat=35)
    assert d.mode == 11 and d.frame_errors == 1
    dup = encode_dsm_frame([dsm_word(1, 5), dsm_word(1, 6)])
    feed_frames(d, [dup], 11_000, t0=35 * 11_000)
    assert d.frame_errors == 2 and d.mode is None
    feed_frames(d, [FRAME11], 11_000, t0=36 * 11_000, repeat=16)
    assert d.mode == 11  # re-learned with the kept count: no second quirk drop
    assert d.frame_errors == 2
    far = encode_dsm_frame([dsm_word(9, 5)])
    feed_frames(d, [far], 11_000, t0=60 * 11_000)
    assert d.frame_errors == 3 and d.mode is None


def test_invalid_word_is_a_drop_without_reguess() -> None:
    d = DsmDecoder()
    feed_frames(d, [FRAME11], 11_000, repeat=35)
    bad = encode_dsm_frame([dsm_word(13, 5)])
    feed_frames(d, [bad], 11_000, t0=35 * 11_000)
    assert d.frame_errors == 2 and d.mode == 11


def test_guess_reset_after_one_second_silence() -> None:
    d = DsmDecoder()
    feed_frames(d, [FRAME11], 11_000, repeat=10)
    assert d._samples == 10
    feed_frames(d, [FRAME11], 11_000, t0=2_000_000)
    assert d._samples == 1


@pytest.mark.parametrize("byte0,pct", [(0x00, None), (0x05, None), (0x80, 0), (256 - 42, 100),
                                       (256 - 80, 50), (256 - 92, 0), (256 - 100, 0),
                                       (256 - 20, 100)])
def test_rssi_from_fades_byte(byte0: int, pct: int | None) -> None:
    assert dsm_rssi_percent(byte0) == pct


def test_fades_and_dbm_reported() -> None:
    d = DsmDecoder()
    frame = bytearray(FRAME11)
    frame[0] = 256 - 80
    feed_frames(d, [bytes(frame)], 11_000, repeat=35)
    assert d.rssi == 50
    frame[0] = 3
    feed_frames(d, [bytes(frame)], 11_000, t0=35 * 11_000)
    assert d.rssi is None and d.fades == 3 and d.lost_frames == 3


def test_bad_scaling_name() -> None:
    with pytest.raises(ValueError):
        DsmDecoder(scaling="spektrum")
