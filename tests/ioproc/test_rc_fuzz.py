"""Random and corrupted input never raises, never hangs, never yields out-of-range values."""

from __future__ import annotations

from hypothesis import given
from hypothesis import strategies as st

from ioproc.rc import (
    DsmDecoder,
    PpmDecoder,
    RcInput,
    SbusDecoder,
    St24Decoder,
    SumdDecoder,
    encode_dsm_frame,
    encode_sbus_frame,
    encode_st24_frame,
    encode_sumd_frame,
)
from ioproc.rc.dsm import dsm_word
from ioproc.rc.ppm import ppm_edges
from tests.fuzzing import fuzz

DECODERS = [
    lambda: SbusDecoder(), lambda: SbusDecoder(check_end_byte=False, offset_recovery=True),
    lambda: DsmDecoder(), lambda: DsmDecoder(scaling="e14", px4_count_quirk=False),
    lambda: SumdDecoder(), lambda: St24Decoder(), lambda: St24Decoder(scaling="e14"),
]

# (gap before the chunk in µs, chunk) pairs: timing matters to the gap-framed decoders.
chunks = st.lists(st.tuples(st.integers(-100, 30_000), st.binary(max_size=64)), max_size=40)


def _valid_frames(seed: int) -> bytes:
    """A mix of valid frames of every byte protocol, so corruption hits real structure."""
    raw = [(seed * 31 + 97 * i) % 2048 for i in range(16)]
    dsm = encode_dsm_frame([dsm_word(c, raw[c]) for c in range(7)])
    return (encode_sbus_frame(raw, failsafe=bool(seed & 1), end=(0, 4, 0x14)[seed % 3])
            + dsm + encode_sumd_frame([800 + r // 2 for r in raw[:12]])
            + encode_st24_frame([r * 2 for r in raw[:12]]))


def _check(dec, t: int, data: bytes) -> None:
    dec.feed(t, data)
    assert dec.channel_count == len(dec.channels)
    assert all(dec.min_us <= v <= dec.max_us for v in dec.channels), (type(dec), dec.channels)
    assert dec.rssi is None or 0 <= dec.rssi <= 100


@fuzz(examples=400)
@given(stream=chunks, which=st.integers(0, len(DECODERS) - 1))
def test_random_streams(stream: list[tuple[int, bytes]], which: int) -> None:
    dec = DECODERS[which]()
    t = 0
    for gap, data in stream:
        t += gap
        _check(dec, t, data)


@fuzz(examples=400)
@given(seed=st.integers(0, 10_000), which=st.integers(0, len(DECODERS) - 1),
       edits=st.lists(st.tuples(st.integers(0, 10_000), st.integers(0, 255),
                                st.sampled_from(["flip", "drop", "insert", "set"])),
                      max_size=12),
       repeats=st.integers(1, 30))
def test_corrupted_valid_streams(seed: int, which: int, edits: list, repeats: int) -> None:
    dec = DECODERS[which]()
    data = bytearray(_valid_frames(seed) * 2)
    for pos, val, op in edits:
        i = pos % len(data)
        if op == "flip":
            data[i] ^= 1 << (val & 7)
        elif op == "drop":
            del data[i]
        elif op == "insert":
            data.insert(i, val)
        else:
            data[i] = val
    for k in range(repeats):
        # Byte by byte with a real inter-frame gap, so the decoders keep resynchronising.
        t0 = k * 11_000
        for i, b in enumerate(data):
            dec.feed_byte(t0 + i * 9, b)
        _check(dec, t0 + 10_000, b"")


@fuzz(examples=400)
@given(widths=st.lists(st.tuples(st.integers(0, 70_000), st.integers(0, 1), st.booleans()),
                       max_size=300),
       capture=st.booleans())
def test_ppm_random_edges(widths: list[tuple[int, int, bool]], capture: bool) -> None:
    d = PpmDecoder()
    t = 0
    for w, lvl, ovf in widths:
        t += w
        if capture:
            d.feed_capture(t & 0xFFFF, lvl, overflow=ovf and w % 7 == 0)
        else:
            d.feed_edge(t, lvl if w % 5 else None)
        assert 0 <= d.channel_count <= 20 and len(d.channels) == d.channel_count
        assert all(800 <= v <= 2200 for v in d.channels)


@fuzz(examples=400)
@given(n=st.integers(1, 22), seed=st.integers(0, 1000),
       edits=st.lists(st.tuples(st.integers(0, 10_000), st.integers(-2500, 2500)), max_size=8))
def test_ppm_corrupted_trains(n: int, seed: int, edits: list[tuple[int, int]]) -> None:
    edges = []
    for k in range(12):
        vals = [700 + (seed + 131 * i + 7 * k) % 1700 for i in range(n)]
        edges += ppm_edges(vals, t0_us=k * 60_000)
    times = [t for t, _ in edges]
    for pos, shift in edits:
        i = pos % len(times)
        if shift % 3 == 0:
            del times[i]
        else:
            times[i] += shift
    times.sort()
    for d, cap in ((PpmDecoder(), False), (PpmDecoder(), True)):
        for i, t in enumerate(times):
            d.feed_capture(t & 0xFFFF, i & 1) if cap else d.feed_edge(t)
            assert all(800 <= v <= 2200 for v in d.channels)
            assert 0 <= d.channel_count <= 20


@fuzz(examples=400)
@given(ops=st.lists(st.tuples(st.integers(0, 3), st.integers(0, 250_000), st.binary(max_size=40)),
                    max_size=30),
       era=st.sampled_from(["e14", "2018"]))
def test_rc_input_random(ops: list[tuple[int, int, bytes]], era: str) -> None:
    rc = RcInput(arbitration=era)
    t = 0
    for port, dt, data in ops:
        t += dt
        if port == 0:
            rc.feed_sbus_port(t, data)
        elif port == 1:
            rc.feed_dsm_port(t, data)
        elif port == 2:
            for i, b in enumerate(data):
                rc.feed_ppm_edge(t + i * b * 10, i & 1)
        else:
            rc.tick(t)
        assert rc.channel_count == len(rc.channels) <= 18
        assert all(0 <= v <= 8191 for v in rc.channels)
        if not rc.rc_ok:
            assert rc.channel_count == 0 and rc.source is None
