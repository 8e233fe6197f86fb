"""RcInput: source tracking, arbitration eras, RC-lost timeout, RSSI and flags."""

from __future__ import annotations

import pytest

from ioproc.rc import (
    DSM,
    PPM,
    RC_LOST_US,
    SBUS,
    ST24,
    SUMD,
    RcInput,
    encode_dsm_frame,
    encode_sbus_frame,
    encode_st24_frame,
    encode_sumd_frame,
    ppm_edges,
)
from ioproc.rc.dsm import dsm_word

SBUS_PERIOD = 14_000


def sbus_stream(rc: RcInput, t0: int, frames: int, **flags) -> int:
    t = t0
    for _ in range(frames):
        rc.feed_sbus_port(t, encode_sbus_frame([1024] * 16, **flags))
        t += SBUS_PERIOD
    return t


def test_rc_lost_after_200ms_of_silence() -> None:
    rc = RcInput()
    rc.tick(0)
    assert not rc.rc_ok and not rc.rc_lost_alarm
    t = sbus_stream(rc, 1000, 5)
    last = rc.last_frame_us
    assert rc.rc_ok and rc.source == SBUS and rc.channel_count == 18
    assert rc.channels[0] == 1514 and rc.active_sources == {SBUS}
    rc.tick(last + RC_LOST_US)
    assert rc.rc_ok  # exactly 200 ms is not yet lost
    rc.tick(last + RC_LOST_US + 1)
    assert not rc.rc_ok and rc.rc_lost_alarm and rc.source is None
    assert rc.channel_count == 0 and rc.rssi == 0 and not rc.active_sources
    sbus_stream(rc, t + RC_LOST_US, 1)
    assert rc.rc_ok and rc.rc_lost_alarm  # the alarm is latched until the FMU clears it
    rc.clear_rc_lost_alarm()
    assert not rc.rc_lost_alarm


def test_alarm_set_when_no_receiver_at_all() -> None:
    rc = RcInput()
    rc.tick(RC_LOST_US + 1)
    assert rc.rc_lost_alarm and not rc.rc_ok


@pytest.mark.parametrize("era,normal,lost,fs", [("e14", 255, 100, 0), ("2018", 100, 50, 50)])
def test_sbus_flags_and_rssi_by_era(era: str, normal: int, lost: int, fs: int) -> None:
    rc = RcInput(arbitration=era)
    sbus_stream(rc, 0, 1)
    assert rc.rssi == normal and not rc.failsafe
    sbus_stream(rc, SBUS_PERIOD, 1, frame_lost=True)
    assert rc.rssi == lost and rc.frame_lost and not rc.failsafe
    sbus_stream(rc, 2 * SBUS_PERIOD, 1, failsafe=True)
    assert rc.rssi == fs and rc.failsafe and rc.rc_ok  # receiver failsafe keeps RC_OK


def test_dsm_source_and_11bit_flag() -> None:
    rc = RcInput()
    frame = encode_dsm_frame([dsm_word(c, 1024) for c in range(7)])
    for k in range(40):
        rc.feed_dsm_port(k * 11_000, frame)
    assert rc.source == DSM and rc.dsm_11bit and rc.channel_count == 7
    assert rc.frame_drops == 1  # PX4's guess quirk


def test_sumd_and_st24_on_dsm_port() -> None:
    rc = RcInput()
    rc.feed_dsm_port(0, encode_sumd_frame([1500] * 8, failsafe=True))
    assert rc.source == SUMD and rc.failsafe and rc.rssi == 100
    rc2 = RcInput()
    rc2.feed_dsm_port(0, encode_st24_frame([2000] * 12, rssi=255))
    assert rc2.source == ST24 and rc2.rssi == 100 and rc2.channels == [1499] * 12
    rc2.feed_dsm_port(20_000, encode_st24_frame([500] * 12, lost=1))
    assert rc2.channels == [1499] * 12  # packets with lost frames are not used


def ppm_stream(rc: RcInput, t0: int, frames: int, n: int = 8) -> int:
    t = t0
    for _ in range(frames):
        for te, lvl in ppm_edges([1200] * n, t0_us=t):
            rc.feed_ppm_edge(te, lvl)
        t += 22_500
    return t


def test_ppm_source_and_capture_entry() -> None:
    rc = RcInput()
    ppm_stream(rc, 0, 10)
    assert rc.source == PPM and rc.channels == [1200] * 8 and rc.rssi is None
    rc2 = RcInput()
    for k in range(10):
        for te, lvl in ppm_edges([1300] * 6, t0_us=k * 22_500):
            rc2.feed_ppm_capture(te, te & 0xFFFF, lvl)
    assert rc2.source == PPM and rc2.channels == [1300] * 6


def test_e14_latest_source_wins() -> None:
    rc = RcInput(arbitration="e14")
    t = ppm_stream(rc, 0, 10)
    sbus_stream(rc, t, 1)
    assert rc.source == SBUS
    ppm_stream(rc, t + 1000, 3)
    assert rc.source == PPM


def test_2018_arbitration_blocks_dsm_port_while_sbus_active() -> None:
    rc = RcInput(arbitration="2018")
    t = sbus_stream(rc, 0, 3)
    rc.feed_dsm_port(t, encode_sumd_frame([1500] * 8))
    assert rc.source == SBUS and rc.sumd.frames == 0
    # After 200 ms of S.BUS silence the flag clears and the DSM port is read again.
    t2 = rc.last_frame_us + RC_LOST_US + 1
    rc.feed_dsm_port(t2, encode_sumd_frame([1500] * 8))
    assert rc.source == SUMD
    sbus_stream(rc, t2 + 1000, 1)
    assert rc.source == SUMD  # S.BUS is not decoded while a DSM-port source is active


def test_bad_arbitration_name() -> None:
    with pytest.raises(ValueError):
        RcInput(arbitration="2025")
