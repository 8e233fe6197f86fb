"""The TP100 driver and its shell module: the example driver of docs/driver_guide.md.

PX4's state-machine shape (its bmp388, icm42688p and ms5611 drivers): every step ends by
scheduling the next run of the work item, nothing waits in a loop.

    RESET ──► WAIT_FOR_RESET ──► CONFIGURE ──► READ ◄─┐
      ▲            │ (timeout)       │ (bad reg)   │    │ every 20 ms: collect the
      └────────────┴─────────────────┴─────────────┘    │ conversion started last run,
                  (10 failures in a row)            └───┘ start the next one

Errors are results: a NAK is a status from ``transfer``, counted in ``perf_bad_transfer`` and
``error_count``; a conversion not ready when collected is counted in ``perf_not_ready``; a
control register that does not read back what was written is a bad register and a reset.
Warnings go to dmesg at most once per second, with the count of those held back.
"""

from __future__ import annotations

import enum
from typing import TYPE_CHECKING, Final

from firmware.drivers.device import BUS_TYPE_I2C, DeviceId, I2cDeviceHandle, SensorDriver
from firmware.drivers.modules import DriverModule
from firmware.platform import Platform
from firmware.platform.perf import PC_COUNT
from firmware.platform.uorb import Publication

if TYPE_CHECKING:
    from board.protocols import BoardHardware
    from board.specs import DevicePlace
    from firmware.platform.params import Params

# <guide:driver-constants>
WHO_AM_I: Final = 0x00
CTRL: Final = 0x01
STATUS: Final = 0x02
WHO_AM_I_VALUE: Final = 0xB1
CTRL_SOFT_RST: Final = 1 << 7
CTRL_OSR_4X: Final = 2 << 1
CTRL_START: Final = 1 << 0
STATUS_DRDY: Final = 1 << 0

DRV_BARO_DEVTYPE_TP100: Final = 0xF1   # a device type of our own (PX4's drv_sensor.h list)
INTERVAL_US: Final = 20_000            # 50 Hz; a conversion at OSR 4x takes 8 ms
RESET_WAIT_US: Final = 2_000           # the chip NAKs for 1 ms after SOFT_RST
RESET_TIMEOUT_US: Final = 100_000
RETRY_US: Final = 100_000              # after giving up, try a reset again this much later
PROBE_TRIES: Final = 3
MAX_FAILURES: Final = 10               # in a row, then reset
LOG_INTERVAL_US: Final = 1_000_000     # at most one warning per second
# </guide:driver-constants>


# <guide:driver-decode>
def decode(data: bytes) -> tuple[float, float] | str:
    """STATUS, PRESS (3 bytes) and TEMP (2) as read in one burst from 0x02: ``(pressure_pa,
    temperature_c)``, or why the bytes are no sample (a result, never an exception)."""
    if len(data) != 6:
        return f"{len(data)} bytes, expected 6"
    if not data[0] & STATUS_DRDY:
        return "not ready"
    pressure_pa = int.from_bytes(data[1:4], "big") / 64
    temperature_c = int.from_bytes(data[4:6], "big", signed=True) / 100
    return pressure_pa, temperature_c
# </guide:driver-decode>


# <guide:driver-class>
class State(enum.Enum):
    RESET = 0
    WAIT_FOR_RESET = 1
    CONFIGURE = 2
    READ = 3


class Tp100Driver(SensorDriver):
    """Reads a TP100 through ``i2c`` (the handle at the spec's address) and publishes
    ``sensor_baro`` at 50 Hz."""

    def __init__(self, platform: Platform, i2c: I2cDeviceHandle, bus: int,
                 name: str = "tp100") -> None:
        super().__init__(platform, name, f"wq:I2C{bus}")   # PX4: one work queue per bus
        self.i2c = i2c
        self.device_id = DeviceId(BUS_TYPE_I2C, bus, i2c.addr, DRV_BARO_DEVTYPE_TP100).value
        self.perf_not_ready = self.perf_alloc(PC_COUNT, "not ready")
        self.perf_reset = self.perf_alloc(PC_COUNT, "reset")
        self.state = State.RESET
        self.samples = 0
        self.failures = 0               # in a row
        self._reset_us = 0
        self._measuring = False         # a conversion was started by the last run
        self._log_us = -LOG_INTERVAL_US
        self._held_back = 0
        self._pub: Publication | None = None
        self._msg = platform.orb.new("sensor_baro", device_id=self.device_id)
    # </guide:driver-class>

    # <guide:driver-bus>
    # -- the bus: errors are results ---------------------------------------------------------

    def _read(self, reg: int, n: int) -> bytes | None:
        status, data = self.i2c.transfer(bytes((reg,)), n)
        if status:
            self._failed(f"read of 0x{reg:02X}: no ACK ({status})")
            return None
        return data

    def _write(self, reg: int, value: int) -> bool:
        status, _ = self.i2c.transfer(bytes((reg, value)))
        if status:
            self._failed(f"write of 0x{reg:02X}: no ACK ({status})")
        return status == 0

    def _failed(self, why: str) -> None:
        self.perf_bad_transfer.count()
        self.error_count += 1
        self.failures += 1
        self._warn(why)

    def _warn(self, text: str) -> None:
        """A warning in dmesg, at most one per LOG_INTERVAL_US: a chip that is gone must not
        flood the log (and the MAVLink link behind it) at 50 Hz."""
        now = self.platform.time_us()
        if now - self._log_us < LOG_INTERVAL_US:
            self._held_back += 1
            return
        more = f" (+{self._held_back} more)" if self._held_back else ""
        self.platform.warn(self.name, text + more)
        self._log_us, self._held_back = now, 0
    # </guide:driver-bus>

    # <guide:driver-probe>
    # -- probe and start (the shell module calls try_start) ----------------------------------

    def probe(self) -> str | None:
        for _ in range(PROBE_TRIES):                # PX4 retries I2C transfers while probing
            status, data = self.i2c.transfer(bytes((WHO_AM_I,)), 1)
            if status == 0:
                if data[0] != WHO_AM_I_VALUE:
                    return f"WHO_AM_I 0x{data[0]:02X}, expected 0x{WHO_AM_I_VALUE:02X}"
                return None
        return f"no ACK at I2C address 0x{self.i2c.addr:02X} ({PROBE_TRIES} tries)"

    def _start(self) -> None:
        self._pub = self.advertise_multi("sensor_baro")   # the module's: freed at stop
        self.state = State.RESET
        self.schedule_now()
    # </guide:driver-probe>

    # <guide:driver-run>
    # -- the state machine -------------------------------------------------------------------

    def run(self) -> None:
        if not self.running:
            return
        now = self.platform.time_us()
        if self.state is State.RESET:
            self.perf_reset.count()
            self._measuring, self.failures = False, 0
            if not self._write(CTRL, CTRL_SOFT_RST):
                self.schedule_delayed(RETRY_US)       # nobody there: try again later
                return
            self._reset_us = now
            self.state = State.WAIT_FOR_RESET
            self.schedule_delayed(RESET_WAIT_US)      # never busy-wait: come back later
        elif self.state is State.WAIT_FOR_RESET:
            ident = self._read(WHO_AM_I, 2)           # WHO_AM_I and CTRL
            if ident == bytes((WHO_AM_I_VALUE, 0x00)):
                self.state = State.CONFIGURE
                self.schedule_now()
            elif now - self._reset_us > RESET_TIMEOUT_US:
                got = "no answer" if ident is None else f"WHO_AM_I 0x{ident[0]:02X}"
                self._warn(f"reset failed: {got}, retrying")
                self.state = State.RESET
                self.schedule_delayed(RETRY_US)
            else:
                self.schedule_delayed(RESET_WAIT_US)
        elif self.state is State.CONFIGURE:
            self._write(CTRL, CTRL_OSR_4X)
            if self._read(CTRL, 1) == bytes((CTRL_OSR_4X,)):
                self.state = State.READ
                self.schedule_now()
            else:
                self.perf_bad_register.count()
                self.state = State.RESET
                self.schedule_delayed(RETRY_US)
        else:
            self._read_cycle()

    def _read_cycle(self) -> None:
        self.perf_interval.count()
        self.perf_cycle.begin()
        if self._measuring:
            self._collect()
        if self.failures >= MAX_FAILURES:
            self._warn(f"{self.failures} failures in a row, resetting")
            self.state = State.RESET
            self.schedule_delayed(RETRY_US)
        else:
            self._measuring = self._write(CTRL, CTRL_OSR_4X | CTRL_START)
            self.schedule_delayed(INTERVAL_US)
        self.perf_cycle.end()

    def _collect(self) -> None:
        t_sample_us = self.platform.time_us()
        data = self._read(STATUS, 6)
        if data is None:
            return
        sample = decode(data)
        if isinstance(sample, str):                   # "not ready": counted, not published
            self.perf_not_ready.count()
            self.error_count += 1
            self.failures += 1
            return
        self.failures = 0
        self.samples += 1
        msg = self._msg
        msg.timestamp_sample = t_sample_us
        msg.pressure, msg.temperature = sample
        msg.error_count = self.error_count
        msg.timestamp = self.platform.time_us()
        assert self._pub is not None
        self._pub.publish(msg)
    # </guide:driver-run>

    def status(self) -> str:
        return "\n".join([super().status(), "  " + self.perf_not_ready.summary(),
                          "  " + self.perf_reset.summary(),
                          f"  state {self.state.name}, {self.samples} samples, "
                          f"last {self._msg.pressure:.1f} Pa {self._msg.temperature:.2f} degC"])


# <guide:driver-module>
class Tp100Module(DriverModule):
    """``tp100 start|stop|status``: the driver for the TP100 the board's spec puts on a bus."""

    NAME = "tp100"
    DESCRIPTION = "TP100 example barometer (docs/driver_guide.md)"

    @classmethod
    def build(cls, platform: Platform, hw: BoardHardware, place: DevicePlace,
              opts: dict[str, str | bool], params: Params | None) -> Tp100Driver:
        return Tp100Driver(platform, hw.i2c[place.bus].device(place.address),
                           bus=place.bus_number, name=place.name)
# </guide:driver-module>
