"""The FMUv2 board boots its drivers and, held still on a turntable, reports the truth.

Every value reaches the topics through a real driver over the emulated buses: register-level
models on SPI1, SPI2, I2C1 and UART4.
"""

import math

import pytest

from fmu.board import BOOT_TO_SENSORS_NS, FmuV2Board
from hil.turntable import Turntable
from hil.world.atmosphere import isa_pressure_pa
from hil.world.magnetic import earth_field_ned_gauss
from common.truth import rotate_ned_to_body
from common.units import G0_M_S2

S = 1_000_000_000


@pytest.fixture(scope="module")
def still_board():
    board = FmuV2Board(seed=7, firmware="sensors")
    table = Turntable(board.kernel, board.env, roll_deg=10.0, pitch_deg=-5.0, yaw_deg=30.0,
                      alt_m=488.0)
    board.kernel.run(BOOT_TO_SENSORS_NS + 2 * S)
    start = {key: node.publish_count for key, node in board.platform.orb._nodes.items()}
    board.kernel.run(BOOT_TO_SENSORS_NS + 12 * S)
    counts = {key: node.publish_count - start.get(key, 0)
              for key, node in board.platform.orb._nodes.items()}
    return board, table, counts


def _instances(board, topic):
    return [(i, node) for (t, i), node in sorted(board.platform.orb._nodes.items())
            if t == topic and node.last is not None]


def test_every_driver_started(still_board):
    board, _, _ = still_board
    started = {mod for _, sev, mod, text in board.platform.dmesg if text == "started"}
    assert {"mpu6000", "l3gd20", "lsm303d", "ms5611", "hmc5883", "gps"} <= started
    assert not [line for line in board.platform.dmesg if line[1] <= 3], board.platform.dmesg


def test_accelerometers_report_gravity_at_the_attitude(still_board):
    board, _, _ = still_board
    expect = rotate_ned_to_body((0.0, 0.0, -G0_M_S2), math.radians(10), math.radians(-5),
                                math.radians(30))
    accels = _instances(board, "sensor_accel")
    assert len(accels) == 2  # MPU6000 and LSM303D
    for _, node in accels:
        m = node.last
        for got, want in zip((m.x, m.y, m.z), expect):
            assert got == pytest.approx(want, abs=0.35)  # noise + bias of an uncalibrated part


def test_gyros_report_zero_rate(still_board):
    board, _, _ = still_board
    gyros = _instances(board, "sensor_gyro")
    assert len(gyros) == 2  # MPU6000 and L3GD20
    for _, node in gyros:
        m = node.last
        assert max(abs(m.x), abs(m.y), abs(m.z)) < 0.05


def test_magnetometers_report_the_field(still_board):
    board, _, _ = still_board
    field_ned = earth_field_ned_gauss(47.397742, 8.545594, 488.0)
    expect = rotate_ned_to_body(field_ned, math.radians(10), math.radians(-5), math.radians(30))
    mags = _instances(board, "sensor_mag")
    assert len(mags) == 2  # LSM303D and the external HMC5883L
    for _, node in mags:
        m = node.last
        for got, want in zip((m.x, m.y, m.z), expect):
            assert got == pytest.approx(want, abs=0.03)


def test_barometer_reports_the_altitude_pressure(still_board):
    board, _, _ = still_board
    (_, node), = _instances(board, "sensor_baro")
    assert node.last.pressure == pytest.approx(isa_pressure_pa(488.0), abs=15.0)


def test_gps_has_a_3d_fix_at_the_location(still_board):
    board, _, _ = still_board
    (_, node), = _instances(board, "sensor_gps")
    m = node.last
    assert m.fix_type >= 3
    assert m.latitude_deg == pytest.approx(47.397742, abs=3e-5)
    assert m.longitude_deg == pytest.approx(8.545594, abs=3e-5)


def test_publication_rates(still_board):
    board, _, counts = still_board
    drv = board.drivers["mpu6000"]
    gyro_instance = next(i for i, n in _instances(board, "sensor_gyro")
                         if n.last.device_id == drv.device_id)
    rate = counts[("sensor_gyro", gyro_instance)] / 10.0
    assert rate == pytest.approx(drv.publish_rate_hz, rel=0.01)
    assert counts[("sensor_baro", 0)] / 10.0 == pytest.approx(75, rel=0.05)
    assert counts[("sensor_gps", 0)] / 10.0 == pytest.approx(5, rel=0.05)
