"""The IO firmware: boot sequence and main loop (E14 px4io ``user_start``, §3.2).

Main-loop model. The real loop never sleeps: it runs ``mixer_tick``, ``controls_tick`` and the
LED/reboot housekeeping as fast as the 24 MHz CPU allows (a pass with mixing takes a few hundred
µs). Here one pass is a kernel event every ``LOOP_PERIOD_NS`` (1 ms, first pass at start).
1 ms is the granularity at which the real IO sees RC bytes anyway (its serial DMA is polled
by a 1 ms callback), and every timeout the firmware defines (500 ms FMU loss, 200 ms RC loss,
250 ms heartbeat) is then detected on the first 1 ms pass *after* it expired: e.g. FMU_OK drops
on the first pass with ``now - last_write > 500 000 µs``. The FMU link itself is interrupt
driven and does not wait for a pass; the safety button (100 ms) and amber LED (125 ms) have
their own periodic callbacks, as on the chip.

The firmware keeps every kernel handle it creates so a reset (:meth:`IoFirmware.stop`) leaves
nothing behind; the board then builds a fresh firmware, as a real reset would.
"""

from __future__ import annotations

from typing import Final

from board.kernel import PRIO_ISR, Kernel, Periodic
from ioproc.firmware.bits import AR, SF
from ioproc.firmware.controls import Controls
from ioproc.firmware.hardware import IoHardware
from ioproc.firmware.mixer_tick import MixerTick
from ioproc.firmware.pwm_out import PwmServo
from ioproc.firmware.safety import (
    FAILSAFE_BLINK_US,
    HEARTBEAT_US,
    SAFETY_FIRST_US,
    SAFETY_PERIOD_US,
    Leds,
    SafetySwitch,
)
from ioproc.firmware.sbus_out import SbusOut
from ioproc.firmware.serial_link import FmuLink
from ioproc.pages import IoHooks, IoPages
from ioproc.protocol import ERA
from ioproc.pwm_limit import PwmLimit

__all__ = ["LOOP_PERIOD_NS", "IoFirmware"]

#: [model] One main-loop pass per millisecond (see the module docstring).
LOOP_PERIOD_NS: Final = 1_000_000
#: Main-loop priority: after interrupts at the same instant, like a thread.
PRIO_MAIN: Final = 100

F: Final = SF


class IoFirmware:
    """One boot of the PX4IO E14 firmware on an :class:`IoHardware`."""

    def __init__(self, hw: IoHardware, firmware_crc: int = 0,
                 loop_period_ns: int = LOOP_PERIOD_NS) -> None:
        self.hw = hw
        self.kernel: Kernel = hw.kernel
        self.loop_period_ns = loop_period_ns
        pin = hw.pin
        self.leds = Leds(pin("PB14"), pin("PB15"), pin("PB13"), pin("PA11"))
        self.pwm = PwmServo(hw.pwm_timers)
        self.sbus_out = SbusOut(hw.usart3, pin("PB4"))
        self.dsm_power = pin("PC13")
        self.dsm_bind_pin = pin("PA10")
        self.dsm_bind_requests: list[tuple[int, int]] = []
        hooks = IoHooks(adc_measure=hw.adc.read, set_rate_group=self.pwm.set_rate,
                        dsm_bind=self._dsm_bind, set_sbus_out=self.sbus_out.enable,
                        set_amber_led=lambda on: self.leds.set("amber", on))
        self.regs = IoPages(ERA, hooks, firmware_crc)
        self.mixer = MixerTick(self.regs, self.pwm, PwmLimit(ERA), self.sbus_out.send)
        self.controls = Controls(hw, self.regs, self.mixer.tick)
        self.safety = SafetySwitch(self.regs, pin("PB5"), self.leds)
        self.link = FmuLink(self.kernel, hw.usart2, self.regs)
        self.passes = 0
        self.running = False
        self.reset_requested = False
        self._last_heartbeat_us = 0
        self._amber_blink = False
        self._handles: list[Periodic | list] = []
        self.on_reset: list = []  # callables run when the firmware resets the chip

    # -- boot ------------------------------------------------------------------------------
    def start(self) -> None:
        """user_start: the E14 init order of §3.2 (HRT, LEDs, safety, PWM, RC ports, link)."""
        k = self.kernel
        hw = self.hw
        self.controls.start_ppm_capture()  # TIM1 is the HRT; CH1 the PPM capture
        self.leds.all_off()
        self.sbus_out.enable(False)
        self.dsm_power.set(1)  # GPIO_SPEKTRUM_PWR_EN resets high: satellite powered
        self._handles.append(k.call_every(SAFETY_PERIOD_US * 1000, self.safety.sample,
                                          first_ns=k.now_ns + SAFETY_FIRST_US * 1000,
                                          priority=PRIO_ISR))
        self.pwm.init()
        for uart in (hw.usart1, hw.usart3):
            uart.reset_input_buffer()
            uart.take_errors()
        self.link.start()
        self.mixer.limit = PwmLimit(ERA)
        self._handles.append(k.call_every(FAILSAFE_BLINK_US * 1000, self._failsafe_blink,
                                          priority=PRIO_ISR))
        self._last_heartbeat_us = k.now_ns // 1000
        self._handles.append(k.call_every(self.loop_period_ns, self._loop,
                                          first_ns=k.now_ns, priority=PRIO_MAIN))
        self.running = True

    def stop(self) -> None:
        """Halt everything this boot scheduled (the chip is being reset)."""
        for handle in self._handles:
            Kernel.cancel(handle)
        self._handles.clear()
        self.link.stop()
        self.hw.tim1.attach_irq(None)
        self.running = False

    # -- main loop -------------------------------------------------------------------------
    def _loop(self) -> None:
        now_us = self.kernel.now_ns // 1000
        self.passes += 1
        self.mixer.tick(now_us)
        self.controls.tick(now_us)
        if now_us - self._last_heartbeat_us > HEARTBEAT_US:
            self._last_heartbeat_us = now_us
            self.leds.set("blue", not self.leds.on["blue"])
        flags, arming = self.regs.status_flags, self.regs.arming
        ring = bool(flags & F.SAFETY_OFF and arming & AR.FMU_ARMED)
        self.leds.ring_mode = "on" if ring else "breathing"
        if ring != self.leds.on["ring"]:
            self.leds.set("ring", ring)
        reboot = self.regs.reboot_at_us
        if reboot is not None and now_us > reboot:
            self.reset_requested = True
            for fn in list(self.on_reset):
                fn()

    def _failsafe_blink(self) -> None:
        flags = self.regs.status_flags
        if not flags & F.INIT_OK:
            self.leds.set("amber", True)
            return
        self._amber_blink = not self._amber_blink if not flags & F.FMU_OK else False
        self.leds.set("amber", self._amber_blink)

    # -- DSM bind (SETUP DSM register, §2.9, §5.9) -----------------------------------------
    def _dsm_bind(self, command: int, pulses: int) -> None:
        """Power the satellite and pulse its data line (E14: 25 µs low / 25 µs high)."""
        now = self.kernel.now_ns
        self.dsm_bind_requests.append((command, pulses))
        if command == 0:
            self.dsm_power.set(0)
        elif command == 1:
            self.dsm_power.set(1)
            self.controls.rc.dsm._reset_guess()
        elif command == 2:
            self.dsm_bind_pin.set(1)
        elif command == 3:
            for i in range(pulses):
                self.dsm_bind_pin.set(0, now + (2 * i + 1) * 25_000)
                self.dsm_bind_pin.set(1, now + (2 * i + 2) * 25_000)
        elif command == 4:
            self.dsm_bind_pin.release()
