"""The Pixhawk 1 IO coprocessor (PX4 io-v2) as a board: STM32F100 peripherals + IO firmware.

Built from :data:`board.specs.IO_V2`: USART1 (DSM in, 115200 8N1), USART2 (FMU link, 1.5 Mbit/s
8N1), USART3 (S.BUS in, 100 kbit/s 8E2 behind the board's inverter), TIM1 (HRT at 1 MHz, CH1
captures PPM on PA8), TIM2/3/4 for the eight PWM outputs (24 MHz), the ADC (servo rail on PA4
through a 3:1 divider, analog RSSI on PA5), and the GPIOs (safety button PB5, LEDs).

Ports (names from board/wiring.py):

==================  ======  =========================================================
``fmu_link``        uart    USART2, to the FMU's USART6
``sbus_in``         uart    USART3 (RX: S.BUS receiver; TX: S.BUS output when enabled)
``dsm_in``          uart    USART1 (RX: Spektrum satellite; TX: IO console, silent)
``ppm_in``          pin in  PA8 (TIM1 CH1 capture)
``safety_button``   pin in  PB5, 1 = pressed
``pwm1`` … ``pwm8`` pwm     MAIN outputs from the timer channels
``led_blue`` …      pin out PB14/PB15/PB13/PA11 (raw pin levels; the three first are active low),
                            ``spektrum_power`` PC13, unwired in PIXHAWK1
==================  ======  =========================================================

Power-on: the PX4 IO bootloader waits ``BOOT_DELAY_NS`` (200 ms) for an upload before it
starts the application; if the safety button is held at that moment it stays in the
bootloader (§3.11). The bootloader's upload protocol is not modelled: in the bootloader the IO
does not answer (its UART stays at 1.5 Mbit/s so nothing is decoded). A reset (SETUP REBOOT_BL
magic, or :meth:`IoV2Board.ctl_reset` for a brown-out/watchdog fault) returns every peripheral
to its reset state and goes through the bootloader again.
"""

from __future__ import annotations

from typing import Any

from board.adc import Adc
from board.board import Board
from board.gpio import Gpio
from board.specs import IO_V2, BoardSpecData
from board.timer import Timer
from board.uart import Uart, UartConfig
from ioproc.firmware import FIRMWARE_CRC, LOOP_PERIOD_NS, IoFirmware, IoHardware
from ioproc.firmware.hardware import PWM_CHANNELS, TIMER_CLOCK_HZ
from ioproc.pages import ADC_RSSI, ADC_VSERVO
from ioproc.protocol import Alarms, Arming, StatusFlags

__all__ = ["BOOT_DELAY_NS", "UART_CONFIGS", "IoV2Board"]

#: IO bootloader wait for a host before jumping to the application (§3.11).
BOOT_DELAY_NS = 200_000_000

#: USART line formats as the E14 firmware programs them (§1.1, §4.1, §5.1).
UART_CONFIGS: dict[str, UartConfig] = {
    "USART1": UartConfig(115_200, 8, "N", 1),
    "USART2": UartConfig(1_500_000, 8, "N", 1),
    "USART3": UartConfig(100_000, 8, "E", 2, invert=True),
}

_TIMER_REGS_RESET = (("DIER", 0), ("CR1", 0), ("CCER", 0), ("CCMR1", 0), ("CCMR2", 0),
                     ("PSC", 0), ("ARR", 0xFFFF), ("CCR1", 0), ("CCR2", 0), ("CCR3", 0),
                     ("CCR4", 0), ("CNT", 0), ("SR", 0))
_LED_PORTS = (("led_blue", "PB14"), ("led_amber", "PB15"), ("led_safety", "PB13"),
              ("led_ring", "PA11"), ("spektrum_power", "PC13"))


class IoV2Board(Board):
    """The IO chip; its firmware starts by itself at power-on."""

    def __init__(self, name: str = "io", seed: int = 0, spec: BoardSpecData = IO_V2,
                 boot_delay_ns: int = BOOT_DELAY_NS, loop_period_ns: int = LOOP_PERIOD_NS,
                 servo_rail_v: float = 5.0, rssi_v: float = 0.0,
                 firmware_crc: int = FIRMWARE_CRC) -> None:
        super().__init__(name, seed)
        k = self.kernel
        self.spec = spec
        self.boot_delay_ns = boot_delay_ns
        self.loop_period_ns = loop_period_ns
        self.firmware_crc = firmware_crc
        self.gpio = Gpio(k, f"{name}.gpio")
        self.uarts = {u.name: Uart(k, f"{name}.{u.name}", UART_CONFIGS[u.name])
                      for u in spec.uarts}
        self.timers = {t: Timer(k, f"{name}.{t}", hz, advanced=(t == "TIM1"))
                       for t, hz in spec.timers_hz.items()}
        if any(hz != TIMER_CLOCK_HZ for hz in spec.timers_hz.values()):
            raise ValueError(f"board {name}: IO timers must run at {TIMER_CLOCK_HZ} Hz")
        self.adc = Adc(k, "ADC1", bits=12, vref_v=3.3)
        self._servo_rail_v = servo_rail_v
        self._rssi_v = rssi_v
        self.adc.set_source(ADC_VSERVO, lambda t: self._servo_rail_v / 3.0)
        self.adc.set_source(ADC_RSSI, lambda t: self._rssi_v)
        pins = spec.pins
        self.gpio.pin(pins["safety_button"])  # floating input; 1 = pressed (external pull)
        self.gpio.pin(pins["servo_power_fault"], pull="up")
        for role in ("led_blue", "led_amber", "led_safety"):  # open drain, LED to 3.3 V
            self.gpio.pin(pins[role], pull="up")
        ppm_pin = self.gpio.pin(pins["ppm_in"])
        self.timers["TIM1"].channel(1).bind_input(ppm_pin)
        pwm_timers = (self.timers["TIM2"], self.timers["TIM3"], self.timers["TIM4"])
        self.hw = IoHardware(k, self.gpio, self.uarts["USART1"], self.uarts["USART2"],
                             self.uarts["USART3"], self.timers["TIM1"], pwm_timers, self.adc)
        self._check_pwm_map(pwm_timers)
        self._expose_ports()
        self.firmware: IoFirmware | None = None
        self.in_bootloader = True
        self.boots = 0
        self.resets = 0
        self._boot_event = k.call_at(boot_delay_ns, self._boot)

    # -- construction -----------------------------------------------------------------------
    def _check_pwm_map(self, pwm_timers: tuple[Timer, ...]) -> None:
        """The firmware's output table must be the spec's (one source of truth for ports)."""
        names = [t.name.rsplit(".", 1)[1] for t in pwm_timers]
        for i, out in enumerate(self.spec.pwm):
            group, ch = PWM_CHANNELS[i]
            if (names[group], ch) != (out.timer, out.channel):
                raise ValueError(f"board {self.name}: {out.name} is {out.timer} CH{out.channel}"
                                 f" in the spec but {names[group]} CH{ch} in the firmware")

    def _expose_ports(self) -> None:
        spec = self.spec
        for u in spec.uarts:
            if u.port is not None:
                self.expose_uart(u.port, self.uarts[u.name])
        self.expose_pin_in("ppm_in", self.gpio.pin(spec.pins["ppm_in"]))
        self.expose_pin_in("safety_button", self.gpio.pin(spec.pins["safety_button"]))
        for out in spec.pwm:
            if out.port is not None:
                self.expose_pwm(out.port, self.timers[out.timer].channel(out.channel))
        for port, pin in _LED_PORTS:
            self.expose_pin_out(port, self.gpio.pin(pin))

    # -- boot and reset ---------------------------------------------------------------------
    def _boot(self) -> None:
        """End of the bootloader's wait: start the application unless PB5 is held."""
        self._boot_event = None
        if self.gpio.pin(self.spec.pins["safety_button"]).level:
            return  # force-bootloader pin: stay in the bootloader
        self.in_bootloader = False
        self.boots += 1
        fw = IoFirmware(self.hw, self.firmware_crc, self.loop_period_ns)
        fw.on_reset.append(self._system_reset)
        self.firmware = fw
        fw.start()

    def _system_reset(self) -> None:
        """NVIC system reset: peripherals to reset values, then the bootloader again."""
        self.resets += 1
        if self.firmware is not None:
            self.firmware.stop()
        self.firmware = None
        self.in_bootloader = True
        for tim in self.timers.values():
            tim.attach_irq(None)
            for reg, value in _TIMER_REGS_RESET:
                tim.write_reg(reg, value)
        for uart in self.uarts.values():
            uart.on_idle(None)
            uart.on_rx(None)
            uart.reset_input_buffer()
            uart.take_errors()
        for _, pin in _LED_PORTS:
            self.gpio.pin(pin).release()
        for pin in ("PB4", "PA10"):
            self.gpio.pin(pin).release()
        self.kernel.cancel(self._boot_event)
        self._boot_event = self.kernel.call_later(self.boot_delay_ns, self._boot)

    # -- control calls (tests, tools, fault injection) --------------------------------------
    def ctl_status(self) -> dict[str, Any]:
        """Firmware state in plain data: flags, alarms, arming (raw and by name), source."""
        fw = self.firmware
        if fw is None:
            return {"running": False, "in_bootloader": self.in_bootloader, "boots": self.boots,
                    "resets": self.resets}
        regs = fw.regs
        return {
            "running": True, "in_bootloader": False, "boots": self.boots, "resets": self.resets,
            "flags": regs.status_flags, "alarms": regs.alarms, "arming": regs.arming,
            "flag_names": [f.name for f in StatusFlags if regs.status_flags & f],
            "alarm_names": [a.name for a in Alarms if regs.alarms & a],
            "arming_names": [a.name for a in Arming if regs.arming & a],
            "source": fw.mixer.source.value, "should_arm": fw.mixer.should_arm,
            "outputs_armed": fw.mixer.servos_armed, "pwm_limit": fw.mixer.limit.state.name,
            "loop_passes": fw.passes, "safety_counter": fw.safety.counter,
            "link": {"packets": fw.link.packets, "replies": fw.link.replies,
                     "bad_idle": fw.link.bad_idle, "line_errors": fw.link.line_errors,
                     "corrupt": fw.link.corrupt},
            "rc_source": fw.controls.rc.source, "pwm_rates_hz": list(fw.pwm.rates_hz),
        }

    def ctl_registers(self, page: int) -> list[int] | None:
        """A snapshot of one register page (no read side effects), None if not running."""
        fw = self.firmware
        if fw is None or page not in fw.regs.spec:
            return None
        return list(fw.regs.page(int(page)))

    def ctl_pwm(self) -> list[tuple[int, int]]:
        """(high_ns, period_ns) of pwm1..pwm8 as the pins show them now."""
        out = []
        for o in self.spec.pwm:
            ch = self.timers[o.timer].channel(o.channel)
            out.append((ch.pulse_ns, ch.period_ns))
        return out

    def ctl_leds(self) -> dict[str, Any]:
        """LED states (True = lit) from the pin levels and their polarity."""
        lvl = {port: self.gpio.pin(pin).level for port, pin in _LED_PORTS}
        ring_mode = self.firmware.leds.ring_mode if self.firmware is not None else "off"
        return {"blue": lvl["led_blue"] == 0, "amber": lvl["led_amber"] == 0,
                "safety": lvl["led_safety"] == 0, "ring": lvl["led_ring"] == 1,
                "ring_mode": ring_mode}

    def ctl_reset(self) -> None:
        """Fault injection: the IO resets now (brown-out, watchdog, glitch)."""
        self._system_reset()

    def ctl_set_servo_rail_v(self, volts: float) -> None:
        self._servo_rail_v = float(volts)

    def ctl_set_rssi_v(self, volts: float) -> None:
        self._rssi_v = float(volts)

    def ctl_mixer_source(self) -> str | None:
        return self.firmware.mixer.source.value if self.firmware is not None else None
