"""MPU-6000 end to end: host microseconds per sample, model to uORB.

One kernel with SPI1, the DRDY pin and the platform; the chip at the driver's default
configuration (8 kHz, FIFO, data-ready interrupt) and the driver publishing sensor_accel and
sensor_gyro at 1 kHz. Per sample this covers the model's lazy sample generation, the DRDY pulse
and EXTI interrupt, 1/8 of the FIFO count and burst reads, the conversion and the publication.
The whole FMU must run faster than real time with 8000 of these per virtual second.
"""

from __future__ import annotations

import statistics
import time

from board.gpio import Gpio
from board.kernel import NS_PER_MS, NS_PER_S, Kernel
from board.spi import SpiBus
from firmware.drivers.imu.mpu6000 import FIFO_READ, Mpu6000Driver
from firmware.platform import Platform
from peripherals.errors import rng_for
from peripherals.mpu6000 import Mpu6000
from peripherals.physics import Environment

VIRTUAL_S = 2


def _run_once() -> float:
    kernel = Kernel("bench")
    platform = Platform(kernel)
    pin = Gpio(kernel).pin("PD15")
    chip = Mpu6000(kernel, Environment(), rng_for(1, "mpu6000"), drdy_pin=pin)
    bus = SpiBus(kernel, "spi1", pclk_hz=84_000_000)
    bus.attach("PC2", chip)
    driver = Mpu6000Driver(platform, bus.device("PC2", mode=3), drdy_pin=pin)
    kernel.run(100 * NS_PER_MS)
    kernel.call_later(0, driver.start)
    kernel.run_for(300 * NS_PER_MS)  # reset, configure: not timed
    if driver.state != FIFO_READ:
        raise RuntimeError(f"driver did not start: {platform.dmesg_text()}")
    s0 = chip.samples_produced
    t0 = time.perf_counter()
    kernel.run_for(VIRTUAL_S * NS_PER_S)
    wall = time.perf_counter() - t0
    return wall * 1e6 / (chip.samples_produced - s0)


def bench_mpu6000_sample_us() -> float:
    """Median over 3 runs of host microseconds per MPU-6000 sample, end to end."""
    return statistics.median(_run_once() for _ in range(3))


if __name__ == "__main__":
    print(f"mpu6000_sample_us: {bench_mpu6000_sample_us():.2f}")
