"""FMU chip and CPU faults: a drifting sensor bias, a greedy work item, an FRAM whose write
enable fails (parameter save reports it and loses nothing)."""

from __future__ import annotations

import pytest

from fmu.board import BOOT_TO_SENSORS_NS, FmuV2Board
from hil.turntable import Turntable

S = 1_000_000_000
MS = 1_000_000


def _sensors_board(seed: int = 3) -> FmuV2Board:
    board = FmuV2Board(seed=seed, firmware="sensors")
    Turntable(board.kernel, board.env, alt_m=488.0)
    board.kernel.run(BOOT_TO_SENSORS_NS + S)
    return board


def _mean_gyro_x(board, ms: int = 200) -> float:
    node = board.drivers["mpu6000"]._pub_gyro.node
    xs = []
    for _ in range(ms):
        board.kernel.run_for(MS)
        xs.append(node.last.x)
    return sum(xs) / len(xs)


def test_bias_drift_ramps_at_the_stated_rate_and_stops_where_it_is():
    board = _sensors_board()
    m0 = _mean_gyro_x(board)
    board.call("sensor_drift", "mpu6000", (0.05, 0.0, 0.0))     # rad/s per second
    board.kernel.run_for(2 * S)
    m1 = _mean_gyro_x(board)                                    # centred 2.1 s after the start
    assert m1 - m0 == pytest.approx(0.05 * 2.1, abs=0.01)
    board.call("sensor_drift", "mpu6000", (0.0, 0.0, 0.0))
    held = board.devices["mpu6000"].faults.bias_step[0]
    board.kernel.run_for(S)
    assert board.devices["mpu6000"].faults.bias_step[0] == held
    with pytest.raises(ValueError, match="no device"):
        board.call("sensor_drift", "bmi088", (1.0, 0.0, 0.0))


def _latency_us(board, ms: int = 300) -> float:
    node = board.drivers["mpu6000"]._pub_gyro.node
    lat = []
    for _ in range(ms):
        board.kernel.run_for(MS)
        m = node.last
        lat.append(m.timestamp - m.timestamp_sample)
    return sum(lat) / len(lat)


def test_a_greedy_item_on_the_spi1_queue_makes_the_imu_driver_run_late():
    board = _sensors_board()
    calm = _latency_us(board)
    board.call("cpu_load", "wq:SPI1", 0.9, 2000)        # 1.8 ms of every 2 ms
    loaded = _latency_us(board)
    assert loaded > calm + 100, (calm, loaded)   # the newest sample waits for the hog
    board.call("cpu_load", "wq:SPI1", 0.0)
    board.kernel.run_for(50 * MS)
    assert _latency_us(board) < calm + 100
    with pytest.raises(ValueError, match="no work queue"):
        board.call("cpu_load", "wq:nowhere", 0.5)


def test_fram_write_enable_failure_makes_param_save_fail_and_keeps_what_was_saved(tmp_path):
    fram = str(tmp_path / "fram.bin")
    board = FmuV2Board(seed=1, fram_path=fram, sd_root=str(tmp_path / "sd"),
                       params={"SYS_AUTOSTART": 4011}, exclude=("gps",))
    board.kernel.run(BOOT_TO_SENSORS_NS + S)
    assert board.call("shell", "param set MIS_TAKEOFF_ALT 7.5")[0] == 0
    assert board.call("shell", "param save")[0] == 0
    board.call("fault", "fram", "write_fail", True)
    assert board.call("shell", "param set MIS_TAKEOFF_ALT 9.5")[0] == 0
    status, out = board.call("shell", "param save")
    assert status != 0
    errors = [t for _, sev, mod, t in board.platform.dmesg if sev <= 3]
    assert any("write enable latch did not set" in t for t in errors)
    assert any("failed" in t for t in errors)
    # the chip kept the last good save: a fresh load gets 7.5 back
    board.call("fault", "fram", "write_fail", False)
    assert board.call("shell", "param load")[0] == 0
    assert board.call("shell", "param show MIS_TAKEOFF_ALT")[1].count("7.5") == 1
