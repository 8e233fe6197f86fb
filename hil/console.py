"""Serial bridges between an emulated UART and the host: a pseudo-terminal and a TCP port.

:class:`SerialBridge` is a host device (see :mod:`hil.devices`) owning one port wired to a
board's UART. Bytes the board transmits are written to a host pseudo-terminal (open it with
``screen /dev/pts/N`` or pyserial) and to every client of a TCP server on 127.0.0.1; bytes typed
there are sent to the board's UART at the current virtual time, as a terminal on the real
connector would. With it the FMU's nsh console (UART7, 57600 baud) is reachable from
``hil shell``, ``screen`` or a script.

Host input is polled between quanta (every ``poll_every`` quanta), so what a person types enters
virtual time at the next poll: interactive use is not deterministic, by nature.
"""

from __future__ import annotations

import errno
import os
import selectors
import socket
import tty
from typing import Any

__all__ = ["SerialBridge"]


class SerialBridge:
    """One emulated UART bridged to a host pty and/or a TCP server on 127.0.0.1."""

    def __init__(self, port: str = "console", baud: int = 57_600, pty: bool = True,
                 tcp_port: int | None = 0, poll_every: int = 10,
                 config: tuple = (8, "N", 1, 0)) -> None:
        self.port = port
        self.ports = (port,)
        self.baud = baud
        self._cfg = (baud, *config)
        self.poll_every = max(1, poll_every)
        self._calls = 0
        self._out: list = []
        self._t_ns = 0
        self.rx_bytes = 0
        self.tx_bytes = 0
        self.transcript = bytearray()  # what the board sent (tests, logs)
        self._sel = selectors.DefaultSelector()
        self.pty_name: str | None = None
        self._master: int | None = None
        self._slave: int | None = None
        if pty:
            self._master, self._slave = os.openpty()
            # Raw: no echo, no line editing; otherwise the line discipline would echo the
            # board's own output back to it as typed input.
            tty.setraw(self._slave)
            os.set_blocking(self._master, False)
            self.pty_name = os.ttyname(self._slave)
            self._sel.register(self._master, selectors.EVENT_READ, "pty")
        self._server: socket.socket | None = None
        self._clients: list[socket.socket] = []
        self.tcp_port: int | None = None
        if tcp_port is not None:
            srv = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
            srv.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            srv.bind(("127.0.0.1", tcp_port))
            srv.listen(4)
            srv.setblocking(False)
            self._server = srv
            self.tcp_port = srv.getsockname()[1]
            self._sel.register(srv, selectors.EVENT_READ, "accept")

    # -- host device interface ----------------------------------------------------------------

    def run_until(self, t_ns: int) -> None:
        self._t_ns = t_ns
        self._calls += 1
        if self._calls % self.poll_every == 0:
            self.poll()

    def poll(self) -> None:
        """Read whatever the host side typed (non-blocking) and queue it for the board."""
        for key, _ in self._sel.select(timeout=0):
            tag = key.data
            if tag == "accept":
                try:
                    conn, _addr = self._server.accept()  # type: ignore[union-attr]
                except BlockingIOError:
                    continue
                conn.setblocking(False)
                self._clients.append(conn)
                self._sel.register(conn, selectors.EVENT_READ, "client")
            elif tag == "pty":
                try:
                    data = os.read(self._master, 4096)  # type: ignore[arg-type]
                except OSError as exc:
                    if exc.errno in (errno.EAGAIN, errno.EIO):
                        continue
                    raise
                self.feed(data)
            else:
                conn = key.fileobj
                try:
                    data = conn.recv(4096)  # type: ignore[union-attr]
                except (BlockingIOError, InterruptedError):
                    continue
                except OSError:
                    data = b""
                if not data:
                    self._drop(conn)  # type: ignore[arg-type]
                else:
                    self.feed(data)

    def feed(self, data: bytes) -> None:
        """Send ``data`` to the board's UART now (as if typed on the terminal)."""
        if data:
            self.rx_bytes += len(data)
            self._out.append((self.port, self._t_ns, (*self._cfg, bytes(data))))

    def outputs(self, until_ns: int) -> list:
        out, self._out = self._out, []
        return out

    def input(self, port: str, t_ns: int, payload: Any) -> None:
        data = payload[5]
        if not data:
            return  # a line break: nothing to show
        self.tx_bytes += len(data)
        self.transcript += data
        if len(self.transcript) > 1 << 20:
            del self.transcript[: len(self.transcript) - (1 << 19)]
        if self._master is not None:
            try:
                os.write(self._master, data)
            except OSError:
                pass  # nobody reading the pty: its buffer is full; drop, as a terminal would
        for conn in list(self._clients):
            try:
                conn.sendall(data)
            except OSError:
                self._drop(conn)

    def _drop(self, conn: socket.socket) -> None:
        try:
            self._sel.unregister(conn)
        except (KeyError, ValueError):
            pass
        conn.close()
        if conn in self._clients:
            self._clients.remove(conn)

    def close(self) -> None:
        for conn in list(self._clients):
            self._drop(conn)
        if self._server is not None:
            self._sel.unregister(self._server)
            self._server.close()
            self._server = None
        for fd in (self._master, self._slave):
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass
        self._master = self._slave = None
        self._sel.close()
