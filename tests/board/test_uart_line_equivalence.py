"""Differential test: the integer LineDecoder against the original Fraction-based one.

``board/uart_line.py`` decodes mismatched UART lines with integer arithmetic and a per-burst
fast path for speed. Its results must stay *identical* to the original exact implementation
(kept verbatim in ``_line_decoder_reference.py``): same frames (arrival ns, value, flags), same
``wake_ns``, ``mark_since_ns`` and ``pending`` after every call, because runs must be
deterministic and bit-exact. Hypothesis drives both with random bursts (bauds, formats,
inversion, breaks, gaps from back-to-back to long, bursts that start inside a frame the
receiver is still decoding, format changes on either side) and random or ``Uart``-like
``final`` calls, comparing after every call.

Set ``LINE_DECODER_EXAMPLES`` to run more examples (the default keeps the test short).
"""

from __future__ import annotations

import os

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bench.bench_uart_mismatch import drive, nmea_at_38400, ubx_at_57600
from board.uart_line import BREAK, NS_PER_S, LineDecoder, UartConfig, _burst_bytes, burst_levels
from tests.board._line_decoder_reference import LineDecoder as RefDecoder
from tests.board._line_decoder_reference import burst_levels as ref_burst_levels

EXAMPLES = int(os.environ.get("LINE_DECODER_EXAMPLES", "150"))
#: A fixed seed by default (repeatable CI); a fresh random one when asked for a longer run.
DERANDOMIZE = "LINE_DECODER_EXAMPLES" not in os.environ

BAUDS = [9600, 19_200, 38_400, 57_600, 100_000, 115_200, 230_400, 1_500_000,
         # odd ones: awkward ratios, large common denominators, extremes
         300, 9601, 31_250, 250_000, 333_333, 1_000_003, 2_000_000, 100_000_000]

configs = st.builds(
    UartConfig,
    baud=st.sampled_from(BAUDS),
    data_bits=st.sampled_from([7, 8, 9]),
    parity=st.sampled_from(["N", "E", "O"]),
    stop_bits=st.sampled_from([1, 2]),
    invert=st.booleans(),
)

payloads = st.one_of(
    st.binary(min_size=1, max_size=10),
    st.sampled_from([b"\x00", b"\xff", b"\x55", b"\xaa", b"\x00\x00", b"\xf0\x0f", b"\x80"]),
    st.just(BREAK),
)

# Write time relative to the transmitter going idle: queued behind it (Uart.write floors the
# previous burst's end, so the bursts overlap by a fraction of a ns), shortly after, inside
# what the receiver may still be decoding, or long after.
gaps = st.one_of(
    st.just(None),
    st.just(0),
    st.integers(1, 50),
    st.integers(0, 3_000_000),
    st.integers(0, 2 * NS_PER_S),
)

step = st.fixed_dictionaries({
    "gap": gaps,
    "data": payloads,
    "new_tx": st.one_of(st.none(), st.none(), st.none(), configs),
    "new_rx": st.one_of(st.none(), st.none(), st.none(), st.none(), configs),
    "final_before": st.sampled_from([False, False, False, True]),
    "final_after": st.sampled_from([False, False, False, True]),
    "overlap": st.one_of(st.just(0), st.integers(0, 100), st.integers(0, 5_000_000)),
})


def _check(ref: RefDecoder, new: LineDecoder, rx: UartConfig, final: bool, where: str) -> tuple:
    want = ref.decode(rx, final)
    got = new.decode(rx, final)
    assert got == want, f"{where}: decode(final={final}) differs"
    assert new.pending == ref.pending, f"{where}: pending differs"
    return want


@settings(max_examples=EXAMPLES, deadline=None, derandomize=DERANDOMIZE,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(tx0=configs, rx0=configs, steps=st.lists(step, min_size=1, max_size=8),
       mode=st.sampled_from(["uart", "random_final", "overlap"]), start=st.integers(0, 10**12))
def test_integer_decoder_matches_fraction_reference(tx0, rx0, steps, mode, start):
    """Feed both decoders the same calls; every result must be identical.

    ``uart``: ``final=True`` exactly as ``Uart`` schedules it (once the returned wake time has
    passed before the next write). ``random_final``: at random points, which also lets a burst
    start before where the receiver resumed looking for an edge. ``overlap``: as that, and
    bursts may also start up to a few ms before the previous one ends, which ``Uart`` never
    does (its bursts overlap by under 1 ns) but the original decoder defines.
    """
    uart_like = mode == "uart"
    ref, new = RefDecoder(), LineDecoder()
    tx, rx = tx0, rx0
    tx_idle = start
    now = start
    wake = None
    for n, s in enumerate(steps):
        where = f"step {n}"
        if s["gap"] is not None:
            now = max(now, tx_idle + s["gap"])
        if uart_like and wake is not None and wake < now:
            wake = _check(ref, new, rx, True, where + " (wake)")[1]
        if not uart_like and s["final_before"]:
            _check(ref, new, rx, True, where + " (before)")
        if s["new_rx"] is not None:
            rx = s["new_rx"]
        if s["new_tx"] is not None:
            tx = s["new_tx"]
        data = s["data"]
        t0 = max(tx_idle, now)
        if mode == "overlap":
            t0 = max(0, t0 - s["overlap"])
        nbits = (tx.bits_per_frame + tx.stop_bits if data is BREAK
                 else len(data) * tx.bits_per_frame)
        tx_idle = t0 + (nbits * NS_PER_S) // tx.baud
        ref.feed(t0, tx, data, rx)
        new.feed(t0, tx, data, rx)
        wake = _check(ref, new, rx, False, where)[1]
        if not uart_like and s["final_after"]:
            _check(ref, new, rx, True, where + " (after)")
    for k in range(3):  # run out the line
        wake = _check(ref, new, rx, True, f"end {k}")[1]


@given(cfg=configs, data=payloads)
@settings(max_examples=60, deadline=None, derandomize=True)
def test_burst_bytes_match_reference_levels(cfg, data):
    assert list(_burst_bytes(cfg, data)) == ref_burst_levels(cfg, data) == burst_levels(cfg, data)


def test_gps_baud_scan_workloads_match_reference():
    """The benchmark's GPS-like traffic (NMEA at 9600 heard at 38400, UBX at 115200 heard at
    57600), driven the way Uart does: identical call by call."""
    for bursts, rx in (nmea_at_38400(1), ubx_at_57600(1, 2)):
        want = drive(RefDecoder(), bursts, rx)
        assert sum(len(r[0]) for r in want) > 100
        assert drive(LineDecoder(), bursts, rx) == want


def test_every_baud_pair_on_a_long_burst():
    """One 24-byte burst per (tx, rx) baud pair and format: covers every offset table."""
    data = bytes(range(0, 240, 10))
    for tx_baud in BAUDS:
        for rx_baud in BAUDS:
            tx = UartConfig(tx_baud)
            rx = UartConfig(rx_baud, 9 if rx_baud % 2 else 7, "E" if rx_baud > 50_000 else "O")
            ref, new = RefDecoder(), LineDecoder()
            for dec in (ref, new):
                dec.feed(12_345, tx, data, rx)
                dec.feed(12_345 + tx.burst_ns(len(data)), tx, data, rx)
            for final in (False, True):
                assert new.decode(rx, final) == ref.decode(rx, final), (tx_baud, rx_baud)


def test_burst_starting_inside_an_earlier_one_is_masked_by_it():
    """Out of Uart's contract but defined by the original: where bursts overlap, the earlier
    one is what the receiver samples, even for a frame whose edge is in the later one."""
    tx = UartConfig(9600, stop_bits=2)
    rx = UartConfig(115_200)
    results = []
    for dec in (RefDecoder(), LineDecoder()):
        dec.feed(1_000_000, tx, b"\xff", rx)  # start bit, then mark: no edge after the frame
        first = dec.decode(rx, False)
        dec.feed(1_500_000, tx, b"\x00", rx)  # starts 0.5 ms before the first one ends
        results.append((first, dec.decode(rx, False), dec.decode(rx, True)))
    assert results[1] == results[0]
    assert results[0][1][0] == []  # the later burst's start bit reads as a false start
