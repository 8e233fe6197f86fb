"""pymavlink's mavutil as a ground station on ``hil fly``'s GCS link (the vehicle sends to UDP
14550, its socket is 127.0.0.1:18570), as QGroundControl or MAVProxy would use it.

One emulator for the module; the tests run in file order:

1. parameters: the whole list (PARAM_REQUEST_LIST) against the board's ``param show``,
2. log download: LOG_REQUEST_LIST / LOG_REQUEST_DATA of the log of a short arm-disarm, bytes
   identical to the file on the emulated SD card,
3. PARAM_SET, reboot (MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN: the FMU reboots in the run, on the
   same FRAM), the value survives,
4. flood: while hovering at 10 m, garbage and unknown messages into the vehicle's socket; the
   altitude holds and mc_rate_control keeps its virtual-time rate (``top once``).
"""

from __future__ import annotations

import math
import os
import random
import re
import struct
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from tests.clients.conftest import GCS_PORT, VEHICLE_GCS_SOCKET, wait_until, wall

os.environ.setdefault("MAVLINK20", "1")
from pymavlink import mavutil
from pymavlink.generator.mavcrc import x25crc

pytestmark = [pytest.mark.slow, pytest.mark.paced]

MAV = mavutil.mavlink
ALT_M = 10.0


class Gcs:
    """A mavutil connection that heartbeats at 1 Hz (a thread) like a ground station."""

    def __init__(self) -> None:
        self.conn = mavutil.mavlink_connection(f"udpin:127.0.0.1:{GCS_PORT}", source_system=255,
                                               source_component=190, dialect="common")
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self.last: dict[str, Any] = {}
        self.texts: list[str] = []
        self._hb = threading.Thread(target=self._heartbeat, daemon=True, name="gcs-heartbeat")

    @property
    def mav(self) -> Any:
        return self.conn.mav

    def send(self, fn: str, *args: Any) -> None:
        with self._lock:
            getattr(self.conn.mav, fn)(*args)

    def _heartbeat(self) -> None:
        while not self._stop.wait(1.0):
            # the vehicle's address, learnt from its first datagram (pymavlink's udpin keeps
            # it in ``clients``; older versions in ``last_address``)
            if getattr(self.conn, "clients", None) or self.conn.last_address is not None:
                try:
                    self.send("heartbeat_send", MAV.MAV_TYPE_GCS, MAV.MAV_AUTOPILOT_INVALID,
                              0, 0, 0)
                except OSError:
                    pass

    def start(self, timeout_s: float = 120) -> None:
        hb = self.conn.wait_heartbeat(timeout=wall(timeout_s))
        assert hb is not None, f"no HEARTBEAT on UDP {GCS_PORT} within {wall(timeout_s):.0f} s"
        assert hb.autopilot == MAV.MAV_AUTOPILOT_PX4, hb
        if not self._hb.is_alive():
            self._hb.start()

    def close(self) -> None:
        self._stop.set()
        self.conn.close()

    def recv(self, types: Any = None, timeout_s: float = 1.0) -> Any:
        m = self.conn.recv_match(type=types, blocking=True, timeout=timeout_s)
        if m is not None:
            self._note(m)
        return m

    def _note(self, m: Any) -> None:
        t = m.get_type()
        if t == "BAD_DATA":
            return
        self.last[t] = m
        if t == "STATUSTEXT":
            self.texts.append(m.text)

    def drain(self) -> None:
        while True:
            m = self.conn.recv_match(blocking=False)
            if m is None:
                return
            self._note(m)

    def wait(self, types: Any, pred: Any, timeout_s: float, what: str) -> Any:
        deadline = time.monotonic() + wall(timeout_s)
        while time.monotonic() < deadline:
            m = self.recv(types, timeout_s=min(1.0, max(0.01, deadline - time.monotonic())))
            if m is not None and pred(m):
                return m
        raise AssertionError(f"timed out after {wall(timeout_s):.0f} s waiting for {what} "
                             f"(last {types}: {self.last.get(types if isinstance(types, str) else '')}; "
                             f"status texts: {self.texts[-5:]})")

    def command(self, cmd: int, *params: float, timeout_s: float = 30, tries: int = 3) -> Any:
        p = list(params) + [0.0] * (7 - len(params))
        for attempt in range(tries):
            self.send("command_long_send", 1, 1, cmd, attempt, *p)
            try:
                return self.wait("COMMAND_ACK", lambda m: m.command == cmd, timeout_s / tries,
                                 f"COMMAND_ACK for command {cmd}")
            except AssertionError:
                continue
        raise AssertionError(f"no COMMAND_ACK for command {cmd} after {tries} tries "
                             f"(status texts: {self.texts[-5:]})")

    # -- parameters -------------------------------------------------------------------------

    def param_read(self, name: str, timeout_s: float = 30) -> Any:
        for _ in range(3):
            self.send("param_request_read_send", 1, 1, name.encode(), -1)
            try:
                return self.wait("PARAM_VALUE", lambda m: m.param_id == name, timeout_s / 3,
                                 f"PARAM_VALUE {name}")
            except AssertionError:
                continue
        raise AssertionError(f"no PARAM_VALUE for {name}")

    def param_set(self, name: str, value: float, ptype: int = MAV.MAV_PARAM_TYPE_REAL32,
                  timeout_s: float = 30) -> Any:
        for _ in range(3):
            self.send("param_set_send", 1, 1, name.encode(), value, ptype)
            try:
                return self.wait("PARAM_VALUE",
                                 lambda m: m.param_id == name and abs(m.param_value - value) < 1e-4,
                                 timeout_s / 3, f"PARAM_VALUE {name} = {value}")
            except AssertionError:
                continue
        raise AssertionError(f"PARAM_SET {name} = {value}: no PARAM_VALUE with the new value "
                             f"(status texts: {self.texts[-5:]})")


def param_float(m: Any) -> float:
    """A PARAM_VALUE's value in its own type (INT32 travels byte-wise in the float field)."""
    if m.param_type in (MAV.MAV_PARAM_TYPE_INT32, MAV.MAV_PARAM_TYPE_UINT32,
                        MAV.MAV_PARAM_TYPE_INT8, MAV.MAV_PARAM_TYPE_UINT8,
                        MAV.MAV_PARAM_TYPE_INT16, MAV.MAV_PARAM_TYPE_UINT16):
        raw = struct.pack("<f", m.param_value)
        return float(struct.unpack("<i" if m.param_type == MAV.MAV_PARAM_TYPE_INT32 else "<I",
                                   raw)[0])
    return float(m.param_value)


@pytest.fixture(scope="module")
def gcs(hil_fly):
    g = Gcs()
    try:
        g.start()
        yield g
    finally:
        g.close()


def wait_ready(gcs: Gcs, timeout_s: float = 180) -> Any:
    """The estimator has a global position and the home is set."""
    gcs.wait("GPS_RAW_INT", lambda m: m.fix_type >= 3, timeout_s, "GPS_RAW_INT 3D fix")
    return gcs.wait("HOME_POSITION", lambda m: True, timeout_s, "HOME_POSITION")


def arm(gcs: Gcs, timeout_s: float = 120) -> None:
    """Arm (COMPONENT_ARM_DISARM, param2 0), retried while the preflight checks refuse."""
    deadline = time.monotonic() + wall(timeout_s)
    while True:
        ack = gcs.command(MAV.MAV_CMD_COMPONENT_ARM_DISARM, 1, 0)
        if ack.result == MAV.MAV_RESULT_ACCEPTED:
            break
        assert time.monotonic() < deadline, \
            f"arming refused (result {ack.result}): {gcs.texts[-5:]}"
        time.sleep(2)
    gcs.wait("HEARTBEAT", lambda m: m.base_mode & MAV.MAV_MODE_FLAG_SAFETY_ARMED, 30,
             "an armed HEARTBEAT")


# -- 1 ------------------------------------------------------------------------------------------

def test_param_list_matches_board(hil_fly, gcs):
    board_total = int(re.search(r"/(\d+) parameters shown",
                                hil_fly.shell("param show MAV_SYS_ID")).group(1))
    gcs.drain()
    gcs.send("param_request_list_send", 1, 1)
    values: dict[int, Any] = {}
    count = None
    hash_check = None
    deadline = time.monotonic() + wall(240)
    quiet_since = time.monotonic()
    while time.monotonic() < deadline:
        m = gcs.recv("PARAM_VALUE", timeout_s=1.0)
        if m is None:
            if count is not None and time.monotonic() - quiet_since > wall(20):
                break  # nothing more is coming
            continue
        quiet_since = time.monotonic()
        if m.param_id == "_HASH_CHECK":
            hash_check = m
            continue
        count = m.param_count
        values[m.param_index] = m
        if len(values) >= count:
            break
    assert count is not None, "no PARAM_VALUE after PARAM_REQUEST_LIST"
    missing = sorted(set(range(count)) - set(values))
    assert not missing, f"{len(missing)} of {count} parameters never arrived: {missing[:20]}"
    assert count == board_total, f"PARAM_VALUE param_count {count}, board has {board_total}"
    assert hash_check is not None, "no _HASH_CHECK before the list (as PX4 sends it)"
    names = [values[i].param_id for i in range(count)]
    assert len(set(names)) == count, "duplicate names in the list"

    # a sample of values (every 25th, and some well-known ones) against the console
    by_name = {m.param_id: m for m in values.values()}
    sample = names[::25] + [n for n in ("SYS_AUTOSTART", "MAV_SYS_ID", "MIS_TAKEOFF_ALT",
                                        "EKF2_MAG_DECL", "MAV_TYPE") if n in by_name]
    wrong = []
    for name in sample:
        m = by_name[name]
        mine = param_float(m)
        board = hil_fly.param(name)
        if not (math.isclose(mine, board, rel_tol=1e-4, abs_tol=1e-4)
                or (math.isnan(mine) and math.isnan(board))):
            wrong.append((name, mine, board))
    assert not wrong, f"PARAM_VALUE vs 'param show' (name, mavlink, board): {wrong}"
    assert param_float(by_name["SYS_AUTOSTART"]) == 4011


# -- 2 ------------------------------------------------------------------------------------------

def test_log_download_identical(hil_fly, gcs):
    log_root = hil_fly.out_dir / "sd" / "log"
    before = set(log_root.rglob("*.ulg")) if log_root.exists() else set()
    wait_ready(gcs)
    arm(gcs)
    time.sleep(wall(4))
    ack = gcs.command(MAV.MAV_CMD_COMPONENT_ARM_DISARM, 0, 0)
    assert ack.result == MAV.MAV_RESULT_ACCEPTED, f"disarm refused: {gcs.texts[-5:]}"
    gcs.wait("HEARTBEAT", lambda m: not m.base_mode & MAV.MAV_MODE_FLAG_SAFETY_ARMED, 30,
             "a disarmed HEARTBEAT")
    new = wait_until(lambda: sorted(set(log_root.rglob("*.ulg")) - before), 60,
                     f"a new .ulg under {log_root} after arm/disarm")
    path: Path = new[-1]
    # the logger closes the file at disarm: wait until its size settles
    sizes = []
    wait_until(lambda: (sizes.append(path.stat().st_size) or len(sizes) > 3
                        and sizes[-1] == sizes[-4] and sizes[-1] > 0), 60,
               f"{path} to stop growing", every_s=1.0)
    data_on_card = path.read_bytes()

    gcs.drain()
    gcs.send("log_request_list_send", 1, 1, 0, 0xFFFF)
    entries: dict[int, Any] = {}
    deadline = time.monotonic() + wall(60)
    while time.monotonic() < deadline:
        m = gcs.recv("LOG_ENTRY", timeout_s=2.0)
        if m is None:
            if entries:
                break
            continue
        if m.num_logs == 0:
            break
        entries[m.id] = m
        if len(entries) >= m.num_logs:
            break
    assert entries, "no LOG_ENTRY after LOG_REQUEST_LIST"
    all_logs = sorted(log_root.rglob("*.ulg"))
    assert len(entries) == len(all_logs), \
        f"{len(entries)} LOG_ENTRY for {len(all_logs)} files: {all_logs}"
    entry = entries[max(entries)]  # ids in time order: the newest is ours
    assert entry.size == len(data_on_card), \
        f"LOG_ENTRY {entry.id} size {entry.size}, file {path} has {len(data_on_card)} bytes"

    size = entry.size
    got = bytearray(size)
    have = bytearray(size)  # 1 where received
    t0 = time.monotonic()
    deadline = t0 + wall(600)
    gcs.send("log_request_data_send", 1, 1, entry.id, 0, 0xFFFFFFFF)
    received = 0
    while received < size and time.monotonic() < deadline:
        m = gcs.recv("LOG_DATA", timeout_s=3.0)
        if m is None:  # a gap: ask again from the first missing byte
            first_missing = have.find(0)
            gcs.send("log_request_data_send", 1, 1, entry.id, first_missing, 0xFFFFFFFF)
            continue
        if m.id != entry.id or m.count == 0:
            continue
        chunk = bytes(m.data[:m.count])
        end = min(size, m.ofs + len(chunk))
        for i in range(m.ofs, end):
            if not have[i]:
                have[i] = 1
                received += 1
        got[m.ofs:end] = chunk[:end - m.ofs]
    gcs.send("log_request_end_send", 1, 1)
    assert received == size, \
        f"downloaded {received} of {size} bytes in {time.monotonic() - t0:.0f} s"
    assert bytes(got) == data_on_card, "downloaded log differs from the file on the SD card"
    print(f"log {path.name}: {size} bytes in {time.monotonic() - t0:.1f} s wall",
          file=sys.stderr)


# -- 3 ------------------------------------------------------------------------------------------

PERSIST_PARAM = "MPC_XY_CRUISE"


def test_param_set_survives_reboot(hil_fly, gcs):
    old = param_float(gcs.param_read(PERSIST_PARAM))
    new = 3.25 if abs(old - 3.25) > 0.1 else 4.5
    m = gcs.param_set(PERSIST_PARAM, new)
    assert abs(param_float(m) - new) < 1e-4
    assert abs(hil_fly.param(PERSIST_PARAM) - new) < 1e-4, "the board does not show the new value"
    time.sleep(wall(3))  # FRAM autosave: 300 ms of virtual time after the set

    ack = gcs.command(MAV.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN, 1)
    assert ack.result == MAV.MAV_RESULT_ACCEPTED, \
        f"reboot refused (result {ack.result}): {gcs.texts[-5:]}"
    # the FMU reboots in the run (the orchestrator restarts its process on the same FRAM);
    # the ground station's heartbeats wake the new FMU's UDP link, as QGC's would
    assert _watch_reboot(gcs, timeout_s=30), \
        f"no reboot seen (ATTITUDE.time_boot_ms kept counting); status texts: {gcs.texts[-5:]}"
    m = gcs.param_read(PERSIST_PARAM, timeout_s=60)
    assert abs(param_float(m) - new) < 1e-4, \
        f"{PERSIST_PARAM} is {param_float(m)} after the reboot, was set to {new}"
    assert abs(hil_fly.param(PERSIST_PARAM) - new) < 1e-4


def _watch_reboot(gcs: Gcs, timeout_s: float) -> bool:
    """True once the vehicle's boot time restarts (or its heartbeat stops and comes back)."""
    last_boot_ms = None
    deadline = time.monotonic() + wall(timeout_s)
    while time.monotonic() < deadline:
        m = gcs.recv("ATTITUDE", timeout_s=2.0)
        if m is None:
            continue
        if last_boot_ms is not None and m.time_boot_ms + 1000 < last_boot_ms:
            return True
        last_boot_ms = m.time_boot_ms
    return False


# -- 4 ------------------------------------------------------------------------------------------

FLOOD_WALL_S = 6.0
#: the hover the flood is thrown at: low, so the climb and the landing around it are short
FLOOD_ALT_M = 5.0


def _top_rate(fly: Any) -> tuple[float, float]:
    """(mc_rate_control runs per virtual second, virtual interval) since the previous top."""
    out = fly.shell("top once")
    m = re.search(r"interval ([\d.]+) s", out)
    r = re.search(r"^\s+mc_rate_control\s+\d+\s+([\d.]+)", out, re.MULTILINE)
    assert m and r, f"unexpected 'top once' output:\n{out}"
    return float(r.group(1)), float(m.group(1))


def _flood_datagrams(mav: Any, rng: random.Random) -> list[bytes]:
    out = []
    for _ in range(50):  # garbage: random bytes, some starting like MAVLink frames
        n = rng.randint(1, 280)
        blob = bytearray(rng.randbytes(n))
        if rng.random() < 0.5:
            blob[0] = rng.choice((0xFD, 0xFE))
        out.append(bytes(blob))
    for _ in range(25):  # well-framed MAVLink 2 with ids outside the dialect
        msgid = rng.choice((12000, 42424, 60000, 0xFFFFFF))
        payload = rng.randbytes(rng.randint(1, 64))
        hdr = struct.pack("<BBBBBBBHB", 0xFD, len(payload), 0, 0, rng.randint(0, 255), 255, 190,
                          msgid & 0xFFFF, msgid >> 16)
        crc = x25crc(hdr[1:] + payload)
        out.append(hdr + payload + struct.pack("<H", crc.crc))
    for _ in range(25):  # valid messages the vehicle does not handle
        m = rng.choice((
            MAV.MAVLink_named_value_float_message(0, b"flood", rng.random()),
            MAV.MAVLink_debug_message(0, 1, rng.random()),
            MAV.MAVLink_debug_vect_message(b"flood", 0, 1.0, 2.0, 3.0),
        ))
        out.append(m.pack(mav))
    return out


def test_flood_does_not_disturb_hover(hil_fly, gcs):
    gcs.conn.last_address = gcs.conn.last_address or ("127.0.0.1", VEHICLE_GCS_SOCKET)
    wait_ready(gcs)
    gcs.param_set("MIS_TAKEOFF_ALT", FLOOD_ALT_M)
    gcs.param_set("RTL_RETURN_ALT", FLOOD_ALT_M)
    arm(gcs)
    ack = gcs.command(MAV.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, math.nan, math.nan, math.nan)
    assert ack.result == MAV.MAV_RESULT_ACCEPTED, f"takeoff refused: {gcs.texts[-5:]}"
    gcs.wait("GLOBAL_POSITION_INT",
             lambda m: m.relative_alt > (FLOOD_ALT_M - 0.7) * 1000, 180,
             f"relative altitude {FLOOD_ALT_M - 0.7} m after takeoff")
    time.sleep(wall(2))  # settle into the hover

    def alt_window(seconds: float, action: Any = None) -> list[float]:
        alts: list[float] = []
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            if action is not None:
                action()
            gcs.drain()
            m = gcs.last.get("GLOBAL_POSITION_INT")
            if m is not None:
                alts.append(m.relative_alt / 1000.0)
            if action is None:
                time.sleep(0.05)
        return alts

    _top_rate(hil_fly)  # start a top interval
    base_alts = alt_window(wall(FLOOD_WALL_S))
    base_rate, base_dt = _top_rate(hil_fly)
    status0 = hil_fly.shell("mavlink status")

    rng = random.Random(1)
    datagrams = _flood_datagrams(gcs.mav, rng)
    sock = gcs.conn.port  # the GCS's own socket: the bridge keeps answering the GCS
    sent = [0]

    def burst() -> None:
        for d in rng.sample(datagrams, 40):
            try:
                sock.sendto(d, ("127.0.0.1", VEHICLE_GCS_SOCKET))
                sent[0] += 1
            except BlockingIOError:
                pass
        time.sleep(0.005)

    flood_alts = alt_window(wall(FLOOD_WALL_S), burst)
    flood_rate, flood_dt = _top_rate(hil_fly)
    status1 = hil_fly.shell("mavlink status")
    after_alts = alt_window(wall(3))

    print(f"flood: {sent[0]} datagrams in {wall(FLOOD_WALL_S):.0f} s wall; mc_rate_control "
          f"{base_rate:.1f}/s over {base_dt:.2f} virtual s before, {flood_rate:.1f}/s over "
          f"{flood_dt:.2f} virtual s during", file=sys.stderr)
    assert sent[0] > 1000, f"only {sent[0]} datagrams sent"
    # the flood reached the vehicle's GCS link and was counted
    rx0 = _link_rx(status0)
    rx1 = _link_rx(status1)
    assert rx1["malformed"] + rx1["unknown"] + rx1["dropped"] > \
        rx0["malformed"] + rx0["unknown"] + rx0["dropped"], \
        f"the flood left no trace in 'mavlink status':\n{status1}"
    # the rate controller kept its virtual-time rate
    assert flood_dt > 0.5 and base_dt > 0.5, (base_dt, flood_dt)
    assert flood_rate >= 0.95 * base_rate, \
        f"mc_rate_control ran {flood_rate:.1f}/s during the flood, {base_rate:.1f}/s before"
    # the altitude held
    for name, alts in (("before", base_alts), ("during", flood_alts), ("after", after_alts)):
        assert alts, f"no GLOBAL_POSITION_INT {name} the flood"
        worst = max(abs(a - FLOOD_ALT_M) for a in alts)
        assert worst < 1.0, \
            f"altitude {name} the flood strayed {worst:.2f} m from {FLOOD_ALT_M} m"
    # telemetry kept flowing to the GCS during the flood
    assert len(flood_alts) > 10

    # land and let the commander disarm
    ack = gcs.command(MAV.MAV_CMD_NAV_LAND, 0, 0, 0, math.nan, math.nan, math.nan, math.nan)
    assert ack.result == MAV.MAV_RESULT_ACCEPTED, f"land refused: {gcs.texts[-5:]}"
    gcs.wait("HEARTBEAT", lambda m: not m.base_mode & MAV.MAV_MODE_FLAG_SAFETY_ARMED, 300,
             "disarmed after landing")


def _link_rx(status: str) -> dict[str, int]:
    """rx counters of the UDP 18570 link in 'mavlink status'."""
    block = status.split(f"udp local port {VEHICLE_GCS_SOCKET}", 1)
    assert len(block) == 2, status
    rx = re.search(r"rx: (\d+) msgs, (\d+) malformed, (\d+) unknown, (\d+) unhandled.*?"
                   r"(\d+) dropped by the port", block[1])
    assert rx, status
    keys = ("msgs", "malformed", "unknown", "unhandled", "dropped")
    return dict(zip(keys, map(int, rx.groups())))
