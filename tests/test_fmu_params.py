"""Parameters on the FMU: they survive a reboot through the FRAM's host file, and a corrupted
FRAM image gives the defaults with a clear message."""

import pytest

from fmu.board import FmuV2Board
from tests.helpers import terminates

BOOTED = 1_500_000_000


def boot(tmp_path, **kw):
    b = FmuV2Board(seed=1, fram_path=str(tmp_path / "fram.bin"), sd_root=None, **kw)
    b.kernel.run(BOOTED)
    return b


def test_parameters_survive_a_reboot_through_fram(tmp_path):
    b = boot(tmp_path)
    assert b.ctl_shell("param set SDLOG_PROFILE 17")[0] == 0
    assert b.ctl_shell("param save")[0] == 0
    b.devices["fram"].close()
    again = boot(tmp_path)  # a new board on the same FRAM file: a power cycle
    assert again.ctl_shell("param get SDLOG_PROFILE")[1].strip() == "17"
    assert any("parameters loaded from slot" in line[3] for line in again.platform.dmesg)


def test_corrupted_fram_gives_defaults_and_says_so(tmp_path):
    image = bytearray(16384)
    image[0:4] = b"\x00\x10\x00\x00"  # a document length the data cannot back
    image[4:16] = b"garbage here"
    (tmp_path / "fram.bin").write_bytes(bytes(image))
    b = boot(tmp_path)
    errors = [line[3] for line in b.platform.dmesg if line[1] <= 3 and line[2] == "param"]
    assert errors and "corrupt" in errors[0] and "defaults loaded" in errors[0]
    assert b.ctl_shell("param get SDLOG_PROFILE")[1].strip() == "1"  # the default
    assert b.ctl_shell("ver all")[0] == 0  # and the board runs on


def test_the_mpu6000_reads_its_fifo_at_imu_gyro_ratemax(tmp_path):
    # As PX4's gyro front end hands IMU_GYRO_RATEMAX to the driver's ConfigureSampleRate: the
    # default 400 Hz is 20 records every 2.5 ms; 1000 Hz (a reboot later) eight every 1 ms.
    b = boot(tmp_path)
    status = b.ctl_shell("mpu6000 status")[1]
    assert "FIFO read every 2500 us (400.0 Hz, 20 records)" in status, status
    assert b.ctl_shell("param set IMU_GYRO_RATEMAX 1000")[0] == 0
    assert b.ctl_shell("param save")[0] == 0
    b.devices["fram"].close()
    again = boot(tmp_path)
    assert "FIFO read every 1000 us (1000.0 Hz, 8 records)" in again.ctl_shell("mpu6000 status")[1]


def test_a_twelve_byte_fram_image_boots_with_defaults(tmp_path):
    # A STRING element of length -7 at offset 0 used to hang the boot for ever (the loader
    # decoded a bare document when neither slot was valid, and the decoder looped).
    (tmp_path / "fram.bin").write_bytes(bytes.fromhex("0c000000 02 41 00 f9ffffff 00"))
    with terminates(60.0):
        b = boot(tmp_path)
    errors = [line[3] for line in b.platform.dmesg if line[1] <= 3 and line[2] == "param"]
    assert errors and "defaults loaded" in errors[0]
    assert b.ctl_shell("param get SDLOG_PROFILE")[1].strip() == "1"


def test_cli_param_values_beyond_float32_are_refused_before_anything_runs(capsys):
    from hil.cli import _parse_params, main

    with pytest.raises(ValueError, match="float32"):
        _parse_params(["MPC_XY_VEL_MAX=1e39"])
    with pytest.raises(ValueError, match="unknown parameter"):
        _parse_params(["NO_SUCH_PARAM=1"])
    with pytest.raises(ValueError, match="int32"):
        _parse_params(["SDLOG_PROFILE=1,4294967296"])
    assert _parse_params(["MPC_XY_VEL_MAX=5,7.5", "SDLOG_PROFILE=3"]) == \
        {"MPC_XY_VEL_MAX": [5, 7.5], "SDLOG_PROFILE": [3]}
    status = main(["scenario", "hil/scenarios/library/battery_dying.yaml",
                   "--param", "MPC_XY_VEL_MAX=1e39"])
    err = capsys.readouterr().err
    assert status == 2 and "float32" in err and "Traceback" not in err
