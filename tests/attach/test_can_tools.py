"""python-can's own tools and a dronecan node on the FMU's CAN1 through the ``hil`` plug-in.

The logger and the player run as separate processes (``python -m can.logger -i hil -c CAN1``),
finding the emulator as ``hil shell`` does (an instance file in the runtime folder, here a
temporary one); the dronecan node runs in this process, where the plug-in drives the emulator
in virtual time while the node waits for frames.
"""

from __future__ import annotations

import json
import os
import re
import pty
import select
import signal
import subprocess
import sys
import time

import can
import dronecan
import pytest

from hil.can_interface_host import TcpEndpoint
from dronecan.transport import Transfer

from tests.helpers import ctrl_c_reaches_child

from .conftest import FMU_NODE_ID, FMU_NODE_STATUS_ID


@pytest.fixture
def announced(can_rig, tmp_path, monkeypatch):
    """An instance file announcing the rig's CAN1 endpoint, in a runtime folder of the test's
    own (so no running ``hil fly`` interferes); returns the environment for tools."""
    runtime = tmp_path / "runtime"
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(runtime))
    (runtime / "fmu-hil").mkdir(parents=True)
    (runtime / "fmu-hil" / f"{os.getpid()}.json").write_text(json.dumps({
        "pid": os.getpid(), "started": time.time(),
        "can": {"CAN1": {"port": can_rig.host.tcp_port, "bitrate": 1_000_000}}}))
    env = {**os.environ, "XDG_RUNTIME_DIR": str(runtime)}
    env.pop("CAN_CONFIG", None)
    return env


def _tcp_clients(rig) -> int:
    return sum(isinstance(e, TcpEndpoint) and not e.closed for e in rig.host.endpoints)


def test_can_logger_records_the_fmu_node_status(can_rig, announced, tmp_path):
    path = tmp_path / "can1.log"
    proc = subprocess.Popen([sys.executable, "-m", "can.logger", "-i", "hil", "-c", "CAN1",
                             "-f", str(path)], env=announced, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True,
                            preexec_fn=ctrl_c_reaches_child)  # noqa: PLW1509
    try:
        can_rig.run_until(lambda: _tcp_clients(can_rig) or proc.poll() is not None, 60,
                          "can.logger to connect")
        assert proc.poll() is None, proc.communicate()[0]
        t0 = can_rig.orch.t_ns
        can_rig.run_s(2.6)  # two or three NodeStatus
        # the frames are on their way through the socket: give the logger a moment
        time.sleep(0.3)
    finally:
        proc.send_signal(signal.SIGINT)
        out = proc.communicate(timeout=120)[0]  # generous: a loaded machine
    assert "Connected to HilBus" in out, out
    frames = [m for m in can.LogReader(str(path)) if m.arbitration_id == FMU_NODE_STATUS_ID]
    assert len(frames) >= 2, f"logger wrote {len(frames)} NodeStatus frames:\n{out}"
    uptimes = [int.from_bytes(m.data[:4], "little") for m in frames]
    assert uptimes == sorted(uptimes) and uptimes[-1] > uptimes[0]
    # unpaced: timestamps are the frames' virtual times (end of frame on the bus), 1 s apart
    assert all(t0 / 1e9 < m.timestamp <= can_rig.orch.t_ns / 1e9 for m in frames)
    gaps = [b.timestamp - a.timestamp for a, b in zip(frames, frames[1:])]
    assert all(abs(g - 1.0) < 0.02 for g in gaps), gaps


def test_can_player_replays_a_recording_that_the_fmu_sees(can_rig, announced, tmp_path):
    recording = tmp_path / "node77.asc"
    with can.Logger(str(recording)) as writer:
        for i in range(3):  # NodeStatus of node 77, serialised by dronecan
            status = dronecan.uavcan.protocol.NodeStatus(uptime_sec=10 + i)
            (frame,) = Transfer(payload=status, source_node_id=77, transfer_id=i,
                                transfer_priority=16, service_not_message=False).to_frames()
            writer(can.Message(timestamp=100.0 + 0.2 * i, arbitration_id=frame.message_id,
                               is_extended_id=True, data=bytes(frame.bytes)))
    assert "node 77" not in can_rig.uavcan_status()
    before = can_rig.uavcan()["node_status_rx"]
    proc = subprocess.Popen([sys.executable, "-m", "can.player", "-i", "hil", "-c", "CAN1",
                             str(recording)], env=announced, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True,
                            preexec_fn=ctrl_c_reaches_child)  # noqa: PLW1509
    try:
        can_rig.run_until(lambda: proc.poll() is not None, 60, "can.player to finish")
        can_rig.run_s(0.1)  # the last frames cross into the board
    finally:
        if proc.poll() is None:
            proc.kill()
        out = proc.communicate(timeout=120)[0]  # generous: a loaded machine
    assert proc.returncode == 0, out
    assert can_rig.uavcan()["node_status_rx"] - before == 3
    status = can_rig.uavcan_status()
    assert re.search(r"node 77: online, .*uptime 12 s", status), status


def test_can_viewer_starts_and_shows_the_fmu_frames(can_rig, announced):
    """can.viewer is a curses program: it runs on a pseudo-terminal and its screen must show
    the FMU's NodeStatus identifier."""
    master, slave = pty.openpty()
    env = {**announced, "TERM": "xterm", "LINES": "40", "COLUMNS": "120"}
    proc = subprocess.Popen([sys.executable, "-m", "can.viewer", "-i", "hil", "-c", "CAN1"],
                            env=env, stdin=slave, stdout=slave, stderr=slave,
                            start_new_session=True,
                            preexec_fn=ctrl_c_reaches_child)  # noqa: PLW1509
    os.close(slave)
    screen = bytearray()
    try:
        def shown() -> bool:
            while select.select([master], [], [], 0)[0]:
                try:
                    screen.extend(os.read(master, 65536))
                except OSError:
                    return True
            return b"10015501" in bytes(screen).upper() or proc.poll() is not None

        can_rig.run_until(shown, 60, "can.viewer to show a NodeStatus frame", step_s=0.2)
        assert proc.poll() is None, bytes(screen).decode(errors="replace")
    finally:
        if proc.poll() is None:
            os.write(master, b"q")  # the viewer's own quit key
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(10)
        os.close(master)
    assert f"{FMU_NODE_STATUS_ID:X}".encode() in bytes(screen).upper()


def test_dronecan_node_sees_the_fmu_and_the_fmu_sees_it(can_rig):
    """dronecan.make_node through python-can's 'hil' interface (the channel is registered in
    this process; dronecan passes no other argument to python-can)."""
    node = dronecan.make_node("CAN1", bustype="hil", bitrate=1000000, node_id=100)
    heard: dict[int, list[int]] = {}
    node.add_handler(dronecan.uavcan.protocol.NodeStatus,
                     lambda e: heard.setdefault(e.transfer.source_node_id, []).append(
                         e.message.uptime_sec))
    try:
        end = can_rig.orch.t_ns + 4_000_000_000
        while can_rig.orch.t_ns < end and len(heard.get(FMU_NODE_ID, [])) < 2:
            node.spin(0.001)
        fmu = heard.get(FMU_NODE_ID, [])
        assert len(fmu) >= 2 and fmu[-1] > fmu[0], heard
        # dronecan sends its own NodeStatus once a (wall-clock) second: let it
        can_rig.run_until(lambda: "node 100: online" in can_rig.uavcan_status() or
                          node.spin(0.001), 10, "the FMU to list node 100", step_s=0.01)
    finally:
        node.close()


def test_bitrate_mismatch_and_unknown_channel_are_clear_errors(can_rig, announced):
    with pytest.raises(can.CanInitializationError, match="1000000 bit/s, not 500000"):
        can.Bus(interface="hil", channel="CAN1", bitrate=500_000)
    with pytest.raises(can.CanInitializationError, match="no running emulator announces"):
        can.Bus(interface="hil", channel="CAN2")
    configs = can.detect_available_configs(interfaces=["hil"])
    assert {"interface": "hil", "channel": "CAN1", "port": can_rig.host.tcp_port} in configs


def test_garbage_from_a_tcp_client_is_counted_and_dropped(can_rig):
    """A client speaking nonsense costs it its bad records, not the emulator; its valid record
    after them still reaches the bus."""
    import socket

    from hil.can_interface_wire import RECORD, WireFrame, encode

    bad_before = can_rig.host.bad_records
    sent_before = can_rig.orch.call("fmu", "can_stats", "CAN1")["host"]["sent"]
    with socket.create_connection(("127.0.0.1", can_rig.host.tcp_port)) as sock:
        garbage = bytes([9, 0xFF, 20, 0]) + bytes(RECORD.size - 4)   # kind 9, bad flags, DLC 20
        ok = encode(WireFrame(1, 0x321, False, False, b"\x07"))
        sock.sendall(garbage * 3 + ok)
        can_rig.run_until(lambda: can_rig.host.bad_records >= bad_before + 3, 30,
                          "the bad records to be counted")
        can_rig.run_s(0.05)
    assert can_rig.host.bad_records == bad_before + 3
    assert can_rig.orch.call("fmu", "can_stats", "CAN1")["host"]["sent"] == sent_before + 1
