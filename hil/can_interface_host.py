"""The host side of an emulated CAN bus: the tools attached to it, in this process or outside.

:class:`CanHost` is a host device (:mod:`hil.devices`) owning the ``can1`` and ``can1_host``
ports wired to the FMU's adapter node (:mod:`fmu.can_port`). Every attached tool is an
:class:`Endpoint` with a tag: frames from the bus go to all of them; a frame a tool sends enters
the bus at the current virtual time (as the adapter receives it over USB), and once it went out
its confirmation (with its wire time) comes back, and it is handed to the *other* endpoints, as
a real bus would show it to them. Endpoints:

* :class:`QueueEndpoint`: the python-can plug-in in this process (:mod:`hil.can_interface`);
* :class:`TcpEndpoint`: a client of the TCP server on 127.0.0.1 (the plug-in in another
  process; the format is :mod:`hil.can_interface_wire`);
* :class:`hil.bindings_can.BoundBus`: a real or virtual python-can bus (``hil fly --can``).

The adapter node joins the bus (ACKs frames) only while at least one endpoint is attached.

Timestamps: virtual time in seconds when the emulator is not paced (``speed`` None); when it is
paced, wall-clock epoch seconds (``time.time()``) mapped from virtual time by the pacing ratio,
re-anchored whenever the emulator drifts from its pace by more than 50 ms (it lags under load).
Outside input is polled between quanta (every ``poll_every``), so frames from a tool enter
virtual time at the next poll: attached tools make a run non-deterministic, by nature.
"""

from __future__ import annotations

import selectors
import socket
import sys
import time
from collections import deque
from typing import Any, Callable

from hil.can_interface_wire import KIND_ECHO, KIND_FRAME, RECORD, WireFrame, decode, encode

__all__ = ["CanHost", "Endpoint", "QueueEndpoint", "TcpEndpoint", "find_host", "register",
           "registered", "unregister"]

NS_PER_S = 1_000_000_000
_RESYNC_S = 0.05


class Endpoint:
    """One tool on the bus. Subclasses override :meth:`deliver` and, if they pull input from
    outside, :meth:`poll`; frames to send go into ``tx``."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.tag = 0
        self.tx: deque[WireFrame] = deque()
        self.closed = False
        self.frames_in = 0
        self.frames_out = 0
        self.dropped = 0

    def poll(self, host: CanHost) -> None:
        """Pull what the tool sent since the last poll into ``tx``."""

    def deliver(self, frame: WireFrame) -> None:
        """A frame seen on the bus (kind 1), or this tool's own frame gone out (kind 2)."""

    def close(self) -> None:
        self.closed = True


class QueueEndpoint(Endpoint):
    """The in-process plug-in: two deques (appends and pops are atomic, so a tool's threads,
    such as dronecan's writer, may send while another thread runs the emulator)."""

    def __init__(self, name: str, receive_own: bool = False, maxlen: int = 100_000) -> None:
        super().__init__(name)
        self.receive_own = receive_own
        self.rx: deque[WireFrame] = deque(maxlen=maxlen)

    def deliver(self, frame: WireFrame) -> None:
        if frame.kind == KIND_ECHO and not self.receive_own:
            return
        self.rx.append(frame)
        self.frames_out += 1


class TcpEndpoint(Endpoint):
    """A client of the host's TCP server (the plug-in in another process)."""

    #: Bytes waiting for a client that reads slowly; beyond this, frames are dropped whole
    #: (so the record stream never loses its alignment).
    OUT_BUFFER_MAX = 1 << 20

    def __init__(self, conn: socket.socket, name: str) -> None:
        super().__init__(name)
        self.conn = conn
        self._buf = bytearray()
        self._outbuf = bytearray()

    def poll(self, host: CanHost) -> None:
        self._flush()

    def read_ready(self, host: CanHost) -> None:
        try:
            data = self.conn.recv(RECORD.size * 256)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if not data:
            self.close()
            return
        self._buf += data
        frames, bad = decode(self._buf, kinds=(KIND_FRAME,))
        if bad:
            self.dropped += bad
            host.bad_records += bad
        self.frames_in += len(frames)
        self.tx.extend(frames)

    def deliver(self, frame: WireFrame) -> None:
        if len(self._outbuf) >= self.OUT_BUFFER_MAX:
            self.dropped += 1  # the client does not read: drop, as a full USB buffer would
            return
        self._outbuf += encode(frame)
        self.frames_out += 1
        self._flush()

    def _flush(self) -> None:
        if not self._outbuf or self.closed:
            return
        try:
            n = self.conn.send(self._outbuf)
            del self._outbuf[:n]
        except (BlockingIOError, InterruptedError):
            pass
        except OSError:
            self.close()

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            try:
                self.conn.close()
            except OSError:
                pass


class CanHost:
    """Tools on the emulated bus ``bus`` (``CAN1``); a TCP server if ``tcp_port`` is not None
    (0: any free port, see ``tcp_port`` after construction)."""

    def __init__(self, bus: str = "CAN1", bitrate: int = 1_000_000, speed: float | None = None,
                 tcp_port: int | None = None, poll_every: int = 10,
                 log: Callable[[str], None] | None = None) -> None:
        self.bus = bus
        self.port = bus.lower()
        self.ports = (self.port, f"{self.port}_host")
        self.bitrate = bitrate
        self.speed = speed
        self.poll_every = max(1, poll_every)
        self.log = log or (lambda text: print(text, file=sys.stderr, flush=True))
        self.endpoints: list[Endpoint] = []
        self._next_tag = 1
        self._t_ns = 0
        self._calls = 0
        self._out: list = []
        self._attached = False
        self._anchor: tuple[float, int] | None = None
        self.frames_from_bus = 0
        self.frames_to_bus = 0
        self.bad_records = 0
        self._sel: selectors.BaseSelector | None = None
        self._server: socket.socket | None = None
        self.tcp_port: int | None = None
        if tcp_port is not None:
            srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            srv.bind(("127.0.0.1", tcp_port))
            srv.listen(8)
            srv.setblocking(False)
            self._server = srv
            self.tcp_port = srv.getsockname()[1]
            self._sel = selectors.DefaultSelector()
            self._sel.register(srv, selectors.EVENT_READ, None)

    # -- endpoints --------------------------------------------------------------------------------

    def attach(self, ep: Endpoint) -> Endpoint:
        ep.tag = self._next_tag
        self._next_tag += 1
        self.endpoints.append(ep)
        return ep

    def detach(self, ep: Endpoint) -> None:
        if ep in self.endpoints:
            self.endpoints.remove(ep)
        if isinstance(ep, TcpEndpoint) and self._sel is not None:
            try:
                self._sel.unregister(ep.conn)
            except (KeyError, ValueError):
                pass
        ep.close()

    @property
    def t_ns(self) -> int:
        return self._t_ns

    def timestamp(self, t_ns: int) -> float:
        """A frame's timestamp: virtual seconds, or wall-clock epoch seconds when paced."""
        if self.speed is None:
            return t_ns / NS_PER_S
        if self._anchor is None:
            self._anchor = (time.time(), t_ns)
        wall0, t0 = self._anchor
        return wall0 + (t_ns - t0) / NS_PER_S / self.speed

    # -- host device interface -------------------------------------------------------------------

    def run_until(self, t_ns: int) -> None:
        self._t_ns = t_ns
        self._calls += 1
        if self.speed is not None:
            now = time.time()
            if self._anchor is None or abs(self.timestamp(t_ns) - now) > _RESYNC_S:
                self._anchor = (now, t_ns)
        if self._calls % self.poll_every == 0:
            self._poll_outside()
        for ep in list(self.endpoints):
            if ep.closed:
                self.detach(ep)
                continue
            tx = ep.tx
            while tx:
                f = tx.popleft()
                self._out.append((self.port, t_ns, (f.arbitration_id, f.is_extended,
                                                    f.is_remote, f.data, ep.tag)))
                self.frames_to_bus += 1
        attached = bool(self.endpoints)
        if attached != self._attached:
            self._attached = attached
            self._out.append((self.ports[1], t_ns, attached))

    def _poll_outside(self) -> None:
        sel = self._sel
        if sel is not None:
            for key, _ in sel.select(timeout=0):
                if key.data is None:
                    self._accept()
                else:
                    key.data.read_ready(self)
        for ep in self.endpoints:
            if not ep.closed:
                ep.poll(self)

    def _accept(self) -> None:
        assert self._server is not None and self._sel is not None
        try:
            conn, addr = self._server.accept()
        except (BlockingIOError, InterruptedError):
            return
        conn.setblocking(False)
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        ep = TcpEndpoint(conn, f"tcp {addr[0]}:{addr[1]}")
        self.attach(ep)
        self._sel.register(conn, selectors.EVENT_READ, ep)

    def outputs(self, until_ns: int) -> list:
        out, self._out = self._out, []
        return out

    def input(self, port: str, t_ns: int, payload: Any) -> None:
        aid, ext, rtr, data, tag = payload
        ts = self.timestamp(t_ns)
        frame = WireFrame(KIND_FRAME, aid, ext, rtr, bytes(data), ts)
        if tag == 0:
            self.frames_from_bus += 1
        for ep in self.endpoints:
            if ep.closed:
                continue
            if tag and ep.tag == tag:
                ep.deliver(WireFrame(KIND_ECHO, aid, ext, rtr, bytes(data), ts))
            else:
                ep.deliver(frame)

    def stats(self) -> dict[str, Any]:
        return {"endpoints": [(e.name, e.frames_in, e.frames_out, e.dropped)
                              for e in self.endpoints],
                "frames_from_bus": self.frames_from_bus, "frames_to_bus": self.frames_to_bus,
                "bad_records": self.bad_records}

    def close(self) -> None:
        for ep in list(self.endpoints):
            self.detach(ep)
        if self._server is not None and self._sel is not None:
            self._sel.unregister(self._server)
            self._server.close()
            self._server = None
            self._sel.close()
        unregister(self)


# -- in-process registry (the plug-in finds a host by channel name) ----------------------------

_REGISTRY: dict[str, tuple[CanHost, Any]] = {}


def register(host: CanHost, driver: Any = None) -> None:
    """Make ``host`` what ``can.Bus(interface="hil", channel=host.bus)`` reaches in this process
    (for tools that cannot be given ``board=``, such as ``dronecan.make_node``). ``driver``: an
    orchestrator the plug-in runs while it waits for frames (unpaced, in-process tests)."""
    _REGISTRY[host.bus] = (host, driver)


def unregister(host: CanHost) -> None:
    for k, (h, _d) in list(_REGISTRY.items()):
        if h is host:
            del _REGISTRY[k]


def registered(channel: str) -> tuple[CanHost, Any] | None:
    return _REGISTRY.get(channel)


def find_host(target: Any, channel: str) -> tuple[CanHost, Any]:
    """(host, orchestrator or None) for ``board=`` of the plug-in: a :class:`CanHost`, an
    orchestrator or device hub holding one for ``channel``, or the devices dict of
    :func:`hil.system.build_system`."""
    if isinstance(target, CanHost):
        return target, None
    driver = target if hasattr(target, "run") and hasattr(target, "quantum_ns") else None
    pool: list[Any] = []
    if isinstance(target, dict):
        pool = list(target.values())
    else:
        world = getattr(target, "world", None) if driver is not None else target
        pool = list(getattr(world, "devices", ()) or ())
    for d in pool:
        if isinstance(d, CanHost) and d.bus == channel:
            return d, driver
    raise ValueError(f"hil CAN: {type(target).__name__} has no host side for {channel!r} "
                     f"(build the system with SystemConfig(can_hosts=({channel!r},)))")
