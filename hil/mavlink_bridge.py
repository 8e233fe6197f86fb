"""MAVLink over UDP between host programs (QGroundControl, MAVProxy, MAVSDK) and the FMU.

The FMU's mavlink module sends and receives whole datagrams on the board's network ports
(``udp_out`` / ``udp_in``, payload ``(fmu_port, remote_port, data)``); this host device owns the
real sockets. Each :class:`UdpEndpoint` binds one socket on 127.0.0.1 and joins it to one FMU
port, following PX4 SITL's conventions:

====================  ===========  =============  ======================================
link                  host socket  sends to        FMU side
====================  ===========  =============  ======================================
GCS (QGC, MAVProxy)   18570        14550           ``mavlink start -u 18570 -o 14550``
API / offboard        14580        14540           ``mavlink start -u 14580 -o 14540 -m onboard``
====================  ===========  =============  ======================================

Until a client has talked, datagrams go to 127.0.0.1 at the remote port the FMU names (QGC
listens on 14550 and picks the vehicle up from its heartbeats); afterwards to the address of the
last client that talked, as PX4's UDP link does.

Sockets are non-blocking and polled once per ``poll_every`` quanta: what a host program sends
enters virtual time at the next poll (interactive use is not deterministic, by nature).

Heartbeat keepalive (wall clock, here at the edge only). The FMU's HEARTBEAT is paced in virtual
time, so an emulator running slower than the wall clock would look like a lost link to clients
that time out in wall time (QGroundControl and MAVSDK after ~3-5 s without a HEARTBEAT).
:class:`HeartbeatKeepalive` re-sends the vehicle's last HEARTBEAT, byte for byte, at 1 Hz of
wall time once ``KEEPALIVE_AFTER_S`` of wall time have passed without one, but only while the
vehicle itself is not silent in virtual time (its last HEARTBEAT is under
``VEHICLE_SILENT_NS`` old in its own time): clients see a slow vehicle, not a lost one, and a
vehicle that really stopped sending (or an emulator that stopped stepping) still times out.
The boards never see any of this: nothing is logged or changed below hil/.
"""

from __future__ import annotations

import socket
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from pymavlink.dialects.v20 import common as mavlink2

from board.wiring import WORLD, Wire

__all__ = ["DEFAULT_ENDPOINTS", "HeartbeatKeepalive", "MavlinkUdpBridge", "UdpEndpoint",
           "heartbeat_frame", "udp_wires"]

#: datagrams read from one socket per poll at most (a flood waits in the socket buffer)
MAX_DATAGRAMS_PER_POLL = 256
#: wall seconds without a HEARTBEAT to a client before the last one is re-sent (PX4 sends 1 Hz;
#: QGC/MAVSDK give up after ~3-5 s, so this leaves room for a re-send before they do)
KEEPALIVE_AFTER_S = 1.5
#: wall seconds between re-sent HEARTBEATs (the MAVLink heartbeat rate, 1 Hz)
KEEPALIVE_EVERY_S = 1.0
#: virtual time without a HEARTBEAT after which the vehicle itself counts as silent: no re-sends
VEHICLE_SILENT_NS = 2_500_000_000


def heartbeat_frame(data: bytes) -> bytes | None:
    """The last whole HEARTBEAT frame (MAVLink v1 or v2) in a datagram, or None.

    A datagram may carry several frames (PX4's UDP link packs them). pymavlink's own parser
    reads them (checksums included, garbage skipped), a fresh one per datagram so that no
    state leaks between datagrams; a frame cut short at the end is not a frame.
    """
    parser = mavlink2.MAVLink(None)
    parser.robust_parsing = True                   # bad bytes are skipped, never raised
    found: bytes | None = None
    for msg in parser.parse_buffer(data) or ():
        if msg.get_msgId() == mavlink2.MAVLINK_MSG_ID_HEARTBEAT:
            found = bytes(msg.get_msgbuf())
    return found


class HeartbeatKeepalive:
    """When to re-send the vehicle's last HEARTBEAT to a client (see the module docstring).

    ``clock`` gives wall seconds (``time.monotonic``; a fake one in tests). Fed with every
    datagram the vehicle sends (``vehicle_sent``) and asked at each poll (``due``).
    """

    def __init__(self, clock: Callable[[], float] = time.monotonic,
                 after_s: float = KEEPALIVE_AFTER_S, every_s: float = KEEPALIVE_EVERY_S,
                 vehicle_silent_ns: int = VEHICLE_SILENT_NS) -> None:
        self.clock = clock
        self.after_s = after_s
        self.every_s = every_s
        self.vehicle_silent_ns = vehicle_silent_ns
        self.frame: bytes | None = None
        self.resent = 0
        self._hb_t_ns = 0
        self._next_due_s = 0.0

    def vehicle_sent(self, data: bytes, t_ns: int) -> None:
        """A datagram from the vehicle at virtual time ``t_ns`` went to the client."""
        frame = heartbeat_frame(data)
        if frame is not None:
            self.frame = frame
            self._hb_t_ns = t_ns
            self._next_due_s = self.clock() + self.after_s

    def due(self, t_ns: int) -> bytes | None:
        """The HEARTBEAT to re-send now, or None."""
        if self.frame is None or t_ns - self._hb_t_ns > self.vehicle_silent_ns:
            return None  # never heard, or the vehicle is silent in its own time: a real loss
        now = self.clock()
        if now < self._next_due_s:
            return None
        self._next_due_s = now + self.every_s
        self.resent += 1
        return self.frame


def udp_wires(host_port: str, board: str = "fmu") -> list[Wire]:
    """The two wires between a host device's port and the board's UDP network ports."""
    return [Wire((WORLD, host_port), (board, "udp_in"), "datagrams to the FMU's network"),
            Wire((board, "udp_out"), (WORLD, host_port), "datagrams from the FMU's network")]


@dataclass
class UdpEndpoint:
    """One host socket joined to one FMU UDP port."""

    fmu_port: int
    bind_port: int
    remote_port: int
    host: str = "127.0.0.1"
    sock: socket.socket | None = field(default=None, repr=False)
    client: tuple[str, int] | None = None
    rx_datagrams: int = 0
    tx_datagrams: int = 0
    keepalive: HeartbeatKeepalive = field(default_factory=HeartbeatKeepalive, repr=False)


DEFAULT_ENDPOINTS = ((18570, 18570, 14550), (14580, 14580, 14540))


class MavlinkUdpBridge:
    """Host device: real UDP sockets <-> the FMU's UDP port records."""

    def __init__(self, port: str = "mavlink_udp",
                 endpoints: tuple[tuple[int, int, int], ...] | list[UdpEndpoint] =
                 DEFAULT_ENDPOINTS, host: str = "127.0.0.1", poll_every: int = 1,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.port = port
        self.ports = (port,)
        self.poll_every = max(1, poll_every)
        self._calls = 0
        self._t_ns = 0
        self._out: list = []
        self.endpoints: dict[int, UdpEndpoint] = {}
        for e in endpoints:
            ep = e if isinstance(e, UdpEndpoint) else UdpEndpoint(*e, host=host)
            ep.keepalive.clock = clock
            if ep.fmu_port in self.endpoints:
                raise ValueError(f"FMU UDP port {ep.fmu_port} bridged twice")
            s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
            try:
                s.bind((ep.host, ep.bind_port))
            except OSError as exc:
                s.close()
                self.close()
                raise OSError(f"cannot bind UDP {ep.host}:{ep.bind_port} for FMU port "
                              f"{ep.fmu_port}: {exc}") from None
            s.setblocking(False)
            ep.sock = s
            ep.bind_port = s.getsockname()[1]  # 0 asks the OS for a free port (tests)
            self.endpoints[ep.fmu_port] = ep

    # -- host device interface ----------------------------------------------------------------

    def run_until(self, t_ns: int) -> None:
        self._t_ns = t_ns
        self._calls += 1
        if self._calls % self.poll_every == 0:
            self.poll()
            self._keep_alive()

    def _keep_alive(self) -> None:
        """Re-send the vehicle's last HEARTBEAT to clients the emulator keeps waiting."""
        for ep in self.endpoints.values():
            frame = ep.keepalive.due(self._t_ns)
            if frame is not None and ep.sock is not None:
                self._send(ep, frame)

    def poll(self) -> None:
        """Read what host programs sent (non-blocking) and queue it for the FMU."""
        for ep in self.endpoints.values():
            if ep.sock is None:
                continue
            for _ in range(MAX_DATAGRAMS_PER_POLL):
                try:
                    data, addr = ep.sock.recvfrom(65536)
                except (BlockingIOError, InterruptedError):
                    break
                except OSError:
                    break  # ICMP port unreachable from an earlier send: nobody listening
                ep.client = addr
                ep.rx_datagrams += 1
                self._out.append((self.port, self._t_ns, (ep.fmu_port, addr[1], data)))

    def outputs(self, until_ns: int) -> list:
        out, self._out = self._out, []
        return out

    def input(self, port: str, t_ns: int, payload: Any) -> None:
        fmu_port, remote_port, data = payload
        ep = self.endpoints.get(fmu_port)
        if ep is None or ep.sock is None:
            return  # a datagram for a port this bridge does not carry (another device's)
        ep.keepalive.vehicle_sent(data, t_ns)
        self._send(ep, data)

    @staticmethod
    def _send(ep: UdpEndpoint, data: bytes) -> None:
        # The host side decides where its programs listen (the defaults match rcS's -o ports);
        # once a client has talked, replies go to it, as PX4's UDP link does.
        if ep.sock is None:
            return
        dest = ep.client or (ep.host, ep.remote_port)
        try:
            ep.sock.sendto(data, dest)
            ep.tx_datagrams += 1
        except OSError:
            pass  # nobody listening yet: UDP drops it, as the real network would

    def close(self) -> None:
        for ep in self.endpoints.values():
            if ep.sock is not None:
                ep.sock.close()
                ep.sock = None

    def describe(self) -> list[str]:
        return [f"UDP {ep.host}:{ep.bind_port} <-> FMU port {ep.fmu_port} "
                f"(sending to {ep.client or (ep.host, ep.remote_port)})"
                for ep in self.endpoints.values()]
