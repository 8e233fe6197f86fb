"""A test-side PX4IO: a UART wired to the driver's, answering with the real register pages.

Requests are framed by the IDLE interrupt as on the IO (§1.6) and answered by
:func:`ioproc.protocol.handle_request` over an :class:`ioproc.pages.IoPages`. Knobs make
the link misbehave in the ways the driver must survive: corrupt the CRC of the next replies,
drop them, delay them, answer ERROR for a page, reboot (fresh registers), or stay silent.

The IO main loop is not modelled; the few things it would do that the driver can see are
done on each request: FMU_INITIALIZED follows FMU_OK, MIXER_OK after a good upload.

Also here: the rigs the driver tests share (:func:`make_rig` with this fake,
:func:`io_board_rig` with the real IoV2Board, :func:`fmu_board_with_px4io` for the
orchestrator).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from typing import Any

from board.kernel import NS_PER_MS, NS_PER_US, Kernel
from board.uart import Uart, UartConfig, UartWire
from firmware.drivers.px4io import Px4ioModule
from firmware.modules.system_params import PARAMS as SYSTEM_PARAMS
from firmware.platform import Platform
from firmware.platform.params import ParamDef, Params
from firmware.system import System
from ioproc.pages import IoPages
from ioproc.protocol import (
    LAYOUT,
    PageNo,
    RawRc,
    RawRcFlags,
    StatusFlags,
    handle_request,
)

#: [model] time between the end of a request and the start of the reply: the IO's interrupt
#: handler (CRC, register access, DMA restart) on a 24 MHz Cortex-M3.
DEFAULT_TURNAROUND_US = 20


@dataclass
class Request:
    t_us: int
    data: bytes

    @property
    def code(self) -> int:
        return self.data[0] & 0xC0

    @property
    def page(self) -> int:
        return self.data[2]

    @property
    def offset(self) -> int:
        return self.data[3]

    @property
    def regs(self) -> tuple[int, ...]:
        pkt, _ = LAYOUT.unpack(self.data)
        return pkt.regs


class FakeIo:
    """The IO end of the FMU-IO cable for driver tests."""

    def __init__(self, kernel: Kernel, fmu_uart: Uart, protocol_version: int | None = None,
                 turnaround_us: int = DEFAULT_TURNAROUND_US) -> None:
        self.kernel = kernel
        self.uart = Uart(kernel, "io.USART2", UartConfig(baud=1_500_000), rx_buffer_size=68)
        self.wire = UartWire(fmu_uart, self.uart)
        self.uart.on_idle(self._on_idle)
        self.turnaround_us = turnaround_us
        self.protocol_version = protocol_version
        self.requests: list[Request] = []
        self.replies = 0
        # knobs
        self.corrupt_next = 0  #: flip the CRC of this many replies
        self.drop_next = 0  #: swallow this many requests without reply
        self.delay_next_us: list[int] = []  #: extra delays for the next replies, in order
        self.error_pages: set[int] = set()  #: pages answered with ERROR
        self.silent = False  #: no replies at all (IO dead or unplugged)
        self.reboots = 0
        self.regs = self._fresh()

    def _fresh(self) -> IoPages:
        regs = IoPages()
        if self.protocol_version is not None:
            regs.values[PageNo.CONFIG][0] = self.protocol_version
        return regs

    # -- knobs ------------------------------------------------------------------------------

    def reboot(self) -> None:
        """A reset of the IO: every register back to its reset value (mixer gone, no sync)."""
        self.reboots += 1
        self.regs = self._fresh()

    def set_rc(self, values: list[int], flags: int = RawRcFlags.RC_OK, rssi: int = 255,
               source: int = StatusFlags.RC_SBUS) -> None:
        """What the IO's RC decoder would leave in RAW_RC_INPUT and STATUS_FLAGS."""
        page = self.regs.page(PageNo.RAW_RC_INPUT)
        page[RawRc.COUNT] = len(values)
        page[RawRc.FLAGS] = int(flags)
        page[RawRc.NRSSI] = rssi
        for i in range(18):
            page[RawRc.BASE + i] = values[i] if i < len(values) else 0
        sources = (StatusFlags.RC_PPM | StatusFlags.RC_DSM | StatusFlags.RC_SBUS
                   | StatusFlags.RC_ST24 | StatusFlags.RC_SUMD | StatusFlags.RC_OK)
        ok = StatusFlags.RC_OK if flags & RawRcFlags.RC_OK else 0
        self.regs.status_flags = (self.regs.status_flags & ~sources) | int(source) | ok

    # -- the IO's serial interrupt -----------------------------------------------------------

    def writes_to(self, page: int) -> list[Request]:
        return [r for r in self.requests if r.code == 0x40 and r.page == page]

    def reads_of(self, page: int, offset: int | None = None) -> list[Request]:
        return [r for r in self.requests if r.code == 0x00 and r.page == page
                and (offset is None or r.offset == offset)]

    def _on_idle(self, t_ns: int) -> None:
        data = self.uart.read()
        self.uart.take_errors()
        if not data:
            return
        now_us = t_ns // NS_PER_US
        self.requests.append(Request(now_us, data))
        if self.silent:
            return
        if self.drop_next:
            self.drop_next -= 1
            return
        if len(data) >= 3 and data[2] in self.error_pages:
            reply = LAYOUT.pack(0x80, data[2], data[3] if len(data) > 3 else 0, ())
        else:
            reply = handle_request(data, self.regs, now_us)
        self._main_loop_effects()
        if reply is None:
            return
        if self.corrupt_next:
            self.corrupt_next -= 1
            reply = bytes((reply[0], reply[1] ^ 0x5A)) + reply[2:]
        delay = self.turnaround_us + (self.delay_next_us.pop(0) if self.delay_next_us else 0)
        self.kernel.call_at(t_ns + delay * NS_PER_US, self._send, reply)

    def _send(self, reply: bytes) -> None:
        self.replies += 1
        self.uart.write(reply)

    def _main_loop_effects(self) -> None:
        regs = self.regs
        if regs.status_flags & StatusFlags.FMU_OK:
            regs.status_flags |= StatusFlags.FMU_INITIALIZED


# -- rigs: the driver in a system, against the fake or the real IO board --------------------

MIXER = "quad_x.main.mix"
#: the commander owns this circuit breaker; declared here so the rig has it
CBRK_IO_SAFETY = ParamDef("CBRK_IO_SAFETY", "INT32", 0, min=0, max=22027)


@dataclass
class Rig:
    """One FMU (platform, system, px4io) and what its USART6 is wired to, on one kernel."""

    kernel: Kernel
    platform: Platform
    system: System
    uart: Uart
    io: FakeIo
    console: list[str] = field(default_factory=list)
    pubs: dict[str, Any] = field(default_factory=dict)

    def run_ms(self, ms: float) -> None:
        self.kernel.run(self.kernel.now_ns + int(ms * NS_PER_MS))

    def cmd(self, *args: str) -> int:
        return self.system.modules.command("px4io", list(args))

    @property
    def module(self) -> Px4ioModule:
        return self.system.modules.get("px4io")

    @property
    def driver(self):
        return self.module.driver

    def dmesg(self) -> str:
        return self.platform.dmesg_text()

    def perf(self, name: str) -> int:
        return self.platform.perf.find(f"px4io: {name}").events

    def topic(self, name: str):
        return self.platform.orb.node(name).last

    def publish(self, topic: str, **fields) -> None:
        orb = self.platform.orb
        pub = self.pubs.get(topic) or self.pubs.setdefault(topic, orb.advertise(topic))
        pub.publish(orb.new(topic, timestamp=self.platform.time_us(), **fields))


def make_rig(start: bool = True, mixer: str | None = MIXER, settle_ms: float = 60,
             **io_kw) -> Rig:
    k = Kernel("fmu")
    p = Platform(k)
    params = Params(p, list(SYSTEM_PARAMS) + list(Px4ioModule.PARAMS) + [CBRK_IO_SAFETY])
    console: list[str] = []
    system = System(p, params, modules={"px4io": Px4ioModule}, console=console.append)
    uart = Uart(k, "USART6", UartConfig(baud=1_500_000))
    system.uarts = {"USART6": uart}  # what the board will hand the system (see the report)
    io = FakeIo(k, uart, **io_kw)
    rig = Rig(k, p, system, uart, io, console)
    if start:
        args = ["start"] + (["-m", mixer] if mixer else [])
        assert rig.cmd(*args) == 0
        rig.run_ms(settle_ms)
    return rig


def controls_publisher(rig: Rig, rate_hz: int, values=(0.1, -0.2, 0.3, 0.5)) -> None:
    """actuator_controls_0 at ``rate_hz`` from now on (a controller's output)."""
    period = 1_000_000_000 // rate_hz
    vals = list(values) + [0.0] * (8 - len(values))
    rig.kernel.call_every(period, lambda: rig.publish("actuator_controls_0", control=vals))


def mixer_text_from_writes(writes) -> str:
    text = b""
    for w in writes:
        payload = struct.pack(f"<{len(w.regs)}H", *w.regs)
        magic, action = struct.unpack_from("<HB", payload)
        assert magic == 0x6D74
        assert action == (0 if not text else 1)
        text += payload[3:]
    return text.replace(b"\0", b"").decode()


def io_board_rig() -> tuple[Rig, Any]:
    """The driver against IoV2Board (its firmware, its USART2), both on the IO's kernel."""
    from ioproc.board import IoV2Board

    board = IoV2Board()
    k = board.kernel
    p = Platform(k)
    params = Params(p, list(SYSTEM_PARAMS) + list(Px4ioModule.PARAMS))
    console: list[str] = []
    system = System(p, params, modules={"px4io": Px4ioModule}, console=console.append)
    uart = Uart(k, "fmu.USART6", UartConfig(baud=1_500_000))
    system.uarts = {"USART6": uart}
    rig = Rig(k, p, system, uart, None, console)  # type: ignore[arg-type]
    UartWire(uart, board.uarts["USART2"])
    return rig, board


def fmu_board_with_px4io(mixer: str = MIXER, controls_hz: int = 400):
    """Orchestrator factory: an FMUv2 board whose only firmware is px4io and a controls source."""
    from fmu.board import FmuV2Board

    board = FmuV2Board(firmware="none")
    p = board.platform
    params = Params(p, list(SYSTEM_PARAMS) + list(Px4ioModule.PARAMS))
    system = System(p, params, modules={"px4io": Px4ioModule}, board=board.spec)
    system.hw = board  # as FmuV2Board.boot() does
    board.system = system
    system.modules.command("px4io", ["start", "-m", mixer])
    pub = p.orb.advertise("actuator_controls_0")
    msg = p.orb.new("actuator_controls_0", control=[0.0] * 8)
    board.kernel.call_every(1_000_000_000 // controls_hz, pub.publish, msg)
    return board


