"""u-blox M8 GNSS receiver on a UART: UBX/NMEA protocol engine over the solution model.

The receiver is only reachable through its :class:`~board.uart.Uart` (its UART1, wired to the
FMU's UART4): it powers up at its saved baud rate (factory 9600 8N1) talking NMEA, accepts UBX
commands, acknowledges every CFG message, and after each navigation epoch writes the messages
whose CFG-MSG rate says so. Bytes go out at the port's baud rate; the transmit buffer is finite
like the chip's (4 kB), so a port configured too slow for its messages drops output instead of
falling ever further behind, as the real receiver does.

A baud change arriving on the port it changes is acknowledged at the old rate and applied when
that acknowledgement has left the transmitter; output produced in between is held and sent at
the new rate.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from typing import Final

import numpy as np

from board.kernel import PRIO_HW, Kernel
from board.uart import Uart, UartConfig
from peripherals.faults import FaultState
from peripherals.physics import Environment
from peripherals.ublox import messages as m
from peripherals.ublox.config import (
    NMEA_IDS,
    OUTPUT_MESSAGES,
    PORT_UART1,
    PROTO_NMEA,
    PROTO_UBX,
    ConfigStore,
)
from peripherals.ublox.frame import UbxReader, ubx_frame
from peripherals.ublox.solution import (
    GnssErrorParams,
    GnssFaults,
    START_UTC_NS,
    Solution,
    SolutionModel,
)

__all__ = ["UbloxM8"]

NS_PER_MS: Final = 1_000_000
CLS_NAV: Final = 0x01
CLS_ACK: Final = 0x05
CLS_CFG: Final = 0x06
CLS_MON: Final = 0x0A
ACK_NAK: Final = 0x00
ACK_ACK: Final = 0x01
CFG_RST: Final = 0x04


class UbloxM8:
    """A u-blox M8 (NEO-M8N-like) receiver: ``UbloxM8(kernel, env, rng, name, uart)``.

    Fault knobs: ``faults`` (the common :class:`FaultState`: ``absent`` silences the receiver
    completely, ``random_data`` replaces its output with noise) and ``gnss_faults``
    (:class:`GnssFaults`: ``no_fix``, ``degraded``, ``jump_m``, ``jamming``), plus the helper
    methods below that set them.
    """

    def __init__(self, kernel: Kernel, env: Environment, rng: np.random.Generator,
                 name: str = "gps", uart: Uart | None = None, *, baud: int = 9600,
                 ttff_s: float | None = None, params: GnssErrorParams | None = None,
                 tx_buffer_bytes: int = 4096, utc_start_ns: int = START_UTC_NS) -> None:
        self.kernel = kernel
        self.env = env
        self.name = name
        self.rng = rng
        params = params or GnssErrorParams()
        if ttff_s is not None:
            params.ttff_s = ttff_s
        self.uart = uart if uart is not None else Uart(kernel, name, UartConfig(baud))
        self.uart.config = UartConfig(baud)
        self.config = ConfigStore(baud)
        self.model = SolutionModel(env, rng, params, utc_start_ns)
        self.faults = FaultState()
        self.tx_buffer_bytes = tx_buffer_bytes
        self.reader = UbxReader()
        # Counters a test (or MON-TXBUF, if it were modelled) can look at.
        self.acks = 0
        self.naks = 0
        self.tx_dropped = 0
        self.epochs = 0
        #: (t_ns, text) of what the receiver did with odd input (NAKs, ignored frames).
        self.log: list[tuple[int, str]] = []
        self.last_solution = Solution()
        self._gnss_stopped = False
        self._epoch_event: list | None = None
        self._switch_event: list | None = None
        self._held: list[bytes] = []
        self._power_on_ns = kernel.now_ns
        self.uart.on_rx(self._on_rx)
        self._schedule_epoch()

    # -- fault knobs ----------------------------------------------------------------------------

    @property
    def gnss_faults(self) -> GnssFaults:
        return self.model.faults

    def set_absent(self, absent: bool = True) -> None:
        """Receiver unplugged / dead: no output, no reaction to input."""
        self.faults.absent = absent

    def lose_fix(self, lost: bool = True) -> None:
        self.model.faults.no_fix = lost

    def degrade(self, factor: float) -> None:
        """Accuracy worse by ``factor`` (error and the reported hAcc/vAcc/sAcc grow alike)."""
        self.model.faults.degraded = factor

    def jump(self, north_m: float, east_m: float = 0.0, down_m: float = 0.0) -> None:
        """Offset the reported position (a multipath or spoofing jump); (0, 0, 0) to undo."""
        self.model.faults.jump_m = (north_m, east_m, down_m)

    def jam(self, level: int) -> None:
        """Jamming indicator 0..255: noise rises, C/N0 and satellites drop, fix lost > 230."""
        self.model.faults.jamming = level

    # -- input ---------------------------------------------------------------------------------

    def _on_rx(self, t_ns: int, byte: int, flags: int) -> None:
        """RX interrupt of the receiver's UART1: one byte (garbage at a wrong baud, too)."""
        if self.faults.absent:
            return
        for cls, msg_id, payload in self.reader.feed(bytes((byte & 0xFF,))):
            if not self.config.current.ports[PORT_UART1].in_mask & PROTO_UBX:
                continue
            self._handle(cls, msg_id, payload)

    def _handle(self, cls: int, msg_id: int, payload: bytes) -> None:
        if cls == CLS_CFG:
            self._handle_cfg(msg_id, payload)
        elif cls == CLS_MON and not payload and msg_id == 0x04:
            self._send_ubx(CLS_MON, 0x04, m.mon_ver())
        elif cls == CLS_MON and not payload and msg_id == 0x09:
            self._send_ubx(CLS_MON, 0x09, m.mon_hw(self.last_solution))
        elif cls == CLS_NAV and not payload and (cls, msg_id) in self._builders():
            self._send_ubx(cls, msg_id, self._builders()[(cls, msg_id)](self.last_solution))
        else:
            self.log.append((self.kernel.now_ns, (f"ignored {cls:02X}-{msg_id:02X} "
                                                 f"len {len(payload)}")))

    def _handle_cfg(self, msg_id: int, payload: bytes) -> None:
        if msg_id == CFG_RST:
            if len(payload) == 4:
                self._reset(payload)
            return
        cur = self.config.current
        old = (cur.ports[PORT_UART1].baud, cur.meas_rate_ms, cur.nav_rate)
        res = self.config.handle(msg_id, payload, PORT_UART1)
        if res.reply is not None:
            self._send_ubx(CLS_CFG, msg_id, res.reply)
        if res.ack:
            self.acks += 1
            self._send_ubx(CLS_ACK, ACK_ACK, bytes((CLS_CFG, msg_id)))
        else:
            self.naks += 1
            self.log.append((self.kernel.now_ns, f"NAK CFG {msg_id:02X} len {len(payload)}"))
            self._send_ubx(CLS_ACK, ACK_NAK, bytes((CLS_CFG, msg_id)))
        self._apply(old)

    def _apply(self, old: tuple[int, int, int]) -> None:
        """Make a configuration change take effect (baud after the ACK, new epoch timing)."""
        cur = self.config.current
        baud = cur.ports[PORT_UART1].baud
        if baud != old[0]:
            Kernel.cancel(self._switch_event)
            t = max(self.uart.tx_idle_ns, self.kernel.now_ns)
            self._switch_event = self.kernel.call_at(t, self._switch_baud, baud,
                                                     priority=PRIO_HW)
        if (cur.meas_rate_ms, cur.nav_rate) != old[1:]:
            self._schedule_epoch()

    def _switch_baud(self, baud: int) -> None:
        self._switch_event = None
        self.uart.config = UartConfig(baud)
        held, self._held = self._held, []
        for data in held:
            self._write(data)

    def _reset(self, payload: bytes) -> None:
        """CFG-RST: no acknowledgement; hardware/software resets reload the saved config."""
        nav_bbr, mode = struct.unpack("<HB", payload[:3])
        if mode == 0x08:
            self._gnss_stopped = True
            return
        if mode == 0x09:
            self._gnss_stopped = False
            return
        now = self.kernel.now_ns
        self.model.restart(now, cold=nav_bbr == 0xFFFF)
        if mode in (0x00, 0x01, 0x04):
            Kernel.cancel(self._switch_event)
            self._switch_event = None
            self._held.clear()
            self.config.reload()
            self.uart.config = UartConfig(self.config.current.ports[PORT_UART1].baud)
            self.reader.reset()
            self._power_on_ns = now
        self._gnss_stopped = False
        self._schedule_epoch()

    # -- output --------------------------------------------------------------------------------

    def _builders(self) -> dict[tuple[int, int], Callable[[Solution], bytes]]:
        msss = (self.kernel.now_ns - self._power_on_ns) // NS_PER_MS
        return {(0x01, 0x03): lambda s: m.nav_status(s, msss), (0x01, 0x04): m.nav_dop,
                (0x01, 0x07): m.nav_pvt, (0x01, 0x30): m.nav_svinfo, (0x01, 0x35): m.nav_sat,
                (0x0A, 0x09): m.mon_hw}

    def _schedule_epoch(self) -> None:
        """Next epoch on a whole multiple of the solution period since power-on, as the
        receiver aligns its measurements to its time base."""
        Kernel.cancel(self._epoch_event)
        cur = self.config.current
        period = cur.meas_rate_ms * cur.nav_rate * NS_PER_MS
        now = self.kernel.now_ns
        t = self._power_on_ns + ((now - self._power_on_ns) // period + 1) * period
        self._epoch_event = self.kernel.call_at(t, self._epoch, priority=PRIO_HW)

    def _epoch(self) -> None:
        self._epoch_event = None
        self._schedule_epoch()
        if self._gnss_stopped:
            return
        self.epochs += 1
        sol = self.model.step(self.kernel.now_ns)
        self.last_solution = sol
        if self.faults.absent:
            return
        if self.faults.random_data:
            self._write(self.rng.integers(0, 256, 100, dtype=np.uint8).tobytes())
            return
        cur = self.config.current
        out = cur.ports[PORT_UART1].out_mask
        builders = self._builders()
        for key in OUTPUT_MESSAGES:
            rate = cur.rate(key, PORT_UART1)
            if not rate or self.epochs % rate:
                continue
            if key[0] == 0xF0:
                if out & PROTO_NMEA and key[1] in NMEA_IDS:
                    for sentence in m.nmea_messages(sol, key[1]):
                        self._write(sentence)
            elif out & PROTO_UBX:
                self._write(ubx_frame(key[0], key[1], builders[key](sol)))

    def _send_ubx(self, cls: int, msg_id: int, payload: bytes) -> None:
        if self.config.current.ports[PORT_UART1].out_mask & PROTO_UBX:
            self._write(ubx_frame(cls, msg_id, payload))

    def _write(self, data: bytes) -> None:
        """Queue a message in the transmit buffer, or drop it if it does not fit."""
        if self.faults.absent:
            return
        if self._switch_event is not None:
            self._held.append(data)
            return
        if self.uart.tx_pending + len(data) > self.tx_buffer_bytes:
            self.tx_dropped += 1
            return
        self.uart.write(data)

    def __repr__(self) -> str:
        return f"<UbloxM8 {self.name} {self.uart.config}>"
