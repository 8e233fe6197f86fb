"""The paper's fallback scenario, paced: an experimental attitude controller as a ROS node flies
the vehicle through the companion, and the FMU takes over when the node dies.

Arrangement (docs/ros.md, "Native ROS nodes (ROS-N)"):

- FMU: ``MC_ATT_IMPL`` 2 (``mc_att_companion``): forwards ``companion_rates_setpoint`` to its
  rate controller while fresh (``MC_CMP_TIMEOUT``) and inside the envelope, else PX4's own
  attitude law (warm standby), latched;
- companion on TELEM2: ``uorb_bridge`` (FMU <-> companion) and ``ros_bridge`` (companion <->
  the ROS edge of ``hil fly --ros``), so the node's ``/fmu/in/vehicle_rates_setpoint`` reaches
  the FMU as ``companion_rates_setpoint``;
- ``hil rosnode mc_att_control``: PX4's attitude controller, unchanged, as a native ROS node on
  ``/fmu/out/*`` and ``/clock``.

The vehicle takes off (``commander takeoff`` on the FMU console) and hovers on the node's
attitude control: the FMU forwards it (source companion, no fallback, rate setpoints counted).
Then the node is killed (SIGKILL: a crash, no goodbye). Asserted from the FMU's own records:
its dmesg line says it fell back because the companion went stale, ``MC_CMP_TIMEOUT`` after the
last companion message (FMU virtual time) plus at most one attitude period; the tilt error
against the setpoint stays below :data:`TILT_ERR_MAX_DEG` from the takeoff to the end of the
run (ULog, vehicle_attitude against vehicle_attitude_setpoint), and after the fallback the
vehicle keeps hovering: armed, in the air, altitude within :data:`ALT_BAND_M` of the hover.

``MC_CMP_TIMEOUT`` is :data:`TIMEOUT_MS` here, not the 20 ms default meant for the companion's
own ``mc_att_control`` on the bridge: a ROS node sees the attitude at the ROS list's 50 Hz and
shares two cores with the whole emulator paced to the wall clock, where a 20 ms silence is not
a crash. Wall time ~40-50 s on two cores (boot, GPS fix, takeoff, 4 s on the node, 4 s after).
"""

from __future__ import annotations

import math
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest

from hil.ros import msggen
from hil.shell_client import run_command
from tests.helpers import ctrl_c_reaches_child

pytestmark = [pytest.mark.paced]

ROOT = Path(__file__).resolve().parents[2]
HIL_EXE = Path(sys.executable).with_name("hil")
#: MC_CMP_TIMEOUT for a ROS node (see the module docstring)
TIMEOUT_MS = 300
#: the FMU's attitude period: the fallback is decided on an attitude update
ATT_PERIOD_MS = 4.0
#: bounds: tilt error against the setpoint (whole flight), altitude after the fallback
TILT_ERR_MAX_DEG = 10.0
ALT_BAND_M = 1.0
#: wall-clock limits (generous: a loaded 2-core machine runs below 1x)
START_TIMEOUT_S = 60.0
TAKEOFF_TIMEOUT_S = 90.0


class _Proc:
    """A subprocess in its own session with its output kept (and a line to wait for)."""

    def __init__(self, cmd: list[str], env: dict[str, str], ready: str) -> None:
        self.lines: list[str] = []
        self.ready_text = ready
        self.ready = threading.Event()
        self.proc = subprocess.Popen(cmd, cwd=str(ROOT), env=env, stdin=subprocess.DEVNULL,
                                     stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                                     bufsize=1, start_new_session=True,
                                     preexec_fn=ctrl_c_reaches_child)  # noqa: PLW1509
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self) -> None:
        assert self.proc.stdout is not None
        for line in self.proc.stdout:
            self.lines.append(line.rstrip("\n"))
            if self.ready_text in line:
                self.ready.set()
        self.ready.set()

    def output(self, n: int = 40) -> str:
        return "\n".join(self.lines[-n:])

    def stop(self, sig: int = signal.SIGINT) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(sig)
            try:
                self.proc.wait(20)
            except subprocess.TimeoutExpired:
                pass
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)  # its children (board processes) too
        except ProcessLookupError:
            pass
        self.proc.wait(10)


def _wait(pred: Any, timeout_s: float, what: str, every_s: float = 0.25) -> Any:
    deadline = time.monotonic() + timeout_s
    while True:
        value = pred()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout_s:.0f} s waiting for {what}")
        time.sleep(every_s)


def _tilt_deg(q: tuple[float, ...], qd: tuple[float, ...]) -> float:
    """Angle between the body z axes of two attitudes (heading ignored), degrees."""
    def ez(w: float, x: float, y: float, z: float) -> tuple[float, float, float]:
        return 2 * (x * z + w * y), 2 * (y * z - w * x), w * w - x * x - y * y + z * z
    a, b = ez(*q), ez(*qd)
    dot = max(-1.0, min(1.0, sum(i * j for i, j in zip(a, b))))
    return math.degrees(math.acos(dot))


def _ulog_checks(path: Path, t_takeoff_us: int, t_fallback_us: int) -> dict[str, float]:
    """From the FMU's ULog: the largest tilt error after takeoff, and the altitude band and
    arming after the fallback."""
    from pyulog import ULog

    ulog = ULog(str(path), ["vehicle_attitude", "vehicle_attitude_setpoint",
                            "vehicle_local_position"])
    data = {d.name: d.data for d in ulog.data_list}
    att, sp = data["vehicle_attitude"], data["vehicle_attitude_setpoint"]
    sp_t = sp["timestamp"]
    worst = 0.0
    j = 0
    n_att = 0
    for i, t in enumerate(att["timestamp"]):
        if t < t_takeoff_us:
            continue
        while j + 1 < len(sp_t) and sp_t[j + 1] <= t:
            j += 1
        if sp_t[j] > t:
            continue
        q = tuple(float(att[f"q[{k}]"][i]) for k in range(4))
        qd = tuple(float(sp[f"q_d[{k}]"][j]) for k in range(4))
        worst = max(worst, _tilt_deg(q, qd))
        n_att += 1
    lp = data["vehicle_local_position"]
    z_before = [float(z) for t, z in zip(lp["timestamp"], lp["z"])
                if t_fallback_us - 2_000_000 <= t < t_fallback_us]
    z_after = [float(z) for t, z in zip(lp["timestamp"], lp["z"]) if t >= t_fallback_us]
    t_end = float(lp["timestamp"][-1])
    return {"tilt_max_deg": worst, "samples": n_att, "z_hover": sum(z_before) / len(z_before),
            "z_min_after": min(z_after), "z_max_after": max(z_after),
            "after_s": (t_end - t_fallback_us) / 1e6}


def test_ros_node_flies_then_the_fmu_takes_over(roscore: str, ros_env: dict[str, str],
                                                tmp_path: Path) -> None:
    assert HIL_EXE.exists(), f"{HIL_EXE} not found (pip install -e .)"
    pkg = msggen.ensure_package()
    env = {**ros_env, **pkg.env(), "PYTHONUNBUFFERED": "1"}
    out_dir = tmp_path / "fly"
    fly = _Proc([str(HIL_EXE), "fly", "--ros", "--speed", "1", "--seed", "1", "--fixed-utc",
                 "--out", str(out_dir), "--param", "MC_ATT_IMPL=2",
                 "--param", f"MC_CMP_TIMEOUT={TIMEOUT_MS}"], env, "Ctrl-C to stop")
    node: _Proc | None = None
    try:
        assert fly.ready.wait(START_TIMEOUT_S) and fly.proc.poll() is None, \
            f"hil fly --ros did not start:\n{fly.output()}"
        port = int(next(m.group(1) for ln in fly.lines
                        if (m := re.search(r"tcp 127\.0\.0\.1:(\d+)", ln))))

        def sh(cmd: str) -> str:
            return run_command(port, cmd, 30.0)

        _wait(lambda: _answers(port), 30, "the FMU console")
        assert re.search(r"MC_ATT_IMPL \[\d+\]\s*:\s*2\b", sh("param show MC_ATT_IMPL"))
        node = _Proc([str(HIL_EXE), "rosnode", "mc_att_control"], env, "started at")
        assert node.ready.wait(START_TIMEOUT_S) and node.proc.poll() is None, \
            f"hil rosnode did not start:\n{node.output()}"
        assert "publishes /fmu/in/vehicle_attitude_setpoint /fmu/in/vehicle_rates_setpoint" \
            in node.output()

        # take off once the preflight checks pass (GPS fix, estimator)
        last = [""]

        def takeoff() -> bool:
            last[0] = sh("commander takeoff")
            return "arm: accepted" in last[0].lower()
        try:
            _wait(takeoff, TAKEOFF_TIMEOUT_S, "commander takeoff to be accepted", every_s=1.0)
        except AssertionError as exc:
            raise AssertionError(f"{exc}; last answer: {last[0]!r}\n{fly.output(8)}") from None

        def status() -> str:
            return sh("mc_att_companion status")

        def forwarding() -> bool:
            s = status()
            m = re.search(r"outputs: (\d+) forwarded", s)
            return "source: companion" in s and m is not None and int(m.group(1)) > 500
        _wait(forwarding, TAKEOFF_TIMEOUT_S, "the FMU to forward the ROS node's rates")
        time.sleep(4.0)  # hover on the node
        before = status()
        assert "source: companion" in before and "fallbacks: 0" in before, before
        fwd = int(re.search(r"outputs: (\d+) forwarded", before).group(1))  # type: ignore[union-attr]
        assert fwd > 1000, before
        t_takeoff_us = _takeoff_time_us(sh("dmesg"))

        node.stop(signal.SIGKILL)          # the experimental controller crashes
        after = _wait(lambda: s if "fallback, latched" in (s := status()) else None, 10,
                      "the FMU's fallback")
        dmesg = sh("dmesg")
        # "[  19.831279] WARN [mc_att_companion] ... (latched): stale: no ... for 303.3 ms"
        m = re.search(r"\[\s*([0-9.]+)\] WARN \[mc_att_companion\] [^\n]*\(latched\): "
                      r"stale: [^\n0-9]*([0-9.]+) ms", dmesg)
        assert m, f"no fallback line in dmesg:\n{dmesg[-3000:]}\n{after}"
        t_fallback_us = int(float(m.group(1)) * 1e6)
        silence_ms = float(m.group(2))
        # decided on the first attitude update after MC_CMP_TIMEOUT of silence
        assert TIMEOUT_MS < silence_ms <= TIMEOUT_MS + ATT_PERIOD_MS, m.group(0)
        print(f"ROS-N: fallback at {t_fallback_us / 1e6:.3f} s, {silence_ms} ms after the last "
              f"companion rate setpoint (MC_CMP_TIMEOUT {TIMEOUT_MS} ms); before: {before}")
        time.sleep(4.0)  # keeps flying on the FMU's law
        later = status()
        assert "fallback, latched" in later and "stale" in later, later
        assert "armed True landed False" in later, later
    finally:
        if node is not None:
            node.stop(signal.SIGKILL)
        fly.stop()
    logs = sorted(out_dir.rglob("*.ulg"))
    assert logs, f"no ULog under {out_dir}"
    got = _ulog_checks(logs[-1], t_takeoff_us, t_fallback_us)
    print(f"ROS-N: {got}")
    assert got["samples"] > 200, got
    assert got["tilt_max_deg"] < TILT_ERR_MAX_DEG, got
    assert got["after_s"] > 3.0, got
    assert got["z_hover"] < -1.0, got      # NED: in the air
    assert abs(got["z_min_after"] - got["z_hover"]) < ALT_BAND_M, got
    assert abs(got["z_max_after"] - got["z_hover"]) < ALT_BAND_M, got


def _answers(port: int) -> bool:
    """The banner comes before rcS has finished (a line typed too early is lost): ask until
    nsh answers."""
    try:
        return "FW version" in run_command(port, "ver all", 5.0)
    except (OSError, TimeoutError):
        return False


def _takeoff_time_us(dmesg: str) -> int:
    """The FMU's time of arming (the takeoff), from dmesg."""
    m = re.search(r"\[\s*([0-9.]+)\] INFO \[commander\] Armed", dmesg)
    assert m, f"no arming line in dmesg:\n{dmesg[-3000:]}"
    return int(float(m.group(1)) * 1e6)
