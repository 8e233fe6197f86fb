"""The UDP bridge with real sockets on 127.0.0.1: a host GCS (pymavlink over a socket) hears
the vehicle's heartbeat and gets its parameters."""

import socket

from pymavlink.dialects.v20 import common as mav

from hil.devices import DeviceHub
from hil.mavlink_bridge import MavlinkUdpBridge, UdpEndpoint, udp_wires
from hil.orchestrator import BoardSpec, Orchestrator
from tests.mavlink.conftest import BOARD, MS


def test_host_gcs_over_udp(tmp_path):
    (tmp_path / "sd").mkdir()
    gcs_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    gcs_sock.bind(("127.0.0.1", 0))
    gcs_sock.settimeout(0)
    gcs_port = gcs_sock.getsockname()[1]
    bridge = MavlinkUdpBridge("udp", [UdpEndpoint(18570, 0, gcs_port)])
    orch = Orchestrator({"fmu": BoardSpec(BOARD, {"fram_path": str(tmp_path / "fram.bin"),
                                                  "sd_root": str(tmp_path / "sd")})},
                        udp_wires("udp"), world=DeviceHub(bridge), mode="local")
    parser = mav.MAVLink(None)
    parser.robust_parsing = True
    got: list = []

    def drain():
        while True:
            try:
                data, _ = gcs_sock.recvfrom(65536)
            except BlockingIOError:
                return
            got.extend(parser.parse_buffer(data) or [])

    try:
        orch.start()
        orch.run(duration_ns=350 * MS)
        orch.run(duration_ns=1100 * MS)  # rcS started the link on FMU port 18570
        drain()
        assert any(m.get_type() == "HEARTBEAT" and m.autopilot == 12 for m in got)
        # The GCS talks from its own socket; the bridge answers to that address.
        out = mav.MAVLink(None, 255, 190)
        vehicle = ("127.0.0.1", bridge.endpoints[18570].bind_port)
        gcs_sock.sendto(out.param_request_read_encode(1, 1, b"MAV_SYS_ID", -1).pack(out),
                        vehicle)
        for _ in range(50):
            orch.run(duration_ns=10 * MS)
            drain()
            if any(m.get_type() == "PARAM_VALUE" for m in got):
                break
        pv = next(m for m in got if m.get_type() == "PARAM_VALUE")
        assert pv.param_id == "MAV_SYS_ID" and pv.param_type == mav.MAV_PARAM_TYPE_INT32
        assert bridge.endpoints[18570].client == ("127.0.0.1", gcs_port)
    finally:
        orch.close()
        bridge.close()
        gcs_sock.close()
