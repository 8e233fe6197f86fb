"""PPM decoder: channel counts, limits, lock, errors, 16-bit capture counter wrap."""

from __future__ import annotations

import pytest

from ioproc.rc.ppm import PPM_MIN_CHANNELS_E14, PpmDecoder, ppm_edges

FRAME_US = 22_500


def values(n: int, k: int = 0) -> list[int]:
    return [1000 + (97 * i + 13 * k) % 1000 for i in range(n)]


def run_edges(d: PpmDecoder, frames: int, n: int, *, t0: int = 0, period: int = FRAME_US,
              capture: bool = False, marker: int = 400) -> list[list[int]]:
    out = []
    for k in range(frames):
        for t, lvl in ppm_edges(values(n, k), t0_us=t0 + k * period, marker_us=marker):
            got = d.feed_capture(t & 0xFFFF, lvl) if capture else d.feed_edge(t, lvl)
            if got:
                out.append(list(d.channels))
    return out


@pytest.mark.parametrize("n", range(4, 13))
def test_channel_counts_4_to_12(n: int) -> None:
    d = PpmDecoder()
    out = run_edges(d, 12, n)
    if n < 5:
        assert out == [] and d.channel_count == 0  # PX4 needs at least 5 channels
        return
    # Sync (1), first count seen (2), four hold-off frames, accepted (7), output from the 8th
    # frame edge on: frames 7..10 are output when the next frame's first marker arrives.
    assert len(out) == 4
    assert out[-1] == values(n, 10)
    assert d.channel_count == n and d.frame_len_us == FRAME_US


def test_e14_needs_six_channels() -> None:
    d = PpmDecoder(min_channels=PPM_MIN_CHANNELS_E14)
    assert run_edges(d, 12, 5) == []
    assert run_edges(PpmDecoder(min_channels=PPM_MIN_CHANNELS_E14), 12, 6)


@pytest.mark.parametrize("t0", [0, 65_000, 0xFFFF - 1500, 3_000_000])
def test_capture_counter_wrap(t0: int) -> None:
    """The 16-bit CCR wraps every 65.536 ms, several times within this run."""
    d = PpmDecoder()
    out = run_edges(d, 20, 8, t0=t0, capture=True)
    assert len(out) == 12
    assert out[-1] == values(8, 18)
    assert d.frame_errors == 0 and d.frame_len_us == FRAME_US


def test_capture_with_hrt_time_stamp() -> None:
    d = PpmDecoder()
    for k in range(10):
        for t, lvl in ppm_edges(values(8, k), t0_us=1_000_000 + k * FRAME_US):
            d.feed_capture(t & 0xFFFF, lvl, t_us=t)
    assert d.last_frame_us == 1_000_000 + 9 * FRAME_US


def test_inverted_polarity_decodes_the_same() -> None:
    d = PpmDecoder()
    for k in range(10):
        for t, lvl in ppm_edges(values(8, k), t0_us=k * FRAME_US):
            d.feed_edge(t, 1 - lvl)
    assert d.channels == values(8, 8)


def test_count_change_needs_new_lock() -> None:
    d = PpmDecoder()
    run_edges(d, 10, 8)
    assert d.accepted_count == 8
    out = run_edges(d, 10, 6, t0=10 * FRAME_US)
    assert d.accepted_count == 6
    assert out[0] == values(8, 9)  # the last 8-channel frame ends at the first new edge
    assert len(out[1:]) == 3 and out[-1] == values(6, 8)


@pytest.mark.parametrize("marker", [150, 650])
def test_marker_out_of_range_is_an_error(marker: int) -> None:
    d = PpmDecoder()
    assert run_edges(d, 10, 8, marker=marker) == []
    assert d.frame_errors > 0


def test_channel_out_of_range_resets_lock() -> None:
    d = PpmDecoder()
    run_edges(d, 10, 8)
    assert d.accepted_count == 8
    t = 10 * FRAME_US
    bad = ppm_edges([1000, 2300, 1000, 1000, 1000], t0_us=t)
    for e in bad:
        d.feed_edge(*e)
    assert d.frame_errors == 1 and d.accepted_count == 0


def test_overflow_and_missed_edge() -> None:
    d = PpmDecoder()
    run_edges(d, 10, 8)
    d.feed_edge(10 * FRAME_US, 1, overflow=True)
    assert d.missed_edges == 1 and d.accepted_count == 0
    d2 = PpmDecoder()
    run_edges(d2, 10, 8)
    d2.feed_edge(10 * FRAME_US, 0)  # same level as the last edge: one was not captured
    assert d2.missed_edges == 1


def test_more_than_twenty_channels_rejected() -> None:
    d = PpmDecoder()
    assert run_edges(d, 12, 21, period=50_000) == []
    assert d.channel_count == 0
