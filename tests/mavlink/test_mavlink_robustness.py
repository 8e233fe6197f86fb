"""What a link must survive: garbage, unknown and wrongly-addressed messages, floods; and
MAVLink 2 signing refusing unsigned commands."""

from pymavlink.dialects.v20 import common as mav

from tests.mavlink.conftest import open_session


def _unknown_frame(gcs, msg_id=60001):
    msg = mav.MAVLink_message(msg_id, "NOT_IN_COMMON")
    buf = msg._pack(gcs.mav, 42, b"\x01\x02\x03")
    gcs.mav.seq = (gcs.mav.seq + 1) % 256
    return buf


def test_malformed_and_unknown_counted_and_ignored(session):
    gcs = session.gcs
    c0 = session.counters()
    good = mav.MAVLink_param_request_read_message(1, 1, b"MAV_SYS_ID", -1).pack(gcs.mav)
    bad_crc = bytearray(good)
    bad_crc[-1] ^= 0xFF
    gcs.send_bytes(_unknown_frame(gcs))                              # id not in the dialect
    gcs.send(mav.MAVLink_gps_raw_int_message(0, 3, 0, 0, 0, 0, 0, 0, 0, 0))  # known, unhandled
    gcs.send_bytes(bytes(range(1, 200)))                             # no start marker at all
    gcs.send_bytes(bytes(bad_crc))                                   # CRC error
    # A truncated frame swallows what follows up to its announced length (as in PX4's parser);
    # a frame's worth of idle bytes later the parser is in step again.
    gcs.send_bytes(good[:7] + bytes(280))
    gcs.step(0.1)
    c1 = session.counters()
    assert c1["rx_errors"] > c0["rx_errors"]
    assert c1["rx_unknown"] == c0["rx_unknown"] + 1
    assert c1["rx_unhandled"] == c0["rx_unhandled"] + 1
    assert gcs.param_get("MAV_SYS_ID") == 1  # the parser resynchronised
    assert not session.orch.dead


def test_flood_does_not_stop_the_module(session):
    gcs = session.gcs
    c0 = session.counters()
    mark = gcs.mark()
    att = mav.MAVLink_attitude_message(0, 0, 0, 0, 0, 0, 0)
    for _ in range(300):   # 300 quanta, each with 50 messages: 15000 messages in 0.3 s
        gcs.send_bytes(b"".join(att.pack(gcs.mav) for _ in range(50)))
        session.orch.step()
    gcs.step(1.0)
    c1 = session.counters()
    assert c1["rx_lost"] > c0["rx_lost"]          # the port dropped what could not be read
    assert c1["max_cost_ns"] < 10_000_000          # no run longer than the loop interval
    hbs = [t for t, m in gcs.log[mark - gcs._base:] if m.get_type() == "HEARTBEAT"]
    assert len(hbs) >= 1
    assert gcs.param_get("MAV_SYS_ID") == 1


def test_signing_refuses_unsigned_commands(tmp_path):
    key = bytes(range(32))
    s = open_session(tmp_path)
    try:
        gcs = s.gcs
        gcs.wait_heartbeat()
        s.shell("mavlink signing --key " + key.hex())
        assert (tmp_path / "sd" / "mavlink" / "mavlink-signing-key.bin").read_bytes()[:32] == key
        assert "active" in s.shell("mavlink signing")
        gcs.step(0.1)
        mark = gcs.mark()
        req = [mav.MAVLINK_MSG_ID_AUTOPILOT_VERSION]
        gcs.send(mav.MAVLink_command_long_message(1, 1, mav.MAV_CMD_REQUEST_MESSAGE, 0, *req,
                                                  0, 0, 0, 0, 0, 0))
        gcs.step(0.3)
        assert not gcs.messages("COMMAND_ACK", mark)
        assert s.counters()["rx_unsigned_rejected"] >= 1
        # Signed with the right key: accepted, and the vehicle's answers are signed too.
        gcs.set_signing_key(key)
        ack = gcs.command_long(mav.MAV_CMD_REQUEST_MESSAGE, req, retries=0)
        assert ack.result == mav.MAV_RESULT_ACCEPTED and ack._signed
        # A wrong key is refused like no signature.
        gcs.set_signing_key(bytes(32 * [7]))
        mark = gcs.mark()
        gcs.send(mav.MAVLink_command_long_message(1, 1, mav.MAV_CMD_REQUEST_MESSAGE, 0, *req,
                                                  0, 0, 0, 0, 0, 0))
        gcs.step(0.3)
        assert not [m for m in gcs.messages(None, mark) if m.get_type() == "COMMAND_ACK"]
        gcs.set_signing_key(key)
        s.shell("mavlink signing off")
        gcs.set_signing_key(None)
        assert gcs.command_long(mav.MAV_CMD_REQUEST_MESSAGE, req).result == \
            mav.MAV_RESULT_ACCEPTED
    finally:
        s.close()
