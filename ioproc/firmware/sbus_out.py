"""S.BUS output on USART3 TX (FEATURES SBUS1_OUT / SBUS2_OUT, io-and-rc.md §3.10, E14).

Why: some vehicles drive S.BUS servos from the IO's S.BUS port. E14 sends a frame only from the
output path of ``mixer_tick`` and at most one per 14 ms; the 8 outputs' µs become channels 1-8
(``raw = (µs - 874) / 0.625 + 0.5`` truncated, limited to 0x7FF), the rest 0, flags 0, end 0.
The E14 S.BUS2 output is a stub that writes the single byte ``'B'``. PB4 low enables the
output driver.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Final

from board.gpio import Pin
from board.uart import Uart
from ioproc.rc.sbus import encode_sbus_frame

__all__ = ["SBUS1_FRAME_DELAY_US", "SbusOut"]

SBUS1_FRAME_DELAY_US: Final = 14_000


def _us_to_raw(us: int) -> int:
    value = (us - 874) / 0.625 + 0.5
    return 0 if value <= 0 else min(int(value), 0x7FF)


class SbusOut:
    """Frame pacing and the output-enable pin."""

    def __init__(self, uart: Uart, enable_pin: Pin) -> None:
        self.uart = uart
        self.enable_pin = enable_pin
        self.enabled = False
        self.frames = 0
        self._last_us = 0

    def enable(self, on: bool) -> None:
        self.enabled = on
        self.enable_pin.set(0 if on else 1)

    def send(self, servos: Sequence[int], now_us: int, sbus2: bool) -> None:
        if now_us - self._last_us <= SBUS1_FRAME_DELAY_US:
            return
        self._last_us = now_us
        self.frames += 1
        if sbus2:
            self.uart.write(b"B")
            return
        raw = [_us_to_raw(v) for v in servos[:8]] + [0] * 8
        self.uart.write(encode_sbus_frame(raw))
