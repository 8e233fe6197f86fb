"""One MAVLink link (PX4's ``Mavlink`` object): a transport, streams, and the protocol services.

Each instance is one work item on its own queue (``wq:ttySn`` for a serial port, as PX4 runs a
task per instance), run every :data:`LOOP_INTERVAL_US` of virtual time. A run

1. reads what arrived (at most :data:`RX_BYTES_PER_RUN` bytes, so a flood cannot make one run
   arbitrarily long: the rest waits in the UART buffer or the UDP queue, which overflow and
   count their losses as real ones do), parses it with pymavlink and dispatches each message;
2. lets the services do their periodic work (parameter list streaming, mission retries, log
   download, shell output);
3. sends the streams that are due, within the link's data rate (a token bucket refilled at
   ``-r`` bytes/s; streams that do not fit wait, as PX4 scales its rates to the link);
4. publishes ``telemetry_status`` (last GCS heartbeat) once per second and on the first
   heartbeat.

Everything goes out in one write per run (one datagram on UDP, one burst on a UART). A UDP
link sends only HEARTBEAT until a client's first datagram arrives (PX4 announces itself with
heartbeats until a GCS connects); a serial link streams from the start, as a radio may listen
without talking.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Final

from firmware.modules.mavlink.dialect import mav
from firmware.modules.mavlink.streams import (
    DEFAULT_RATES,
    MAX_INTERVAL_US,
    STREAM_BY_ID,
    STREAMS,
    StreamDef,
)
from firmware.platform.workqueue import WorkItem

if TYPE_CHECKING:
    from firmware.modules.mavlink.module import MavlinkModule
    from firmware.modules.mavlink.transport import Transport

__all__ = ["LOOP_INTERVAL_US", "MavlinkInstance"]

LOOP_INTERVAL_US: Final = 10_000
RX_BYTES_PER_RUN: Final = 4096
#: messages handled per run at most; the rest waits in the parser, then in the port's buffer
RX_MSGS_PER_RUN: Final = 128
#: modelled STM32 time per received message and per sent message (parsing, CRC, copying)
CPU_NS_PER_RX_MSG: Final = 20_000
CPU_NS_PER_TX_MSG: Final = 15_000
CPU_NS_BASE: Final = 20_000
GCS_TIMEOUT_US: Final = 3_000_000
#: unsigned messages PX4 still accepts when signing is on (the radio's own reports)
UNSIGNED_ALLOWED: Final = frozenset({mav.MAVLINK_MSG_ID_RADIO_STATUS})


class _Stream:
    __slots__ = ("interval_us", "next_us", "sdef")

    def __init__(self, sdef: StreamDef, interval_us: int) -> None:
        self.sdef = sdef
        self.interval_us = interval_us
        self.next_us = 0


class MavlinkInstance(WorkItem):
    """A link: transport + pymavlink codec + streams + services (params, commands, ...)."""

    def __init__(self, module: MavlinkModule, index: int, transport: Transport, mode: str,
                 datarate_bps: int, wq: str) -> None:
        super().__init__(module.platform, f"mavlink_if{index}", wq)
        self.module = module
        self.index = index
        self.transport = transport
        self.mode = mode
        self.datarate = datarate_bps
        self.system = module.system
        self.sysid = int(module.param("MAV_SYS_ID"))
        self.compid = int(module.param("MAV_COMP_ID"))
        self.mav = mav.MAVLink(None, self.sysid, self.compid)
        self.mav.robust_parsing = True
        self._out = bytearray()
        self._udp: Any = transport if getattr(transport, "kind", "") == "udp" else None
        #: earliest next_us of any stream: runs before it skip the stream loop
        self._streams_due_us = 0
        self._silent = False
        self._tokens = float(datarate_bps) * 0.1
        self._subs: dict[tuple[str, int], Any] = {}
        self.streams: dict[str, _Stream] = {}
        for name, rate in DEFAULT_RATES[mode].items():
            self.set_stream_rate(name, rate)
        # counters
        self.rx_messages = self.rx_errors = self.rx_unknown = self.rx_unhandled = 0
        self.rx_not_for_us = self.rx_unsigned_rejected = self.rx_handler_errors = 0
        self.tx_messages = self.tx_bytes = self.tx_dropped = 0
        self.last_rx_seq: dict[tuple[int, int], int] = {}
        self.rx_seq_lost = 0
        self.gcs_heartbeat_us = 0
        self.gcs_sysid = 0
        self._telem_next_us = 0
        self._telem_pub = module.advertise("telemetry_status", index) if index < 4 else None
        self._telem = module.platform.orb.new("telemetry_status")
        self._busy_ns = 0
        # services (import here: they need this class's API, not the other way round)
        from firmware.modules.mavlink.available_modes import AvailableModesService
        from firmware.modules.mavlink.commands import CommandService
        from firmware.modules.mavlink.ftp import FtpService
        from firmware.modules.mavlink.mission import MissionService
        from firmware.modules.mavlink.params import ParamService
        from firmware.modules.mavlink.services import (
            LogService,
            OffboardService,
            ShellService,
            StatustextService,
        )
        from firmware.modules.mavlink.systime import SystemTimeService

        self.params = ParamService(self)
        self.commands = CommandService(self)
        self.mission = MissionService(self)
        self.shell = ShellService(self)
        self.logs = LogService(self)
        self.offboard = OffboardService(self)
        self.statustext = StatustextService(self)
        self.ftp = FtpService(self)
        self.systime = SystemTimeService(self)
        self.available_modes = AvailableModesService(self)
        self.services = (self.params, self.commands, self.mission, self.shell, self.logs,
                         self.offboard, self.statustext, self.ftp, self.systime,
                         self.available_modes)
        self.handlers: dict[int, Callable[[Any], None]] = {
            mav.MAVLINK_MSG_ID_HEARTBEAT: self._on_heartbeat,
            mav.MAVLINK_MSG_ID_PING: self._on_ping,
            mav.MAVLINK_MSG_ID_TIMESYNC: self._on_timesync,
            mav.MAVLINK_MSG_ID_SETUP_SIGNING: self._on_setup_signing,
        }
        for svc in self.services:
            self.handlers.update(svc.handlers())
        self.apply_signing()

    # -- helpers used by streams and services ---------------------------------------------------

    def latest(self, topic: str, instance: int = 0) -> Any:
        """The latest message of a topic (read-only), or None: streams sample, they don't queue."""
        sub = self._subs.get((topic, instance))
        if sub is None:
            sub = self._subs[(topic, instance)] = self.module.subscribe(topic, instance)
        return sub.node.last

    def param(self, name: str, default: float = 0) -> int | float:
        p = self.system.params
        if p is None:
            return default
        v = p.get(name, default)
        return default if v is None else v

    def time_us(self) -> int:
        return self.platform.hrt.absolute_time()

    def boot_ms(self) -> int:
        return (self.time_us() // 1000) & 0xFFFFFFFF

    def nav_state(self) -> int:
        st = self.latest("vehicle_status")
        return -1 if st is None else int(st.nav_state)

    def rx_drop_rate(self) -> float:
        total = self.rx_messages + self.rx_seq_lost
        return self.rx_seq_lost / total if total else 0.0

    def silent(self) -> bool:
        """A UDP link no client has talked to yet: it only announces itself (HEARTBEAT)."""
        return self._udp is not None and not self._udp.rx_datagrams

    def load_permille(self) -> int:
        """SYS_STATUS ``load``: ``cpuload.load`` in permille, as PX4 (0 before load_mon's first
        message or without load_mon)."""
        cpu = self.latest("cpuload")
        if cpu is None or not 0.0 <= cpu.load <= 1.0:
            return 0
        return round(cpu.load * 1000)

    # -- stream configuration -----------------------------------------------------------------

    def set_stream_rate(self, name: str, rate_hz: float) -> bool:
        """Set a stream's rate (0 stops it); False for a stream this firmware does not have."""
        sdef = STREAMS.get(name.upper())
        if sdef is None:
            return False
        if rate_hz <= 0:
            self.streams.pop(sdef.name, None)
            return True
        # 1 kHz at most; at least once per MESSAGE_INTERVAL's int32 µs (~36 min), so that a
        # rate however low keeps an interval GET_MESSAGE_INTERVAL can report
        interval = min(max(round(1e6 / rate_hz), 1000), MAX_INTERVAL_US)
        self._streams_due_us = 0  # look at every stream on the next run
        s = self.streams.get(sdef.name)
        if s is None:
            self.streams[sdef.name] = _Stream(sdef, interval)
        else:
            s.interval_us = interval
            s.next_us = min(s.next_us, self.time_us() + interval)  # a faster rate applies now
        return True

    def stream_interval_us(self, msg_id: int) -> int | None:
        sdef = STREAM_BY_ID.get(msg_id)
        if sdef is None:
            return None
        s = self.streams.get(sdef.name)
        return s.interval_us if s is not None else -1

    # -- signing ----------------------------------------------------------------------------

    def apply_signing(self) -> None:
        """Take the module's key: sign outgoing, refuse unsigned incoming (except radio status)."""
        key = self.module.signing_key if self.module.signing_active() else None
        sig = self.mav.signing
        sig.secret_key = key
        sig.sign_outgoing = key is not None
        sig.link_id = self.index
        sig.allow_unsigned_callback = (lambda _mav, msg_id: msg_id in UNSIGNED_ALLOWED) \
            if key is not None else None
        if key is not None:
            sig.timestamp = max(sig.timestamp, self.time_us() // 10)

    # -- sending ----------------------------------------------------------------------------

    def send(self, msg: Any, budget: bool = False) -> bool:
        """Queue a message for this run's write; False (and counted) if the link has no room.

        ``budget`` messages (streams, parameter and log streaming) also spend the data-rate
        tokens; answers to requests only need room in the transmit buffer, as in PX4.
        """
        buf = msg.pack(self.mav)
        return self._queue(buf, budget)

    def send_packed(self, msg: Any, crc_extra: int, payload: bytes, budget: bool = False
                    ) -> bool:
        """Send ``msg`` with a payload packed by the caller (exact bytes, e.g. PARAM_VALUE)."""
        buf = msg._pack(self.mav, crc_extra, payload)
        return self._queue(buf, budget)

    def _queue(self, buf: bytes, budget: bool) -> bool:
        n = len(buf)
        if self.transport.room() - len(self._out) < n or (budget and self._tokens < n):
            self.tx_dropped += 1
            return False
        if budget:
            self._tokens -= n
        self.mav.seq = (self.mav.seq + 1) % 256
        self._out += buf
        self.tx_messages += 1
        self.tx_bytes += n
        return True

    def tokens(self) -> float:
        return self._tokens

    def send_text(self, severity: int, text: str) -> None:
        """A STATUSTEXT to this link only (protocol errors concern the GCS that caused them)."""
        self.statustext.send_text(severity, text)

    def ack_command(self, command: int, result: int, target_system: int, target_component: int,
                    progress: int = 0, result_param2: int = 0) -> None:
        self.send(mav.MAVLink_command_ack_message(command, result, progress, result_param2,
                                                  target_system, target_component))

    # -- the loop ---------------------------------------------------------------------------

    def run(self) -> None:
        now = self.time_us()
        if self.module.signing_active() != (self.mav.signing.secret_key is not None):
            self.apply_signing()  # MAV_SIGN_CFG changed
        n_rx = self._receive()
        for svc in self.services:
            svc.update(now)
        self._tokens = min(self._tokens + self.datarate * LOOP_INTERVAL_US / 1e6,
                           self.datarate * 0.1 + 300)
        self._send_streams(now)
        if now >= self._telem_next_us:
            self._publish_telemetry(now)
        if self._out:
            self.transport.write(bytes(self._out))
            self._out.clear()
        n_tx = self.tx_messages - self._tx_at_last_run
        self._tx_at_last_run = self.tx_messages
        self.cpu_cost_ns = CPU_NS_BASE + n_rx * CPU_NS_PER_RX_MSG + n_tx * CPU_NS_PER_TX_MSG
        self.max_cost_ns = max(self.max_cost_ns, self.cpu_cost_ns)

    _tx_at_last_run = 0
    #: the longest modelled run so far (ns): the budget a flood must not blow
    max_cost_ns = 0

    def _receive(self) -> int:
        """Parse and handle at most RX_MSGS_PER_RUN messages; read only what the parser's
        backlog leaves room for, so a flood stays in (and overflows) the port's buffer."""
        p = self.mav
        room = RX_BYTES_PER_RUN - p.buf_len()
        data = self.transport.read(room) if room > 0 else b""
        if not data and room == RX_BYTES_PER_RUN:
            return 0  # nothing arrived and nothing buffered: no parser call
        n = 0
        chunk: bytes = data
        while n < RX_MSGS_PER_RUN:
            try:
                m = p.parse_char(chunk)
            except Exception:  # noqa: BLE001 - pymavlink may raise on garbage it cannot frame
                self.rx_errors += 1
                p.buf = bytearray()
                p.buf_index = 0
                p.expected_length = mav.HEADER_LEN_V1 + 2
                m = None
            chunk = b""
            if m is None:
                break
            n += 1
            self._dispatch(m)
        return n

    def _dispatch(self, m: Any) -> None:
        if isinstance(m, mav.MAVLink_unknown):  # a message id not in the common dialect
            self.rx_unknown += 1
            return
        msg_id = m.get_msgId()
        if msg_id < 0:  # MAVLink_bad_data: bad prefix, CRC, unknown id, refused signature
            reason = getattr(m, "reason", "")
            if "Invalid signature" in reason:
                self.rx_unsigned_rejected += 1
            else:
                self.rx_errors += 1
            return
        self.rx_messages += 1
        src = (m.get_srcSystem(), m.get_srcComponent())
        seq = m.get_seq()
        last = self.last_rx_seq.get(src)
        if last is not None:
            self.rx_seq_lost += (seq - last - 1) & 0xFF
        self.last_rx_seq[src] = seq
        tsys = getattr(m, "target_system", None)
        if tsys is not None and tsys not in (0, self.sysid):
            self.rx_not_for_us += 1
            return
        tcomp = getattr(m, "target_component", None)
        if tcomp is not None and tcomp not in (0, self.compid) and \
                msg_id not in (mav.MAVLINK_MSG_ID_COMMAND_LONG, mav.MAVLINK_MSG_ID_COMMAND_INT):
            self.rx_not_for_us += 1
            return
        handler = self.handlers.get(msg_id)
        if handler is None:
            self.rx_unhandled += 1
            return
        try:
            handler(m)
        except Exception as exc:  # noqa: BLE001 - a GCS message must not crash the FMU
            self.handler_failed(m, exc)

    def handler_failed(self, m: Any, exc: BaseException, context: str = "") -> None:
        """Record a message handler that raised: counted in :attr:`rx_handler_errors` and
        logged as an ERR in dmesg with the exception. Every guard that contains a handler's
        exception (this dispatcher's, the mission protocol's, the commands') reports here,
        so a bug answered politely to the GCS is still visible to tests and fuzz targets."""
        self.rx_handler_errors += 1
        self.module.error(f"{m.get_type()}{context}: {type(exc).__name__}: {exc}")

    def _send_streams(self, now: int) -> None:
        # A UDP link nobody has talked to yet only announces itself (HEARTBEAT, as PX4
        # broadcasts heartbeats until a GCS connects); the other streams start with the first
        # datagram received, so unobserved links build no telemetry.
        silent = self.silent()
        if now < self._streams_due_us and silent == self._silent:
            return
        self._silent = silent
        due = 1 << 62
        for s in self.streams.values():
            if now >= s.next_us:
                if silent and s.sdef.name != "HEARTBEAT":
                    continue  # stays due: it starts with the client's first datagram
                msg = s.sdef.build(self)
                if msg is None:
                    s.next_us = now + s.interval_us
                elif self.send(msg, budget=s.sdef.name != "HEARTBEAT"):
                    nxt = s.next_us + s.interval_us
                    s.next_us = nxt if nxt > now else now + s.interval_us
                else:
                    due = 0  # retry next run, as PX4 does when the buffer is full
                    continue
            if s.next_us < due:
                due = s.next_us
        self._streams_due_us = due

    def send_stream_once(self, msg_id: int) -> bool:
        """REQUEST_MESSAGE for a streamed message: build and send it now."""
        sdef = STREAM_BY_ID.get(msg_id)
        if sdef is None:
            return False
        msg = sdef.build(self)
        return msg is not None and self.send(msg)

    def _publish_telemetry(self, now: int) -> None:
        self._telem_next_us = now + 1_000_000
        if self._telem_pub is None:
            return
        t = self._telem
        t.timestamp = now
        t.type = self.transport.link_type
        t.heartbeat_gcs_timestamp = self.gcs_heartbeat_us
        t.heartbeat_type_gcs = bool(self.gcs_heartbeat_us) and \
            now - self.gcs_heartbeat_us <= GCS_TIMEOUT_US
        t.gcs_system_id = self.gcs_sysid
        t.rx_message_count = self.rx_messages & 0xFFFFFFFF
        t.tx_message_count = self.tx_messages & 0xFFFFFFFF
        self._telem_pub.publish(t)

    # -- link-level messages ----------------------------------------------------------------

    def _on_heartbeat(self, m: Any) -> None:
        if m.type != mav.MAV_TYPE_GCS:
            return
        first = self.gcs_heartbeat_us == 0
        self.gcs_heartbeat_us = self.time_us()
        self.gcs_sysid = m.get_srcSystem()
        if first:
            self._telem_next_us = 0  # tell the commander at once

    def _on_ping(self, m: Any) -> None:
        if m.target_system == 0 and m.target_component == 0:
            self.send(mav.MAVLink_ping_message(m.time_usec, m.seq, m.get_srcSystem(),
                                               m.get_srcComponent()))

    def _on_timesync(self, m: Any) -> None:
        if m.tc1 == 0:
            self.send(mav.MAVLink_timesync_message(self.time_us() * 1000, m.ts1))

    def _on_setup_signing(self, m: Any) -> None:
        """A new key from the GCS (accepted on an unsigned link or over a signed message)."""
        if self.module.signing_active() and not getattr(m, "_signed", False):
            return
        self.module.set_signing_key(bytes(m.secret_key), int(m.initial_timestamp))

    def stop(self) -> None:
        self.schedule_clear()
        self.transport.close()

    def status_lines(self) -> list[str]:
        gcs = (f"GCS {self.gcs_sysid} heard {(self.time_us() - self.gcs_heartbeat_us) / 1e6:.1f}"
               f" s ago" if self.gcs_heartbeat_us else "no GCS heard")
        sign = "on" if self.mav.signing.secret_key is not None else "off"
        return [f"instance #{self.index}: {self.transport.describe()}",
                f"  mode: {self.mode}, data rate: {self.datarate} B/s, {gcs}, signing {sign}",
                (f"  rx: {self.rx_messages} msgs, {self.rx_errors} malformed, "
                 f"{self.rx_unknown} unknown, {self.rx_unhandled} unhandled, "
                 f"{self.rx_not_for_us} for others, {self.rx_unsigned_rejected} unsigned "
                 f"refused, {self.rx_handler_errors} handler errors, "
                 f"{self.rx_seq_lost} lost (seq), "
                 f"{getattr(self.transport, 'rx_lost', 0)} dropped by the port"),
                f"  tx: {self.tx_messages} msgs, {self.tx_bytes} bytes, {self.tx_dropped} dropped",
                "  streams: " + ", ".join(f"{n} {1e6 / s.interval_us:.3g} Hz"
                                         for n, s in self.streams.items())]
