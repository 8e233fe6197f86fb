"""``controls_tick``: RC input into the register pages, RC loss, manual override (E14, §3.6-3.7).

Why here and not in :mod:`ioproc.rc`: the decoders and their arbitration are shared with other
eras and tools; what is the *IO firmware's* business is where their results land (RAW_RC and
RC_INPUT pages, STATUS flags, ALARMS), the RC_CONFIG scaling, the 200 ms loss rule, and the
override decision that hands the servos to the pilot.

Inputs are read only from the hardware: USART1 (DSM port) and USART3 (S.BUS) buffers once per
pass - the real IO's 1 ms DMA poll makes bytes reach the decoders in such batches, stamped
with the time they are read - and PPM edges from the TIM1 CH1 capture interrupt.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Final

from board.timer import Timer
from board.uart import Uart
from ioproc.firmware.bits import AL, AR, FE, RF, SF
from ioproc.firmware.hardware import IoHardware
from ioproc.pages import ADC_RSSI, IoPages
from ioproc.protocol import (
    CONTROL_CHANNELS,
    RC_ASSIGN_MODESWITCH,
    RC_CONFIG_STRIDE,
    RC_INPUT_CHANNELS,
    RC_OPTIONS_ENABLED,
    RC_OPTIONS_REVERSE,
    PageNo,
    RawRc,
    RcConfig,
    RcInput,
    Setup,
    signed_to_reg,
)
from ioproc.rc import DSM, PPM, SBUS, ST24, SUMD, DsmDecoder, PpmDecoder, SbusDecoder
from ioproc.rc import RcInput as RcMux
from ioproc.rc.common import f32
from ioproc.rc.ppm import PPM_MIN_CHANNELS_E14

__all__ = ["RC_CHANNEL_LOW_THRESH", "RC_INPUT_LOST_US", "Controls", "scale_channel"]

#: Override switch position "manual": scaled value below this (§3.6).
RC_CHANNEL_LOW_THRESH: Final = -8000
#: No frame from any source for longer than this = RC lost (§3.7).
RC_INPUT_LOST_US: Final = 200_000

F: Final = SF
_SOURCE_FLAGS: Final = {SBUS: F.RC_SBUS, DSM: F.RC_DSM, PPM: F.RC_PPM, ST24: F.RC_ST24,
                 SUMD: F.RC_SUMD}
_ALL_SOURCES: Final = F.RC_SBUS | F.RC_DSM | F.RC_PPM | F.RC_ST24 | F.RC_SUMD

# TIM1 bits used by the PPM capture (RM0041).
_CC1IF: Final = 0x0002
_CC1OF: Final = 0x0200
_CC1P: Final = 0x0002


def _c_float_to_int16(value: float) -> int:
    """``(int16_t)`` of a float as the Cortex-M3 build does it: VCVT to int32 (saturating,
    NaN -> 0), then the low 16 bits."""
    if math.isnan(value):
        return 0
    v = -0x80000000 if value <= -2147483648.0 else (
        0x7FFFFFFF if value >= 2147483647.0 else int(value))
    v &= 0xFFFF
    return v - 0x10000 if v & 0x8000 else v


def _f32_div(num: int, den: int) -> float:
    """float32 ``num / (float)den`` with IEEE results for a zero divisor (inf or NaN)."""
    if den == 0:
        return float("nan") if num == 0 else (float("inf") if num > 0 else float("-inf"))
    return f32(f32(num) / f32(den))


def scale_channel(raw: int, c_min: int, c_center: int, c_max: int, c_dz: int) -> int:
    """E14 RC scaling of one channel to -10000..10000 (float32 maths, C cast to int16).

    The FMU's sanity checks only run when OPTIONS is written, so later MIN/MAX writes can leave
    a nonsensical calibration on an enabled channel; the maths then does what the C does.
    """
    raw = max(raw, c_min)
    raw = min(raw, c_max)
    if raw > c_center + c_dz:
        ratio = _f32_div(raw - c_center - c_dz, c_max - c_center - c_dz)
    elif raw < c_center - c_dz:
        ratio = _f32_div(raw - c_center + c_dz, c_center - c_dz - c_min)
    else:
        return 0
    value = 10000.0 * ratio
    return _c_float_to_int16(f32(value) if math.isfinite(value) else value)


def e14_rc_input() -> RcMux:
    """The decoders as the 2014-12 IO ran them (E14 quirks switched on)."""
    return RcMux(arbitration="e14",
                 sbus=SbusDecoder(check_end_byte=False, e14_ch18_bug=True),
                 dsm=DsmDecoder(scaling="e14"),
                 ppm=PpmDecoder(min_channels=PPM_MIN_CHANNELS_E14))


class Controls:
    """RC side of the IO main loop plus the PPM capture interrupt."""

    def __init__(self, hw: IoHardware, regs: IoPages,
                 mixer_tick: Callable[[int], None], rc: RcMux | None = None) -> None:
        self.hw = hw
        self.regs = regs
        self.rc = rc or e14_rc_input()
        self._mixer_tick = mixer_tick
        self._raw = regs.page(PageNo.RAW_RC_INPUT)
        self._scaled = regs.page(PageNo.RC_INPUT)
        self._conf = regs.page(PageNo.RC_CONFIG)
        #: The mode-switch channel scaled like the others (assignment 100).
        self.override_value = 0
        self.rc_received_us = 0  # system_state.rc_channels_timestamp_received
        self.uart_errors = 0
        self._ppm_new = False

    # -- PPM capture (TIM1 CH1 on PA8, §6.2) ------------------------------------------------
    def start_ppm_capture(self) -> None:
        """TIM1: free-running 1 MHz HRT counter, CH1 input capture on TI1, interrupt on capture."""
        tim = self.hw.tim1
        tim.write_reg("CR1", 0)
        tim.write_reg("PSC", 23)
        tim.write_reg("ARR", 0xFFFF)
        tim.write_reg("CCMR1", 0x0001)  # CC1S = 01: IC1 mapped on TI1
        tim.write_reg("CCER", 0x0001)  # CC1E, rising edge first
        tim.write_reg("DIER", _CC1IF)
        tim.attach_irq(self._ppm_isr)
        tim.write_reg("EGR", 1)
        tim.write_reg("CR1", 1)

    def _ppm_isr(self, tim: Timer, t_ns: int) -> None:
        sr = tim.read_reg("SR")
        if not sr & _CC1IF:
            return
        count = tim.read_reg("CCR1")  # clears CC1IF
        overflow = bool(sr & _CC1OF)
        if overflow:
            tim.write_reg("SR", 0xFFFF & ~_CC1OF)
        ccer = tim.read_reg("CCER")
        level = 0 if ccer & _CC1P else 1  # the edge this capture was armed for
        tim.write_reg("CCER", ccer ^ _CC1P)  # the F1 captures one edge: flip for the next
        if self.rc.feed_ppm_capture(t_ns // 1000, count, level, overflow=overflow):
            self._ppm_new = True

    # -- the pass ---------------------------------------------------------------------------
    def _read(self, uart: Uart) -> bytes:
        if uart.flags:
            uart.take_errors()  # [?] NuttX hands bad bytes on; the decoders judge them
            self.uart_errors += 1
        return uart.read()

    def tick(self, now_us: int) -> None:
        regs, rc, raw = self.regs, self.rc, self._raw
        hw = self.hw
        updated = False
        data = self._read(hw.usart1)
        if data and rc.feed_dsm_port(now_us, data):
            updated = True
            if rc.source == DSM:
                if rc.dsm_11bit:
                    raw[RawRc.FLAGS] |= RF.RC_DSM11
                else:
                    raw[RawRc.FLAGS] &= ~RF.RC_DSM11
        data = self._read(hw.usart3)
        if data and rc.feed_sbus_port(now_us, data):
            updated = True
        if self._ppm_new:
            self._ppm_new = False
            if rc.last_frame_us is not None and now_us - rc.last_frame_us <= RC_INPUT_LOST_US:
                updated = True
                raw[RawRc.DATA] = rc.ppm.frame_len_us & 0xFFFF

        if updated:
            # RSSI is stored with each new frame: the analog input (mV / 13, 0..253) unless
            # S.BUS set it (255, 100 on frame lost, 0 on failsafe)
            rssi = 0
            if regs.page(PageNo.SETUP)[Setup.FEATURES] & FE.ADC_RSSI:
                rssi = hw.adc.read(ADC_RSSI) * 3300 // 4096 // 13
            if rc.source == SBUS:
                rssi = rc.rssi or 0
            raw[RawRc.NRSSI] = rssi
            self._take_frame(now_us)

        flags = regs.status_flags
        if now_us - self.rc_received_us > RC_INPUT_LOST_US:
            flags &= ~_ALL_SOURCES
            flags &= ~(F.OVERRIDE | F.RC_OK)
            raw[RawRc.FLAGS] &= ~RF.RC_OK
            self._scaled[RcInput.VALID] = 0
            regs.alarms |= AL.RC_LOST
            raw[RawRc.COUNT] = 0
        regs.status_flags = flags

        arming = regs.arming
        if (arming & AR.MANUAL_OVERRIDE_OK and flags & F.RC_OK
                and not raw[RawRc.FLAGS] & RF.FAILSAFE):
            override = self.override_value < RC_CHANNEL_LOW_THRESH or bool(
                not flags & F.FMU_OK and arming & AR.OVERRIDE_IMMEDIATE
                and flags & F.MIXER_OK)
            if override:
                regs.status_flags |= F.OVERRIDE
                if updated:
                    self._mixer_tick(now_us)  # low-latency manual flight
            else:
                regs.status_flags &= ~F.OVERRIDE
        else:
            regs.status_flags &= ~F.OVERRIDE

    def _take_frame(self, now_us: int) -> None:
        """A new frame from any source: raw page, flags, scaling into RC_INPUT."""
        regs, rc, raw = self.regs, self.rc, self._raw
        count = min(rc.channel_count, RC_INPUT_CHANNELS)
        values = rc.channels
        raw[RawRc.COUNT] = count
        for i in range(count):
            raw[RawRc.BASE + i] = values[i] & 0xFFFF
        flags = raw[RawRc.FLAGS]
        if rc.source == SBUS:
            flags = (flags | RF.FRAME_DROP) if rc.frame_lost else (
                flags & ~RF.FRAME_DROP)
            flags = (flags | RF.FAILSAFE) if rc.failsafe else (
                flags & ~RF.FAILSAFE)
        else:
            flags &= ~(RF.FRAME_DROP | RF.FAILSAFE)
        regs.status_flags |= _SOURCE_FLAGS.get(rc.source or "", 0)
        self.rc_received_us = now_us
        if flags & RF.FAILSAFE:
            raw[RawRc.FLAGS] = flags
            return  # receiver failsafe: command nothing, let the FMU see it
        conf, scaled = self._conf, self._scaled
        assigned = 0
        for i in range(count):
            base = i * RC_CONFIG_STRIDE
            options = conf[base + RcConfig.OPTIONS]
            if not options & RC_OPTIONS_ENABLED:
                continue
            s = scale_channel(values[i], conf[base + RcConfig.MIN], conf[base + RcConfig.CENTER],
                              conf[base + RcConfig.MAX], conf[base + RcConfig.DEADZONE])
            if options & RC_OPTIONS_REVERSE:
                s = -s
            mapped = conf[base + RcConfig.ASSIGNMENT]
            if mapped < CONTROL_CHANNELS:
                if mapped == 1:
                    s = -s  # pitch: stick pulled = pitch up
                scaled[RcInput.BASE + mapped] = signed_to_reg(s)
                assigned |= 1 << mapped
            elif mapped == RC_ASSIGN_MODESWITCH:
                self.override_value = s
        for i in range(CONTROL_CHANNELS):
            if not assigned & (1 << i):
                scaled[RcInput.BASE + i] = 0
        scaled[RcInput.VALID] = assigned
        flags |= RF.RC_OK
        flags = (flags | RF.MAPPING_OK) if assigned > 4 else (
            flags & ~RF.MAPPING_OK)
        raw[RawRc.FLAGS] = flags
        regs.status_flags |= F.RC_OK
