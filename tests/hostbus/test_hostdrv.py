"""``hil hostdrv``: a driver on a host bus in real time. The command's path is the real one
(smbus2-API object, SMBusHandle, the driver on a minimal platform, listener-style output) with
the emulated chip behind the smbus2 API; a missing /dev/i2c-N is exit 2 with a message."""

from __future__ import annotations

import io
import os
import re

import pytest

from board.i2c import I2cBus
from board.kernel import Kernel
from hil import cli, hostdrv
from hil.hostbus import SMBusHandle
from hil.smbus_emulated import EmulatedSMBus
from peripherals.errors import rng_for
from peripherals.hmc5883 import Hmc5883
from tests.hostbus.rigs import environment, real_smbus_on


class FakeClock:
    """time.monotonic/time.sleep for the pacing loop: sleeping moves the clock."""

    def __init__(self) -> None:
        self.t = 100.0
        self.slept = 0.0

    def __call__(self) -> float:
        return self.t

    def sleep(self, dt: float) -> None:
        assert dt > 0
        self.t += dt
        self.slept += dt


def test_emulated_run_prints_listener_lines_and_a_summary() -> None:
    clock, out = FakeClock(), io.StringIO()
    rc = hostdrv.main("hmc5883", emulated=True, duration_s=0.5, print_hz=4.0, out=out,
                      clock=clock, sleep=clock.sleep)
    text = out.getvalue()
    assert rc == 0, text
    blocks = re.findall(r"TOPIC: sensor_mag instance 0 #(\d+)\n((?:    .*\n)+)", text)
    assert len(blocks) == 2                               # at 0.25 s and 0.5 s
    assert "    is_external: True" in blocks[0][1] and "    x: 0.2" in blocks[0][1]
    n = int(re.search(r"hostdrv: (\d+) sensor_mag messages in 0.50 s", text).group(1))
    assert 60 <= n <= 75                                  # 150 Hz less the bus time
    assert "driver errors 0, host bus errors 0" in text
    assert clock.slept == pytest.approx(0.5, abs=0.01)     # paced: it waited, not spun


def test_the_i2c_path_opens_smbus2_and_closes_it(monkeypatch) -> None:
    """``--i2c 1`` as on a Raspberry Pi: smbus2's own SMBus class opened on bus 1, only its
    I2C_RDWR ioctl answered by an emulated HMC5883L (which shares the run's kernel, as a real
    chip shares the wall clock)."""
    import smbus2

    k = Kernel("host")
    bus = I2cBus(k, "I2C1", clock_hz=400_000)
    bus.attach(0x1E, Hmc5883(k, environment(), rng_for(0, "hmc5883")))
    opened: list = []

    def smbus_factory(n: int):
        opened.append(n)
        opened.append(real_smbus_on(bus, monkeypatch))
        return opened[-1]

    monkeypatch.setattr(smbus2, "SMBus", smbus_factory)
    monkeypatch.setattr(hostdrv, "Kernel", lambda name: k)
    clock, out = FakeClock(), io.StringIO()
    rc = hostdrv.main("hmc5883", i2c=1, duration_s=0.3, print_hz=0, out=out, clock=clock,
                      sleep=clock.sleep)
    assert rc == 0, out.getvalue()
    assert opened[0] == 1 and opened[1].fd is None          # opened bus 1, closed at the end
    n = int(re.search(r"hostdrv: (\d+) sensor_mag messages", out.getvalue()).group(1))
    assert n >= 40


def test_ms5611_emulated_run() -> None:
    clock, out = FakeClock(), io.StringIO()
    rc = hostdrv.main("ms5611", emulated=True, duration_s=0.2, print_hz=0, out=out,
                      clock=clock, sleep=clock.sleep)
    assert rc == 0
    assert re.search(r"hostdrv: 1\d sensor_baro messages in 0.20 s", out.getvalue())


def test_no_chip_is_exit_1_with_the_driver_reason() -> None:
    k = Kernel("host")
    handle = SMBusHandle(EmulatedSMBus(I2cBus(k, "I2C1")), 1)   # nothing on the bus
    clock, out = FakeClock(), io.StringIO()
    run = hostdrv.HostRun("hmc5883", handle, 1, k, out, clock, clock.sleep)
    assert run.run(0.1) == 1
    assert "not starting: no ACK at I2C address 0x1E" in out.getvalue()


def _missing_i2c_bus() -> int:
    free = [n for n in range(5) if not os.path.exists(f"/dev/i2c-{n}")]
    assert free, "every /dev/i2c-0..4 exists here: this test needs one that does not"
    return free[0]


def test_missing_dev_i2c_is_a_clear_error(capsys) -> None:
    n = _missing_i2c_bus()
    assert cli.main(["hostdrv", "hmc5883", "--i2c", str(n)]) == 2
    err = capsys.readouterr().err
    assert f"hil hostdrv: /dev/i2c-{n} does not exist" in err and "Traceback" not in err


@pytest.mark.parametrize("argv, message", [
    (["hostdrv", "hmc5883"], "give --i2c N"),
    (["hostdrv", "hmc5883", "--i2c", "9"], "buses 0..4"),
    (["hostdrv", "ms5611", "--spi", "zero"], "BUS.CS"),
    (["hostdrv", "ms5611"], "give --spi BUS.CS"),
])
def test_bad_command_lines_are_exit_2(capsys, argv, message) -> None:
    assert cli.main(argv) == 2
    assert message in capsys.readouterr().err


def test_missing_spidev_is_a_clear_error(capsys) -> None:
    assert not os.path.exists("/dev/spidev0.0")
    assert cli.main(["hostdrv", "ms5611", "--spi", "0.0"]) == 2
    err = capsys.readouterr().err
    # spidev is not a dependency: either it is missing, or the device is
    assert ("spidev package is not installed" in err or "/dev/spidev0.0 does not exist" in err)
    assert "Traceback" not in err


@pytest.mark.paced
def test_hostdrv_command_in_real_time(capsys) -> None:
    assert cli.main(["hostdrv", "hmc5883", "--emulated", "--duration", "0.3",
                     "--print-hz", "5"]) == 0
    out = capsys.readouterr().out
    assert out.count("TOPIC: sensor_mag instance 0") == 1
    n = int(re.search(r"hostdrv: (\d+) sensor_mag messages in 0.30 s", out).group(1))
    assert n > 30
