"""Real receiver captures (PX4 rc_tests data) and ArduPilot's RCProtocolTest vectors.

Expectations are those stated in ../shared/fixtures/README.md §1-2: the upstream assertions
exactly, plus the README's derived counts and values as cross-checks. Bytes are fed one at a
time with the capture's timestamps after the same 20-line skip the upstream test uses.
"""

from __future__ import annotations

from collections import Counter
from itertools import groupby

import pytest

from ioproc.rc import DsmDecoder, SbusDecoder, St24Decoder, SumdDecoder
from ioproc.rc.sbus import sbus_raw_to_us_ardupilot
from tests.ioproc._captures import ardupilot_vectors, read_capture, replay_ardupilot

# file: (channel count, drops, chan0 reference, reported frames, first report byte index,
#        first reported values)
DSM_CAPTURES = {
    "dsm_x_data.txt": (10, 2, 1500, 27, 508,
                       [1500, 1500, 1109, 1500, 1898, 1898, 1898, 1500, 1500, 1500]),
    "dsm_x_dx9_data.txt": (16, 1, 1500, 204, 588,
                           [1500, 1500, 1108, 1502, 1898, 1898, 1898, 1548, 1499, 1500, 1500,
                            1500, 1500, 1500, 1500, 1500]),
    "dsm_x_dx9_px4_binding_data.txt": (16, 1, 1499, 211, 556,
                                       [1499, 1499, 1104, 1499, 1102, 1500, 1898, 1557, 1898,
                                        1500, 1500, 1500, 1500, 1500, 1500, 1500]),
    "orangerx_dsmx_12.txt": (12, 1, 1499, 2696, 508,
                             [1495, 1495, 903, 1494, 1499, 1965, 1032, 1499, 1499, 903, 903,
                              903]),
    "dsm_x_data_before_error_injection.txt": (10, 1, 1500, 37, 508,
                                              [1500, 1500, 1109, 1500, 1898, 1898, 1898, 1500,
                                               1500, 1500]),
}

SBUS_VALUES = [1525, 1514, 1934, 1514, 1094, 1934, 1514, 1514] + [1514] * 8 + [998, 998]


def dma_batches(rows: tuple[tuple[int, int], ...], poll_us: int = 1000):
    """Group bytes the way the IO's 1 ms DMA poll hands them over (one time per batch)."""
    for k, g in groupby(rows, key=lambda r: r[0] // poll_us):
        yield (k + 1) * poll_us, bytes(b for _, b in g)


@pytest.mark.parametrize("name", list(DSM_CAPTURES))
def test_dsm_capture(name: str) -> None:
    count, drops, chan0, reports, first_at, first_vals = DSM_CAPTURES[name]
    d = DsmDecoder()
    got = []
    for i, (t, b) in enumerate(read_capture(name)):
        if d.feed_byte(t, b):
            got.append(i)
            if i + 1 > 320:
                assert d.channel_count == count, (name, i)
            assert abs(d.channels[0] - chan0) < 30, (name, i, d.channels)
            if len(got) == 1:
                assert (i, d.channels) == (first_at, first_vals)
            assert all(903 <= v <= 2097 for v in d.channels)
            assert d.dsm_11bit
    assert d.channel_count == count
    assert d.frame_errors == drops
    assert len(got) == reports == d.frames


@pytest.mark.parametrize("name", ["dsm_x_data.txt", "orangerx_dsmx_12.txt"])
def test_dsm_capture_in_dma_batches(name: str) -> None:
    count, drops, _, reports, _, _ = DSM_CAPTURES[name]
    d = DsmDecoder()
    for t, chunk in dma_batches(read_capture(name)):
        d.feed(t, chunk)
    assert (d.channel_count, d.frame_errors, d.frames) == (count, drops, reports)


def _sbus_run(name: str, with_time: bool) -> tuple[SbusDecoder, Counter, set]:
    d = SbusDecoder()
    ends: Counter = Counter()
    values = set()
    for t, b in read_capture(name):
        if d.feed_byte(t if with_time else 0, b):
            ends[d.end_byte] += 1
            values.add(tuple(d.channels))
            assert not d.failsafe and not d.frame_lost
    return d, ends, values


def test_sbus2_capture_as_upstream_without_time() -> None:
    """Upstream ignores the time column: README's 80 frames, 20 of each S.BUS2 end byte."""
    d, ends, values = _sbus_run("sbus2_r7008SB.txt", with_time=False)
    assert d.frames == 80
    assert ends == {0x04: 20, 0x14: 20, 0x24: 20, 0x34: 20}
    assert values == {tuple(SBUS_VALUES)}
    assert d.partial_frames == 0


def test_sbus2_capture_with_timestamps() -> None:
    """With the capture's times the 3 ms gap rule also saves the frame after the third cut."""
    d, ends, values = _sbus_run("sbus2_r7008SB.txt", with_time=True)
    assert d.frames == 81
    assert ends == {0x04: 20, 0x14: 20, 0x24: 20, 0x34: 21}
    assert values == {tuple(SBUS_VALUES)}
    assert d.frame_errors == 2  # one gap-truncated partial, one bad end byte
    assert d.lost_frames == 0


def test_sbus2_capture_undamaged_and_batched() -> None:
    d, ends, values = _sbus_run("sbus2_r7008SB_before_error_injection.txt", with_time=True)
    assert values == {tuple(SBUS_VALUES)}
    assert d.frames == 84 and d.frame_errors == 0
    assert ends == {0x04: 21, 0x14: 21, 0x24: 21, 0x34: 21}
    b = SbusDecoder()
    for t, chunk in dma_batches(read_capture("sbus2_r7008SB.txt")):
        b.feed(t, chunk)
    assert b.frames == 81 and b.channels == SBUS_VALUES


def test_st24_capture() -> None:
    d = St24Decoder()
    first = None
    rssi = set()
    for t, b in read_capture("st24_data.txt"):
        if d.feed_byte(t, b):
            first = first or list(d.channels)
            rssi.add(d.rssi_raw)
            assert d.channel_count == 12
            assert all(832 <= v <= 2197 for v in d.channels)
    assert d.frames == 560 and d.unknown_packets == 62
    assert d.bad_crc == 0 and d.frame_errors == 0
    assert first == [1065, 1515, 1515, 1515, 1969, 1060, 1515, 1969, 1515, 1515, 1058, 1058]
    assert min(rssi) == 181 and max(rssi) == 222


def test_sumd_capture() -> None:
    d = SumdDecoder()
    first = None
    lo = [9999] * 12
    hi = [0] * 12
    for t, b in read_capture("sumd_data.txt"):
        if d.feed_byte(t, b):
            first = first or list(d.channels)
            assert d.status == 0x01 and d.channel_count == 12
            lo = [min(a, v) for a, v in zip(lo, d.channels)]
            hi = [max(a, v) for a, v in zip(hi, d.channels)]
    assert d.frames == 498 and d.bad_crc == 0
    assert first == [1499, 1500, 1102, 1499, 1100, 1100, 1900, 1100, 1100, 1900, 1500, 1500]
    assert list(zip(lo[:4], hi[:4])) == [(1497, 1500), (1498, 1501), (1101, 1900), (1497, 1503)]
    assert lo[4:] == hi[4:]


# --- ArduPilot RCProtocolTest vectors ----------------------------------------------------------

def _replay(dec, vector: dict, passes: int) -> int:
    n = 0
    for t, b in replay_ardupilot(vector, passes):
        n += dec.feed_byte(t, b)
    return n


def test_ardupilot_sbus_vector() -> None:
    """PX4 scaling (offset 874) per README; ArduPilot's own formula on our raw values exactly."""
    v = ardupilot_vectors()["SBUS"]
    d = SbusDecoder()
    assert _replay(d, v, v["repeats"] + 4) == v["repeats"] + 4
    assert d.channels[:16] == [1562, 1496, 1000, 1530, 1806, 2006, 1494, 1494] + [874] * 8
    assert [sbus_raw_to_us_ardupilot(r) for r in d.raw_channels[:16]] == v["expected_channels_us"]
    assert all(abs(a - b) <= 1 for a, b in zip(d.channels, v["expected_channels_us"]))


@pytest.mark.parametrize("name", ["SUMD", "SUMD2", "SUMD3"])
def test_ardupilot_sumd_vectors(name: str) -> None:
    v = ardupilot_vectors()[name]
    d = SumdDecoder()
    assert _replay(d, v, v["repeats"] + 4) == v["repeats"] + 4
    assert d.channel_count == v["num_channels"]
    assert d.channels == v["expected_channels_us"]  # PX4 and ArduPilot agree exactly


DSM_VECTORS = ["DSM2", "DSM3", "DSM4", "DSM5", "DSMX22", "DSMX11"]


@pytest.mark.parametrize("name", DSM_VECTORS)
def test_ardupilot_dsm_vectors(name: str) -> None:
    """ArduPilot scales like PX4 before 2020-08 (scaling='e14'): exact; PX4 2021+: within 4 µs.

    PX4's guess needs 15 frames, twice because of the count quirk, so we replay 40 passes
    instead of ArduPilot's repeats + 4 and look at the final output.
    """
    v = ardupilot_vectors()[name]
    exp = v["expected_channels_us"]
    e14 = DsmDecoder(scaling="e14")
    assert _replay(e14, v, 40) > 0
    assert e14.channel_count == v["num_channels"]
    assert e14.channels == exp
    px4 = DsmDecoder()
    _replay(px4, v, 40)
    assert px4.channel_count == v["num_channels"]
    assert max(abs(a - b) for a, b in zip(px4.channels, exp)) <= 4


def test_ardupilot_dsm1_needs_a_gap_between_its_frames() -> None:
    """DSM1's two frames are replayed back to back; PX4 resynchronises after every guessing
    frame by silence, so it never sees the second frame (7 of 8 channels). With the 10 ms
    gap a real satellite leaves, the decoder gives ArduPilot's values exactly."""
    v = dict(ardupilot_vectors()["DSM1"])
    d = DsmDecoder(scaling="e14")
    _replay(d, v, 40)
    assert d.channel_count == 7
    v["pause_at"] = 16
    d = DsmDecoder(scaling="e14")
    _replay(d, v, 40)
    assert d.channel_count == 8 and d.channels == v["expected_channels_us"]
    assert d.dsm_11bit


# The DSMX22_VTX and DSMX11_VTX vectors are not replayed: VTX frames are ArduPilot-only and
# PX4's decoder has no VTX handling (fixtures README, section 2).
