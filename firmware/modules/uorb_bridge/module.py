"""``uorb_bridge``: uORB topics over a serial link, the same module on the FMU and the companion.

::

    uorb_bridge start -d /dev/ttyS2 [-b 921600|p:SER_TEL2_BAUD] -r fmu|companion [-c FILE]
    uorb_bridge status
    uorb_bridge stop

``-r`` says which list of the topic file (:mod:`.topics`) this side sends; it receives the
other. The module never asks which board it runs on: the role is an argument.

It is one waiter, PX4 task style: ONE ``poll()`` over the serial port and every subscription
it sends (:class:`firmware.platform.task.PollWaiter`), with the timeout at the next thing due
(a heartbeat, the link timeout, a rate-limited topic's next slot). When it wakes it reads what
the port has, decodes and publishes the frames (:mod:`.protocol`), then sends what its
subscriptions have. Writes never block: a frame the UART's transmit buffer has no room for is
dropped and counted (``tx_dropped``), as a non-blocking write to a full NuttX serial buffer.

A rate-limited topic with unread data is left out of the poll list until its slot comes (the
timeout covers it), so a 250 Hz topic sent at 50 Hz does not wake the bridge 250 times a second.

Link state: a good frame (any topic, or the heartbeat sent at ``heartbeat_hz``) within
``link_timeout_ms`` means the link is up; quiet for longer is reported once ("link lost",
PX4_WARN) and its return once ("link regained"). ``bridge_status`` is published at the
heartbeat rate and at every change of the link state.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, ClassVar

from firmware.modules.uorb_bridge.params import PARAMS
from firmware.modules.uorb_bridge.protocol import (
    CRC_NAME,
    HEARTBEAT_ID,
    Frame,
    FrameDecoder,
    Heartbeat,
    encode_frame,
)
from firmware.modules.uorb_bridge.topics import ROLES, BridgeConfig, BridgeConfigError, Route
from firmware.platform.module import ModuleBase, ModuleError, UsageError
from firmware.platform.uorb import Publication, Subscription, SubscriptionInterval

if TYPE_CHECKING:
    from firmware.platform.params import ParamDef
    from firmware.platform.serial import SerialPort
    from firmware.platform.task import PollWaiter
    from firmware.system import System

__all__ = ["DEFAULT_BAUD", "DEFAULT_CONFIG", "UorbBridgeModule"]

DEFAULT_CONFIG = "/etc/bridge/topics.yaml"
DEFAULT_BAUD = 921600


class _TxRoute:
    """A topic this side sends: its route, subscription and counters."""

    __slots__ = ("route", "sub", "interval_sub", "frames", "dropped")

    def __init__(self, route: Route, sub: Subscription) -> None:
        self.route = route
        self.sub = sub
        self.interval_sub: SubscriptionInterval | None = (
            sub if isinstance(sub, SubscriptionInterval) else None)
        self.frames = 0
        self.dropped = 0


class _RxRoute:
    """A topic this side receives: its route, class, publication (advertised on the first
    frame, so a topic nobody sends is not advertised) and counter."""

    __slots__ = ("route", "cls", "pub", "frames")

    def __init__(self, route: Route, cls: Any) -> None:
        self.route = route
        self.cls = cls
        self.pub: Publication | None = None
        self.frames = 0


class UorbBridgeModule(ModuleBase):
    NAME: ClassVar[str] = "uorb_bridge"
    DESCRIPTION: ClassVar[str] = "uORB topics over a serial link to a companion computer"
    USAGE: ClassVar[tuple[str, ...]] = (
        "start -d DEV [-b BAUD|p:PARAM] -r fmu|companion [-c FILE]",
        "   -d DEV   serial device (/dev/ttyS2 on the FMU, /dev/ttyUSB0 on the companion)",
        f"   -b BAUD  speed (default {DEFAULT_BAUD}); p:NAME reads it from parameter NAME",
        "   -r ROLE  fmu or companion: which list of the topic file this side sends",
        f"   -c FILE  topic list (default {DEFAULT_CONFIG})",
    )
    PARAMS: ClassVar[tuple[ParamDef, ...]] = PARAMS

    def __init__(self, system: System, args: Sequence[str] = ()) -> None:
        super().__init__(system, args)
        self.device = ""
        self.baud = DEFAULT_BAUD
        self.role = ""
        self.config_path = DEFAULT_CONFIG
        self.config: BridgeConfig | None = None
        self.port: SerialPort | None = None
        self.decoder = FrameDecoder({})
        self.tx: list[_TxRoute] = []
        self.rx: dict[tuple[int, int], _RxRoute] = {}
        self._waiter: PollWaiter | None = None
        self._status_pub: Publication | None = None
        self._status: Any = None
        self._seq = 0
        self.tx_frames = 0
        self.tx_bytes = 0
        self.tx_dropped = 0
        self.rx_frames = 0
        self.heartbeats_rx = 0
        self.wakes = 0
        self.link_ok = False
        self.link_lost_count = 0
        self.last_rx_us = 0
        self._ever_up = False
        self._crc_ok_seen = 0
        self._next_hb_us = 0
        self._hb_interval_us = 500_000
        self._timeout_us = 500_000
        self.peer = Heartbeat()

    # -- start-up ---------------------------------------------------------------------------

    @classmethod
    def instantiate(cls, system: System, args: Sequence[str]) -> ModuleBase:
        self = cls(system, args)
        rest = list(args)
        baud_text = str(DEFAULT_BAUD)
        while rest:
            opt = rest.pop(0)
            if opt not in ("-d", "-b", "-r", "-c"):
                raise UsageError(f"unknown option {opt!r}")
            if not rest:
                raise UsageError(f"option {opt} needs a value")
            val = rest.pop(0)
            if opt == "-d":
                self.device = val
            elif opt == "-b":
                baud_text = val
            elif opt == "-r":
                if val not in ROLES:
                    raise UsageError(f"-r must be fmu or companion, not {val!r}")
                self.role = val
            else:
                self.config_path = val
        if not self.device:
            raise UsageError("missing -d DEV")
        if not self.role:
            raise UsageError("missing -r fmu|companion")
        self.baud = self._baud(baud_text)
        return self

    def _baud(self, text: str) -> int:
        if text.startswith("p:"):
            name = text[2:]
            params = self.system.params
            if params is None or name not in params:
                raise UsageError(f"-b {text}: no parameter {name}")
            value = int(params[name])
        else:
            try:
                value = int(text, 10)
            except ValueError:
                raise UsageError(f"-b: bad baud rate {text!r}") from None
        if value <= 0:
            raise UsageError(f"-b: bad baud rate {value}")
        return value

    def _start(self) -> None:
        from firmware.platform.serial import open_serial
        from firmware.system import PathError

        orb = self.platform.orb
        try:
            host_path = self.system.resolve_path(self.config_path)
            cfg = BridgeConfig.load_file(self.config_path, host_path, orb.registry)
        except (BridgeConfigError, PathError) as exc:
            raise ModuleError(str(exc)) from None
        self.config = cfg
        self._timeout_us = cfg.link_timeout_ms * 1000
        self._hb_interval_us = max(1, int(round(1e6 / cfg.heartbeat_hz)))
        self.tx = []
        for r in cfg.sends(self.role):
            if r.interval_us > 0:
                sub: Subscription = SubscriptionInterval(orb, r.topic, r.interval_us,
                                                         r.instance)
            else:
                sub = Subscription(orb, r.topic, r.instance)
            self.subscriptions.append(sub)
            self.tx.append(_TxRoute(r, sub))
        self.rx = {(r.topic_id, r.instance): _RxRoute(r, orb.registry.cls(r.publish_as))
                   for r in cfg.receives(self.role)}
        self.decoder = FrameDecoder({r.topic_id: r.size for r in cfg.receives(self.role)})
        self._status_pub = self.advertise("bridge_status")
        self._status = orb.new("bridge_status")
        self.port = open_serial(self.system, self.device, self.baud)
        # tcflush(TCIFLUSH): what the UART buffered before the port was opened is the middle
        # of a stream that overran the buffer; read from here on, it resynchronises cleanly
        self.port.read()
        now = self.platform.time_us()
        self._next_hb_us = now
        self.info(f"{self.role} side on {self.device} at {self.baud} baud: "
                  f"{len(self.tx)} topics out, {len(self.rx)} in ({cfg.source})")
        self._poll()

    def _stop(self) -> None:
        if self._waiter is not None:
            self._waiter.cancel()
            self._waiter = None
        if self.port is not None:
            self.port.close()
            self.port = None
        self.rx.clear()
        self.tx.clear()

    # -- the loop ---------------------------------------------------------------------------

    def _poll(self) -> None:
        """Wait (one poll) on the port and the subscriptions that may be sent now."""
        from firmware.platform.task import PollWaiter

        port = self.port
        if port is None:
            return
        now = self.platform.time_us()
        due = self._next_hb_us
        if self.link_ok:
            due = min(due, self.last_rx_us + self._timeout_us)
        items: list[Any] = [port]
        for t in self.tx:
            isub = t.interval_sub
            if isub is not None and isub.node.generation != isub.last_gen:
                # unread data waiting for its slot: the timeout covers it, not a wake-up
                due = min(due, isub.last_update_us + isub.interval_us)
                continue
            items.append(t.sub)
        self._waiter = PollWaiter(self.platform, items, max(1, due - now), self._on_ready)

    def _on_ready(self, n: int) -> None:
        self._waiter = None
        if self.port is None:
            return
        self.wakes += 1
        now = self.platform.time_us()
        self._receive(now)
        self._send_topics()
        if now >= self._next_hb_us:
            self._send_heartbeat(now)
            self._next_hb_us = now + self._hb_interval_us
            self._publish_status(now)
        if self.link_ok and now - self.last_rx_us >= self._timeout_us:
            self.link_ok = False
            self.link_lost_count += 1
            self.decoder.flush()              # a frame cut by the loss is truncated
            self.decoder.forget_sequence()
            self.warn("link lost")
            self._publish_status(now)
        self._poll()

    # -- receiving --------------------------------------------------------------------------

    def _receive(self, now: int) -> None:
        port = self.port
        assert port is not None
        data = port.read()
        if not data:
            return
        dec = self.decoder
        for frame in dec.feed(data):
            self._handle(frame)
        ok = dec.frames + dec.drops.unknown_id + dec.drops.bad_size
        if ok != self._crc_ok_seen:            # whole frames arrived: the link is alive
            self._crc_ok_seen = ok
            self.last_rx_us = now
            if not self.link_ok:
                self.link_ok = True
                if self._ever_up:
                    self.info("link regained")
                else:
                    self._ever_up = True
                    self.info("link up")
                self._publish_status(now)

    def _handle(self, frame: Frame) -> None:
        if frame.topic_id == HEARTBEAT_ID:
            self.peer = Heartbeat.unpack(frame.payload)
            self.heartbeats_rx += 1
            self.rx_frames += 1
            return
        r = self.rx.get((frame.topic_id, frame.instance))
        if r is None:                         # a known topic, another instance
            self.decoder.drops.unknown_id += 1
            return
        self.rx_frames += 1
        msg = r.cls.unpack(frame.payload)
        pub = r.pub
        if pub is None:
            pub = r.pub = self.advertise(r.route.publish_as, r.route.instance)
        r.frames += 1
        pub.publish(msg)

    # -- sending ----------------------------------------------------------------------------

    def _send_topics(self) -> None:
        for t in self.tx:
            sub = t.sub
            if not sub.updated():
                continue
            r = t.route
            if t.interval_sub is not None:
                msg = sub.update()
                if msg is not None:
                    self._send(t, r.topic_id, r.instance, msg.pack())
            else:
                for msg in sub.update_all():
                    self._send(t, r.topic_id, r.instance, msg.pack())

    def _send(self, t: _TxRoute | None, topic_id: int, instance: int, payload: bytes) -> None:
        port = self.port
        assert port is not None
        frame = encode_frame(topic_id, instance, self._seq, payload)
        if port.room() < len(frame):
            self.tx_dropped += 1
            if t is not None:
                t.dropped += 1
            return
        port.write(frame)
        self._seq = (self._seq + 1) & 0xFF
        self.tx_frames += 1
        self.tx_bytes += len(frame)
        if t is not None:
            t.frames += 1

    def _send_heartbeat(self, now: int) -> None:
        hb = Heartbeat(now, self.tx_frames + 1, self.rx_frames, self.decoder.drops.frames,
                       self.tx_dropped)
        self._send(None, HEARTBEAT_ID, 0, hb.pack())

    # -- status -----------------------------------------------------------------------------

    def _publish_status(self, now: int) -> None:
        s = self._status
        pub = self._status_pub
        if s is None or pub is None:
            return
        d = self.decoder.drops
        m = 0xFFFFFFFF
        s.timestamp = now
        s.link_ok = self.link_ok
        s.last_rx_us = self.last_rx_us
        s.link_lost_count = self.link_lost_count & m
        s.tx_frames = self.tx_frames & m
        s.tx_bytes = self.tx_bytes & m
        s.tx_dropped = self.tx_dropped & m
        s.rx_frames = self.rx_frames & m
        s.rx_bytes = self.decoder.bytes & m
        s.rx_crc_errors = d.crc & m
        s.rx_truncated = d.truncated & m
        s.rx_unknown_id = d.unknown_id & m
        s.rx_bad_size = d.bad_size & m
        s.rx_garbage_bytes = d.garbage_bytes & m
        s.rx_lost = d.lost & m
        s.peer_tx_frames = self.peer.tx_frames
        s.peer_rx_frames = self.peer.rx_frames
        s.peer_rx_dropped = self.peer.rx_dropped
        s.peer_tx_dropped = self.peer.tx_dropped
        pub.publish(s)

    def status_lines(self) -> list[str]:
        d = self.decoder.drops
        link = "up" if self.link_ok else ("lost" if self._ever_up else "waiting")
        last = (f", last frame {(self.platform.time_us() - self.last_rx_us) / 1000:.0f} ms ago"
                if self._ever_up else "")
        out = [
            f"{self.role} side on {self.device} at {self.baud} baud, topics from "
            f"{self.config.source if self.config else '?'}; frames {CRC_NAME}",
            f"link {link}{last}; lost {self.link_lost_count} times",
            f"tx: {self.tx_frames} frames, {self.tx_bytes} bytes, {self.tx_dropped} dropped "
            f"(no room in the UART's TX buffer)",
            f"rx: {self.rx_frames} frames ({self.heartbeats_rx} heartbeats), "
            f"{self.decoder.bytes} bytes",
            f"rx dropped: crc {d.crc}, truncated {d.truncated}, unknown id {d.unknown_id}, "
            f"bad size {d.bad_size}; {d.garbage_bytes} garbage bytes, {d.lost} lost by sequence",
            f"peer: tx {self.peer.tx_frames}, rx {self.peer.rx_frames}, rx dropped "
            f"{self.peer.rx_dropped}, tx dropped {self.peer.tx_dropped}",
        ]
        for t in self.tx:
            rate = "every update" if t.route.rate_hz <= 0 else f"<= {t.route.rate_hz:g} Hz"
            out.append(f"  out {t.route.topic}[{t.route.instance}] ({rate}): {t.frames} frames"
                       + (f", {t.dropped} dropped" if t.dropped else ""))
        for r in self.rx.values():
            name = r.route.topic if r.route.publish_as == r.route.topic else \
                f"{r.route.topic} as {r.route.publish_as}"
            out.append(f"  in  {name}[{r.route.instance}]: {r.frames} frames")
        return out
