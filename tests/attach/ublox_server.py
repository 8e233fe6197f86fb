"""A u-blox receiver behind a TCP port, as ser2net or a u-center "server" would put a real one:
the project's own u-blox M8 model (peripherals/ublox) on a kernel of its own, run in wall time
by a thread, its UART bytes to and from the one client. Test equipment, not part of the
emulator (the thread and the wall clock are the point: it stands for hardware outside)."""

from __future__ import annotations

import select
import socket
import threading
import time

from board.kernel import Kernel
from peripherals.errors import rng_for
from peripherals.physics import Environment
from peripherals.ublox.receiver import UbloxM8

HOME = (47.397742, 8.545594, 488.0)


class _ToSocket:
    def __init__(self, server: UbloxServer) -> None:
        self.server = server

    def transmit(self, t_start_ns: int, config: object, data: object) -> None:
        if isinstance(data, (bytes, bytearray)):
            self.server.send(bytes(data))


class UbloxServer:
    def __init__(self, garbage: bytes = b"", ttff_s: float = 0.2) -> None:
        self.kernel = Kernel("ublox_server")
        env = Environment()
        env.set_truth(0, (0.0, 0.0, -9.81), (0.0, 0.0, 0.0), (0.21, 0.0, 0.43), 95_000.0, 20.0,
                      HOME[0], HOME[1], HOME[2], (0.0, 0.0, 0.0))
        self.gps = UbloxM8(self.kernel, env, rng_for(1, "ublox_server"), name="gps",
                           baud=38_400, ttff_s=ttff_s)
        self.gps.uart.attach(_ToSocket(self))
        self.garbage = garbage
        self.srv = socket.socket()
        self.srv.bind(("127.0.0.1", 0))
        self.srv.listen(1)
        self.port = self.srv.getsockname()[1]
        self.conn: socket.socket | None = None
        self.bytes_from_client = 0
        self._lock = threading.Lock()
        self._stop = False
        self._thread = threading.Thread(target=self._loop, daemon=True, name="ublox-server")
        self._thread.start()

    @property
    def url(self) -> str:
        return f"socket://127.0.0.1:{self.port}"

    def send(self, data: bytes) -> None:
        conn = self.conn
        if conn is not None:
            try:
                conn.sendall(data)
            except OSError:
                pass

    def _loop(self) -> None:
        start = time.monotonic()
        k = self.kernel
        while not self._stop:
            socks = [self.srv] + ([self.conn] if self.conn is not None else [])
            try:
                ready, _, _ = select.select(socks, [], [], 0.005)
            except (OSError, ValueError):
                ready = []
            k.run(int((time.monotonic() - start) * 1e9))
            for s in ready:
                if s is self.srv:
                    conn, _ = self.srv.accept()
                    self.conn = conn
                    continue
                try:
                    data = s.recv(4096)
                except OSError:
                    data = b""
                if not data:
                    self.conn = None
                    continue
                if not self.bytes_from_client and self.garbage:
                    # noise on the line once the driver talks (and listens)
                    s.sendall(self.garbage)
                self.bytes_from_client += len(data)
                self.gps.uart.receive(k.now_ns, self.gps.uart.config, data)

    def inject(self, data: bytes) -> None:
        """Noise on the line now (between the receiver's messages, or inside one)."""
        self.send(data)

    def drop_client(self) -> None:
        """The device disappears: its end of the connection closes."""
        conn, self.conn = self.conn, None
        if conn is not None:
            conn.close()

    def close(self) -> None:
        self._stop = True
        self._thread.join(5)
        self.drop_client()
        self.srv.close()
