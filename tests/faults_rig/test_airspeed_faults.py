"""The airspeed sensor's catalogue faults on an in-process FMU variant carrying the MS4525DO:
blocked pitot (stuck, zero), stale conversions, an I2C NAK storm on the external bus, and the
generic sensor kinds that reach it (and the one that cannot: it has no identity register)."""

from __future__ import annotations

import pytest

from fmu.board import BOOT_TO_SENSORS_NS, FmuV2Board
from board.specs import FMU_V2, MS4525DO_AIRSPEED
from hil.faults import BoardRig, FaultError
from hil.turntable import Turntable

S = 1_000_000_000
MS = 1_000_000
SPEC = FMU_V2.with_device("I2C1", MS4525DO_AIRSPEED)


@pytest.fixture(scope="module")
def board() -> FmuV2Board:
    b = FmuV2Board(seed=8, firmware="sensors", spec=SPEC)
    Turntable(b.kernel, b.env)
    b.env.diff_pressure_pa = 150.0
    b.kernel.run(BOOT_TO_SENSORS_NS + S // 2)
    return b


def _dp(board: FmuV2Board):
    return board.platform.orb.node("differential_pressure", 0)


def test_a_stuck_pitot_holds_its_pressure_and_a_zero_one_reads_nothing(board):
    rig = BoardRig(board)
    af = rig.start("airspeed.pitot_blocked", "ms4525", {"mode": "stuck"}, duration_s=0.5)
    board.kernel.run_for(50 * MS)
    board.env.diff_pressure_pa = 60.0                      # the vehicle slows down
    board.kernel.run_for(200 * MS)
    assert _dp(board).last.differential_pressure_raw_pa == pytest.approx(150.0, abs=5.0)
    board.kernel.run_for(300 * MS)                         # the fault ends by itself
    assert not af.active
    board.kernel.run_for(50 * MS)
    assert _dp(board).last.differential_pressure_raw_pa == pytest.approx(60.0, abs=5.0)
    rig.start("airspeed.pitot_blocked", "ms4525", {"mode": "zero"}, duration_s=0.2)
    board.kernel.run_for(100 * MS)
    assert _dp(board).last.differential_pressure_raw_pa == pytest.approx(0.0, abs=5.0)
    assert board.drivers["ms4525_airspeed"].error_count == 0    # the driver cannot see it
    board.kernel.run_for(200 * MS)
    board.env.diff_pressure_pa = 150.0
    with pytest.raises(FaultError, match="mode must be 'stuck' or 'zero'"):
        rig.start("airspeed.pitot_blocked", "ms4525", {"mode": "iced"})


def test_stale_conversions_silence_the_driver_which_counts_them(board):
    rig = BoardRig(board)
    drv = board.drivers["ms4525_airspeed"]
    err0, n0 = drv.error_count, _dp(board).publish_count
    rig.start("airspeed.stale", "ms4525", duration_s=0.3)
    board.kernel.run_for(300 * MS)
    assert _dp(board).publish_count - n0 <= 1
    assert drv.error_count - err0 >= 25 and drv.perf_stale.events >= 25
    board.kernel.run_for(100 * MS)
    assert _dp(board).publish_count - n0 >= 5                 # conversions back


def test_an_i2c_nak_storm_on_the_external_bus_reaches_the_airspeed_sensor(board):
    rig = BoardRig(board)
    drv = board.drivers["ms4525_airspeed"]
    err0, n0 = drv.error_count, _dp(board).publish_count
    rig.start("bus.i2c_nak_storm", "fmu.I2C1", duration_s=0.2)
    board.kernel.run_for(200 * MS)
    assert _dp(board).publish_count - n0 <= 1
    assert drv.error_count - err0 >= 20
    assert any("no ACK from 0x28" in m[3] for m in board.ctl_dmesg()
               if m[2] == "ms4525_airspeed")
    board.kernel.run_for(100 * MS)
    assert _dp(board).publish_count - n0 >= 5
    assert _dp(board).last.error_count == drv.error_count


def test_generic_sensor_kinds_reach_it_but_not_the_identity_one(board):
    rig = BoardRig(board)
    from hil.faults import get_kind

    assert "ms4525" in get_kind("sensor.absent").targets_on(rig)
    assert "ms4525" not in get_kind("sensor.wrong_id").targets_on(rig)
    assert "ms4525" not in get_kind("sensor.drdy_stuck").targets_on(rig)
    assert get_kind("airspeed.stale").targets_on(rig) == ("ms4525",)
    n0 = _dp(board).publish_count
    rig.start("sensor.bias_step", "ms4525", {"x": 25.0}, duration_s=0.1)
    board.kernel.run_for(50 * MS)
    assert _dp(board).last.differential_pressure_raw_pa == pytest.approx(175.0, abs=5.0)
    board.kernel.run_for(100 * MS)
    assert _dp(board).publish_count > n0
