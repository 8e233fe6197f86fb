"""RC transmitter and receiver models, checked through the IO's own decoders.

Every round trip feeds the records a receiver puts on its world port into ``ioproc.rc``: UART
records byte by byte at their wire times (byte i of a burst arrives at
``t_start + (i + 1) * bits * 1e9 / baud``), PPM records edge by edge.
"""

from __future__ import annotations

import itertools

import pytest

from hil.devices import DeviceHub
from hypothesis import given, settings
from hypothesis import strategies as st

from board.board import Board
from board.gpio import Gpio
from board.kernel import Kernel
from board.uart import Uart, UartConfig
from board.wiring import WORLD, Wire
from hil.orchestrator import BoardSpec, Orchestrator
from hil.rc import RcRig, Transmitter, make_receiver
from hil.rc.dsm import DsmReceiver
from hil.rc.ppm import PpmReceiver
from hil.rc.sbus import SbusReceiver
from ioproc.rc import DsmDecoder, PpmDecoder, RcInput, SbusDecoder

MS = 1_000_000
NS = 1_000_000_000


# -- helpers ------------------------------------------------------------------------------------


def uart_bytes(records):
    """(t_ns, byte) per byte of UART records, at the end of each byte's last stop bit."""
    for _port, t0, (baud, bits, parity, stop, _inv, data) in records:
        nbits = 1 + bits + (parity != "N") + stop
        for i, b in enumerate(data):
            yield t0 + (i + 1) * nbits * NS // baud, b


def feed_uart(dec, records):
    """Feed a byte decoder; return [(t_us, channels, failsafe, frame_lost)] per frame output."""
    frames = []
    for t_ns, b in uart_bytes(records):
        if dec.feed_byte(t_ns // 1000, b):
            frames.append((t_ns // 1000, list(dec.channels), dec.failsafe, dec.frame_lost))
    return frames


def feed_ppm(dec, records):
    frames = []
    for _port, t_ns, level in records:
        if dec.feed_edge(t_ns // 1000, level):
            frames.append((t_ns // 1000, list(dec.channels)))
    return frames


def run(rx, until_ns):
    rx.run_until(until_ns)
    return rx.outputs(until_ns)


def tx_with(values):
    """A transmitter whose first channels hold ``values`` (µs) from t = 0."""
    tx = Transmitter(18)
    for ch, v in enumerate(values, 1):
        tx.set(0, ch, v)
    return tx


SPREAD = [1000, 1100, 1234, 1500, 1501, 1666, 1777, 1888, 1999, 2000, 1003, 1250,
          1750, 1432, 1010, 1990]


# -- transmitter ---------------------------------------------------------------------------------


def test_transmitter_defaults_follow_px4_map():
    tx = Transmitter()
    v = tx.sample(0)
    assert len(v) == 18
    assert v[2] == 1000 and v[0] == v[1] == v[3] == 1500  # throttle is channel 3
    assert tx.failsafe_us[2] == 1000
    tx.set_sticks(10 * MS, roll=1.0, pitch=-1.0, yaw=0.5, throttle=0.25)
    assert tx.sample(10 * MS)[:4] == [2000, 1000, 1250, 1750]
    assert tx.sample(10 * MS - 1)[:4] == [1500, 1500, 1000, 1500]


def test_ramp_and_override_in_virtual_time():
    tx = Transmitter()
    tx.ramp(100 * MS, 200 * MS, 1, 2000)
    assert tx.value(100 * MS, 1) == 1500
    assert tx.value(150 * MS, 1) == 1750
    assert tx.value(300 * MS, 1) == 2000
    # a step in the middle of the ramp stops it where it is
    tx.set(160 * MS, 1, 1200)
    assert tx.value(159 * MS, 1) == 1795
    assert tx.value(160 * MS, 1) == 1200
    assert tx.value(250 * MS, 1) == 1200


def test_script_and_power():
    tx = Transmitter()
    tx.play([(0.1, "throttle", 0.5, 0.1), (0.3, "mode", 2), (0.4, 8, 1900),
             (0.5, "power", False), (0.6, "power", True)])
    assert tx.value(150 * MS, 3) == 1250 and tx.value(200 * MS, 3) == 1500
    assert tx.value(300 * MS, 5) == 2000 and tx.value(299 * MS, 5) == 1000
    assert tx.value(400 * MS, 8) == 1900
    assert tx.powered(499 * MS) and not tx.powered(500 * MS) and tx.powered(600 * MS)
    with pytest.raises(ValueError, match="unknown target"):
        tx.play([(1.0, "flaps", 1)])
    with pytest.raises(ValueError, match="outside"):
        tx.set(0, 1, 3000)
    with pytest.raises(ValueError):
        tx.set(0, 19, 1500)


# -- S.BUS ----------------------------------------------------------------------------------------


def test_sbus_round_trip_every_channel_exact():
    tx = tx_with(SPREAD + [2000, 1000])  # channels 17/18: digital on / off
    rx = SbusReceiver(tx)
    frames = feed_uart(SbusDecoder(), run(rx, 100 * MS))
    assert len(frames) == 7  # 14, 28, ... 98 ms
    for _t, ch, fs, lost in frames:
        assert ch == SPREAD + [1998, 998]
        assert not fs and not lost


def test_sbus_frame_timing_through_the_io_uart():
    rx = SbusReceiver(Transmitter())
    recs = run(rx, 60 * MS)
    assert [r[1] for r in recs] == [14 * MS, 28 * MS, 42 * MS, 56 * MS]
    assert all(r[0] == "rc_sbus" and r[2][:5] == (100_000, 8, "E", 2, True) for r in recs)
    assert all(len(r[2][5]) == 25 for r in recs)
    # Through the board's USART model set up like the IO's USART3 (inverter in front).
    k = Kernel("io")
    u = Uart(k, "usart3", UartConfig(100_000, 8, "E", 2, True))
    got = []
    u.on_rx(lambda t, b, f: got.append((t, b, f)))
    for _port, t, payload in recs:
        u.receive(t, UartConfig(*payload[:5]), payload[5])
    k.run(70 * MS)
    assert [b for _t, b, _f in got] == [b for r in recs for b in r[2][5]]
    assert all(f == 0 for _t, _b, f in got)
    times = [t for t, _b, _f in got]
    assert times[0] == 14 * MS + 120_000
    assert all(times[i + 1] - times[i] == 120_000 for i in range(24))
    assert times[25] - times[0] == 14 * MS


def test_sbus_fast_mode_and_sbus2_end_bytes():
    rx = SbusReceiver(Transmitter(), high_speed=True, sbus2=True)
    recs = run(rx, 30 * MS)
    assert [r[1] for r in recs] == [7 * MS, 14 * MS, 21 * MS, 28 * MS]
    assert sorted(r[2][5][24] for r in recs) == [0x04, 0x14, 0x24, 0x34]
    assert len(feed_uart(SbusDecoder(), recs)) == 4


@pytest.mark.parametrize("on_loss", ["failsafe", "hold", "no_pulses"])
def test_sbus_link_loss_frame_lost_then_failsafe(on_loss):
    tx = tx_with([1800, 1200, 1700, 1400])
    tx.power(100 * MS, False)
    rx = SbusReceiver(tx, on_loss=on_loss, failsafe_delay_ns=200 * MS)
    frames = feed_uart(SbusDecoder(), run(rx, 500 * MS))
    start = [(t - 3000, *rest) for t, *rest in frames]  # decoded 3 ms after the frame start
    good = [f for f in start if f[0] < 100_000]
    lost = [f for f in start if 100_000 <= f[0] < 300_000]
    fs = [f for f in start if f[0] >= 300_000]
    assert good and all(not f[2] and not f[3] for f in good)
    # frame lost: flag set, last values held, no failsafe yet
    assert len(lost) >= 13 and all(f[3] and not f[2] and f[1][:4] == [1800, 1200, 1700, 1400]
                                   for f in lost)
    if on_loss == "no_pulses":
        assert fs == []
    else:
        assert fs and all(f[2] for f in fs)
        want = [1500, 1500, 1000, 1500] if on_loss == "failsafe" else [1800, 1200, 1700, 1400]
        assert all(f[1][:4] == want for f in fs)


def test_sbus_recovers_and_forced_failsafe_and_drop_burst():
    tx = Transmitter()
    rx = SbusReceiver(tx, failsafe_delay_ns=NS)
    rx.drop_frames(50 * MS, 80 * MS)  # frames at 56, 70 ms
    rx.force_failsafe(100 * MS, 130 * MS)  # frames at 112, 126 ms
    frames = feed_uart(SbusDecoder(), run(rx, 160 * MS))
    by_t = {t // 1000 - 3: (fs, lost) for t, _c, fs, lost in frames}
    assert by_t[42] == (False, False)
    assert by_t[56] == (False, True) and by_t[70] == (False, True)
    assert by_t[84] == (False, False)
    assert by_t[112] == (True, False) and by_t[126] == (True, False)
    assert by_t[140] == (False, False)


def test_sbus_glitches_are_seeded_and_caught():
    def records(seed):
        rx = SbusReceiver(Transmitter(), seed=seed)
        rx.glitch(0, None, byte_prob=0.5, spike_prob=0.5)
        return run(rx, 600 * MS)

    a, b, c = records(1), records(1), records(2)
    assert a == b and a != c
    dec = SbusDecoder()
    frames = feed_uart(dec, a)
    assert 0 < len(frames) < len(a)  # some frames rejected (bad header/end byte)
    assert any(ch[:16] != [1500, 1500, 1000, 1500] + [1000] * 3 + [1500] * 9
               for _t, ch, _f, _l in frames)  # spikes or damaged payload got through


def test_sbus_without_inverter_is_garbage_at_the_io():
    rx = SbusReceiver(Transmitter(), invert=False)
    recs = run(rx, 30 * MS)
    k = Kernel("io")
    u = Uart(k, "usart3", UartConfig(100_000, 8, "E", 2, True))
    for _port, t, payload in recs:
        u.receive(t, UartConfig(*payload[:5]), payload[5])
    k.run(40 * MS)
    dec = SbusDecoder()
    assert not dec.feed(40_000, u.read())
    assert u.framing_errors + u.parity_errors > 0


# -- DSM ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("mode,channels,tol", [("dsmx_11", 12, 0), ("dsmx_22", 7, 0),
                                               ("dsm2_11", 8, 0), ("dsm2_22", 8, 1)])
def test_dsm_round_trip(mode, channels, tol):
    values = SPREAD[:channels]
    rx = DsmReceiver(tx_with(values), mode=mode, channels=channels)
    dec = DsmDecoder()
    # PX4 needs 15 frames to guess the resolution, rejects the next one (count quirk) and
    # guesses again: about 31 frames before the first output (≈ 0.7 s at 22 ms).
    recs = run(rx, 800 * MS)
    frames = feed_uart(dec, recs)
    assert frames, "decoder never locked"
    assert dec.mode == (10 if mode == "dsm2_22" else 11)
    assert dec.channel_count == channels
    for _t, ch, _fs, _lost in frames:
        assert all(abs(a - b) <= tol for a, b in zip(ch, values, strict=True))
    rec_t = [t for _p, t, _pl in recs]
    assert all(b - a == rx.period_ns for a, b in itertools.pairwise(rec_t))


def test_dsm_frame_format_and_order_on_the_wire():
    tx = tx_with([1100, 1200, 1300, 1400])  # roll, pitch, throttle, yaw
    rx = DsmReceiver(tx, mode="dsmx_11", channels=4)
    (_port, t, payload), = run(rx, 11 * MS)
    assert t == 11 * MS and payload[:5] == (115_200, 8, "N", 1, False)
    frame = payload[5]
    assert len(frame) == 16 and frame[1] == 0xB2
    ids = [((frame[i] << 8 | frame[i + 1]) >> 11) & 0xF for i in range(2, 10, 2)]
    assert ids == [1, 2, 0, 3]  # aileron, elevator, throttle, rudder


def test_dsm_loss_silence_then_rc_lost_after_200ms():
    tx = Transmitter()
    tx.power(400 * MS, False)
    rx = DsmReceiver(tx, mode="dsmx_11")
    recs = run(rx, NS)
    assert recs[-1][1] < 400 * MS  # a satellite without link sends nothing
    rc = RcInput()
    for t_ns, b in uart_bytes(recs):
        rc.feed_dsm_port(t_ns // 1000, bytes((b,)))
    last = rc.last_frame_us
    assert rc.rc_ok and rc.source == "dsm" and last is not None
    rc.tick(last + 200_000)
    assert rc.rc_ok
    rc.tick(last + 200_001)
    assert not rc.rc_ok and rc.rc_lost_alarm


def test_dsm_fades_count_lost_frames_and_resume():
    tx = Transmitter()
    rx = DsmReceiver(tx, mode="dsmx_22")
    rx.drop_frames(100 * MS, 170 * MS)  # slots 110, 132, 154 ms
    recs = run(rx, 300 * MS)
    times = [t // MS for _p, t, _pl in recs]
    assert 110 not in times and 132 not in times and 154 not in times and 176 in times
    assert [pl[5][0] for _p, t, pl in recs if t > 170 * MS] == [3] * 6
    assert rx.fades == 3


def test_dsm_rssi_byte_and_wrong_port():
    rx = DsmReceiver(Transmitter(), rssi_dbm=-60)
    dec = DsmDecoder()
    assert feed_uart(dec, run(rx, 400 * MS)) and dec.rssi is not None and 0 < dec.rssi < 100
    # Wrong protocol: a satellite plugged into the S.BUS connector.
    wrong = make_receiver("dsm", Transmitter(), port="rc_sbus")
    recs = run(wrong, 400 * MS)
    assert recs and all(r[0] == "rc_sbus" for r in recs)
    assert feed_uart(SbusDecoder(), recs) == []


# -- PPM ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("n", range(4, 13))
def test_ppm_round_trip_4_to_12_channels(n):
    values = [2000] * n if n == 12 else SPREAD[:n]
    rx = PpmReceiver(tx_with(values), channels=n, marker_level=n % 2)
    dec = PpmDecoder()
    frames = feed_ppm(dec, run(rx, 300 * MS))
    if n < 5:
        assert frames == [] and dec.accepted_count == 4  # PX4 needs at least 5 channels
        return
    assert len(frames) >= 3  # the lock takes about 7 frames
    assert all(ch == values for _t, ch in frames)
    if n == 12:  # 24 ms of channels: the frame stretches past 22.5 ms to keep a sync gap
        assert dec.frame_len_us == 24_000 + 400 + 3000
    else:
        assert dec.frame_len_us == 22_500


def test_ppm_edges_markers_and_gap():
    rx = PpmReceiver(Transmitter(), channels=8)
    recs = run(rx, 45 * MS)
    assert recs[0] == ("rc_ppm", 0, 0)  # line driven idle at power-up
    frame = [r for r in recs if 22_500_000 <= r[1] < 45 * MS]
    assert len(frame) == 18  # 9 markers
    assert [lvl for _p, _t, lvl in frame] == [1, 0] * 9
    ts = [t for _p, t, _l in frame]
    assert all(ts[i + 1] - ts[i] == 400_000 for i in range(0, 18, 2))
    assert 45 * MS - ts[-1] >= 2_300_000


@pytest.mark.parametrize("on_loss", ["no_pulses", "hold"])
def test_ppm_loss(on_loss):
    tx = tx_with(SPREAD[:8])
    tx.power(300 * MS, False)
    rx = PpmReceiver(tx, on_loss=on_loss, failsafe_delay_ns=100 * MS)
    recs = run(rx, 800 * MS)
    rc = RcInput()
    for _p, t, lvl in recs:
        rc.feed_ppm_edge(t // 1000, lvl)
    rc.tick(800_000)
    if on_loss == "no_pulses":
        assert recs[-1][1] < 420 * MS  # repeated for the failsafe delay, then silence
        assert not rc.rc_ok and rc.rc_lost_alarm
    else:
        assert recs[-1][1] > 780 * MS
        assert rc.rc_ok and rc.channels == SPREAD[:8]


def test_ppm_glitches_break_frames_deterministically():
    def records(seed):
        rx = PpmReceiver(tx_with(SPREAD[:8]), seed=seed)
        rx.glitch(200 * MS, 400 * MS, byte_prob=0.5, spike_prob=0.3)
        return run(rx, 700 * MS)

    a = records(7)
    assert a == records(7) and a != records(8)
    dec = PpmDecoder()
    frames = feed_ppm(dec, a)
    assert dec.frame_errors > 0
    assert frames[-1][1] == SPREAD[:8]  # relocks after the glitches


# -- timing of scripted moves, determinism, rig ----------------------------------------------------


def test_scripted_moves_arrive_in_the_first_frame_after_them():
    tx = Transmitter()
    tx.set_sticks(100_500_000, roll=1.0)  # between the 98 and 112 ms S.BUS frames
    tx.ramp(200 * MS, 300 * MS, 2, 2000)
    frames = feed_uart(SbusDecoder(), run(SbusReceiver(tx), 400 * MS))
    roll = {t // 1000: ch[0] for t, ch, _f, _l in frames}
    pitch = {t // 1000: ch[1] for t, ch, _f, _l in frames}
    # decode time = frame start + 25 bytes (3 ms)
    assert roll[98 + 3] == 1500 and roll[112 + 3] == 2000
    assert pitch[196 + 3] == 1500 and pitch[210 + 3] == 1550 and pitch[308 + 3] == 2000
    ramp = [pitch[t] for t in sorted(pitch) if 200 <= t <= 320]
    assert ramp == sorted(ramp)


def build_rig(seed):
    rig = RcRig(Transmitter())
    rig.tx.play([(0.05, "throttle", 1.0, 0.2), (0.3, "power", False), (0.35, "power", True)])
    rig.add("sbus", seed=seed, frame_loss_prob=0.2)
    rig.add("dsm", seed=seed, frame_loss_prob=0.2)
    rig.add("ppm", seed=seed, frame_loss_prob=0.2).glitch(0, None, byte_prob=0.2)
    return rig


def test_determinism_and_quantum_independence():
    one = build_rig(3)
    one.run_until(500 * MS)
    whole = one.outputs(500 * MS)
    stepped = []
    other = build_rig(3)
    for q in range(1, 501):
        other.run_until(q * MS)
        stepped += other.outputs(q * MS)
    assert stepped == whole
    assert all(whole[i][1] <= whole[i + 1][1] for i in range(len(whole) - 1))
    assert {r[0] for r in whole} == {"rc_sbus", "rc_dsm", "rc_ppm"}
    third = build_rig(4)
    third.run_until(500 * MS)
    assert third.outputs(500 * MS) != whole


def test_outputs_hold_back_future_edges():
    rx = PpmReceiver(Transmitter())
    rx.run_until(23 * MS)  # the frame starting at 22.5 ms is generated whole
    out = rx.outputs(23 * MS)
    assert out[-1][1] <= 23 * MS
    assert rx.next_event_ns() is not None and rx.next_event_ns() > 23 * MS
    assert rx.outputs(30 * MS)[0][1] > 23 * MS


def test_make_receiver_rejects_unknown_kind():
    with pytest.raises(ValueError, match="known: sbus, dsm, ppm"):
        make_receiver("crsf", Transmitter())
    with pytest.raises(ValueError, match="on_loss"):
        SbusReceiver(Transmitter(), on_loss="sometimes")


# -- property: any in-range value decodes in range ------------------------------------------------

us_values = st.lists(st.integers(800, 2200), min_size=8, max_size=8)


@settings(max_examples=25, deadline=None)
@given(us_values)
def test_any_values_decode_within_resolution(values):
    """Extended travel included: each protocol clamps to what it can carry, then round-trips."""
    tx = tx_with(values)
    sb = feed_uart(SbusDecoder(), run(SbusReceiver(tx), 30 * MS))
    assert sb and sb[-1][1][:8] == [min(2153, max(874, v)) for v in values]
    ppm = feed_ppm(PpmDecoder(), run(PpmReceiver(tx), 200 * MS))
    assert ppm and ppm[-1][1] == values
    dsm_dec = DsmDecoder()
    dsm = feed_uart(dsm_dec, run(DsmReceiver(tx, mode="dsm2_22"), 750 * MS))
    want = [min(2096, max(903, v)) for v in values]
    assert dsm and all(abs(a - b) <= 1 for a, b in zip(dsm[-1][1], want, strict=True))
    assert all(dsm_dec.min_us <= v <= dsm_dec.max_us for v in dsm[-1][1])


def test_value_inverses_cover_every_microsecond():
    from hil.rc.dsm import us_to_dsm_pos
    from hil.rc.sbus import us_to_sbus_raw
    from ioproc.rc.dsm import DSM10_TO_US, DSM11_TO_US
    from ioproc.rc.sbus import SBUS_RAW_TO_US

    assert all(SBUS_RAW_TO_US[us_to_sbus_raw(us)] == us for us in range(874, 2154))
    assert all(DSM11_TO_US[us_to_dsm_pos(us, 11)] == us for us in range(903, 2097))
    assert all(abs(DSM10_TO_US[us_to_dsm_pos(us, 10)] - us) <= 1 for us in range(903, 2097))


# -- through the orchestrator into a board's ports --------------------------------------------------


class RcSinkBoard(Board):
    """The IO's RC inputs only: USART3 as S.BUS input and PA8 as the PPM pin, with probes."""

    def __init__(self, name: str = "io", seed: int = 0) -> None:
        super().__init__(name, seed)
        self.sbus_rx: list[tuple[int, int]] = []
        self.ppm_rx: list[tuple[int, int]] = []
        uart = Uart(self.kernel, "USART3", UartConfig(100_000, 8, "E", 2, True))
        uart.on_rx(lambda t, b, f: self.sbus_rx.append((t, b)))
        self.expose_uart("sbus_in", uart)
        pin = Gpio(self.kernel).pin("PA8", pull="down")
        pin.on_change(lambda _pin, t, level: self.ppm_rx.append((t, level)))
        self.expose_pin_in("ppm_in", pin)


@pytest.mark.parametrize("lead", [True, False])
def test_through_orchestrator_into_board_ports(lead):
    rig = RcRig(Transmitter())
    rig.runs_ahead = lead  # the device hub runs a scripted rig one quantum ahead
    rig.tx.set(0, 1, 1234)
    sbus, ppm = rig.add("sbus"), rig.add("ppm")
    quantum = MS
    wiring = [Wire((WORLD, "rc_sbus"), ("io", "sbus_in")), Wire((WORLD, "rc_ppm"), ("io", "ppm_in"))]
    orch = Orchestrator({"io": BoardSpec("tests.hil.test_rc_receivers:RcSinkBoard")}, wiring,
                        world=DeviceHub(rig), quantum_ns=quantum,
                        mode="local")
    with orch:
        orch.run(300 * MS)
        board = orch.handles["io"].board
    # S.BUS frames start on the quantum grid, so their bytes arrive exactly either way.
    assert board.sbus_rx[:25] == list(itertools.islice(uart_bytes(
        [("rc_sbus", 14 * MS, (100_000, 8, "E", 2, True, sbus.frame_bytes(rig.tx.sample(0))))]),
        25))
    dec = SbusDecoder()
    assert any(dec.feed_byte(t // 1000, b) for t, b in board.sbus_rx)
    assert dec.channels[0] == 1234
    pdec = PpmDecoder()
    out = [pdec.feed_edge(t // 1000, lvl) for t, lvl in board.ppm_rx]
    if lead:  # edges applied at their own stamps: the IO's capture sees the real widths
        assert any(out) and pdec.channels[0] == 1234 and pdec.frame_errors == 0
    else:  # a late pin record is applied at the quantum start: widths are destroyed
        assert not any(out) and pdec.frame_errors > 0
    assert ppm.frames_sent > 5
