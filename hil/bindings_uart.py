"""``hil fly --uart NAME=<pyserial URL or device>``: an emulated UART joined to a real one.

``NAME`` is the connector: ``gps`` (the FMU's GPS port, UART4: the emulated u-blox is unplugged
and the device takes its place), ``telem1``/``telem2`` (instead of their host pty),
``rc`` (the IO's S.BUS input, 100000 8E2 inverted) or ``dsm`` (the IO's Spektrum input, 115200
8N1); the last two are inputs only. The other end is anything pyserial opens
(``serial.serial_for_url``): a device (``/dev/ttyUSB0``, a pty), ``socket://host:port``,
``rfc2217://host:port``, ``hil://...``.

The emulated wire carries line settings, a real port has its own: bytes the board transmits
are written to the port, and when the firmware changes the UART's settings (the GPS driver's
baud scan) the port is set to them (``Serial.baudrate`` ...; a socket ignores them). Bytes from
the port enter the board at the virtual time of the poll (between quanta, every
``poll_every``: 2 quanta, 1 ms, in ``hil fly``) with the UART's present settings, at most as
many per poll as the line carries at that baud in that time (a real device cannot send
faster); the rest wait, up to ``HOST_BUFFER_BYTES``, beyond which they are counted
(``dropped``) and dropped. What the bytes mean is the firmware's business: garbage is what its
parsers count and skip, as on a real port.

A port that fails (device unplugged, socket closed by the peer, pty closed) is reported once
and closed; the emulated UART stays, with nothing on the line, and the emulator keeps running.
Meant for paced runs (a real device runs in wall time); tests drive it unpaced as well.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Any, Callable

from board.wiring import WORLD, Wire
from hil.binding_life import DeviceBinding

__all__ = ["CONNECTORS", "HOST_BUFFER_BYTES", "UartBinding", "add_uart_bindings"]

#: Bytes from the device waiting for the line; more are dropped (and counted).
HOST_BUFFER_BYTES = 65_536


@dataclass(frozen=True)
class Connector:
    board: str
    port: str
    config: tuple[int, int, str, int, int]  # settings at reset: baud, bits, parity, stop, invert
    output: bool = True                      # the board transmits on it


CONNECTORS: dict[str, Connector] = {
    "gps": Connector("fmu", "gps", (9_600, 8, "N", 1, 0)),
    "telem1": Connector("fmu", "telem1", (57_600, 8, "N", 1, 0)),
    "telem2": Connector("fmu", "telem2", (57_600, 8, "N", 1, 0)),
    "rc": Connector("io", "sbus_in", (100_000, 8, "E", 2, 1), output=False),
    "dsm": Connector("io", "dsm_in", (115_200, 8, "N", 1, 0), output=False),
}


class UartBinding(DeviceBinding):
    """A host device owning ``port`` (the world's end of the wire to the board's UART)."""

    def __init__(self, name: str, url: str, port: str, config: tuple, quantum_ns: int,
                 poll_every: int = 10, serial_port: Any = None,
                 log: Callable[[str], None] | None = None) -> None:
        self.name = name
        self.url = url
        self.port = port
        self.ports = (port,)
        self.config = tuple(config)
        self.poll_every = max(1, poll_every)
        self.poll_ns = self.poll_every * quantum_ns
        self.log = log or (lambda text: print(text, file=sys.stderr, flush=True))
        self._calls = 0
        self._t_ns = 0
        self._out: list = []
        self._pending = bytearray()
        self.closed = False
        self.error: str | None = None
        self.bytes_in = 0     # from the device into the board
        self.bytes_out = 0    # from the board to the device
        self.dropped = 0
        self.baud_changes = 0
        if serial_port is None:
            import serial

            try:
                baud, bits, parity, stop, _inv = self.config
                serial_port = serial.serial_for_url(url, baudrate=baud, bytesize=bits,
                                                    parity=parity, stopbits=stop, timeout=0,
                                                    write_timeout=0)
            except (serial.SerialException, ValueError, OSError) as exc:
                raise ValueError(f"--uart {name}={url}: cannot open: {exc}") from None
        self.serial = serial_port

    # -- host device interface ------------------------------------------------------------------

    def run_until(self, t_ns: int) -> None:
        self._t_ns = t_ns
        self._calls += 1
        if self._calls % self.poll_every or self.closed:
            return
        import serial

        try:
            # timeout=0: a non-blocking read, which also notices a device that went away
            # (in_waiting does not: a pty whose other end closed reports 0 bytes forever)
            data = self.serial.read(4096)
            if data:
                room = HOST_BUFFER_BYTES - len(self._pending)
                if len(data) > room:
                    self.dropped += len(data) - room
                    data = data[:room]
                self._pending += data
        except (serial.SerialException, OSError) as exc:
            self._fail(exc)
        if self._pending:
            baud, bits, parity, stop, _inv = self.config
            frame_bits = 1 + bits + (parity != "N") + stop
            # 9/10 of the line: consecutive bursts never overlap on the emulated wire
            limit = max(1, baud * self.poll_ns * 9 // (10 * frame_bits * 1_000_000_000))
            chunk = bytes(self._pending[:limit])
            del self._pending[:limit]
            self.bytes_in += len(chunk)
            self._out.append((self.port, t_ns, (*self.config, chunk)))

    def outputs(self, until_ns: int) -> list:
        out, self._out = self._out, []
        return out

    def input(self, port: str, t_ns: int, payload: Any) -> None:
        if self.closed:
            return
        import serial

        cfg = tuple(payload[:5])
        try:
            if cfg != self.config:
                if cfg[0] != self.config[0]:
                    self.baud_changes += 1
                self.config = cfg
                # the firmware changed the UART: so does the port
                self.serial.baudrate, self.serial.bytesize = cfg[0], cfg[1]
                self.serial.parity, self.serial.stopbits = cfg[2], cfg[3]
            data = payload[5]
            if data:
                self.serial.write(data)
                self.bytes_out += len(data)
        except serial.SerialTimeoutException:
            self.dropped += len(payload[5] or b"")  # the device does not take it: drop
        except (serial.SerialException, OSError, ValueError) as exc:
            self._fail(exc)

    def describe(self) -> str:
        return f"UART binding {self.name}={self.url}"

    def stats(self) -> dict[str, Any]:
        return {"url": self.url, "closed": self.closed, "error": self.error,
                "bytes_in": self.bytes_in, "bytes_out": self.bytes_out, "dropped": self.dropped,
                "baud": self.config[0], "baud_changes": self.baud_changes}

    def _close_device(self) -> None:
        self.serial.close()


def add_uart_bindings(cfg: Any, hub: Any, devices: dict[str, Any], wiring: list[Wire],
                      boards: dict[str, Any]) -> list[Wire]:
    """Bindings for ``cfg.uart_bind`` (SystemConfig): the devices in ``hub`` and
    ``devices["uart_bindings"]``, the FMU's GPS module unplugged if ``gps`` is bound, the wires
    of what they replace removed; returns the new wiring."""
    bindings: dict[str, UartBinding] = devices.setdefault("uart_bindings", {})
    for name, url in cfg.uart_bind.items():
        conn = CONNECTORS.get(name)
        if conn is None:
            raise ValueError(f"--uart: no connector {name!r} (one of {', '.join(CONNECTORS)})")
        if name == "gps":
            kw = boards["fmu"].kwargs
            kw["exclude"] = tuple(dict.fromkeys((*kw.get("exclude", ()), "ublox_m8")))
            kw["host_ports"] = tuple(dict.fromkeys((*kw.get("host_ports", ()), "gps")))
        wport = f"uart_{name}"
        # polled every 2 quanta (1 ms): bytes split across polls keep gaps far below a
        # protocol's frame gap (S.BUS: 3 ms), at a syscall per poll
        binding = UartBinding(name, url, wport, conn.config, cfg.quantum_ns, poll_every=2)
        hub.add(binding)
        bindings[name] = binding
        target = (conn.board, conn.port)
        wiring = [w for w in wiring if w.dst != target and w.src != target]
        wiring.append(Wire((WORLD, wport), target, f"{url} -> {name}"))
        if conn.output:
            wiring.append(Wire(target, (WORLD, wport), f"{name} -> {url}"))
    return wiring
