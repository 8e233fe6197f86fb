"""Safety switch and the IO's LEDs (E14, io-and-rc.md §3.8).

Why the IO owns this: the safety switch is the last physical barrier between a powered
vehicle and spinning propellers, so in E14 the IO itself debounces the button and decides
SAFETY_OFF, and shows the arming state on the LED inside the button, independent of the FMU.

* Button: PB5 sampled every 100 ms (first sample 1 ms after start). Consecutive pressed samples
  are counted; the sample on which the counter *equals* 10 toggles SAFETY_OFF (the 11th
  pressed sample, 1.0-1.1 s after the press), off only while ARMING.IO_ARM_OK is set, on at
  any time. Releasing (or a refused press) restarts the count; holding on does not re-toggle.
* Safety LED (PB13, open drain, 0 = on): one bit of a 16-bit pattern per sample.
* Amber (PB15, 0 = on), every 125 ms: solid while INIT_OK is clear, else blinking while FMU_OK
  is clear, else off.
* Blue (PB14, 0 = on): heartbeat toggled by the main loop every > 250 ms.
* Ring / green (PA11, 1 = on): solid when SAFETY_OFF and FMU_ARMED; otherwise the real IO
  "breathes" it with a software PWM at main-loop speed. [model] The breathing is not put on
  the pin (it would cost an event per sub-step); the pin stays off and ``ring_mode`` says
  "breathing".
"""

from __future__ import annotations

from typing import Final

from board.gpio import Pin
from ioproc.firmware.bits import AR, SF
from ioproc.pages import IoPages

__all__ = [
    "ARM_COUNTER_THRESHOLD",
    "LED_PATTERNS",
    "SAFETY_PERIOD_US",
    "Leds",
    "SafetySwitch",
]

ARM_COUNTER_THRESHOLD: Final = 10
SAFETY_PERIOD_US: Final = 100_000
SAFETY_FIRST_US: Final = 1_000
FAILSAFE_BLINK_US: Final = 125_000
HEARTBEAT_US: Final = 250_000

#: Safety LED patterns (bit i shown on sample i of 16).
LED_PATTERNS: Final = {
    "io_fmu_armed": 0xFFFF,
    "io_armed": 0x5050,
    "fmu_armed": 0x5500,
    "fmu_ok_to_arm": 0x0003,
    "fmu_refuse_to_arm": 0x5555,
}

F: Final = SF


class Leds:
    """The four LED pins with their polarity; ``on`` states are kept for queries."""

    def __init__(self, blue: Pin, amber: Pin, safety: Pin, ring: Pin) -> None:
        self._pins = {"blue": (blue, True), "amber": (amber, True), "safety": (safety, True),
                      "ring": (ring, False)}
        self.on = {name: False for name in self._pins}
        self.ring_mode = "off"

    def set(self, name: str, on: bool) -> None:
        pin, inverted = self._pins[name]
        self.on[name] = on
        level = int(on) ^ int(inverted)
        if pin.level != level or not pin.driven:
            pin.set(level)

    def all_off(self) -> None:
        for name in self._pins:
            self.set(name, False)


class SafetySwitch:
    """Button debounce + safety LED pattern, run every 100 ms from a timer callback."""

    def __init__(self, regs: IoPages, button: Pin, leds: Leds) -> None:
        self.regs = regs
        self.button = button
        self.leds = leds
        self.counter = 0
        self.blink_counter = 0
        self.pattern = LED_PATTERNS["fmu_refuse_to_arm"]

    def sample(self) -> None:
        regs = self.regs
        pressed = self.button.level == 1
        flags, arming = regs.status_flags, regs.arming
        if pressed and (flags & F.SAFETY_OFF or arming & AR.IO_ARM_OK):
            if self.counter < ARM_COUNTER_THRESHOLD:
                self.counter += 1
            elif self.counter == ARM_COUNTER_THRESHOLD:
                regs.status_flags = flags ^ F.SAFETY_OFF
                self.counter += 1
        else:
            self.counter = 0
        flags = regs.status_flags
        if flags & F.SAFETY_OFF:
            name = "io_fmu_armed" if arming & AR.FMU_ARMED else "io_armed"
        elif arming & AR.FMU_ARMED:
            name = "fmu_armed"
        elif arming & AR.IO_ARM_OK:
            name = "fmu_ok_to_arm"
        else:
            name = "fmu_refuse_to_arm"
        self.pattern = LED_PATTERNS[name]
        self.leds.set("safety", bool(self.pattern & (1 << self.blink_counter)))
        self.blink_counter = (self.blink_counter + 1) & 15
