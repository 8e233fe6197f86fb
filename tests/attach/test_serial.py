"""pyserial on the emulated UARTs: ``hil://TELEM1`` (the URL handler, found as ``hil shell``
finds the console) and TELEM2 bound to a pty pair (``hil fly --uart telem2=/dev/pts/N``), MAVLink
both ways through it, and the pty closed under the binding."""

from __future__ import annotations

import json
import os
import time

import serial
from pymavlink.dialects.v20 import common as mavlink2

import hil.serial_urls  # noqa: F401 - registers hil:// with pyserial
from hil.serial_urls.protocol_hil import resolve


def _heartbeats(parser: mavlink2.MAVLink, data: bytes) -> list:
    out = []
    for b in data:
        try:
            m = parser.parse_char(bytes([b]))
        except mavlink2.MAVError:
            continue
        if m is not None and m.get_type() == "HEARTBEAT":
            out.append(m)
    return out


def test_hil_url_reaches_telem1(can_rig, tmp_path, monkeypatch):
    runtime = tmp_path / "runtime"
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(runtime))
    (runtime / "fmu-hil").mkdir(parents=True)
    (runtime / "fmu-hil" / f"{os.getpid()}.json").write_text(json.dumps({
        "pid": os.getpid(), "started": time.time(),
        "uart": {"TELEM1": can_rig.dev["telem1"].tcp_port}}))
    assert resolve("hil://telem1") == ("TELEM1", can_rig.dev["telem1"].tcp_port)
    port = serial.serial_for_url("hil://TELEM1", baudrate=57600, timeout=0)
    try:
        can_rig.run_s(0.05)  # the bridge accepts the connection at its next poll
        parser = mavlink2.MAVLink(None)
        got: list = []
        can_rig.run_until(lambda: got.extend(_heartbeats(parser, port.read(4096))) or got, 30,
                          "a HEARTBEAT on hil://TELEM1", step_s=0.2)
        assert got[0].autopilot == mavlink2.MAV_AUTOPILOT_PX4
    finally:
        port.close()
    try:
        serial.serial_for_url("hil://TELEM9")
        raise AssertionError("hil://TELEM9 opened")
    except ValueError as exc:
        assert "no running emulator announces UART 'TELEM9'" in str(exc)


def test_telem2_bound_to_a_pty_carries_mavlink_both_ways_then_survives_its_loss(can_rig):
    master = can_rig.telem2_master
    binding = can_rig.dev["uart_bindings"]["telem2"]
    status, out = can_rig.orch.call("fmu", "shell", "mavlink start -d /dev/ttyS2")
    assert status == 0, out
    parser = mavlink2.MAVLink(None)
    got: list = []

    def read_master() -> list:
        try:
            got.extend(_heartbeats(parser, os.read(master, 4096)))
        except BlockingIOError:
            pass
        return got

    can_rig.run_until(read_master, 30, "a HEARTBEAT on the TELEM2 pty", step_s=0.2)
    link = next(d for d in can_rig.orch.call("fmu", "mavlink") if d["port"] == "/dev/ttyS2")
    gcs = mavlink2.MAVLink(None, srcSystem=255, srcComponent=190)
    hb = gcs.heartbeat_encode(mavlink2.MAV_TYPE_GCS, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    os.write(master, hb.pack(gcs) * 3)
    can_rig.run_until(lambda: next(d for d in can_rig.orch.call("fmu", "mavlink")
                                   if d["port"] == "/dev/ttyS2")["rx_messages"]
                      >= link["rx_messages"] + 3, 30, "the FMU to read the GCS heartbeats")
    assert binding.bytes_in >= 3 * len(hb.get_msgbuf()) and binding.bytes_out > 0
    os.close(master)  # the device goes away
    can_rig.telem2_master = -1
    t = can_rig.orch.t_ns
    can_rig.run_s(1.5)
    assert binding.closed and any("UART binding telem2=" in line for line in can_rig.log), \
        can_rig.log
    assert can_rig.orch.t_ns > t and not can_rig.orch.dead
