"""FMUv2 sensor path: virtual seconds per host second with all six sensor drivers running.

The board runs ``firmware="sensors"`` (PX4's rc.board_sensors only: MPU6000 at 8 kHz with a
data-ready pulse per sample, L3GD20 at 760 Hz on DRDY, LSM303D accel FIFO and mag, MS5611,
HMC5883 on I2C, u-blox GPS on a UART) on a spinning turntable, so every sample is new. The
whole flight (sensors, estimator, controllers in one process) has to run at least 5x real time;
this is the part of that budget the sensors take. Boot (2 virtual s) is not timed.
"""

from __future__ import annotations

import statistics
import time

VIRTUAL_S = 5
BOOT_NS = 2 * 10**9


def _run_once(virtual_s: int = VIRTUAL_S) -> float:
    from fmu.board import FmuV2Board
    from hil.turntable import Turntable

    b = FmuV2Board(seed=1, firmware="sensors")
    Turntable(b.kernel, b.env, rate_rad_s=(0.1, -0.2, 0.3))
    b.kernel.run(BOOT_NS)
    t0 = time.perf_counter()
    b.kernel.run(BOOT_NS + virtual_s * 10**9)
    return virtual_s / (time.perf_counter() - t0)


def bench_fmu_sensors_rtf(runs: int = 3) -> float:
    """Median over ``runs`` of virtual seconds per wall second (the real-time factor)."""
    return statistics.median(_run_once() for _ in range(runs))


if __name__ == "__main__":
    rtf = bench_fmu_sensors_rtf()
    print(f"fmu_sensors_rtf: {rtf:.2f} (host {1000.0 / rtf:.1f} ms per virtual s)")
