"""The uORB bridge module on both ends of a serial cable (tests/bridge/rig.py): every topic of
the default list round-trips field-exact both ways, bad frames on the wire are dropped and
counted by cause, the link's loss is detected in the configured time, rates are kept, a full
transmit buffer drops frames instead of blocking, and a bad start fails with its reason."""

from __future__ import annotations

import random
import struct

import pytest

from firmware.modules.uorb_bridge.protocol import HEADER_SIZE, encode_frame
from firmware.platform.uorb import Subscription
from tests.bridge.rig import Rig


def random_msg(orb, topic: str, rng: random.Random):
    """A message of ``topic``'s type with every field set to a random value of its type
    (floats finite, as a float32 holds them), via the packed layout."""
    mdef = orb.registry.topic(topic)
    st = mdef.struct
    values: list = []
    for count, code in struct_codes(st.format):
        for _ in range(1 if code == "s" else count):
            if code == "s":
                values.append(bytes(rng.randrange(32, 127) for _ in range(count)))
            elif code in "fd":
                values.append(struct.unpack("<f", struct.pack("<f", rng.uniform(-1e4, 1e4)))[0])
            elif code == "?":
                values.append(rng.random() < 0.5)
            else:
                bits = struct.calcsize(code) * 8
                lo, hi = (0, 2 ** bits - 1) if code.isupper() else \
                    (-2 ** (bits - 1), 2 ** (bits - 1) - 1)
                values.append(rng.randint(lo, hi))
    return mdef.cls.unpack(st.pack(*values))


def struct_codes(fmt: str):
    """(count, code) pairs of a struct format string."""
    out, num = [], ""
    for ch in fmt.lstrip("<"):
        if ch.isdigit():
            num += ch
            continue
        out.append((int(num) if num else 1, ch))
        num = ""
    return out


@pytest.fixture
def rig():
    r = Rig()
    r.start()
    r.run_ms(50)
    return r


def test_every_topic_round_trips_field_exact_both_ways(rig):
    rng = random.Random(24)
    cfg = rig.fmu.bridge.config
    assert cfg is not None
    for sender, receiver, routes in ((rig.fmu, rig.comp, cfg.fmu_to_companion),
                                     (rig.comp, rig.fmu, cfg.companion_to_fmu)):
        for r in routes:
            sub = Subscription(receiver.orb, r.publish_as, r.instance)
            sent = [random_msg(sender.orb, r.topic, rng) for _ in range(3)]
            got = []
            for msg in sent:
                sender.publish(r.topic, msg, r.instance)
                # past the rate limit's slot: every message here must arrive
                rig.run_ms(max(5.0, 1000.0 / r.rate_hz + 1 if r.rate_hz else 5.0))
                got.append(sub.update())
            assert [m.pack() for m in got if m is not None] == [m.pack() for m in sent], r
            assert got == sent
    for side in (rig.fmu, rig.comp):
        d = side.bridge.decoder.drops
        assert (d.frames, d.garbage_bytes, d.lost, side.bridge.tx_dropped) == (0, 0, 0, 0)


def test_rename_publishes_under_the_other_topic(rig):
    plain = Subscription(rig.fmu.orb, "vehicle_rates_setpoint")
    renamed = Subscription(rig.fmu.orb, "companion_rates_setpoint")
    rig.comp.publish("vehicle_rates_setpoint", rig.comp.orb.new("vehicle_rates_setpoint",
                                                                roll=0.5))
    rig.run_ms(5)
    assert not plain.updated() and renamed.update().roll == 0.5


def test_queued_topic_sends_every_message(rig):
    sub = Subscription(rig.fmu.orb, "vehicle_command")
    for i in range(5):                       # in one instant: the queue holds them all
        rig.comp.publish("vehicle_command", rig.comp.orb.new("vehicle_command", command=i + 1))
    rig.run_ms(10)
    assert [m.command for m in sub.update_all()] == [1, 2, 3, 4, 5]


def test_rates_every_update_and_limited(rig):
    att = Subscription(rig.comp.orb, "vehicle_attitude")
    sc = Subscription(rig.comp.orb, "sensor_combined")
    got = {"att": 0, "sc": 0}
    for _ in range(250):                     # 1 s at 250 Hz
        rig.fmu.publish("vehicle_attitude", rig.fmu.orb.new("vehicle_attitude"))
        rig.fmu.publish("sensor_combined", rig.fmu.orb.new("sensor_combined"))
        rig.run_ms(4)
        got["att"] += len(att.update_all())
        got["sc"] += len(sc.update_all())
    assert got["att"] == 250                  # rate_hz 0: every update
    assert 49 <= got["sc"] <= 51              # rate_hz 50


def _inject(rig, data: bytes) -> None:
    """Bytes on the FMU's TX line, as if its transmitter (or the cable) produced them."""
    rig.fmu.uart.write(data)


def test_bad_frames_dropped_and_counted_by_cause(rig):
    comp = rig.comp.bridge
    route = next(r for r in comp.config.fmu_to_companion if r.topic == "vehicle_status")
    good = rig.fmu.orb.new("vehicle_status", nav_state=7).pack()
    sub = Subscription(rig.comp.orb, "vehicle_status")
    corrupt = bytearray(encode_frame(route.topic_id, 0, 200, good))
    corrupt[HEADER_SIZE + 5] ^= 0x04
    truncated = encode_frame(route.topic_id, 0, 201, good)[:HEADER_SIZE + 10]
    unknown = encode_frame(0x5EEDBEEF, 0, 202, good)
    wrong_size = encode_frame(route.topic_id, 0, 203, good + b"\0")
    garbage = b"\x00\x11garbage\xb7\x22 more"
    before = comp.rx_frames
    _inject(rig, bytes(corrupt) + truncated + unknown + wrong_size + garbage
            + encode_frame(route.topic_id, 0, 204, good))
    rig.run_ms(20)
    d = comp.decoder.drops
    assert (d.crc, d.truncated, d.unknown_id, d.bad_size) == (1, 1, 1, 1)
    assert d.garbage_bytes >= len(garbage)
    assert sub.update().nav_state == 7 and comp.rx_frames > before   # resynchronised
    rig.run_ms(250)                                                   # a status publication
    st = Subscription(rig.comp.orb, "bridge_status").copy()
    assert (st.rx_crc_errors, st.rx_truncated, st.rx_unknown_id, st.rx_bad_size) == \
        (1, 1, 1, 1) and st.link_ok
    rig.comp.lines.clear()
    assert rig.comp.cmd("uorb_bridge status") == 0
    text = "".join(rig.comp.lines)
    assert "rx dropped: crc 1, truncated 1, unknown id 1, bad size 1" in text


def test_link_loss_detected_in_the_timeout_and_regained(rig):
    comp = rig.comp.bridge
    timeout_us = comp.config.link_timeout_ms * 1000
    for _ in range(20):                       # traffic at 100 Hz, then the cable is cut
        rig.fmu.publish("vehicle_attitude", rig.fmu.orb.new("vehicle_attitude"))
        rig.run_ms(10)
    assert comp.link_ok and rig.fmu.bridge.link_ok
    cut_us = rig.now_us
    last_rx_us = comp.last_rx_us
    rig.wire.disconnect()
    rig.run_ms(3 * comp.config.link_timeout_ms)
    lost = [(t, text) for t, _s, _m, text in rig.comp.platform.dmesg if text == "link lost"]
    assert len(lost) == 1                     # reported once, not every poll
    t_lost = lost[0][0]
    # quiet for exactly the timeout after the last frame; the last frame came < 10 ms
    # before the cut
    assert t_lost - last_rx_us == timeout_us
    assert timeout_us - 10_000 <= t_lost - cut_us <= timeout_us
    assert not comp.link_ok and comp.link_lost_count == 1
    st = Subscription(rig.comp.orb, "bridge_status").copy()
    assert not st.link_ok and st.link_lost_count == 1
    assert "link lost" in rig.fmu.dmesg()     # the FMU side too (heartbeats stopped)
    from board.uart import UartWire
    rig.wire = UartWire(rig.fmu.uart, rig.comp.uart)
    rig.run_ms(500)
    assert comp.link_ok and rig.comp.dmesg().count("link regained") == 1
    assert comp.decoder.drops.lost == 0       # the outage is a lost link, not lost frames
    assert Subscription(rig.comp.orb, "bridge_status").copy().link_ok


def test_stopped_peer_is_a_lost_link(rig):
    assert rig.comp.cmd("uorb_bridge stop") == 0
    rig.run_ms(rig.fmu.bridge.config.link_timeout_ms + 250)
    assert not rig.fmu.bridge.link_ok and rig.fmu.dmesg().count("link lost") == 1


def test_full_tx_buffer_drops_frames_and_never_corrupts():
    rig = Rig()
    assert rig.fmu.cmd("uorb_bridge start -d /dev/ttyS2 -r fmu -b 57600") == 0
    assert rig.comp.cmd("uorb_bridge start -d /dev/ttyUSB0 -r companion -b 57600") == 0
    att = Subscription(rig.comp.orb, "vehicle_attitude")
    got = []
    for i in range(500):                      # 61-byte frames at 500 Hz: 5x what 57600 carries
        rig.fmu.publish("vehicle_attitude", rig.fmu.orb.new("vehicle_attitude",
                                                            timestamp=i + 1))
        rig.run_ms(2)
        got += [m.timestamp for m in att.update_all()]
    fmu, comp = rig.fmu.bridge, rig.comp.bridge
    assert fmu.tx_dropped > 250 and fmu.port.tx_dropped == 0     # whole frames, never bytes
    assert comp.decoder.drops.frames == 0 and comp.decoder.drops.garbage_bytes == 0
    assert len(got) > 50 and got == sorted(got)


@pytest.mark.parametrize("args, reason", [
    ("-d /dev/ttyS2 -r fmu -c /etc/bridge/none.yaml", "cannot read"),
    ("-d /dev/ttyS2 -r fmu -c /fs/microsd/bad.yaml", "not valid YAML"),
    ("-d /dev/ttyS2 -r fmu -c /fs/microsd/unknown.yaml", "unknown uORB topic 'nope'"),
    ("-d /dev/ttyS9 -r fmu", "no serial device /dev/ttyS9"),
    ("-d /dev/ttyS2 -r plane", "-r must be fmu or companion"),
    ("-d /dev/ttyS2", "missing -r"),
    ("-d /dev/ttyS2 -r fmu -b fast", "bad baud rate"),
    ("-d /dev/ttyS2 -r fmu -b p:NO_SUCH", "no parameter NO_SUCH"),
])
def test_bad_start_fails_with_the_reason(tmp_path, args, reason):
    (tmp_path / "bad.yaml").write_text("fmu_to_companion: [\n")
    (tmp_path / "unknown.yaml").write_text("fmu_to_companion: [{topic: nope}]\n")
    rig = Rig(sd_root=tmp_path)
    assert rig.fmu.cmd(f"uorb_bridge start {args}") == 1
    assert reason in "".join(rig.fmu.lines)
    assert not rig.fmu.system.modules.is_running("uorb_bridge")
    # the port was released: a good start works afterwards
    assert rig.fmu.cmd("uorb_bridge start -d /dev/ttyS2 -r fmu") == 0


def test_late_peer_joins_the_stream_cleanly():
    """The companion starts while the FMU has been sending for a while: what its UART
    buffered (and overran) before the port opened is flushed, not parsed as cut frames."""
    rig = Rig()
    assert rig.fmu.cmd("uorb_bridge start -d /dev/ttyS2 -r fmu") == 0
    for _ in range(100):
        rig.fmu.publish("vehicle_attitude", rig.fmu.orb.new("vehicle_attitude"))
        rig.run_ms(5)
    assert rig.comp.uart.in_waiting == 1024 and rig.comp.uart.overruns > 0   # overran
    assert rig.comp.cmd("uorb_bridge start -d /dev/ttyUSB0 -r companion") == 0
    att = Subscription(rig.comp.orb, "vehicle_attitude")
    n = 0
    for _ in range(100):
        rig.fmu.publish("vehicle_attitude", rig.fmu.orb.new("vehicle_attitude"))
        rig.run_ms(5)
        n += len(att.update_all())
    d = rig.comp.bridge.decoder.drops
    assert n == 100 and (d.frames, d.lost) == (0, 0)


def test_heartbeats_carry_the_peers_counters(rig):
    for _ in range(50):
        rig.fmu.publish("vehicle_attitude", rig.fmu.orb.new("vehicle_attitude"))
        rig.run_ms(10)
    fmu, comp = rig.fmu.bridge, rig.comp.bridge
    hb_us = 1e6 / comp.config.heartbeat_hz
    assert comp.heartbeats_rx >= 0.5e6 / hb_us
    peer = comp.peer                           # the FMU's counters when it last sent one
    assert 0 <= rig.now_us - peer.uptime_us <= hb_us + 1000
    assert 30 < peer.tx_frames <= fmu.tx_frames and 0 < peer.rx_frames <= fmu.rx_frames
    st = Subscription(rig.comp.orb, "bridge_status").copy()
    assert 0 < st.peer_tx_frames <= peer.tx_frames     # as of its last publication
