"""Registers and bits by name: the constants models and drivers use agree with the datasheet tables.

Models and drivers name registers and fields with plain ``Final`` ints (``USER_CTRL``,
``USER_CTRL_FIFO_RESET``) rather than raw numbers; ``peripherals.regs.check_names`` ties every
such constant to the model's register table, so a typo in either shows up here. The drivers keep
their own constants (as PX4's register headers do) and are checked against the same tables, and
the configuration they write, spelled in names, is still the bytes the reference sheet gives.
"""

from __future__ import annotations

import re
from pathlib import Path
from types import ModuleType

import pytest

import firmware.drivers.imu.l3gd20 as l3gd20_drv
import firmware.drivers.imu.lsm303d as lsm303d_drv
import firmware.drivers.imu.mpu6000 as mpu6000_drv
import firmware.drivers.imu.st_spi_driver as st_drv
import firmware.drivers.magnetometer.hmc5883 as hmc5883_drv
import peripherals.hmc5883 as hmc5883_model
import peripherals.l3gd20 as l3gd20_model
import peripherals.lsm303d as lsm303d_model
import peripherals.mpu6000.registers as mpu6000_regs
from peripherals.regs import Reg, RegisterMapError, check_names

ROOT = Path(__file__).resolve().parents[2]
MPU6000_TABLE = mpu6000_regs.mpu6000_registers(0x58, mpu6000_regs.SELF_TEST_TRIM)


@pytest.mark.parametrize("module, table, at_least", [
    (mpu6000_regs, MPU6000_TABLE, 40),
    (l3gd20_model, l3gd20_model.REGISTERS, 20),
    (lsm303d_model, lsm303d_model.REGISTERS, 25),
    (hmc5883_model, hmc5883_model.REGISTERS, 4),
    (mpu6000_drv, MPU6000_TABLE, 30),
    (l3gd20_drv, l3gd20_model.REGISTERS, 14),
    (lsm303d_drv, lsm303d_model.REGISTERS, 25),
    (st_drv, l3gd20_model.REGISTERS, 1),
    (st_drv, lsm303d_model.REGISTERS, 1),
    (hmc5883_drv, hmc5883_model.REGISTERS, 10),
], ids=lambda v: v.__name__ if isinstance(v, ModuleType) else "")
def test_module_constants_match_the_register_table(module: ModuleType, table: list[Reg],
                                                   at_least: int) -> None:
    assert check_names(vars(module), table, f"{module.__name__}.") >= at_least


def test_check_names_rejects_a_wrong_address_or_mask() -> None:
    with pytest.raises(RegisterMapError, match=r"USER_CTRL = 0x6B.*register USER_CTRL is 0x6A"):
        check_names({"USER_CTRL": 0x6B}, MPU6000_TABLE)
    with pytest.raises(RegisterMapError, match=r"USER_CTRL_FIFO_RESET = 0x08.*0x04"):
        check_names({"USER_CTRL_FIFO_RESET": 0x08}, MPU6000_TABLE)
    # A multi-bit field is its mask; names that are no register or field are not looked at.
    assert check_names({"GYRO_CONFIG_FS_SEL": 0x18, "GYRO_CONFIG_FS_SEL_2000DPS": 0x18,
                        "USER_CTRL": "not an int"}, MPU6000_TABLE) == 1


def _raw_register_uses(paths: list[Path], root: Path = ROOT) -> list[str]:
    """Register reads by raw address (``values[0x6A]``) and non-zero raw register writes
    (``write_reg(USER_CTRL, 0x14)``)."""
    raw = re.compile(r"(?:values|\bv)\[0x|_reg\(\w+, 0x(?!00\b)[0-9A-Fa-f]+\)")
    found = []
    for path in paths:
        for n, line in enumerate(path.read_text().splitlines(), 1):
            if raw.search(line):
                found.append(f"{path.relative_to(root)}:{n}: {line.strip()}")
    return found


def test_models_and_drivers_use_no_raw_register_addresses(tmp_path: Path) -> None:
    paths = [*sorted((ROOT / "peripherals").rglob("*.py")),
             *sorted((ROOT / "firmware" / "drivers").rglob("*.py"))]
    assert len(paths) > 20
    assert _raw_register_uses(paths) == []
    probe = tmp_path / "probe.py"  # the check itself finds both shapes, not a zero write
    probe.write_text("x = self.regs.values[0x6A]\nself.write_reg(USER_CTRL, 0x14)\n"
                     "self.write_reg(FIFO_EN, 0x00)\n")
    assert [line.split(": ", 1)[1] for line in _raw_register_uses([probe], tmp_path)] == [
        "x = self.regs.values[0x6A]", "self.write_reg(USER_CTRL, 0x14)"]


def test_l3gd20_driver_writes_px4s_configuration_bytes() -> None:
    # Reference sheet 2.8 step 3, and the register values the driver then checks.
    assert [v for _, v in l3gd20_drv.CONFIG_SEQUENCE] == [0x0F, 0x00, 0x08, 0x80, 0x00, 0x40,
                                                         0x00, 0xEF, 0xB0]
    assert {a: s for a, s, c in l3gd20_drv.CHECKED if s | c == 0xFF} == {
        0x20: 0xEF, 0x21: 0x00, 0x22: 0x08, 0x23: 0xB0, 0x24: 0x40, 0x2E: 0x00, 0x39: 0x08}


def test_lsm303d_driver_configuration_gives_the_sheets_register_values() -> None:
    # Reference sheet 3.7: set/clear applied to the chip's reset values.
    table = {r.addr: r for r in lsm303d_model.REGISTERS}
    result = {table[a].name: (table[a].reset & ~c & 0xFF) | s for a, s, c in lsm303d_drv.CONFIG}
    assert result == {"CTRL0": 0x40, "CTRL1": 0xAF, "CTRL2": 0x20, "CTRL5": 0xF0,
                      "CTRL6": 0x60, "CTRL7": 0x00, "FIFO_CTRL": 0x20 | 4}


def test_mpu6000_driver_configuration_in_names_is_the_same_bytes() -> None:
    assert [(s, c) for _, s, c in mpu6000_drv.REGISTER_CONFIG] == [
        (0x00, 0xFF), (0x00, 0x07), (0x18, 0xE0), (0x18, 0xE0), (0x78, 0x80), (0x80, 0x00),
        (0x01, 0x00), (0x50, 0x00), (0x01, 0x40)]
