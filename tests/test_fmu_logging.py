"""The FMU logs through rcS: a ULog on the emulated SD card that pyulog reads, with the board's
parameters and the sensor topics."""

import pyulog

from fmu.board import FmuV2Board
from hil.turntable import Turntable


def test_boot_log_has_the_board_parameters_and_sensors(tmp_path):
    (tmp_path / "sd").mkdir()
    b = FmuV2Board(seed=3, fram_path=str(tmp_path / "fram.bin"), sd_root=str(tmp_path / "sd"),
                   params={"SDLOG_MODE": 1, "SDLOG_PROFILE": 1 | 1 << 6})
    Turntable(b.kernel, b.env)
    b.kernel.run(3_000_000_000)
    status, _ = b.ctl_shell("param set SDLOG_DIRS_MAX 7")
    assert status == 0
    b.kernel.run(3_200_000_000)
    assert b.ctl_shell("logger stop")[0] == 0
    logs = sorted((tmp_path / "sd" / "log").rglob("*.ulg"))
    assert len(logs) == 1
    ulog = pyulog.ULog(str(logs[0]))
    params = b.system.params.values
    for name, value in ulog.initial_parameters.items():
        if name == "SDLOG_DIRS_MAX":
            continue
        assert value == params[name], name
    changed = [(name, value) for _t, name, value in ulog.changed_parameters]
    assert ("SDLOG_DIRS_MAX", 7) in changed
    names = {d.name for d in ulog.data_list}
    assert {"sensor_accel", "sensor_gyro", "sensor_baro", "sensor_mag"} <= names
    baro = ulog.get_dataset("sensor_baro").data["pressure"]
    assert 95_000 < baro.mean() < 96_200
