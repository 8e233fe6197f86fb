"""The companion computer as a board in this process: boot, shell, parameters on its disk,
a bad start-up line, and a module written for the FMU running unchanged on it."""

import math

import pytest

from companion.board import CompanionBoard
from companion.disk import PARAMS_FILE
from firmware.romfs import ROMFS_ROOT
from hil.orchestrator import BoardSpec, Orchestrator

MS = 1_000_000
BOOT_NS = 10 * MS
ROMFS_RC = ROMFS_ROOT / "init.d" / "rc.companion"


def console_text(records):
    return b"".join(r[2][5] for r in records if r[0] == "console" and r[2][5]).decode()


@pytest.fixture(scope="module")
def booted(tmp_path_factory):
    """A companion given the F450's airframe and the attitude controller at start-up."""
    root = tmp_path_factory.mktemp("companion")
    b = CompanionBoard(out_dir=str(root), params={"SYS_AUTOSTART": 4011}, boot_ns=BOOT_NS,
                       startup=("mc_att_control start",))
    out = b.advance(BOOT_NS + 50 * MS, [])
    return b, console_text(out), root


def test_ports_are_the_wiring_s(booted):
    b, _, _ = booted
    assert {(p[0], p[1], p[2]) for p in b.ctl_ports()} >= {
        ("telem2", "uart", "inout"), ("console", "uart", "inout"), ("ros", "value", "inout"),
        ("reboot", "value", "out")}
    assert b.uart_by_device("/dev/ttyUSB0") is b.uarts["ttyUSB0"]
    assert b.uart_by_device("/dev/ttyS2") is None


def test_boot_runs_the_script_and_the_board_s_lines(booted):
    b, console, _ = booted
    assert "[init] airframe: 4011_dji_f450" in console
    assert "[companion] startup done" in console
    assert "mc_att_control" in b.ctl_modules()
    # lines for modules the companion does not run are reported, and the script goes on
    assert "param set: parameter PWM_MIN not found" in console


def test_the_airframe_s_gains_reach_the_companion(booted):
    b, _, _ = booted
    # the F450's tune (airframes/4011_dji_f450), not the modules' defaults (6.5, 0.15)
    assert b.ctl_param("MC_ROLL_P") == pytest.approx(5.5)
    assert b.ctl_param("MC_ROLLRATE_P") == pytest.approx(0.1)
    assert b.ctl_param("SYS_AUTOCONFIG") == 0


def test_shell_answers(booted):
    b, _, _ = booted
    rc, text = b.ctl_shell("param show MC_ROLL_P")
    assert rc == 0 and "MC_ROLL_P" in text and "5.5" in text
    rc, text = b.ctl_shell("uorb status")
    assert rc == 0 and "parameter_update" in text and "vehicle_rates_setpoint" in text
    rc, text = b.ctl_shell("listener parameter_update -n 1")
    assert rc == 0 and "parameter_update" in text
    rc, text = b.ctl_shell("ver hw")
    assert rc == 0 and "COMPANION_RPI4" in text
    rc, text = b.ctl_shell("mc_att_control status")
    assert rc == 0 and "running" in text
    # the bridge may not take the companion's own console (binary frames would lock nsh out)
    assert b.ctl_shell("uorb_bridge stop")[0] == 0
    rc, text = b.ctl_shell("uorb_bridge start -d /dev/ttyS0 -r companion")
    assert rc != 0 and "/dev/ttyS0 is the board's nsh console" in text, text
    assert b.ctl_shell("uorb_bridge start -d /dev/ttyUSB0 -b 921600 -r companion")[0] == 0


def test_console_uart_runs_typed_lines(booted):
    b, _, _ = booted
    t = b.kernel.now_ns + MS
    cfg = (115_200, 8, "N", 1, 0)
    out = b.advance(t + 100 * MS, [("console", t, (*cfg, b"param get MC_ROLL_P\r"))])
    text = console_text(out)
    assert "param get MC_ROLL_P" in text  # echoed
    assert "5.5" in text and text.rstrip().endswith("nsh>")


def test_a_module_written_for_the_fmu_runs_when_its_topics_arrive(booted):
    """mc_att_control, unchanged: attitude level, setpoint rolled 0.1 rad -> a roll rate of
    about MC_ROLL_P x 0.1 (the airframe's 5.5, not the default 6.5)."""
    b, _, _ = booted
    orb = b.platform.orb
    mode = orb.new("vehicle_control_mode")
    mode.flag_control_attitude_enabled = True
    orb.advertise("vehicle_control_mode").publish(mode)
    sp = orb.new("vehicle_attitude_setpoint")
    half = 0.05
    sp.q_d[:] = [math.cos(half), math.sin(half), 0.0, 0.0]
    sp.thrust_body[:] = [0.0, 0.0, -0.5]
    orb.advertise("vehicle_attitude_setpoint").publish(sp)
    att_pub = orb.advertise("vehicle_attitude")
    att = orb.new("vehicle_attitude")
    k = b.kernel

    def publish_attitude():
        att.timestamp = att.timestamp_sample = b.platform.time_us()
        att.q[:] = [1.0, 0.0, 0.0, 0.0]
        att_pub.publish(att)

    for i in range(1, 6):
        k.call_at(k.now_ns + i * 4 * MS, publish_attitude)
    b.advance(k.now_ns + 30 * MS, [])
    rates = b.ctl_topic("vehicle_rates_setpoint")
    assert rates is not None and rates["_count"] >= 5
    assert 0.5 < rates["roll"] < 0.6
    assert abs(rates["pitch"]) < 1e-6 and rates["thrust_body"][2] == pytest.approx(-0.5)


def test_unknown_module_in_startup_is_reported_and_the_rest_runs(tmp_path):
    table = {"mc_att_control": "firmware.modules.mc_att_control:McAttControlModule",
             "ghost": "firmware.modules.no_such_module:GhostModule"}
    b = CompanionBoard(out_dir=str(tmp_path), boot_ns=BOOT_NS, modules=table,
                       startup=("ghost start", "not_a_command start", "mc_att_control start"))
    text = console_text(b.advance(BOOT_NS + 20 * MS, []))
    assert "ghost: not available in this build (no module firmware.modules.no_such_module)" \
        in text
    assert "not_a_command: command not found" in text
    # uorb_bridge is not in this table: the script's line fails clearly and the script goes on
    lineno = next(i for i, line in enumerate(ROMFS_RC.read_text().splitlines(), 1)
                  if line.startswith("uorb_bridge start"))
    assert f"/etc/init.d/rc.companion:{lineno}: nsh: uorb_bridge: command not found" in text
    assert "[companion] startup done" in text
    assert b.ctl_modules() == ["mc_att_control"]


def test_parameters_persist_across_a_reboot(tmp_path):
    """``param set`` (autosaved to the disk file), ``reboot`` on the shell: the orchestrator
    power-cycles the board, which boots from its disk with the value kept."""
    boot_ns = 100 * MS
    spec = BoardSpec("companion.board:CompanionBoard",
                     {"out_dir": str(tmp_path), "boot_ns": boot_ns,
                      "params": {"SYS_AUTOSTART": 4011}})
    with Orchestrator({"companion": spec}, mode="local", quantum_ns=MS) as orch:
        orch.run(duration_ns=boot_ns + 10 * MS)
        assert orch.call("companion", "param", "MC_ROLL_P") == pytest.approx(5.5)
        assert orch.call("companion", "shell", "param set MC_ROLL_P 7.25")[0] == 0
        orch.run(duration_ns=400 * MS)  # the autosave, 300 ms after the change
        assert (tmp_path / PARAMS_FILE).stat().st_size == 16384
        assert orch.call("companion", "shell", "reboot")[0] == 0
        orch.run(duration_ns=130 * MS)  # down after 100 ms, then Linux boots again
        assert orch.reboots == {"companion": 1}
        assert orch.call("companion", "booted") is False
        orch.run(duration_ns=boot_ns)
        assert orch.call("companion", "booted") is True
        assert orch.call("companion", "param", "MC_ROLL_P") == pytest.approx(7.25)
        assert "parameters loaded from slot" in orch.call("companion", "shell", "dmesg")[1]


def test_a_damaged_parameter_file_boots_on_defaults(tmp_path):
    """The disk file is outside input: garbage in it is reported and the companion boots
    (airframe defaults, saved anew), never a traceback."""
    import random

    (tmp_path / PARAMS_FILE).write_bytes(random.Random(7).randbytes(5000))  # short, too
    b = CompanionBoard(out_dir=str(tmp_path), params={"SYS_AUTOSTART": 4011},
                       boot_ns=BOOT_NS)
    text = console_text(b.advance(BOOT_NS + 20 * MS, []))
    assert "[companion] startup done" in text
    errors = [m for _, sev, mod, m in b.ctl_dmesg() if mod == "param" and sev == 3]
    assert errors and "parameter store corrupt" in errors[0]
    assert b.ctl_param("MC_ROLL_P") == pytest.approx(5.5)
    assert (tmp_path / PARAMS_FILE).stat().st_size == 16384
