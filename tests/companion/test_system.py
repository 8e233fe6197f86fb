"""The three-board system: FMU, IO and the companion computer on TELEM2, in lockstep.

Booted in process mode and in one process (local mode): the companion's firmware starts after
its Linux boot, its shell answers through the orchestrator, and the same seed gives a
byte-identical FMU log with the companion in the loop (two in-process runs of 8 s each).
"""

from pathlib import Path

import pytest

from board.wiring import COMPANION_WIRES
from hil.companion_system import companion_summary, format_companion
from hil.system import SystemConfig, build_system

S = 1_000_000_000
#: the companion's boot (companion.board.BOOT_NS, 2 s) and a little more
BOOTED_S = 2.3
SAME_SEED_S = 8.0


def _config(out: Path, mode: str) -> SystemConfig:
    return SystemConfig(out_dir=str(out), mode=mode, companion=True, rc=None)


def _fmu_log(out: Path) -> bytes:
    logs = sorted((out / "sd" / "log").rglob("*.ulg"))
    assert len(logs) == 1, logs
    return logs[0].read_bytes()


def _run_local(out: Path, seconds: float) -> dict:
    orch, _ = build_system(_config(out, "local"))
    with orch:
        assert set(orch.specs) == {"fmu", "io", "companion"}
        assert all(w in orch.wiring for w in COMPANION_WIRES)
        # the FMU logs from here on, so a short run without arming has a log (the airframe's
        # defaults reset SDLOG_MODE on a fresh FRAM: set on the console, as a user would)
        orch.run(duration_ns=S)
        for line in ("param set SDLOG_MODE 2", "logger stop", "logger start"):
            assert orch.call("fmu", "shell", line)[0] == 0, line
        orch.run(duration_ns=int((seconds - 1) * S))
        got = {
            "dead": dict(orch.dead),
            "booted": orch.call("companion", "booted"),
            "modules": orch.call("companion", "modules"),
            "listener": orch.call("companion", "shell", "listener parameter_update -n 1"),
            "uorb": orch.call("companion", "shell", "uorb status"),
            "param": orch.call("companion", "shell", "param show SYS_AUTOSTART"),
            "dmesg": orch.call("companion", "dmesg"),
            "fmu_dmesg": orch.call("fmu", "dmesg"),
            "summary": companion_summary(orch),
        }
    got["log"] = _fmu_log(out)
    return got


@pytest.fixture(scope="module")
def local_run(tmp_path_factory):
    return _run_local(tmp_path_factory.mktemp("companion_local"), SAME_SEED_S)


def test_three_boards_boot_in_one_process(local_run):
    assert local_run["dead"] == {}
    assert local_run["booted"] is True
    assert "uorb_bridge" in local_run["modules"]
    rc, text = local_run["listener"]
    assert rc == 0 and "parameter_update" in text
    rc, text = local_run["uorb"]
    assert rc == 0 and "parameter_update" in text
    rc, text = local_run["param"]
    assert rc == 0 and "SYS_AUTOSTART" in text and "4011" in text  # the FMU's airframe
    # the companion booted on its own clock, two seconds after power-on
    assert min(t for t, *_ in local_run["dmesg"]) >= 2_000_000


def test_the_bridge_carries_frames_both_ways(local_run):
    """hil run's summary of the bridge: both sides up, frames received on each, no CRC
    errors (the FMU sends from its own boot; what reached the companion before its bridge
    opened the port is flushed, not decoded as damaged frames)."""
    sm = local_run["summary"]
    assert sm["alive"] and "uorb_bridge" in sm["modules"]
    fmu, comp = sm["fmu"], sm["companion"]
    assert fmu["link_ok"] and comp["link_ok"]
    assert comp["rx_frames"] > 1000          # attitude, setpoint, state at their rates
    assert fmu["rx_frames"] >= 5             # at least the companion's heartbeats
    assert fmu["rx_crc_errors"] == comp["rx_crc_errors"] == 0
    line = format_companion(sm)
    assert line.startswith("  companion: modules ") and "link up" in line


def test_three_boards_boot_as_processes(tmp_path):
    cfg = _config(tmp_path, "process")
    cfg.companion_att = True  # the companion's own start-up line: mc_att_control
    orch, _ = build_system(cfg)
    with orch:
        orch.run(duration_ns=int(BOOTED_S * S))
        assert orch.dead == {}
        assert orch.call("companion", "booted") is True
        assert "mc_att_control" in orch.call("companion", "modules")
        rc, text = orch.call("companion", "shell", "mc_att_control status")
        assert rc == 0 and "running" in text
        rc, text = orch.call("fmu", "shell", "ver hw")
        assert rc == 0 and "PX4_FMU_V2" in text


def test_same_seed_same_fmu_log_with_the_companion(local_run, tmp_path):
    again = _run_local(tmp_path, SAME_SEED_S)
    assert len(local_run["log"]) > 50_000
    assert again["log"] == local_run["log"]
    assert again["dmesg"] == local_run["dmesg"]
    assert again["fmu_dmesg"] == local_run["fmu_dmesg"]
