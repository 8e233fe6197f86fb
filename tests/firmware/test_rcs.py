"""The ROMFS startup: rcS picks the airframe from SYS_AUTOSTART, runs the SD card hooks and
starts the module set of that vehicle; missing modules are reported and the script goes on."""

import pytest

from firmware import romfs
from firmware.modules.system_params import PARAMS
from firmware.platform.module import FMU_V2_MODULES, ModuleBase
from firmware.platform.params import MemoryPartition, Params, ParamStorage
from firmware.shell import Shell
from firmware.system import System


def dummy(name):
    return type(f"Dummy_{name}", (ModuleBase,), {"NAME": name})


#: modules replaced by dummies (no board hardware in these tests)
DUMMIES = ("mpu6000", "sensors", "commander", "px4io", "fmu", "ekf2", "mc_att_control",
           "mc_pos_control", "logger", "dataman", "rc_update", "battery_status",
           "mc_rate_control", "fw_att_control", "fw_pos_control_l1",
           "mc_att_select")
#: modules made unavailable on purpose, to check that a missing module is reported and skipped
MISSING = ("l3gd20", "lsm303d", "ms5611", "hmc5883", "gps", "navigator", "land_detector",
           "mavlink")


class Board:
    def __init__(self, platform, sd_root, autostart=None, autoconfig=None, storage=None):
        params = Params(platform, PARAMS, storage)
        if autostart is not None:
            params.set("SYS_AUTOSTART", autostart)
        if autoconfig is not None:
            params.set("SYS_AUTOCONFIG", autoconfig)
        table = dict(FMU_V2_MODULES)
        table.update({n: dummy(n) for n in DUMMIES})
        table.update({n: f"firmware.not_in_this_build.{n}:Module" for n in MISSING})
        self.system = System(platform, params, modules=table, sd_root=sd_root)
        self.out = []
        self.shell = Shell(self.system, self.out.append)

    def boot(self):
        status = romfs.boot(self.shell)
        return status, "".join(self.out)

    @property
    def running(self):
        return set(self.system.modules.running())


@pytest.fixture
def sd(tmp_path):
    (tmp_path / "etc").mkdir()
    return tmp_path


def test_conditional_script_starts_a_different_module_set(platform):
    script = """
if param compare SYS_AUTOSTART 4001
then
    alpha start
else
    beta start
fi
"""
    for autostart, want in ((4001, {"alpha"}), (0, {"beta"})):
        params = Params(platform, PARAMS)
        params.set("SYS_AUTOSTART", autostart)
        system = System(platform, params, modules={"alpha": dummy("alpha"),
                                                   "beta": dummy("beta")})
        out = []
        assert Shell(system, out.append).run_script(script) == 0
        assert set(system.modules.running()) == want, out


def test_rcs_no_airframe_starts_no_vehicle(platform, sd):
    b = Board(platform, sd, autostart=0)
    status, text = b.boot()
    assert status == 0
    assert "[init] SYS_AUTOSTART 0: no airframe" in text
    assert b.running == {"mpu6000", "sensors", "logger", "dataman", "rc_update",
                         "battery_status", "failure_injector", "load_mon"}
    assert b.shell.env["VEHICLE_TYPE"] == "none"
    assert text.rstrip().endswith("[init] startup done")


def test_rcs_quad_x_starts_mc_apps_and_reports_missing_modules(platform, sd):
    b = Board(platform, sd, autostart=4001)
    status, text = b.boot()
    assert status == 0
    assert "[init] airframe: 4001_quad_x" in text
    assert b.running == {"mpu6000", "sensors", "commander", "px4io", "ekf2", "mc_att_control",
                         "mc_pos_control", "logger", "dataman", "rc_update", "battery_status",
                         "mc_rate_control", "failure_injector", "load_mon", "mc_att_select"}
    env = b.shell.env
    assert (env["VEHICLE_TYPE"], env["MIXER"], env["PWM_OUT"]) == ("mc", "quad_x", "1234")
    assert env["MIXER_FILE"] == "/etc/mixers/quad_x.main.mix"
    # missing modules: clear errors with their script line, and the script went on
    assert "/etc/init.d/rc.sensors:8: l3gd20: not available in this build" in text
    lineno = next(i for i, line in enumerate(
        (romfs.ROMFS_ROOT / "init.d/rc.mc_apps").read_text().splitlines(), 1)
        if line.startswith("navigator start"))
    assert f"/etc/init.d/rc.mc_apps:{lineno}: navigator: not available in this build" in text
    load_line = next(i for i, line in enumerate(
        (romfs.ROMFS_ROOT / "init.d/rcS").read_text().splitlines(), 1)
        if line.startswith("if param load"))
    assert f"/etc/init.d/rcS:{load_line}: param load: no parameter storage" in text
    assert "[init] startup done" in text


def test_rcs_without_io_uses_fmu_outputs(platform, sd):
    b = Board(platform, sd, autostart=4001)
    b.system.params.set("SYS_USE_IO", 0)
    b.boot()
    assert "fmu" in b.running and "px4io" not in b.running


def test_f450_autoconfig_sets_its_parameters_once(platform, sd):
    b = Board(platform, sd, autostart=4011, autoconfig=1)
    status, text = b.boot()
    assert status == 0
    assert "[init] airframe: 4011_dji_f450" in text
    assert b.shell.env["MIXER"] == "quad_x"
    assert "[init] mixer: /etc/mixers/quad_x.main.mix" in text
    # gains of controllers not in this build: reported with the line, skipped
    lineno = next(i for i, line in enumerate(
        open(romfs.ROMFS_ROOT / "init.d/airframes/4011_dji_f450").read().splitlines(), 1)
        if "param set MC_ROLL_P" in line)
    assert (f"/etc/init.d/airframes/4011_dji_f450:{lineno}: param set: parameter MC_ROLL_P "
            "not found") in text
    assert b.system.params["SYS_AUTOCONFIG"] == 0
    assert b.system.params["SDLOG_MODE"] == 0       # from rc.mc_defaults under AUTOCNF


def test_sd_card_config_overrides_airframe_and_extras_run_last(platform, sd):
    (sd / "etc" / "config.txt").write_text("echo config sees MIXER=$MIXER\nset MIXER quad_plus\n")
    (sd / "etc" / "extras.txt").write_text("echo extras ran\nbeta start\n")
    b = Board(platform, sd, autostart=4001)
    b.system.modules.register("beta", dummy("beta"))
    status, text = b.boot()
    assert status == 0
    lines = text.splitlines()
    assert "config sees MIXER=quad_x" in lines
    assert lines.index("config sees MIXER=quad_x") < lines.index("[init] extras: "
                                                                 "/fs/microsd/etc/extras.txt")
    assert b.shell.env.get("MIXER") == "quad_plus"
    assert "[init] ERROR: mixer /etc/mixers/quad_plus.main.mix not found" in text
    # extras.txt runs after everything else rcS starts
    assert lines[-3:] == ["[init] extras: /fs/microsd/etc/extras.txt", "extras ran",
                          "[init] startup done"]
    assert "beta" in b.running


def test_no_sd_card_is_tolerated(platform):
    b = Board(platform, None, autostart=4001)
    status, text = b.boot()
    assert status == 0
    assert "extras" not in text and "config:" not in text
    assert "mc_att_control" in b.running


def test_unknown_autostart_is_reported(platform, sd):
    b = Board(platform, sd, autostart=1234)
    status, text = b.boot()
    assert status == 0
    assert "[init] ERROR: SYS_AUTOSTART names no file of /etc/init.d/airframes" in text
    assert "commander" not in b.running


def test_parameters_come_from_storage(platform, sd):
    part = MemoryPartition(8192)
    setup = Params(platform, PARAMS, ParamStorage(part))
    setup.set("SYS_AUTOSTART", 4011)
    assert setup.save()
    b = Board(platform, sd, storage=ParamStorage(part))
    status, text = b.boot()
    assert status == 0
    assert "[init] parameters loaded" in text
    assert "[init] airframe: 4011_dji_f450" in text


def test_logging_disabled_by_sdlog_mode(platform, sd):
    b = Board(platform, sd, autostart=0)
    b.system.params.set("SDLOG_MODE", -1)
    b.boot()
    assert "logger" not in b.running


def test_every_airframe_file_is_selectable():
    frames = romfs.airframes()
    assert {a: f.name for a, f in frames.items()} == {2100: "Standard Plane",
                                                     4001: "Generic Quadcopter X",
                                                     4011: "DJI Flame Wheel F450",
                                                     13000: "Generic Standard VTOL"}
    autostart = (romfs.ROMFS_ROOT / "init.d" / "rc.autostart").read_text()
    for num, frame in frames.items():
        assert f"param compare SYS_AUTOSTART {num}" in autostart
        assert frame.file.rsplit("/", 1)[1] in autostart
    assert {f.type for f in frames.values()} == {"Quadrotor x", "Standard Plane",
                                                 "Standard VTOL"}
    assert frames[13000].cls == "VTOL" and frames[13000].outputs[4:] == (
        ("AUX1", "aileron"), ("AUX2", "elevator"), ("AUX3", "throttle"), ("AUX4", "rudder"))
    assert frames[2100].cls == "Plane" and frames[4011].cls == "Copter"
    assert frames[2100].outputs == (("MAIN1", "aileron"), ("MAIN2", "elevator"),
                                    ("MAIN3", "throttle"), ("MAIN4", "rudder"))


def test_standard_plane_starts_fw_apps_with_the_aetr_mixer_at_50_hz(platform, sd):
    b = Board(platform, sd, autostart=2100, autoconfig=1)
    status, text = b.boot()
    assert status == 0
    assert "[init] airframe: 2100_standard_plane" in text
    assert {"ekf2", "fw_att_control", "fw_pos_control_l1", "px4io"} <= b.running
    assert not {"mc_att_control", "mc_pos_control", "mc_rate_control"} & b.running
    env = b.shell.env
    assert (env["VEHICLE_TYPE"], env["MIXER"], env["PWM_RATE"]) == ("fw", "AETR", "50")
    assert "[init] mixer: /etc/mixers/AETR.main.mix" in text
