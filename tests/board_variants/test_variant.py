"""A board variant from the spec alone: one extra I2C device (a model written for the test, its
driver registered through the spec entry) and one device removed (the MS5611).

The extra device's driver starts from the spec, with no edit of the board, the module table or
the ROMFS; the removed device's model is not built and its driver neither started nor
registered; and the FMUv2's own spec is left as it was, so no other test sees the variant.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from fmu.board import BOOT_TO_SENSORS_NS, FmuV2Board
from board.specs import FMU_V2, I2cDevice, SpecError
from firmware import romfs
from firmware.platform.module import FMU_V2_MODULES, board_modules
from tests.board_variants.toybaro import ADDRESS, ToyBaro, ToyBaroDriver

GUIDE = Path(__file__).resolve().parents[2] / "docs" / "driver_guide.md"
S = 1_000_000_000


def guide_example() -> str:
    """The code of the guide's "Adding a device" example (between its markers)."""
    text = GUIDE.read_text()
    m = re.search(r"<!-- example: adding-a-device -->\s*```python\n(.*?)```", text, re.S)
    assert m, "docs/driver_guide.md lost its adding-a-device example"
    return m.group(1)


@pytest.fixture(scope="module")
def example() -> dict:
    """The guide's example, run as written: it builds the variant and runs it 1 s."""
    ns: dict = {}
    exec(compile(guide_example(), str(GUIDE), "exec"), ns)  # noqa: S102 - our own doc
    return ns


def test_the_extra_device_is_one_spec_entry_and_its_driver_starts_and_publishes(example):
    board = example["board"]
    assert isinstance(board.devices["toybaro"], ToyBaro)
    drv = board.drivers["toybaro"]
    assert isinstance(drv, ToyBaroDriver) and drv.running
    assert drv.device_id == example["SPEC"].place("toybaro").bus_number << 3 | 1 | ADDRESS << 8 \
        | 0xF0 << 16  # I2C, bus 2, address 0x77 from the spec: nothing in the driver says so
    (node,) = [n for n in board.platform.orb.nodes() if n.name == "sensor_baro" and n.advertised]
    assert node.last is not None and node.last.device_id == drv.device_id
    # 20 ms interval from start at 0.3 s, run to 1 s: ~35 samples
    assert 30 <= node.publish_count <= 36
    assert node.last.pressure == pytest.approx(board.env.pressure_pa, abs=1 / 16)
    assert board.devices["toybaro"].samples == node.publish_count


def test_the_removed_device_is_not_built_and_its_driver_not_started(example):
    board = example["board"]
    assert "ms5611" not in board.devices and "ms5611" not in board.drivers
    started = {mod for _, _, mod, text in board.platform.dmesg if text == "started"}
    assert started == {"mpu6000", "l3gd20", "lsm303d", "hmc5883", "gps", "toybaro"}
    assert not [line for line in board.platform.dmesg if line[1] <= 3], board.platform.dmesg


def test_the_variant_registers_its_drivers_and_the_fmu_v2_is_unchanged(example):
    spec = example["SPEC"]
    table = board_modules(spec)
    assert table["toybaro"] == "tests.board_variants.toybaro:ToyBaroModule"
    assert "ms5611" not in table
    assert set(table) - {"toybaro"} == set(FMU_V2_MODULES) - {"ms5611"}
    lines = romfs.board_sensor_lines(spec)
    assert lines == ["mpu6000 start", "l3gd20 start", "lsm303d start", "hmc5883 start -X",
                     "toybaro start", "gps start -d /dev/ttyS3"]
    # the product's spec and table are what they were
    assert "toybaro" not in FMU_V2_MODULES and "ms5611" in FMU_V2_MODULES
    assert romfs.board_sensor_lines(FMU_V2)[0] == "mpu6000 start"
    assert romfs.board_sensor_lines(None) == romfs.board_sensor_lines(FMU_V2)


def test_a_variant_that_cannot_be_built_says_why():
    dev = I2cDevice("toy2", "tests.board_variants.toybaro:ToyBaro", 0x1E, driver="toy2",
                    driver_class="tests.board_variants.toybaro:ToyBaroModule")
    with pytest.raises(SpecError, match="I2C1 address 0x1E used twice"):
        FMU_V2.with_device("I2C1", dev)
    with pytest.raises(SpecError, match="no I2C bus 'I2C9'"):
        FMU_V2.with_device("I2C9", dev)
    with pytest.raises(SpecError, match="driver 'nodriver' unknown"):
        FMU_V2.with_device("I2C2", I2cDevice("x", "hmc5883", 0x1E, driver="nodriver"))
    with pytest.raises(SpecError, match="driver hmc5883 named by both hmc5883 and x"):
        FMU_V2.with_device("I2C2", I2cDevice("x", "hmc5883", 0x1E, driver="hmc5883"))
    with pytest.raises(SpecError, match="no device 'nothing' to remove"):
        FMU_V2.without_device("nothing")


def test_the_variant_boots_with_its_drivers_from_rc_sensors():
    """Booted by rcS: rc.sensors starts the variant's drivers from its spec (the ROMFS file
    says ``@board_sensors``), the removed device's driver is no command at all."""
    spec = FMU_V2.with_device("I2C2", I2cDevice(
        "toybaro", "tests.board_variants.toybaro:ToyBaro", ADDRESS, driver="toybaro",
        driver_class="tests.board_variants.toybaro:ToyBaroModule")).without_device("ms5611")
    board = FmuV2Board(seed=1, spec=spec, sd_root=None)
    board.kernel.run(BOOT_TO_SENSORS_NS + S // 2)
    mods = board.system.modules
    assert mods.is_running("toybaro") and "ms5611" not in mods
    status, out = board.ctl_shell("ms5611 start")
    assert status == 127 and "ms5611: command not found" in out, out
    assert "toybaro start" in board.ctl_shell("cat /etc/init.d/rc.sensors")[1]
    status, out = board.ctl_shell("toybaro status")
    assert status == 0 and "publishes sensor_baro[0]" in out, out


def test_rc_sensors_of_the_fmu_v2_starts_what_the_hand_written_script_did():
    """The FMUv2's rc.sensors, expanded from its spec, is the script it replaced: same
    commands, same order (the barometer first), so the default flight is unchanged."""
    text = romfs.expand((romfs.ROMFS_ROOT / "init.d" / "rc.sensors").read_text(), None)
    starts = [line for line in text.splitlines() if line and not line.startswith("#")]
    assert starts == ["ms5611 start", "mpu6000 start", "l3gd20 start", "lsm303d start",
                      "hmc5883 start -X", "gps start -d /dev/ttyS3", "sensors start"]
    assert text.splitlines()[7] == "l3gd20 start"  # line 8, as error messages name it
