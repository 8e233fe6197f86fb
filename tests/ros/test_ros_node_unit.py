"""ROS-N unit tests: a flight-stack module unchanged as a ROS 1 node (hil.ros.node, hil rosnode).

ModuleHost alone (no ROS): the module's subscriptions and publications are its ROS inputs and
outputs, time is only what the caller advances, injected messages are not echoed back. Then the
real thing: ``hil rosnode mc_att_control`` in its own process against a roscore, fed by a plain
rospy publisher and read by a plain rospy subscriber and by Debian's ``rostopic echo``.
"""

from __future__ import annotations

import functools
import math
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any, Iterator

import pytest
from hypothesis import given
from hypothesis import strategies as st

from firmware.platform.module import ModuleError
from firmware.platform.params import ParamError
from hil.ros.node import ModuleHost, ros_topic
from hil.rosnode import ArgError, _coerce, parse_args
from tests.fuzzing import fuzz

ROOT = Path(__file__).resolve().parents[2]
T0_NS = 100_000_000_000   # the first /clock: 100 s of virtual time


def _att(host: ModuleHost, roll_rad: float, t_us: int) -> Any:
    a = host.registry.cls("vehicle_attitude")()
    a.q = [math.cos(roll_rad / 2), math.sin(roll_rad / 2), 0.0, 0.0]
    a.timestamp = a.timestamp_sample = t_us
    return a


def _feed_attitude_inputs(host: ModuleHost) -> None:
    reg = host.registry
    mode = reg.cls("vehicle_control_mode")()
    mode.flag_control_attitude_enabled = True
    host.inject("vehicle_control_mode", 0, mode)
    sp = reg.cls("vehicle_attitude_setpoint")()
    sp.q_d = [1.0, 0.0, 0.0, 0.0]
    sp.thrust_body = [0.0, 0.0, -0.55]
    host.inject("vehicle_attitude_setpoint", 0, sp)


def test_module_host_maps_the_modules_topics_and_runs_in_the_callers_time() -> None:
    outs: list[tuple[str, int, Any]] = []
    host = ModuleHost("mc_att_control", params={"MC_ROLL_P": 5.0},
                      output=lambda t, i, m: outs.append((t, i, m.copy())))
    host.start(T0_NS)
    assert ("vehicle_attitude", 0) in host.inputs
    assert ("vehicle_control_mode", 0) in host.inputs
    assert host.outputs == {("vehicle_rates_setpoint", 0), ("vehicle_attitude_setpoint", 0)}
    _feed_attitude_inputs(host)
    assert outs == []            # injected messages are the module's inputs, never echoed
    host.inject("vehicle_attitude", 0, _att(host, 0.1, T0_NS // 1000))
    assert [o[0] for o in outs] == ["vehicle_rates_setpoint"]
    rates = outs[0][2]
    assert rates.timestamp == T0_NS // 1000                 # hrt time is the caller's time
    assert rates.roll == pytest.approx(-5.0 * 2 * math.sin(0.05), rel=1e-6)   # MC_ROLL_P 5
    assert rates.thrust_body[2] == pytest.approx(-0.55)
    # the callback is limited to 250 Hz in virtual time: a second attitude at the same time
    # is taken but does not run the law; 4 ms later it does
    host.inject("vehicle_attitude", 0, _att(host, 0.1, T0_NS // 1000))
    assert len(outs) == 1
    assert host.advance(T0_NS + 4_000_000)
    host.inject("vehicle_attitude", 0, _att(host, -0.2, T0_NS // 1000 + 4000))
    assert len(outs) == 2 and outs[1][2].timestamp == T0_NS // 1000 + 4000
    assert outs[1][2].roll > 0.0
    assert not host.advance(T0_NS)          # time never goes back
    assert host.counts["clock_backwards"] == 1
    host.stop()
    assert not host.started


def test_interval_work_runs_only_as_time_is_advanced() -> None:
    outs: list[str] = []
    host = ModuleHost("land_detector", output=lambda t, i, m: outs.append(t))
    host.start(T0_NS)
    assert host.outputs == {("vehicle_land_detected", 0)}
    item = host.instance.work_item  # type: ignore[union-attr]
    runs = item.run_count
    for _ in range(5):
        host.inject("vehicle_local_position", 0,
                    host.registry.cls("vehicle_local_position")())
    assert item.run_count == runs           # no virtual time passed: its 50 Hz did not run
    host.advance(T0_NS + 100_000_000)
    assert item.run_count == runs + 5       # 100 ms at 20 ms
    assert outs                             # and published (first message at least)


def test_module_host_refuses_unknown_modules_and_parameters() -> None:
    with pytest.raises(ModuleError, match="no_such_module: no such module"):
        ModuleHost("no_such_module")
    with pytest.raises(ParamError, match="NOT_A_PARAM"):
        ModuleHost("mc_att_control", params={"NOT_A_PARAM": 1})
    host = ModuleHost("land_detector", ["hovercraft"])
    with pytest.raises(ModuleError, match="unknown vehicle type"):
        host.start(T0_NS)


def test_module_log_lines_reach_the_log_callback() -> None:
    lines: list[tuple[int, str, str]] = []
    host = ModuleHost("mc_att_control", log=lambda s, m, t: lines.append((s, m, t)))
    host.start(T0_NS)
    host.stop()
    assert any(m == "mc_att_control" and "stopped after 0 rate setpoints" in t
               for _s, m, t in lines)


def test_rosnode_arguments() -> None:
    assert parse_args(["mc_att_control", "--param", "MC_ROLL_P=7", "__name:=att"]) == (
        "mc_att_control", [], {"MC_ROLL_P": "7"}, None)
    assert parse_args(["land_detector", "fixedwing", "--name", "ld", "--param=A=1"]) == (
        "land_detector", ["fixedwing"], {"A": "1"}, "ld")
    for bad in ([], ["--param", "X"], ["mc_att_control", "--param", "=1"], ["--bogus"]):
        with pytest.raises(ArgError):
            parse_args(bad)
    assert ros_topic("/fmu/out/", "sensor_gyro", 1) == "/fmu/out/sensor_gyro_1"


_WORDS = st.sampled_from(["mc_att_control", "land_detector", "--param", "--name", "--param=",
                          "MC_ROLL_P=7", "=", "MC_ROLL_P=", "x:=y", "-d", "--", "fixedwing",
                          "NOT_A_PARAM=1", "MC_ROLL_P=1e99", "MC_ATT_IMPL=0x2", ""])


@functools.lru_cache(maxsize=1)
def _params() -> Any:
    return ModuleHost("mc_att_control").params


@fuzz(examples=300)
@given(argv=st.lists(st.one_of(_WORDS, st.text(max_size=12)), max_size=7))
def test_fuzz_rosnode_arguments_parse_or_refuse(argv: list[str]) -> None:
    """Any command line: parsed (module first, NAME=VALUE params) or ArgError, never a crash;
    parameter values of a parsed line coerce to their declared type or ArgError."""
    try:
        module, _margs, params, _name = parse_args(argv)
    except ArgError:
        return
    assert module and not module.startswith("-")
    defs = _params()
    try:
        values = _coerce(defs, params)
    except ArgError:
        return
    for pname, v in values.items():
        assert defs.defs[pname].coerce(v) == v


def test_rosnode_without_a_master_says_so() -> None:
    env = {**os.environ, "ROS_MASTER_URI": "http://127.0.0.1:9"}
    out = subprocess.run([sys.executable, "-m", "hil.cli", "rosnode", "mc_att_control"],
                         cwd=ROOT, env=env, capture_output=True, text=True, timeout=60)
    assert out.returncode == 1
    assert "hil rosnode: no ROS master at http://127.0.0.1:9" in out.stderr


# -- the real node, in its own process -------------------------------------------------------------

@pytest.fixture(scope="module")
def rospy_mod(roscore: str) -> Iterator[Any]:
    """rospy in this process, as a plain client node (reused if a test already made one)."""
    from hil.ros import msggen

    msggen.ros_python_path()
    import rospy

    if not rospy.core.is_initialized():
        rospy.init_node("fmu_hil_test_rosn", anonymous=True, disable_signals=True)
    rospy.set_param("/use_sim_time", True)
    try:
        yield rospy
    finally:
        rospy.delete_param("/use_sim_time")


class _Clock:
    """Publishes /clock at 50 Hz (wall) with the time the test sets."""

    def __init__(self, rospy: Any, t_ns: int) -> None:
        from rosgraph_msgs.msg import Clock

        self.rospy, self.t_ns, self._cls = rospy, t_ns, Clock
        self.pub = rospy.Publisher("/clock", Clock, queue_size=10)
        self.published: set[int] = set()
        self._stop = threading.Event()
        self._th = threading.Thread(target=self._loop, daemon=True)
        self._th.start()

    def _loop(self) -> None:
        while not self._stop.wait(0.02):
            t = self.t_ns
            self.published.add(t)
            self.pub.publish(self._cls(clock=self.rospy.Time(nsecs=t)))

    def close(self) -> None:
        self._stop.set()
        self._th.join(2)
        self.pub.unregister()


def _wait(pred: Any, timeout_s: float, what: str) -> None:
    deadline = time.monotonic() + timeout_s
    while not pred():
        if time.monotonic() > deadline:
            pytest.fail(f"timed out waiting for {what}")
        time.sleep(0.02)


def test_hil_rosnode_runs_mc_att_control_on_ros_topics_and_ros_time(rospy_mod: Any,
                                                                    ros_env: dict) -> None:
    rospy = rospy_mod
    from hil.ros import msggen

    pkg, px4 = msggen.load()
    clock = _Clock(rospy, T0_NS)
    env = {**ros_env, "PYTHONUNBUFFERED": "1"}
    proc = subprocess.Popen([sys.executable, "-m", "hil.cli", "rosnode", "mc_att_control",
                             "--param", "MC_ROLL_P=5.0"], cwd=ROOT, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(iter(proc.stdout.readline, "")),
                              daemon=True)
    reader.start()
    echo = None
    rates: list[Any] = []
    pubs: dict[str, Any] = {}
    sub = None
    try:
        _wait(lambda: any("started at" in ln for ln in lines) or proc.poll() is not None, 60,
              "hil rosnode to start")
        started = next((ln for ln in lines if "started at" in ln), "")
        assert "mc_att_control started at 100.0" in started, "".join(lines)
        assert "/fmu/out/vehicle_attitude " in started + " "
        assert "publishes /fmu/in/vehicle_attitude_setpoint /fmu/in/vehicle_rates_setpoint" \
            in started
        sub = rospy.Subscriber("/fmu/in/vehicle_rates_setpoint", px4.VehicleRatesSetpoint,
                               rates.append)
        # Debian's rostopic, another process, loads px4_msgs with the documented variables
        echo = subprocess.Popen(["rostopic", "echo", "-n", "1", "/fmu/in/vehicle_rates_setpoint"],
                                env={**env, **pkg.env()}, stdout=subprocess.PIPE,
                                stderr=subprocess.STDOUT, text=True)
        for name, cls in (("vehicle_control_mode", px4.VehicleControlMode),
                          ("vehicle_attitude_setpoint", px4.VehicleAttitudeSetpoint),
                          ("vehicle_attitude", px4.VehicleAttitude)):
            pubs[name] = rospy.Publisher(f"/fmu/out/{name}", cls, queue_size=10)
        mode = px4.VehicleControlMode(flag_control_attitude_enabled=True)
        sp = px4.VehicleAttitudeSetpoint(q_d=[1.0, 0.0, 0.0, 0.0], thrust_body=[0.0, 0.0, -0.55])

        def attitude(roll: float) -> Any:
            return px4.VehicleAttitude(q=[math.cos(roll / 2), math.sin(roll / 2), 0.0, 0.0],
                                       timestamp=clock.t_ns // 1000,
                                       timestamp_sample=clock.t_ns // 1000)

        def feed(roll: float) -> None:
            pubs["vehicle_control_mode"].publish(mode)
            pubs["vehicle_attitude_setpoint"].publish(sp)
            pubs["vehicle_attitude"].publish(attitude(roll))

        _wait(lambda: all(p.get_num_connections() for p in pubs.values())
              and sub.get_num_connections(), 20, "the node's connections")
        # a plain rospy publisher's messages reach the module; its output a plain subscriber
        # (the three arrive on three connections, in any order: the clock moves on until the
        # attitude comes after the setpoint, or the 250 Hz limit would hold it back)
        deadline = time.monotonic() + 20
        while not rates and time.monotonic() < deadline:
            feed(0.1)
            time.sleep(0.05)
            clock.t_ns += 10_000_000
            assert proc.poll() is None, "".join(lines)
        assert rates, "no rate setpoint from the node:\n" + "".join(lines)
        first = rates[0]
        assert first.timestamp * 1000 in clock.published
        time.sleep(0.3)     # let every late message of the loop above arrive
        first = rates[-1]
        assert first.roll == pytest.approx(-5.0 * 2 * math.sin(0.05), rel=1e-5)
        assert first.thrust_body[2] == pytest.approx(-0.55)
        # time follows /clock: every output is stamped with a /clock time the test published,
        # and frozen /clock means the 250 Hz limit lets nothing more through
        assert first.timestamp * 1000 in clock.published
        feed(0.1)           # the law's first run at the last /clock time, if it moved
        time.sleep(0.3)
        n = len(rates)
        for _ in range(5):
            feed(0.1)
            time.sleep(0.05)
        assert len(rates) == n
        clock.t_ns = T0_NS + 2_000_000_000
        _wait(lambda: (feed(-0.2), time.sleep(0.05),
                       rates[-1].timestamp == clock.t_ns // 1000)[-1], 20,
              "an output stamped with the new /clock time")
        assert rates[-1].roll > 0.0
        assert all(r.timestamp * 1000 in clock.published for r in rates)
        deadline = time.monotonic() + 30
        while echo.poll() is None and time.monotonic() < deadline:
            clock.t_ns += 10_000_000
            feed(0.1)
            time.sleep(0.1)
        out, _ = echo.communicate(timeout=5)
        assert echo.returncode == 0, out
        # the message rostopic printed is one this test's subscriber got, field for field
        fields = dict(ln.split(": ", 1) for ln in out.splitlines() if ": " in ln)
        same = [r for r in rates if str(r.timestamp) == fields.get("timestamp")]
        assert same, out
        assert fields["roll"] == str(same[0].roll) and fields["yaw"] == str(same[0].yaw), out
        assert fields["thrust_body"] == str(list(same[0].thrust_body)), out
    finally:
        if echo is not None and echo.poll() is None:
            echo.kill()
            echo.wait(5)
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        try:
            proc.wait(20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(5)
        reader.join(5)
        clock.close()
        for p in pubs.values():
            p.unregister()
        if sub is not None:
            sub.unregister()
    text = "".join(lines)
    assert proc.returncode == 0, text
    assert "mc_att_control: running" in text and "rate setpoints published" in text, text
    stopped = re.search(r"hil rosnode: stopped at ([0-9.]+) s", text)
    assert stopped and float(stopped.group(1)) == pytest.approx(clock.t_ns / 1e9), text
