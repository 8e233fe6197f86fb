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
"""

from __future__ import annotations

import socket
from dataclasses import dataclass, field
from typing import Any

from board.wiring import WORLD, Wire

__all__ = ["DEFAULT_ENDPOINTS", "MavlinkUdpBridge", "UdpEndpoint", "udp_wires"]

#: datagrams read from one socket per poll at most (a flood waits in the socket buffer)
MAX_DATAGRAMS_PER_POLL = 256


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


DEFAULT_ENDPOINTS = ((18570, 18570, 14550), (14580, 14580, 14540))


class MavlinkUdpBridge:
    """Host device: real UDP sockets <-> the FMU's UDP port records."""

    def __init__(self, port: str = "mavlink_udp",
                 endpoints: tuple[tuple[int, int, int], ...] | list[UdpEndpoint] =
                 DEFAULT_ENDPOINTS, host: str = "127.0.0.1", poll_every: int = 1) -> None:
        self.port = port
        self.ports = (port,)
        self.poll_every = max(1, poll_every)
        self._calls = 0
        self._t_ns = 0
        self._out: list = []
        self.endpoints: dict[int, UdpEndpoint] = {}
        for e in endpoints:
            ep = e if isinstance(e, UdpEndpoint) else UdpEndpoint(*e, host=host)
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
        # The host side decides where its programs listen (the defaults match rcS's -o ports);
        # once a client has talked, replies go to it, as PX4's UDP link does.
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
