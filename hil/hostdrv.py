"""``hil hostdrv``: one of the FMU's drivers on a host bus, in real time, printing like listener.

``hil hostdrv hmc5883 --i2c 1`` opens ``/dev/i2c-1`` with smbus2, wraps it in
:class:`hil.hostbus.SMBusHandle` and starts the project's own HMC5883 driver on a minimal
platform (a kernel, its HRT, a local uORB, the work queues: ``firmware.platform.Platform``, no
board), so the driver that flies in the emulator reads a real chip wired to a Linux computer.
``hil hostdrv ms5611 --spi 0.0`` does the same with ``spidev`` on ``/dev/spidev0.0``.

The platform's kernel is paced to the wall clock here (the HRT reads elapsed real time): this
is wall-clock code, which is why it lives in hil/. Every ``1 / print_hz`` seconds the latest
``sensor_mag`` (``sensor_baro``) message is printed in ``listener``'s format; at the end a
summary line gives the message count and rate, the driver's error count and the host bus's.

``--emulated`` puts the emulated chip (same model, seed and environment as on the emulated
board) behind :class:`hil.smbus_emulated.EmulatedSMBus` (or the emulated SPI chip select,
which has spidev's API) and runs the very same path: the way to try the command without
hardware, and how the tests exercise it.

Exit status: 0 after the run, 1 if the driver refuses to start (no or wrong chip: its dmesg is
printed), 2 for a bus that cannot be opened (no ``/dev/i2c-N``, no permission, spidev missing).
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import Any, TextIO

from board.kernel import Kernel
from firmware.platform import Platform
from firmware.platform.uorb import Subscription

__all__ = ["DRIVERS", "HostRun", "main", "open_i2c", "open_spi"]

#: driver name -> (bus kind, topic it publishes)
DRIVERS = {"hmc5883": ("i2c", "sensor_mag"), "ms5611": ("spi", "sensor_baro")}
HMC5883_ADDR = 0x1E
#: PX4 has I2C work queues for buses 0..4 (firmware/platform/workqueue.py).
MAX_I2C_BUS = 4


class BusOpenError(Exception):
    """The host bus cannot be opened: the message says which and why (exit status 2)."""


def open_i2c(bus_number: int) -> Any:
    """``smbus2.SMBus(bus_number)``, with a clear error instead of a traceback."""
    from smbus2 import SMBus

    path = f"/dev/i2c-{bus_number}"
    try:
        return SMBus(bus_number)
    except FileNotFoundError:
        raise BusOpenError(f"{path} does not exist: no I2C bus {bus_number} on this host (is "
                           f"the i2c-dev module loaded? `ls /dev/i2c-*` lists the buses)") from None
    except PermissionError:
        raise BusOpenError(f"{path}: permission denied (add yourself to the i2c group or run "
                           f"with access to it)") from None
    except OSError as exc:
        raise BusOpenError(f"{path}: cannot open: {exc.strerror or exc}") from None


def open_spi(bus: int, cs: int) -> Any:
    """``spidev.SpiDev`` on ``/dev/spidevBUS.CS``, with a clear error instead of a traceback."""
    try:
        import spidev  # type: ignore[import-not-found]
    except ImportError:
        raise BusOpenError("the spidev package is not installed (`pip install spidev` on a "
                           "Linux host with kernel headers)") from None
    path = f"/dev/spidev{bus}.{cs}"
    dev = spidev.SpiDev()
    try:
        dev.open(bus, cs)
    except FileNotFoundError:
        raise BusOpenError(f"{path} does not exist: no SPI device {bus}.{cs} on this host") \
            from None
    except OSError as exc:
        raise BusOpenError(f"{path}: cannot open: {exc.strerror or exc}") from None
    return dev


def format_listener(topic: str, instance: int, generation: int, msg: Any, now_us: int) -> str:
    """One message as nsh's ``listener`` prints it (firmware/shell/cmd_status.py)."""
    lines = [f"TOPIC: {topic} instance {instance} #{generation}"]
    for name in msg._fields:
        v = getattr(msg, name)
        if name.startswith("timestamp") and isinstance(v, int) and v:
            lines.append(f"    {name}: {v} ({(now_us - v) / 1000:.3f} ms ago)")
        elif isinstance(v, float):
            lines.append(f"    {name}: {v:.4f}")
        else:
            lines.append(f"    {name}: {v}")
    return "\n".join(lines)


class HostRun:
    """A driver on a minimal platform whose kernel follows the wall clock.

    ``clock`` (seconds, monotonic) and ``sleep`` are parameters so that a test can drive the
    loop with a fake clock; the defaults are ``time.monotonic`` and ``time.sleep``.
    """

    def __init__(self, driver_name: str, handle: Any, bus_number: int,
                 kernel: Kernel | None = None, out: TextIO | None = None,
                 clock: Callable[[], float] = time.monotonic,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        if driver_name not in DRIVERS:
            raise ValueError(f"unknown driver {driver_name!r}; known: {', '.join(DRIVERS)}")
        self.kernel = kernel if kernel is not None else Kernel("host")
        self.platform = Platform(self.kernel)
        self.handle = handle
        self.out = out if out is not None else sys.stdout
        self.clock = clock
        self.sleep = sleep
        self.topic = DRIVERS[driver_name][1]
        self.driver = self._make(driver_name, handle, bus_number)
        self.messages: list[Any] = []

    def _make(self, name: str, handle: Any, bus_number: int) -> Any:
        p = self.platform
        if name == "hmc5883":
            from firmware.drivers.magnetometer.hmc5883 import Hmc5883Driver

            return Hmc5883Driver(p, handle.device(HMC5883_ADDR), bus=bus_number)
        from firmware.drivers.barometer.ms5611 import Ms5611Driver

        return Ms5611Driver(p, handle, bus=bus_number)

    def run(self, duration_s: float | None, print_hz: float = 1.0) -> int:
        """Start the driver and run until ``duration_s`` (None: until Ctrl-C)."""
        out = self.out
        if not self.driver.start():
            for _t, _sev, module, text in self.platform.dmesg:
                print(f"{module}: {text}", file=out)
            return 1
        k = self.kernel
        sub = Subscription(self.platform.orb, self.topic)
        start = self.clock()
        t0_ns = k.now_ns
        end_ns = None if duration_s is None else t0_ns + int(duration_s * 1e9)
        print_ns = int(1e9 / print_hz) if print_hz > 0 else None
        next_print = t0_ns + print_ns if print_ns else None
        last: Any = None
        try:
            while True:
                wall_ns = t0_ns + int((self.clock() - start) * 1e9)
                target = wall_ns if end_ns is None else min(wall_ns, end_ns)
                if target > k.now_ns:
                    k.run(target)
                while (msg := sub.update()) is not None:
                    self.messages.append(msg)
                    last = msg
                if next_print is not None and k.now_ns >= next_print and last is not None:
                    node = self.platform.orb.node(self.topic, 0)
                    print(format_listener(self.topic, 0, node.generation, last, k.now_us),
                          file=out, flush=True)
                    next_print += print_ns  # type: ignore[operator]
                if end_ns is not None and k.now_ns >= end_ns:
                    break
                wake = [t for t in (k.peek_ns(), next_print, end_ns) if t is not None]
                delay_ns = (min(wake) if wake else k.now_ns + 100_000_000) - wall_ns
                if delay_ns > 0:
                    self.sleep(delay_ns / 1e9)
        except KeyboardInterrupt:
            pass
        self.driver.stop()
        print(self.summary((k.now_ns - t0_ns) / 1e9), file=out, flush=True)
        return 0

    def summary(self, elapsed_s: float) -> str:
        n = len(self.messages)
        rate = n / elapsed_s if elapsed_s > 0 else 0.0
        h = self.handle
        host = f"host bus errors {getattr(h, 'errors', 0)}"
        if getattr(h, "last_error", None) is not None:
            host += f" (last: {h.last_error})"
        return (f"hostdrv: {n} {self.topic} messages in {elapsed_s:.2f} s ({rate:.1f} Hz), "
                f"driver errors {self.driver.error_count}, {host}")


def _emulated(driver_name: str, kernel: Kernel, seed: int) -> tuple[Any, int]:
    """The emulated chip behind the object a real host bus would give: (that object, bus)."""
    from peripherals.errors import rng_for
    from peripherals.physics import Environment

    env = Environment()
    if driver_name == "hmc5883":
        from board.i2c import I2cBus
        from hil.smbus_emulated import EmulatedSMBus
        from peripherals.hmc5883 import Hmc5883

        i2c = I2cBus(kernel, "I2C1", clock_hz=400_000)
        i2c.attach(HMC5883_ADDR, Hmc5883(kernel, env, rng_for(seed, "hmc5883")))
        return EmulatedSMBus(i2c), 1
    from board.spi import SpiBus
    from peripherals.ms5611 import Ms5611

    spi = SpiBus(kernel, "SPI1", pclk_hz=84_000_000)
    spi.attach("PD7", Ms5611(kernel, env, rng_for(seed, "ms5611")))
    return spi.device("PD7", mode=3, clock_hz=1_000_000), 1


def main(driver_name: str, i2c: int | None = None, spi: str | None = None,
         emulated: bool = False, duration_s: float | None = None, print_hz: float = 1.0,
         seed: int = 0, out: TextIO | None = None, err: TextIO | None = None,
         clock: Callable[[], float] = time.monotonic,
         sleep: Callable[[float], None] = time.sleep) -> int:
    """The ``hil hostdrv`` command; returns the exit status (see the module docstring)."""
    from hil.hostbus import SMBusHandle, SpiDevHandle

    err = err if err is not None else sys.stderr
    kind = DRIVERS.get(driver_name, ("", ""))[0]
    try:
        if not kind:
            raise BusOpenError(f"unknown driver {driver_name!r}; known: {', '.join(DRIVERS)}")
        kernel = Kernel("host")
        if emulated:
            raw, bus_number = _emulated(driver_name, kernel, seed)
        elif kind == "i2c":
            if i2c is None:
                raise BusOpenError(f"{driver_name} is an I2C driver: give --i2c N "
                                   f"(/dev/i2c-N) or --emulated")
            if not 0 <= i2c <= MAX_I2C_BUS:
                raise BusOpenError(f"I2C bus {i2c}: PX4 has work queues for I2C buses "
                                   f"0..{MAX_I2C_BUS}")
            raw, bus_number = open_i2c(i2c), i2c
        else:
            if spi is None:
                raise BusOpenError(f"{driver_name} is an SPI driver: give --spi BUS.CS "
                                   f"(/dev/spidevBUS.CS) or --emulated")
            try:
                b, cs = (int(x) for x in spi.split("."))
            except ValueError:
                raise BusOpenError(f"--spi wants BUS.CS (e.g. 0.0), got {spi!r}") from None
            raw, bus_number = open_spi(b, cs), b
    except BusOpenError as exc:
        print(f"hil hostdrv: {exc}", file=err)
        return 2
    handle = SMBusHandle(raw, bus_number) if kind == "i2c" else SpiDevHandle(raw)
    try:
        return HostRun(driver_name, handle, bus_number, kernel, out, clock, sleep).run(
            duration_s, print_hz)
    finally:
        close = getattr(raw, "close", None)  # the emulated SPI chip select has nothing to close
        if close is not None:
            close()
