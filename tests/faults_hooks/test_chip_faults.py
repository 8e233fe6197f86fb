"""Chip-level faults of the FMU's sensors: a noise burst, an MPU6000 FIFO that overflows at
every read, an identity that goes wrong at the next reset, and a brown-out of the sensor rail.
Each is checked at the chip (what the bus returns) and at the driver (what PX4's driver does)
on a board running only its sensor drivers."""

from __future__ import annotations

import statistics

import pytest

from fmu.board import BOOT_TO_SENSORS_NS, FmuV2Board
from hil.faults import FaultError, get_kind
from hil.turntable import Turntable

S = 1_000_000_000
MS = 1_000_000


def _sensors_board(seed: int = 3) -> FmuV2Board:
    board = FmuV2Board(seed=seed, firmware="sensors")
    Turntable(board.kernel, board.env, alt_m=488.0)
    board.kernel.run(BOOT_TO_SENSORS_NS + S)
    return board


def _spread(board: FmuV2Board, topic: str, instance: int, field: str, n: int,
            step_ns: int = MS) -> float:
    node = board.platform.orb.node(topic, instance)
    xs = []
    for _ in range(n):
        board.kernel.run_for(step_ns)
        xs.append(getattr(node.last, field))
    return statistics.pstdev(xs)


def _count(board: FmuV2Board, topic: str, instance: int = 0) -> int:
    return board.platform.orb.node(topic, instance).publish_count


@pytest.mark.parametrize("device, output, topic, inst, field, sigma, expect, step", [
    # the MPU6000 accel ticks at 1 kHz and repeats in the 8 kHz FIFO: one sample a publication
    ("mpu6000", "accel", "sensor_accel", 0, "x", 3.0, 3.0, MS),
    # its gyro: eight 8 kHz samples averaged per publication
    ("mpu6000", "gyro", "sensor_gyro", 0, "x", 0.5, 0.5 / 8 ** 0.5, MS),
    ("l3gd20", "gyro", "sensor_gyro", 1, "x", 0.5, 0.5, MS),
    ("ms5611", "pressure", "sensor_baro", 0, "pressure", 50.0, 50.0, 10 * MS),
    ("hmc5883", "mag", "sensor_mag", 1, "x", 0.2, 0.2, 10 * MS),
])
def test_a_noise_burst_adds_its_sigma_to_the_chip_output_and_goes_away(
        device, output, topic, inst, field, sigma, expect, step):
    board = _sensors_board()
    calm = _spread(board, topic, inst, field, 150, step)
    board.call("fault", device, "noise", {output: sigma})
    noisy = _spread(board, topic, inst, field, 300, step)
    board.call("fault", device, "noise", None)
    after = _spread(board, topic, inst, field, 150, step)
    assert calm < 0.2 * expect
    assert noisy == pytest.approx(expect, rel=0.25)
    assert after < 0.2 * expect
    assert board.drivers[device].error_count == 0 or device == "ms5611"  # data, not errors


def test_the_noise_of_one_output_leaves_the_other_alone():
    board = _sensors_board()
    gyro0 = _spread(board, "sensor_gyro", 0, "x", 150)
    board.call("fault", "mpu6000", "noise", {"accel": 5.0})
    assert _spread(board, "sensor_gyro", 0, "x", 150) < 2 * gyro0 + 1e-3


def test_a_fifo_overflow_storm_makes_the_driver_reset_its_fifo_every_cycle():
    board = _sensors_board()
    drv = board.drivers["mpu6000"]
    ovf0, err0, pubs0 = drv.perf_fifo_overflow.events, drv.error_count, drv.publications
    board.call("fault", "mpu6000", "fifo_overflow", True)
    board.kernel.run_for(200 * MS + 400_000)    # between two driver cycles
    # the chip, read on the bus: full at every look, FIFO_OFLOW set in INT_STATUS
    h = board.spi_handle("mpu6000")
    r = h.transfer(b"\xf2\x00\x00")            # FIFO_COUNTH | read
    assert (r[1] << 8) | r[2] == 1024
    assert h.transfer(b"\xba\x00")[1] & 0x10     # INT_STATUS | read: FIFO_OFLOW_INT
    overflows = drv.perf_fifo_overflow.events - ovf0
    assert overflows >= 150                      # about one per 1 ms cycle
    assert drv.error_count - err0 == overflows   # each one an error, seen by the voter
    assert drv.publications - pubs0 <= 1         # nothing valid to publish
    assert drv.perf_fifo_reset.events >= overflows
    board.call("fault", "mpu6000", "fifo_overflow", False)
    board.kernel.run_for(100 * MS)
    assert drv.publications - pubs0 >= 80        # back to 1 kHz
    assert drv.perf_fifo_overflow.events - ovf0 <= overflows + 1


def test_wrong_id_after_reset_waits_for_a_reset_and_the_driver_loses_the_chip():
    board = _sensors_board()
    drv = board.drivers["mpu6000"]
    board.call("fault", "mpu6000", "wrong_id_after_reset", 0x00)
    pubs = drv.publications
    board.kernel.run_for(300 * MS)               # periodic WHO_AM_I checks see 0x68
    assert drv.state == "fifo_read" and drv.publications - pubs >= 250
    board.call("sensor_rail", False)             # a power cycle of the chip
    board.kernel.run_for(20 * MS)
    board.call("sensor_rail", True)
    board.kernel.run_for(1500 * MS)
    assert drv.state != "fifo_read"
    texts = [m[3] for m in board.ctl_dmesg() if m[2] == "mpu6000"]
    assert any("reset failed" in t and "WHO_AM_I 0x00" in t for t in texts), texts
    pubs = drv.publications
    board.kernel.run_for(500 * MS)
    assert drv.publications == pubs              # lost
    # The defect cleared: the driver's next reset brings the chip back.
    board.call("fault", "mpu6000", "wrong_id_after_reset", None)
    board.kernel.run_for(1500 * MS)
    assert drv.state == "fifo_read" and drv.publications > pubs


def test_the_sensor_rail_brownout_silences_every_spi1_chip_and_they_come_back():
    board = _sensors_board()
    assert board.call("sensor_rail", False) == ["mpu6000", "l3gd20", "lsm303d", "ms5611"]
    for name in ("mpu6000", "l3gd20", "lsm303d"):
        who = {"mpu6000": 0x75, "l3gd20": 0x0F, "lsm303d": 0x0F}[name]
        h = board.spi_handle(name)
        assert h.transfer(bytes((0x80 | who, 0)))[1] == 0xFF, name   # MISO to its pull-up
    topics = [("sensor_gyro", 0), ("sensor_gyro", 1), ("sensor_accel", 0), ("sensor_accel", 1),
              ("sensor_baro", 0)]
    board.kernel.run_for(30 * MS)
    before = {t: _count(board, *t) for t in topics}
    mag_ext = _count(board, "sensor_mag", 1)
    board.kernel.run_for(50 * MS)
    assert {t: _count(board, *t) for t in topics} == before         # nothing from the rail
    assert _count(board, "sensor_mag", 1) > mag_ext                  # the GPS compass is not on it
    assert not board.devices["mpu6000"].powered
    board.call("sensor_rail", True)
    # The MPU6000 is deaf for 100 ms after power-on; the drivers re-initialise their chips.
    board.kernel.run_for(400 * MS)
    for t in topics:
        assert _count(board, *t) > before[t], t
    assert board.drivers["mpu6000"].state == "fifo_read"


def test_the_kinds_refuse_bad_targets_and_parameters():
    noise = get_kind("sensor.noise_burst")
    with pytest.raises(FaultError, match="no output 'mag'"):
        noise.start(None, "mpu6000", noise.check("mpu6000", {"output": "mag"}), 0)
    with pytest.raises(FaultError, match="sigma"):
        noise.start(None, "mpu6000", noise.check("mpu6000", {"sigma": -1.0}), 0)
    with pytest.raises(FaultError, match="target"):
        get_kind("sensor.fifo_overflow").check("l3gd20", {})
    with pytest.raises(FaultError, match="target"):
        get_kind("board.sensor_rail_brownout").check("io", {})
