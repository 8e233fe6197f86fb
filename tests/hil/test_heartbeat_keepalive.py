"""The bridge's heartbeat keepalive: a slow emulator looks slow to clients, not lost.

A fake wall clock drives hil.mavlink_bridge (no sleeps); the client is a real UDP socket and
pymavlink decodes what it gets.
"""

import socket

from pymavlink.dialects.v20 import common as mavlink2

from hil.mavlink_bridge import HeartbeatKeepalive, MavlinkUdpBridge, heartbeat_frame

S = 1_000_000_000


class FakeClock:
    def __init__(self):
        self.t_s = 100.0

    def __call__(self):
        return self.t_s


def _mav():
    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    mav.robust_parsing = True
    return mav


def _heartbeat(mav, custom_mode=0):
    return mav.heartbeat_encode(mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_PX4, 0,
                                custom_mode, mavlink2.MAV_STATE_STANDBY).pack(mav)


def test_heartbeat_frame_finds_it_among_packed_frames():
    mav = _mav()
    att = mav.attitude_encode(1, 0.1, 0.2, 0.3, 0, 0, 0).pack(mav)
    hb = _heartbeat(mav, custom_mode=7)
    assert heartbeat_frame(att + hb + att) == hb
    assert heartbeat_frame(att) is None
    assert heartbeat_frame(hb[:-1]) is None  # cut short
    assert heartbeat_frame(b"") is None


def test_keepalive_resends_at_1hz_wall_only_while_the_vehicle_is_alive():
    clock = FakeClock()
    k = HeartbeatKeepalive(clock)
    assert k.due(0) is None  # nothing heard yet
    hb = _heartbeat(_mav())
    k.vehicle_sent(hb, 1 * S)
    clock.t_s += 1.4
    assert k.due(1 * S + 200_000_000) is None  # within the 1.5 s of a normal heartbeat period
    clock.t_s += 0.2
    assert k.due(1 * S + 250_000_000) == hb  # 1.6 s of wall time, 0.25 s of virtual time
    clock.t_s += 0.9
    assert k.due(1 * S + 400_000_000) is None  # 1 Hz of wall time
    clock.t_s += 0.1
    assert k.due(1 * S + 400_000_000) == hb
    # A real heartbeat restarts the wait.
    k.vehicle_sent(hb, 2 * S)
    clock.t_s += 1.0
    assert k.due(2 * S + 100_000_000) is None
    # The vehicle silent in its own time (> 2.5 s virtual): no more re-sends, the link may drop.
    clock.t_s += 10.0
    assert k.due(2 * S + 2_600_000_000) is None
    assert k.resent == 2


def test_bridge_resends_the_last_heartbeat_to_the_client_when_the_emulator_lags():
    clock = FakeClock()
    client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    client.bind(("127.0.0.1", 0))
    client.settimeout(2.0)
    bridge = MavlinkUdpBridge(endpoints=((18570, 0, client.getsockname()[1]),), clock=clock)
    try:
        mav = _mav()
        hb = _heartbeat(mav, custom_mode=0x1234)
        bridge.input("mavlink_udp", 1 * S, (18570, 14550, hb))
        assert client.recv(2048) == hb
        bridge.run_until(1 * S + 500_000)  # a quantum later, no wall time gone: nothing
        clock.t_s += 2.0  # the emulator lags: 2 s of wall time for one quantum
        bridge.run_until(1 * S + 1_000_000)
        got = client.recv(2048)
        msgs = _mav().parse_buffer(got)
        assert [m.get_type() for m in msgs] == ["HEARTBEAT"]
        assert msgs[0].custom_mode == 0x1234  # the vehicle's own, unchanged
        client.settimeout(0.0)
        bridge.run_until(1 * S + 1_500_000)  # same wall time: no second copy
        try:
            extra = client.recv(2048)
        except BlockingIOError:
            extra = None
        assert extra is None
        assert bridge.endpoints[18570].keepalive.resent == 1
    finally:
        bridge.close()
        client.close()


from hypothesis import given  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from tests.fuzzing import fuzz  # noqa: E402


@fuzz(examples=300)
@given(st.binary(max_size=300), st.binary(max_size=40))
def test_heartbeat_frame_answers_any_bytes(data, prefix):
    """Any datagram gives None or a HEARTBEAT frame cut from it; a real HEARTBEAT first in the
    datagram is never lost to whatever bytes follow it (pymavlink's parser skips them)."""
    got = heartbeat_frame(prefix + data)
    assert got is None or (got[0] in (0xFD, 0xFE) and got in prefix + data)
    hb = _heartbeat(_mav())
    after = heartbeat_frame(hb + data)
    assert after is not None and after in hb + data
