"""A ground station in virtual time, for scripts and tests.

:class:`GcsClient` is a host device (see :mod:`hil.devices`): it sits in the orchestrator's hub
and speaks MAVLink 2 (pymavlink) to one board port, either a UART (``telem1``, bytes at the
line's baud rate) or the FMU's UDP network port (whole datagrams). No socket is opened. Its
heartbeat goes out at 1 Hz of *virtual* time and every timeout of its helpers is in virtual
seconds: the helpers advance the orchestrator themselves, so a slow host (or a fast speed-up)
never trips a timeout that the real link would not.

    gcs = GcsClient("gcs")                           # UDP to FMU port 18570
    orch = Orchestrator({"fmu": ...}, udp_wires("gcs"), world=DeviceHub(gcs), mode="local")
    gcs.attach(orch)
    gcs.wait_heartbeat()
    params = gcs.param_list()
    gcs.param_set("MPC_XY_VEL_MAX", 8.0)
    ack = gcs.arm()                                  # COMMAND_ACK (result 0 accepted)
    gcs.upload_mission([(47.39, 8.54, 10.0), ...])
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterable, Sequence
from typing import Any

from pymavlink.dialects.v20 import common as mav

from hil.mavlink_bridge import udp_wires

__all__ = ["GcsClient", "GcsTimeout", "udp_wires"]

NS_PER_S = 1_000_000_000
FORCE_ARM_MAGIC = 21196


class GcsTimeout(TimeoutError):
    """The vehicle did not answer within the virtual time given."""


class _Sink:
    def write(self, data: bytes) -> None:  # pymavlink wants a file; packing is done by hand
        pass


class GcsClient:
    """Host device speaking MAVLink to a board port; helpers run the orchestrator."""

    def __init__(self, port: str = "gcs", *, link: str = "udp", fmu_port: int = 18570,
                 gcs_port: int = 14550, baud: int = 57_600, sysid: int = 255,
                 compid: int = mav.MAV_COMP_ID_MISSIONPLANNER, target_system: int = 1,
                 target_component: int = 1, heartbeat_hz: float = 1.0,
                 signing_key: bytes | None = None) -> None:
        if link not in ("udp", "uart"):
            raise ValueError(f"link must be 'udp' or 'uart', got {link!r}")
        self.port = port
        self.ports = (port,)
        self.link = link
        self.fmu_port = fmu_port
        self.gcs_port = gcs_port
        self.uart_cfg = (baud, 8, "N", 1, 0)
        self.target_system = target_system
        self.target_component = target_component
        self.mav = mav.MAVLink(_Sink(), sysid, compid)
        self.mav.robust_parsing = True
        self.rx = mav.MAVLink(_Sink(), sysid, compid)   # a parser of its own (signing state)
        self.rx.robust_parsing = True
        self.heartbeat_interval_ns = int(NS_PER_S / heartbeat_hz) if heartbeat_hz > 0 else 0
        self._next_hb_ns = 0
        self._t_ns = 0
        self._out: list = []
        self._pending: list[bytes] = []
        self.orch: Any = None
        #: every message received: (t_ns, msg); ``_base`` counts messages trimmed off the front
        self.log: list[tuple[int, Any]] = []
        self._base = 0
        self.counts: dict[str, int] = {}
        self.last: dict[str, Any] = {}
        self.bad_data = 0
        self.sent = 0
        #: from the last param_list(): the _HASH_CHECK value and the order names arrived in
        self.param_hash: int | None = None
        self.param_order: list[str] = []
        self._shell_open = False
        self._shell_cursor = 0
        #: ground-link faults (hil/faults/link.py): the radio carries nothing up (to the
        #: vehicle) / down (to the GCS); what was lost is counted
        self.uplink_lost = False
        self.downlink_lost = False
        self.lost_up = 0
        self.lost_down = 0
        #: a flood of traffic to the vehicle: (period_ns, next_ns, message factory) or None
        self._flood: tuple[int, int, Callable[[], Any]] | None = None
        self.flood_sent = 0
        if signing_key is not None:
            self.set_signing_key(signing_key)

    # -- host device interface ------------------------------------------------------------------

    def attach(self, orch: Any) -> GcsClient:
        """The orchestrator the helpers advance (the client must also be in its hub)."""
        self.orch = orch
        return self

    def run_until(self, t_ns: int) -> None:
        if self._flood is not None:
            self._run_flood(t_ns)
        if self.heartbeat_interval_ns:
            while self._next_hb_ns <= t_ns:
                self.send(mav.MAVLink_heartbeat_message(mav.MAV_TYPE_GCS,
                                                        mav.MAV_AUTOPILOT_INVALID, 0, 0,
                                                        mav.MAV_STATE_ACTIVE, 3),
                          t_ns=self._next_hb_ns)
                self._next_hb_ns += self.heartbeat_interval_ns
        self._t_ns = t_ns

    def outputs(self, until_ns: int) -> list:
        out, self._out = self._out, []
        if self.uplink_lost:
            self.lost_up += len(out)
            return []
        return out

    def input(self, port: str, t_ns: int, payload: Any) -> None:
        if self.downlink_lost:
            self.lost_down += 1
            return
        if self.link == "udp":
            fmu_port, _remote, data = payload
            if fmu_port != self.fmu_port:
                return
        else:
            data = payload[5]
            if not data:
                return
        msgs = self.rx.parse_buffer(data) or []
        for m in msgs:
            if m.get_msgId() < 0 and not isinstance(m, mav.MAVLink_unknown):
                self.bad_data += 1
                continue
            name = m.get_type()
            self.log.append((t_ns, m))
            self.counts[name] = self.counts.get(name, 0) + 1
            self.last[name] = m
        if len(self.log) > 50_000:
            cut = len(self.log) - 25_000
            del self.log[:cut]
            self._base += cut

    # -- ground-link faults ---------------------------------------------------------------------

    def set_link_loss(self, up: bool, down: bool) -> None:
        """The telemetry link stops carrying traffic to the vehicle (``up``) and/or from it
        (``down``): a radio out of range, a modem unplugged. The GCS keeps running and keeps
        trying (its heartbeats are lost, not withheld)."""
        self.uplink_lost = bool(up)
        self.downlink_lost = bool(down)

    def flood(self, rate_hz: float, kind: str = "heartbeat", size: int = 0) -> None:
        """Send ``rate_hz`` extra messages per virtual second to the vehicle until
        ``flood(0)``: ``"heartbeat"`` (valid, from a second GCS id), ``"param_request_list"``
        (each one asks for the whole parameter set), ``"statustext"`` (valid, for a message the
        vehicle ignores) or ``"garbage"`` (``size`` random-looking bytes that are not MAVLink;
        deterministic). A UDP datagram carries one message, as MAVLink senders do."""
        if rate_hz < 0 or rate_hz > 1_000_000:
            raise ValueError(f"flood rate must be in [0, 1e6] Hz, got {rate_hz!r}")
        if rate_hz == 0:
            self._flood = None
            return
        flooder = mav.MAVLink(_Sink(), 254, 190)
        tgt = (self.target_system, self.target_component)
        counter = [0]

        def garbage() -> bytes:
            counter[0] += 1
            n = size or 64
            x = counter[0] * 2654435761 & 0xFFFFFFFF
            out = bytearray()
            while len(out) < n:
                x = (1103515245 * x + 12345) & 0x7FFFFFFF
                b = (x >> 16) & 0xFF
                out.append(b if b not in (0xFD, 0xFE) else 0x55)  # never a MAVLink start
            return bytes(out)

        factories: dict[str, Callable[[], Any]] = {
            "heartbeat": lambda: mav.MAVLink_heartbeat_message(
                mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, mav.MAV_STATE_ACTIVE,
                3).pack(flooder),
            "param_request_list": lambda: mav.MAVLink_param_request_list_message(
                *tgt).pack(flooder),
            "statustext": lambda: mav.MAVLink_statustext_message(
                mav.MAV_SEVERITY_INFO, b"flood" + bytes(45)).pack(flooder),
            "garbage": garbage,
        }
        if kind not in factories:
            raise ValueError(f"flood kind must be one of {', '.join(factories)}, got {kind!r}")
        period = max(1, int(NS_PER_S / rate_hz))
        self._flood = (period, self._t_ns, factories[kind])

    def _run_flood(self, t_ns: int) -> None:
        assert self._flood is not None
        period, nxt, make = self._flood
        while nxt <= t_ns:
            self.send_bytes(make(), t_ns=nxt)
            self.flood_sent += 1
            nxt += period
        self._flood = (period, nxt, make)

    # -- sending --------------------------------------------------------------------------------

    def set_signing_key(self, key: bytes | None, sign_outgoing: bool = True) -> None:
        """Sign what we send with ``key`` and check the vehicle's signatures (None: off)."""
        for m in (self.mav, self.rx):
            m.signing.secret_key = key
            m.signing.sign_outgoing = key is not None and sign_outgoing and m is self.mav
            m.signing.timestamp = max(m.signing.timestamp, self._t_ns // 10_000 + 1)
            m.signing.allow_unsigned_callback = None

    def send(self, msg: Any, t_ns: int | None = None, sign: bool | None = None) -> None:
        """Send a message (stamped now); ``sign=False`` sends it unsigned even with a key."""
        saved = self.mav.signing.sign_outgoing
        if sign is not None:
            self.mav.signing.sign_outgoing = sign and self.mav.signing.secret_key is not None
        try:
            buf = msg.pack(self.mav)
        finally:
            self.mav.signing.sign_outgoing = saved
        self.mav.seq = (self.mav.seq + 1) % 256
        self.send_bytes(buf, t_ns)
        self.sent += 1

    def send_bytes(self, data: bytes, t_ns: int | None = None) -> None:
        """Raw bytes to the vehicle (one datagram on UDP): malformed input for tests."""
        t = self._t_ns if t_ns is None else t_ns
        if self.link == "udp":
            self._out.append((self.port, t, (self.fmu_port, self.gcs_port, bytes(data))))
        else:
            self._out.append((self.port, t, (*self.uart_cfg, bytes(data))))

    # -- waiting --------------------------------------------------------------------------------

    def _need_orch(self) -> Any:
        if self.orch is None:
            raise RuntimeError("GcsClient.attach(orchestrator) first: helpers advance its time")
        return self.orch

    def step(self, seconds: float) -> None:
        orch = self._need_orch()
        orch.run(duration_ns=int(seconds * NS_PER_S))

    def wait_for(self, predicate: Callable[[], Any], timeout_s: float = 5.0) -> Any:
        """Advance quantum by quantum until ``predicate()`` is truthy; its value, or
        :class:`GcsTimeout` after ``timeout_s`` of virtual time."""
        orch = self._need_orch()
        end = orch.t_ns + int(timeout_s * NS_PER_S)
        while True:
            v = predicate()
            if v:
                return v
            if orch.t_ns >= end:
                raise GcsTimeout(f"no answer within {timeout_s} s of virtual time")
            orch.step()

    def mark(self) -> int:
        """A cursor: messages received after this point are 'new' for :meth:`wait_message`."""
        return self._base + len(self.log)

    def messages(self, mtype: str | None = None, since: int = 0) -> list[Any]:
        start = max(since - self._base, 0)
        return [m for _, m in self.log[start:] if mtype is None or m.get_type() == mtype]

    def wait_message(self, mtype: str, cond: Callable[[Any], bool] | None = None,
                     timeout_s: float = 5.0, since: int | None = None) -> Any:
        """The first message of a type (matching ``cond``) received after ``since``."""
        cursor = [self.mark() if since is None else since]

        def find() -> Any:
            start = max(cursor[0] - self._base, 0)
            for _, m in self.log[start:]:
                if m.get_type() == mtype and (cond is None or cond(m)):
                    return m
            cursor[0] = self._base + len(self.log)
            return None
        return self.wait_for(find, timeout_s)

    def wait_heartbeat(self, timeout_s: float = 5.0) -> Any:
        return self.wait_message("HEARTBEAT", lambda m: m.get_srcSystem() == self.target_system,
                                 timeout_s, since=0)

    # -- commands -------------------------------------------------------------------------------

    def command_long(self, command: int, params: Sequence[float] = (), timeout_s: float = 3.0,
                     retries: int = 2, sign: bool | None = None) -> Any:
        """Send COMMAND_LONG and wait for its COMMAND_ACK (retrying with confirmation + 1)."""
        p = list(params) + [0.0] * (7 - len(params))
        for confirmation in range(retries + 1):
            mark = self.mark()
            self.send(mav.MAVLink_command_long_message(
                self.target_system, self.target_component, command, confirmation, *p[:7]),
                sign=sign)
            try:
                return self.wait_message("COMMAND_ACK", lambda m: m.command == command,
                                         timeout_s, since=mark)
            except GcsTimeout:
                continue
        raise GcsTimeout(f"no COMMAND_ACK for command {command} after {retries + 1} tries")

    def arm(self, force: bool = False, timeout_s: float = 3.0) -> Any:
        return self.command_long(mav.MAV_CMD_COMPONENT_ARM_DISARM,
                                 [1.0, FORCE_ARM_MAGIC if force else 0.0], timeout_s)

    def disarm(self, force: bool = False, timeout_s: float = 3.0) -> Any:
        return self.command_long(mav.MAV_CMD_COMPONENT_ARM_DISARM,
                                 [0.0, FORCE_ARM_MAGIC if force else 0.0], timeout_s)

    def takeoff(self, alt_m: float, timeout_s: float = 3.0) -> Any:
        """Take off to ``alt_m`` above home. NAV_TAKEOFF's param7 is an AMSL altitude (PX4), so
        it is sent as home's altitude plus ``alt_m``, as MAVSDK does; without a home position
        yet, NaN (the vehicle then uses MIS_TAKEOFF_ALT)."""
        nan = float("nan")
        home = self.last.get("HOME_POSITION")
        amsl = home.altitude / 1000.0 + alt_m if home is not None else nan
        return self.command_long(mav.MAV_CMD_NAV_TAKEOFF, [-1, 0, 0, nan, nan, nan, amsl],
                                 timeout_s)

    def land(self, timeout_s: float = 3.0) -> Any:
        nan = float("nan")
        return self.command_long(mav.MAV_CMD_NAV_LAND, [0, 0, 0, nan, nan, nan, nan], timeout_s)

    def rtl(self, timeout_s: float = 3.0) -> Any:
        return self.command_long(mav.MAV_CMD_NAV_RETURN_TO_LAUNCH, [], timeout_s)

    def start_mission(self, timeout_s: float = 3.0) -> Any:
        return self.command_long(mav.MAV_CMD_MISSION_START, [0, 0], timeout_s)

    def set_mode(self, main_mode: int, sub_mode: int = 0, timeout_s: float = 3.0) -> Any:
        return self.command_long(mav.MAV_CMD_DO_SET_MODE,
                                 [mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, main_mode, sub_mode],
                                 timeout_s)

    # -- parameters -----------------------------------------------------------------------------

    @staticmethod
    def decode_param(m: Any) -> int | float:
        """PX4's byte-wise encoding: an INT32 travels as its 4 bytes in the float field."""
        raw = GcsClient.raw_float_bytes(m)
        if m.param_type == mav.MAV_PARAM_TYPE_INT32:
            return struct.unpack("<i", raw)[0]
        if m.param_type == mav.MAV_PARAM_TYPE_UINT32:
            return struct.unpack("<I", raw)[0]
        return struct.unpack("<f", raw)[0]

    @staticmethod
    def raw_float_bytes(m: Any) -> bytes:
        buf = bytes(m.get_msgbuf())
        head = 10 if buf[:1] == b"\xfd" else 6
        return (buf[head:head + m._header.mlen] + b"\0" * 4)[:4]

    @staticmethod
    def param_name(m: Any) -> str:
        pid = m.param_id
        return (pid.decode("latin-1") if isinstance(pid, bytes) else pid).split("\0", 1)[0]

    def param_list(self, timeout_s: float = 30.0) -> dict[str, int | float]:
        """All parameters (PARAM_REQUEST_LIST, then reads by index for any missed)."""
        mark = self.mark()
        self.send(mav.MAVLink_param_request_list_message(self.target_system,
                                                         self.target_component))
        values: dict[int, tuple[str, int | float]] = {}
        state = {"count": None, "cursor": mark}
        self.param_hash = None
        self.param_order = []

        def collect() -> bool:
            for m in self.messages("PARAM_VALUE", state["cursor"]):
                name = self.param_name(m)
                if name == "_HASH_CHECK":
                    self.param_hash = self.decode_param(m)
                    self.param_order.append(name)
                    continue
                state["count"] = m.param_count
                if m.param_index not in values:
                    self.param_order.append(name)
                values[m.param_index] = (name, self.decode_param(m))
            state["cursor"] = self.mark()
            return state["count"] is not None and len(values) >= state["count"]

        try:
            self.wait_for(collect, timeout_s)
        except GcsTimeout:
            if state["count"] is None:
                raise
            for i in range(state["count"]):  # ask again for what got lost
                if i not in values:
                    self.send(mav.MAVLink_param_request_read_message(
                        self.target_system, self.target_component, b"", i))
            self.wait_for(collect, timeout_s)
        return {name: v for _, (name, v) in sorted(values.items())}

    def param_get(self, name: str, timeout_s: float = 3.0) -> int | float:
        mark = self.mark()
        self.send(mav.MAVLink_param_request_read_message(self.target_system,
                                                         self.target_component,
                                                         name.encode(), -1))
        m = self.wait_message("PARAM_VALUE", lambda m: self.param_name(m) == name, timeout_s,
                              since=mark)
        return self.decode_param(m)

    def param_set(self, name: str, value: float, is_int: bool | None = None,
                  timeout_s: float = 3.0) -> int | float:
        """Set a parameter; returns the value the vehicle answers with."""
        if is_int is None:
            is_int = isinstance(value, int) and not isinstance(value, bool)
        raw = struct.pack("<i", int(value)) if is_int else struct.pack("<f", float(value))
        ptype = mav.MAV_PARAM_TYPE_INT32 if is_int else mav.MAV_PARAM_TYPE_REAL32
        msg = mav.MAVLink_param_set_message(self.target_system, self.target_component,
                                            name.encode(), 0.0, ptype)
        payload = raw + struct.pack("<BB16sB", self.target_system, self.target_component,
                                    name.encode(), ptype)
        mark = self.mark()
        buf = msg._pack(self.mav, mav.MAVLink_param_set_message.crc_extra, payload)
        self.mav.seq = (self.mav.seq + 1) % 256
        self.send_bytes(buf)
        m = self.wait_message("PARAM_VALUE", lambda m: self.param_name(m) == name, timeout_s,
                              since=mark)
        return self.decode_param(m)

    # -- missions -------------------------------------------------------------------------------

    def _mission_items(self, items: Iterable[Any]) -> list[Any]:
        out = []
        for seq, it in enumerate(items):
            if isinstance(it, mav.MAVLink_mission_item_int_message):
                it.seq = seq
                out.append(it)
                continue
            lat, lon, alt = it[:3]
            cmd = it[3] if len(it) > 3 else mav.MAV_CMD_NAV_WAYPOINT
            out.append(mav.MAVLink_mission_item_int_message(
                self.target_system, self.target_component, seq,
                mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, cmd, int(seq == 0), 1, 0.0, 0.0, 0.0,
                float("nan"), round(lat * 1e7), round(lon * 1e7), float(alt), 0))
        return out

    def upload_mission(self, items: Iterable[Any], timeout_s: float = 10.0) -> int:
        """Upload (lat, lon, alt_rel[, cmd]) tuples or MISSION_ITEM_INT messages; returns the
        MISSION_ACK type (0 accepted)."""
        msgs = self._mission_items(items)
        mark = self.mark()
        self.send(mav.MAVLink_mission_count_message(self.target_system, self.target_component,
                                                    len(msgs), 0))
        cursor = [mark]
        result: list[int] = []

        def serve() -> bool:
            for m in self.messages(None, cursor[0]):
                t = m.get_type()
                if t in ("MISSION_REQUEST_INT", "MISSION_REQUEST") and m.seq < len(msgs):
                    self.send(msgs[m.seq])
                elif t == "MISSION_ACK":
                    result.append(m.type)
            cursor[0] = self.mark()
            return bool(result)
        self.wait_for(serve, timeout_s)
        return result[0]

    def download_mission(self, timeout_s: float = 10.0) -> list[Any]:
        mark = self.mark()
        self.send(mav.MAVLink_mission_request_list_message(self.target_system,
                                                           self.target_component, 0))
        count = self.wait_message("MISSION_COUNT", None, timeout_s, since=mark).count
        items = []
        for seq in range(count):
            mark = self.mark()
            self.send(mav.MAVLink_mission_request_int_message(self.target_system,
                                                              self.target_component, seq, 0))
            items.append(self.wait_message("MISSION_ITEM_INT", lambda m, s=seq: m.seq == s,
                                           timeout_s, since=mark))
        self.send(mav.MAVLink_mission_ack_message(self.target_system, self.target_component,
                                                  mav.MAV_MISSION_ACCEPTED, 0))
        return items

    # -- shell and logs -------------------------------------------------------------------------

    def shell(self, line: str, timeout_s: float = 5.0) -> str:
        """Run one line on the MAVLink shell (SERIAL_CONTROL); its output without the echo."""
        if not self._shell_open:
            self._shell_open = True
            self._shell_cursor = self.mark()
            self._serial_send(b"\n")
            self._shell_read("nsh> ", timeout_s)
        self._serial_send(line.encode() + b"\n")
        text = self._shell_read("nsh> ", timeout_s)
        body = text.replace("\r\n", "\n")
        body = body.removesuffix("nsh> ")
        return body.split("\n", 1)[1] if "\n" in body else ""

    def _serial_send(self, data: bytes) -> None:
        for i in range(0, len(data), 70):
            chunk = data[i:i + 70]
            self.send(mav.MAVLink_serial_control_message(
                mav.SERIAL_CONTROL_DEV_SHELL,
                mav.SERIAL_CONTROL_FLAG_EXCLUSIVE | mav.SERIAL_CONTROL_FLAG_RESPOND, 0, 0,
                len(chunk), list(chunk) + [0] * (70 - len(chunk))))

    def _shell_read(self, until: str, timeout_s: float) -> str:
        buf = bytearray()

        def got() -> bool:
            for m in self.messages("SERIAL_CONTROL", self._shell_cursor):
                buf.extend(bytes(m.data[: m.count]))
            self._shell_cursor = self.mark()
            return buf.decode("utf-8", "replace").endswith(until)
        self.wait_for(got, timeout_s)
        return buf.decode("utf-8", "replace")

    def log_list(self, timeout_s: float = 5.0) -> list[Any]:
        mark = self.mark()
        self.send(mav.MAVLink_log_request_list_message(self.target_system,
                                                       self.target_component, 0, 0xFFFF))
        first = self.wait_message("LOG_ENTRY", None, timeout_s, since=mark)
        if first.num_logs == 0:
            return []
        self.wait_for(lambda: len({m.id for m in self.messages("LOG_ENTRY", mark)})
                      >= first.num_logs, timeout_s)
        by_id = {m.id: m for m in self.messages("LOG_ENTRY", mark)}
        return [by_id[i] for i in sorted(by_id)]

    def log_download(self, log_id: int, size: int, timeout_s: float = 60.0) -> bytes:
        """A whole log, re-requesting any gap (LOG_REQUEST_DATA, then LOG_REQUEST_END)."""
        data = bytearray(size)
        have = [False] * ((size + 89) // 90)
        cursor = [self.mark()]
        self.send(mav.MAVLink_log_request_data_message(self.target_system,
                                                       self.target_component, log_id, 0, size))

        def collect() -> bool:
            for m in self.messages("LOG_DATA", cursor[0]):
                if m.id == log_id and m.count:
                    data[m.ofs:m.ofs + m.count] = bytes(m.data[: m.count])
                    have[m.ofs // 90] = True
            cursor[0] = self.mark()
            return all(have)
        try:
            self.wait_for(collect, timeout_s)
        finally:
            self.send(mav.MAVLink_log_request_end_message(self.target_system,
                                                          self.target_component))
        return bytes(data)
