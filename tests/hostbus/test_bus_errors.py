"""Bad input from a host bus is counted the way the drivers count bus errors, never a crash:
an ``OSError`` from smbus2 (a NAK is ENXIO/EREMOTEIO/EIO depending on the adapter) is a failed
transfer for the HMC5883 driver, a failed ``xfer2`` reads as an idle MISO for the MS5611 driver;
random bytes and errors from a misbehaving bus (fuzz target) never raise."""

from __future__ import annotations

import ctypes
import errno

from hypothesis import given
from hypothesis import strategies as st

from board.i2c import I2cBus
from board.kernel import Kernel
from firmware.drivers.magnetometer.hmc5883 import Hmc5883Driver
from firmware.platform import Platform
from firmware.platform.uorb import Subscription
from hil.hostbus import SMBusHandle, SpiDevHandle
from hil.smbus_emulated import EmulatedSMBus
from peripherals.errors import rng_for
from peripherals.hmc5883 import Hmc5883
from tests.fuzzing import fuzz
from tests.hostbus.rigs import MS, RecordingSMBus, RecordingSpiDev, environment, run_baro


def _mag_rig(smbus_for):
    k = Kernel("t")
    p = Platform(k)
    bus = I2cBus(k, "I2C1")
    bus.attach(0x1E, Hmc5883(k, environment(), rng_for(2, "hmc5883")))
    handle = SMBusHandle(smbus_for(EmulatedSMBus(bus)), 1)
    return k, p, Hmc5883Driver(p, handle.device(0x1E), bus=1), handle


def test_oserror_while_running_is_a_counted_bad_transfer() -> None:
    # Calls 40..99 fail as a Raspberry Pi's adapter reports a NAK (EREMOTEIO).
    k, p, drv, handle = _mag_rig(lambda emu: RecordingSMBus(emu, fail=lambda n: 40 <= n < 100))
    sub = Subscription(p.orb, "sensor_mag")
    assert drv.start()
    k.run(600 * MS)
    assert handle.errors == 60
    assert handle.last_error is not None and handle.last_error.errno == errno.EREMOTEIO
    assert drv.perf_bad_transfer.events == 60 and drv.error_count == 60
    assert "no ACK from 0x1E 10 times in a row" in p.dmesg_text()
    msg = sub.update()
    assert msg is not None and msg.error_count == 60       # and it publishes again after
    assert abs(msg.x - environment().mag_gauss[0]) < 0.01


def test_a_bus_that_always_fails_refuses_the_start_with_a_reason() -> None:
    k, p, drv, handle = _mag_rig(lambda emu: RecordingSMBus(emu, fail=lambda n: True,
                                                           fail_errno=errno.ENXIO))
    assert not drv.start()
    assert "no ACK at I2C address 0x1E" in p.dmesg_text()
    assert handle.errors == 10                       # PX4's retries on the first ID byte


def test_emulated_nak_reaches_the_driver_as_a_status() -> None:
    """The chip disappearing: EmulatedSMBus raises ENXIO, the adapter returns it, the driver
    counts it."""
    k, p, drv, handle = _mag_rig(lambda emu: emu)
    assert drv.start()
    k.run(100 * MS)
    bus = handle.smbus.bus
    chip = bus.detach(0x1E)
    k.run(k.now_ns + 50 * MS)
    assert handle.errors > 0 and handle.last_error.errno == errno.ENXIO
    assert drv.perf_bad_transfer.events == handle.errors
    bus.attach(0x1E, chip)
    k.run(k.now_ns + 300 * MS)                       # the driver retries and reads again
    assert drv.last_field_ga[0] == drv.last_field_ga[0]   # not NaN


def test_spidev_oserror_reads_as_idle_miso_and_the_driver_resets() -> None:
    def adapt(dev):
        # fail a stretch of transfers after the start (reset + 8 PROM words = 9)
        return SpiDevHandle(RecordingSpiDev(dev, fail=lambda n: 20 <= n < 24))

    published, drv = run_baro(adapt)
    assert drv.spi.errors == 4
    assert drv.perf_bad_transfer.events >= 1 and drv.perf_reset.events >= 1
    assert published                                  # recovered after the reset


class _MisbehavingSMBus:
    """Answers the probe from the chip, then follows a script: an OSError or random bytes."""

    def __init__(self, emu: EmulatedSMBus, script: list[tuple[int, bytes]]) -> None:
        self.emu = emu
        self.script = script
        self.n = 0

    def i2c_rdwr(self, *msgs) -> None:
        self.n += 1
        if self.n <= 3 or not self.script:
            self.emu.i2c_rdwr(*msgs)
            return
        err, data = self.script[(self.n - 4) % len(self.script)]
        if err:
            raise OSError(err, "fuzzed")
        for m in msgs:
            if m.flags & 1:
                chunk = (data * (m.len // max(1, len(data)) + 1))[:m.len] if data else b""
                ctypes.memmove(m.buf, chunk.ljust(m.len, b"\0"), m.len)

    def write_quick(self, addr: int) -> None:
        raise OSError(errno.ENXIO, "fuzzed")

    def close(self) -> None:
        pass


@fuzz(examples=200)
@given(script=st.lists(st.tuples(st.sampled_from([0, 0, 0, errno.EIO, errno.ENXIO,
                                                  errno.EREMOTEIO, errno.ETIMEDOUT, 0x7FFF]),
                                 st.binary(max_size=8)), min_size=1, max_size=30))
def test_random_bus_answers_never_crash_the_driver(script) -> None:
    k, p, drv, handle = _mag_rig(lambda emu: _MisbehavingSMBus(emu, script))
    assert drv.start()
    k.run(60 * MS)
    assert drv.running
    # Every host error is one bad transfer, counted once.
    assert drv.perf_bad_transfer.events == handle.errors
    assert drv.error_count >= handle.errors
