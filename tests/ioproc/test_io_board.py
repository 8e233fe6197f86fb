"""IoV2Board: ports, boot, the FMU link at the wire, resets, LEDs, firmware CRC.

Also home of :class:`FakeFmu` and :func:`rig`, the test-side FMU the firmware and failsafe
tests share: a USART6 on the IO's kernel wired to the IO's USART2, speaking the protocol with
``encode_read``/``encode_write``/``decode_reply`` one transaction at a time, like the E14 driver.
"""

from __future__ import annotations

import pytest

from board.uart import Uart, UartConfig, UartWire, connect
from board.wiring import PIXHAWK1
from ioproc.board import BOOT_DELAY_NS, IoV2Board
from ioproc.firmware import FIRMWARE_CRC, firmware_crc32
from ioproc.firmware.serial_link import REPLY_LATENCY_NS
from ioproc.mixer import encode_mixer_upload
from ioproc.protocol import (
    REBOOT_BL_MAGIC,
    Alarms,
    Arming,
    PageNo,
    Reply,
    Setup,
    StatusFlags,
    decode_reply,
    encode_read,
    encode_write,
    float_to_reg,
)
from ioproc.rc import encode_sbus_frame

MS = 1_000_000
QUAD_X = "R: 4x 10000 10000 10000 0\n"


class FakeFmu:
    """The FMU end of the link, driven from the test (no FMU firmware involved)."""

    def __init__(self, io: IoV2Board) -> None:
        self.io = io
        self.k = io.kernel
        self.uart = Uart(self.k, "fmu.USART6", UartConfig(1_500_000))
        UartWire(self.uart, io.uarts["USART2"])
        self.uart.on_idle(self._on_idle)
        self.rx = b""
        self.rx_t_ns = 0
        self.controls = [0] * 8
        self.period_ns: int | None = None
        self._next_ns = 0
        self._waiting = False

    def _on_idle(self, t_ns: int) -> None:
        self.rx += self.uart.read()
        self.rx_t_ns = t_ns
        if self._waiting:
            self.k.stop()

    def exchange(self, packet: bytes, timeout_ns: int = 10 * MS) -> bytes:
        """Send one request; return what came back before the reply timeout (maybe b"")."""
        self.rx = b""
        self.uart.write(packet)
        deadline = self.k.now_ns + timeout_ns
        self._waiting = True
        while not self.rx and self.k.now_ns < deadline:
            self.k.run(deadline)
        self._waiting = False
        return self.rx

    def transact(self, packet: bytes) -> Reply:
        return decode_reply(self.exchange(packet))

    def read(self, page: int, offset: int = 0, count: int = 1) -> list[int]:
        reply = self.transact(encode_read(page, offset, count))
        assert reply.ok, reply
        return list(reply.values)

    def write(self, page: int, offset: int, values: list[int]) -> Reply:
        return self.transact(encode_write(page, offset, values))

    def flags(self) -> int:
        return self.read(PageNo.STATUS, 2)[0]

    def alarms(self) -> int:
        return self.read(PageNo.STATUS, 3)[0]

    def set_controls(self, roll: float = 0.0, pitch: float = 0.0, yaw: float = 0.0,
                     thrust: float = 0.0) -> None:
        self.controls = [float_to_reg(v) for v in (roll, pitch, yaw, thrust)] + [0] * 4

    def stream(self, period_ns: int | None = 4 * MS) -> None:
        """Write group-0 CONTROLS every ``period_ns`` while the test advances (None: stop)."""
        self.period_ns = period_ns
        self._next_ns = self.k.now_ns

    def advance(self, duration_ns: int) -> None:
        end = self.k.now_ns + duration_ns
        while self.period_ns is not None and self._next_ns <= end:
            self.k.run(max(self._next_ns, self.k.now_ns))
            assert self.write(PageNo.CONTROLS, 0, self.controls).ok
            self._next_ns += self.period_ns
        self.k.run(max(end, self.k.now_ns))

    def upload_mixer(self, text: str) -> None:
        for chunk in encode_mixer_upload(text):
            assert self.write(PageNo.MIXERLOAD, 0, chunk).ok

    def configure_rc(self, channels: int = 8, mode_channel: int | None = None) -> None:
        """E14 driver's RC config upload: ch i -> control i, optional mode switch (100)."""
        for ch in range(channels):
            assign = 100 if ch == mode_channel else (ch if ch < 5 else 255)
            assert self.write(PageNo.RC_CONFIG, ch * 6, [1000, 1500, 2000, 10, assign, 1]).ok


class SbusTx:
    """An S.BUS receiver's output: inverted 100 kbit/s 8E2 frames every ``period_ns``."""

    def __init__(self, io: IoV2Board, period_ns: int = 14 * MS) -> None:
        self.k = io.kernel
        self.uart = Uart(self.k, "rx.sbus", UartConfig(100_000, 8, "E", 2, invert=True))
        connect(self.uart, io.uarts["USART3"])
        self.raw = [1024] * 16
        self.failsafe = False
        self.period_ns = period_ns
        self.frames = 0
        self._timer = None

    def start(self) -> None:
        self._timer = self.k.call_every(self.period_ns, self._send, first_ns=self.k.now_ns)

    def stop(self) -> None:
        self.k.cancel(self._timer)

    def _send(self) -> None:
        self.frames += 1
        self.uart.write(encode_sbus_frame(self.raw, failsafe=self.failsafe))


def rig(**kwargs) -> tuple[IoV2Board, FakeFmu]:
    """A booted IO (first main-loop pass done) with a fake FMU on its link."""
    io = IoV2Board(**kwargs)
    fmu = FakeFmu(io)
    io.kernel.run(BOOT_DELAY_NS)
    return io, fmu


def arm_quad(io: IoV2Board, fmu: FakeFmu, *, press_safety: bool = False) -> None:
    """The E14 driver's bring-up for a quad, then arming (safety forced off unless pressed)."""
    fmu.configure_rc()
    fmu.upload_mixer(QUAD_X)
    fmu.write(PageNo.SETUP, Setup.ARMING, [Arming.IO_ARM_OK | Arming.FMU_ARMED])
    if not press_safety:
        fmu.write(PageNo.SETUP, Setup.FORCE_SAFETY_OFF, [22027])


# -- tests ----------------------------------------------------------------------------------
def test_ports_are_the_wiring_names() -> None:
    io = IoV2Board()
    ports = {name: (kind, direction) for name, kind, direction in io.ctl_ports()}
    for wire in PIXHAWK1:
        for board, port in (wire.src, wire.dst):
            if board == "io":
                assert port in ports, port
    assert ports["fmu_link"] == ("uart", "inout")
    assert ports["safety_button"] == ("pin", "in") and ports["ppm_in"] == ("pin", "in")
    assert all(ports[f"pwm{i}"] == ("pwm", "out") for i in range(1, 9))


def test_uart_formats() -> None:
    io = IoV2Board()
    assert io.uarts["USART2"].config == UartConfig(1_500_000, 8, "N", 1)
    assert io.uarts["USART3"].config == UartConfig(100_000, 8, "E", 2, invert=True)
    assert io.uarts["USART1"].config == UartConfig(115_200, 8, "N", 1)


def test_silent_in_bootloader_then_config_protocol_4() -> None:
    io = IoV2Board()
    fmu = FakeFmu(io)
    assert fmu.exchange(encode_read(PageNo.CONFIG, 0, 1)) == b""  # bootloader: no answer
    io.kernel.run(BOOT_DELAY_NS)
    assert fmu.exchange(bytes.fromhex("0129 0000 0000")) == bytes.fromhex("017d 0000 0400")
    assert fmu.read(PageNo.CONFIG, 0, 9) == [4, 2, 3, 64, 8, 8, 18, 2, 0]


def test_reply_timing_on_the_port() -> None:
    """Through the lockstep port: reply starts IDLE (one character) + latency after the request."""
    io = IoV2Board()
    io.advance(BOOT_DELAY_NS + MS, [])
    t0 = io.kernel.now_ns
    req = encode_read(PageNo.CONFIG, 0, 1)
    out = io.advance(t0 + MS, [("fmu_link", t0, (1_500_000, 8, "N", 1, 0, req))])
    replies = [r for r in out if r[0] == "fmu_link"]
    end_ns = t0 + len(req) * 10 * 1_000_000_000 // 1_500_000
    idle_ns = end_ns + UartConfig(1_500_000).frame_ns_ceil
    assert replies == [("fmu_link", idle_ns + REPLY_LATENCY_NS,
                        (1_500_000, 8, "N", 1, 0, bytes.fromhex("017d 0000 0400")))]


def test_pwm_ports_emit_records_when_armed() -> None:
    io, fmu = rig()
    arm_quad(io, fmu)
    fmu.set_controls(thrust=0.5)
    fmu.stream()
    records = []
    for _ in range(4):
        fmu.advance(200 * MS)
        records += [r for r in io._outbox if r[0].startswith("pwm")]
        io._outbox.clear()
    last = {port: payload for port, _, payload in records}
    assert last["pwm1"] == (1_499_000, 20_001_000)  # E14: CCR = 1500 - 1, ARR = 20000
    assert last["pwm4"] == (1_499_000, 20_001_000)
    assert last["pwm5"] == (0, 20_001_000)  # no mixer output -> 0 -> pin stays low


def test_firmware_crc_in_setup() -> None:
    _io, fmu = rig()
    assert firmware_crc32(b"123456789") == 0x2DFD2D88
    lo, hi = fmu.read(PageNo.SETUP, Setup.CRC, 2)
    assert (hi << 16) | lo == FIRMWARE_CRC


def test_reset_goes_through_bootloader_and_clears_state() -> None:
    io, fmu = rig()
    fmu.write(PageNo.SETUP, Setup.FORCE_SAFETY_OFF, [22027])
    assert fmu.flags() & StatusFlags.SAFETY_OFF
    io.ctl_reset()
    assert io.ctl_status()["in_bootloader"]
    assert fmu.exchange(encode_read(PageNo.CONFIG, 0, 1)) == b""
    io.kernel.run(io.kernel.now_ns + BOOT_DELAY_NS)
    assert io.ctl_status()["boots"] == 2
    assert not fmu.flags() & StatusFlags.SAFETY_OFF


def test_safety_button_held_at_boot_stays_in_bootloader() -> None:
    io = IoV2Board()
    io.deliver([("safety_button", 0, 1)])
    io.kernel.run(BOOT_DELAY_NS + 50 * MS)
    assert io.ctl_status() == {"running": False, "in_bootloader": True, "boots": 0,
                               "resets": 0}


def test_reboot_to_bootloader_magic() -> None:
    io, fmu = rig()
    t_write = io.kernel.now_ns
    assert fmu.write(PageNo.SETUP, Setup.REBOOT_BL, [REBOOT_BL_MAGIC]).ok
    # the write is applied at the request's IDLE: 6 bytes + one character after the write
    char_ns = UartConfig(1_500_000).frame_ns_ceil
    reboot_at_us = (t_write + 6 * 10 * 1_000_000_000 // 1_500_000 + char_ns) // 1000 + 100_000
    # reset on the first main-loop pass (1 ms grid from boot) strictly after that time
    n = (reboot_at_us * 1000 - BOOT_DELAY_NS) // MS + 1
    t_reset = BOOT_DELAY_NS + n * MS
    io.kernel.run(t_reset - 1)
    assert io.ctl_status()["running"]
    io.kernel.run(t_reset)
    st = io.ctl_status()
    assert st["resets"] == 1 and st["in_bootloader"]


def test_reboot_refused_with_safety_off() -> None:
    io, fmu = rig()
    fmu.write(PageNo.SETUP, Setup.FORCE_SAFETY_OFF, [22027])
    fmu.write(PageNo.SETUP, Setup.REBOOT_BL, [REBOOT_BL_MAGIC])
    io.kernel.run(io.kernel.now_ns + 200 * MS)
    assert io.ctl_status()["resets"] == 0


def test_leds_heartbeat_and_amber() -> None:
    io, fmu = rig()
    k = io.kernel
    blue = []
    io.gpio.pin("PB14").on_change(lambda pin, t, level: blue.append(t))
    amber = []
    io.gpio.pin("PB15").on_change(lambda pin, t, level: amber.append((t, level)))
    k.run(BOOT_DELAY_NS + 800 * MS)
    # toggled on the first pass more than 250 ms after the last toggle (1 ms passes)
    assert blue == [BOOT_DELAY_NS + 251 * MS, BOOT_DELAY_NS + 502 * MS, BOOT_DELAY_NS + 753 * MS]
    # INIT_OK clear: solid on from the first 125 ms callback
    assert io.ctl_leds()["amber"] and amber == [(BOOT_DELAY_NS + 125 * MS, 0)]
    fmu.configure_rc(1)  # INIT_OK; FMU still silent -> amber blinks at 125 ms
    amber.clear()
    k.run(k.now_ns + 500 * MS)
    # callbacks every 125 ms from boot; the 1075 ms one toggles the (solid) LED to "on" again
    assert amber == [(1200 * MS, 1), (1325 * MS, 0), (1450 * MS, 1)]
    fmu.set_controls()
    fmu.stream()
    fmu.advance(300 * MS)
    assert not io.ctl_leds()["amber"]


def test_no_crash_on_garbage_link_bytes() -> None:
    import random

    io, fmu = rig()
    rnd = random.Random(7)
    for _ in range(300):
        n = rnd.choice((1, 3, 4, 6, 20, 68, 69, 100))
        fmu.exchange(bytes(rnd.randrange(256) for _ in range(n)), timeout_ns=MS)
    assert fmu.read(PageNo.CONFIG, 0, 1) == [4]
    st = io.ctl_status()
    assert st["link"]["corrupt"] > 0 and st["link"]["bad_idle"] > 0


@pytest.mark.parametrize("seed", range(4))
def test_no_crash_on_random_register_writes(seed: int) -> None:
    import random

    io, fmu = rig()
    rc = SbusTx(io, period_ns=7 * MS)  # RC frames meet whatever RC_CONFIG the writes leave
    rc.start()
    rnd = random.Random(seed)
    pages = [0, 1, 2, 3, 4, 5, 6, 7, 50, 51, 52, 53, 54, 55, 56, 106, 107, 108, 127, 200]
    for _ in range(200):
        page = rnd.choice(pages)
        offset = rnd.randrange(0, 40) if rnd.random() < 0.8 else rnd.randrange(256)
        values = [rnd.choice((0, 1, 0xFFFF, 22027, 14662, rnd.randrange(65536)))
                  for _ in range(rnd.randrange(0, 33))]
        fmu.exchange(encode_write(page, offset, values), timeout_ns=MS)
        io.kernel.run(io.kernel.now_ns + rnd.randrange(3) * MS)
        rc.raw = [rnd.randrange(2048) for _ in range(16)]
    io.kernel.run(io.kernel.now_ns + 400 * MS)  # a scheduled reboot may have happened
    assert io.ctl_status()["running"]
    assert fmu.read(PageNo.CONFIG, 0, 1) == [4]
    assert Alarms(fmu.alarms()) is not None
