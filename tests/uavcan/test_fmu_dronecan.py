"""DroneCAN on the FMU's CAN1, in-process: the GNSS and compass nodes get node IDs from the
FMU's allocator, are asked for GetNodeInfo, and feed sensor_gps / sensor_mag; an outside node
(a python-can controller driven by this test, frames built with the dronecan package) gets the
FMU's GetNodeInfo and sees its bad transfers counted; a silenced node goes offline after 3 s."""

from __future__ import annotations

from types import SimpleNamespace

import can
import dronecan
import dronecan.transport as dt

from board.can import CanController
from fmu.board import FmuV2Board
from firmware.drivers.device import BUS_TYPE_UAVCAN, DeviceId
from firmware.lib.uavcan.transfer import encode
from hil.faults import get_kind

U = dronecan.uavcan
S = 1_000_000_000
MS = 1_000_000


def _board(tmp_path, nodes, enable=2, **kw):
    return FmuV2Board(seed=3, fram_path=str(tmp_path / "fram.bin"), sd_root=str(tmp_path),
                      params={"SYS_AUTOSTART": 0, "UAVCAN_ENABLE": enable}, uavcan_nodes=nodes,
                      **kw)


def _instances(b, topic):
    return [m for i in range(4) if (m := b.ctl_topic(topic, i)) is not None]


def _frames_from(tester, src):
    out = []
    while (m := tester.recv()) is not None:
        if m.arbitration_id & 0x7F == src:
            out.append(dt.Frame(m.arbitration_id, bytes(m.data)))
    return out


def test_allocation_node_info_and_sensors_from_can_nodes(tmp_path):
    # the serial GPS left out: the CAN GNSS is then sensor_gps instance 0, the one EKF2 reads
    b = _board(tmp_path, ("gnss", "mag"), exclude=("ublox_m8",))
    k = b.kernel
    gnss, mag = b.can_nodes
    assert gnss.node_id == 0 and mag.node_id == 0
    k.run(6 * S)
    # dynamic node-ID allocation completed for both, with distinct IDs from the FMU's table
    assert {gnss.node_id, mag.node_id} <= set(range(2, 126)) and gnss.node_id != mag.node_id
    ok, out = b.ctl_shell("uavcan status")
    assert ok == 0
    assert f"{gnss.node_id}: '{gnss.unique_id.hex()}'" in out
    assert f"{mag.node_id}: '{mag.unique_id.hex()}'" in out
    # node discovery: the FMU asked both for GetNodeInfo and lists them by name
    assert gnss.stats()["node_info_requests"] >= 1 and mag.stats()["node_info_requests"] >= 1
    assert f"node {gnss.node_id}: online, org.hil.gnss sw 1.4" in out
    assert f"node {mag.node_id}: online, org.hil.mag sw 1.2" in out
    st = b.ctl_topic("can_interface_status")
    assert st["nodes_online"] == 2 and st["state"] == 0 and st["tx_timeouts"] == 0
    # Fix2 -> sensor_gps with a UAVCAN device ID, at the world's position
    gps = b.ctl_topic("sensor_gps", 0)
    dev = DeviceId.decode(gps["device_id"])
    assert (dev.bus_type, dev.address, dev.devtype) == (BUS_TYPE_UAVCAN, gnss.node_id, 0x85)
    assert gps["fix_type"] == 3 and gps["satellites_used"] >= 8 and 0.3 < gps["eph"] < 5
    assert abs(gps["latitude_deg"] - b.env.lat_deg) < 5e-5
    assert abs(gps["longitude_deg"] - b.env.lon_deg) < 5e-5
    assert 15 <= gps["_count"] <= 5 * 6 and gps["hdop"] < 5 and gps["time_utc_usec"] > 0
    # MagneticFieldStrength2 -> sensor_mag, external, near the world's field
    (m,) = [m for m in _instances(b, "sensor_mag")
            if DeviceId.decode(m["device_id"]).bus_type == BUS_TYPE_UAVCAN]
    assert DeviceId.decode(m["device_id"]).address == mag.node_id and m["is_external"]
    assert all(abs(v - e) < 0.02 for v, e in zip((m["x"], m["y"], m["z"]), b.env.mag_gauss))


def test_outside_node_gets_node_info_and_bad_transfers_are_counted(tmp_path):
    b = _board(tmp_path, (), enable=1)
    k = b.kernel
    tester = CanController(b.can["CAN1"], "tester", rx_fifo_depth=64)
    k.run(1 * S)
    while tester.recv() is not None:
        pass
    tester.send(encode(U.protocol.GetNodeInfo.Request(), 50, 7, dest=1)[0])
    frames = []
    t = k.now_ns
    while k.now_ns < t + 100 * MS and not (frames and frames[-1].end_of_transfer):
        k.run(k.now_ns + MS)
        frames += _frames_from(tester, 1)
        frames = [f for f in frames if f.message_id & 0x80]  # the service response only
    resp = dt.Transfer()
    resp.from_frames(frames)  # the package checks the CRC and the toggle bits
    assert resp.service_not_message and not resp.request_not_response
    assert (resp.dest_node_id, resp.transfer_id) == (50, 7)
    assert resp.payload.name.decode() == "org.pixhawk.fmuv2"
    assert (resp.payload.software_version.major, resp.payload.software_version.minor) == (1, 14)
    # a bad CRC and a bad toggle bit from the outside node: counted, dropped, no crash
    r = U.protocol.GetNodeInfo.Response()
    r.name = "org.hil.bad"
    good = encode(r, 50, 3, dest=1)

    def flip(msg, i, mask):
        d = bytearray(msg.data)
        d[i] ^= mask
        return can.Message(arbitration_id=msg.arbitration_id, is_extended_id=True,
                           data=bytes(d))

    for bad in ([good[0], flip(good[1], 1, 0x04)] + good[2:],
                [good[0], flip(good[1], 7, 0x20)] + good[2:]):
        for f in bad:
            while not tester.send(f):
                k.run(k.now_ns + 100_000)
            k.run(k.now_ns + 300_000)
    k.run(k.now_ns + 50 * MS)
    _, out = b.ctl_shell("uavcan status")
    assert "bad_crc 1" in out and "bad_toggle 1" in out
    assert "uavcan" in b.system.modules.running()
    st = b.ctl_topic("can_interface_status")
    assert st["state"] == 0


def test_silent_node_goes_offline_after_3_s_and_comes_back(tmp_path):
    b = _board(tmp_path, ("gnss@20",), enable=1)
    k = b.kernel
    node = b.can_nodes[0]
    k.run(3 * S)
    assert b.ctl_topic("can_interface_status")["nodes_online"] == 1
    gps = [m for m in _instances(b, "sensor_gps")
           if DeviceId.decode(m["device_id"]).bus_type == BUS_TYPE_UAVCAN]
    assert gps and gps[0]["fix_type"] == 3
    kind = get_kind("bus.can_node_silent")
    orch = SimpleNamespace(handles={"fmu": None}, t_ns=0,
                           call=lambda name, method, *args: b.call(method, *args))
    rig = SimpleNamespace(orch=orch, dev={})
    params = kind.check("fmu.can_gnss@20", {})
    token = kind.start(rig, "fmu.can_gnss@20", params, k.now_ns)
    t_fault = k.now_ns
    fixes = node.fixes_tx
    k.run(t_fault + 1_950 * MS)
    assert b.ctl_topic("can_interface_status")["nodes_online"] == 1  # not before 2 s
    k.run(t_fault + 3_100 * MS)
    assert b.ctl_topic("can_interface_status")["nodes_online"] == 0
    assert node.fixes_tx == fixes  # a silent node sends nothing
    _, out = b.ctl_shell("uavcan status")
    assert "node 20: offline, org.hil.gnss" in out
    assert any("node 20 (org.hil.gnss) offline" in m[3] for m in b.ctl_dmesg())
    kind.stop(rig, "fmu.can_gnss@20", params, k.now_ns, token)
    k.run(k.now_ns + 1_100 * MS)
    assert b.ctl_topic("can_interface_status")["nodes_online"] == 1
    assert any("node 20 (org.hil.gnss) back online" in m[3] for m in b.ctl_dmesg())


def test_a_bitrate_other_than_the_bus_keeps_the_driver_off_and_says_why(tmp_path):
    b = FmuV2Board(seed=3, fram_path=str(tmp_path / "fram.bin"), sd_root=str(tmp_path),
                   params={"SYS_AUTOSTART": 0, "UAVCAN_ENABLE": 1, "UAVCAN_BITRATE": 500_000})
    b.kernel.run(600 * MS)
    assert "uavcan" not in b.system.modules.running()
    assert any("UAVCAN_BITRATE 500000" in m[3] and "1000000 bit/s" in m[3]
               for m in b.ctl_dmesg())
    assert not b.can_ctrl["CAN1"].enabled
