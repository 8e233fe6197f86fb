"""The GPS's UTC at power on is configuration: log files are named from it.

``hil fly`` passes the host's UTC (hil.system.SystemConfig.gps_utc_start_ns) so that every run's
logs get distinct names, as on a real vehicle; everything else keeps the fixed epoch so that a
seed gives byte-identical logs.
"""

import datetime as dt

import pytest

from hil.system import SystemConfig, build_system
from peripherals.ublox.solution import START_UTC_NS

NS_PER_S = 1_000_000_000


def _first_log_name(tmp_path, gps_utc_start_ns):
    """Boot the FMU until the GPS has a fix, then open a log as arming would (SDLOG_MODE 0)."""
    orch, _dev = build_system(SystemConfig(out_dir=str(tmp_path), mode="local",
                                           gps_utc_start_ns=gps_utc_start_ns))
    with orch:
        orch.run(duration_ns=4 * NS_PER_S)  # boot, GPS configured, first fix (TTFF 2 s)
        module = orch.handles["fmu"].endpoint.board.system.modules.get("logger")
        path = module.logger.start_log()
        module.logger.stop_log()
    return path.relative_to(tmp_path / "sd")


@pytest.fixture(scope="module")
def default_name(tmp_path_factory):
    return _first_log_name(tmp_path_factory.mktemp("default"), None)


def test_default_epoch_is_unchanged(default_name):
    start = dt.datetime.fromtimestamp(START_UTC_NS // NS_PER_S, dt.UTC)
    assert start == dt.datetime(2024, 6, 1, 12, 0, 0, tzinfo=dt.UTC)
    assert default_name.parent.name == "2024-06-01"
    assert default_name.name.startswith("12_00_0")  # a few seconds after power on


def test_a_different_epoch_names_the_log_after_it(tmp_path, default_name):
    epoch = dt.datetime(2031, 3, 4, 5, 6, 7, tzinfo=dt.UTC)
    name = _first_log_name(tmp_path, int(epoch.timestamp()) * NS_PER_S)
    assert name != default_name
    assert name.parent.name == "2031-03-04"
    assert name.name.startswith("05_06_1")  # 2031-03-04 05:06:07 + ~4 s of boot and fix
