"""Two attitude controllers that replace each other in flight (issue 23).

The law of ``mc_att_control_so3`` on its own; ``mc_att_select`` swapping on ``MC_ATT_IMPL``
(with stand-in modules: no flight needed); and the hand-over itself in the in-process rig
(world + truth estimator + the control modules), in stabilized mode during a roll step, when
the two laws disagree most: the rate setpoint must neither pause nor step. The whole system
doing it in a hover is tests/system/test_hot_swap.py.
"""

from __future__ import annotations

import math
import re

import pytest

from firmware.modules.mc_att_control.mc_att_control import attitude_error_rates
from common.quaternion import q_from_euler, q_mul
from firmware.modules.mc_att_control_so3.so3 import so3_error, yaw_feed_forward_body
from firmware.modules.mc_att_select import IMPLS, PARAMS as SELECT_PARAMS
from firmware.platform.module import ModuleBase, ModuleError
from firmware.platform.params import Params
from firmware.shell import Shell
from firmware.system import System
from tests.flight import truth_estimator
from tests.flight.test_mc_control import F450_PARAMS

MS = 1_000_000


# -- the law ----------------------------------------------------------------------------------


def test_so3_error_is_sin_angle_times_axis_in_body_axes():
    for axis in ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (0.6, 0.0, 0.8)):
        for angle in (0.01, 0.3, 1.2, 2.5):
            q = q_from_euler(0.2, -0.1, 1.0)
            s = math.sin(0.5 * angle)
            rot = (math.cos(0.5 * angle), axis[0] * s, axis[1] * s, axis[2] * s)
            qd = q_mul(q, rot)          # the desired attitude: q turned by angle about a body axis
            e = so3_error(q, qd)
            want = tuple(math.sin(angle) * a for a in axis)
            assert e == pytest.approx(want, abs=1e-12), (axis, angle)
            # SO(3) has no sign to choose: -qd is the same attitude
            assert so3_error(q, tuple(-c for c in qd)) == pytest.approx(want, abs=1e-12)


def test_so3_and_quaternion_laws_agree_for_small_errors_only():
    """For a small tilt error both laws give the rotation vector; at 60 degrees of roll error
    the SO(3) error (sin 60 = 0.87) is below PX4's (2 sin 30 = 1.0): another law."""
    q = q_from_euler(0.0, 0.0, 0.5)
    small = q_mul(q, q_from_euler(0.02, -0.01, 0.0))
    assert so3_error(q, small) == pytest.approx(attitude_error_rates(q, small, 1.0), abs=1e-5)
    big = q_mul(q, q_from_euler(math.radians(60.0), 0.0, 0.0))
    assert so3_error(q, big)[0] == pytest.approx(math.sin(math.radians(60.0)), abs=1e-9)
    assert attitude_error_rates(q, big, 1.0)[0] == pytest.approx(2.0 * math.sin(math.radians(30.0)),
                                                                abs=1e-9)


def test_yaw_feed_forward_is_the_world_yaw_rate_in_body_axes():
    assert yaw_feed_forward_body((1.0, 0.0, 0.0, 0.0), 0.5) == pytest.approx((0.0, 0.0, 0.5))
    # rolled 90 degrees right: the right wing (body +y) points down
    r90 = q_from_euler(math.pi / 2, 0.0, 0.3)
    assert yaw_feed_forward_body(r90, 0.5) == pytest.approx((0.0, 0.5, 0.0), abs=1e-12)


# -- the selector, with stand-in controllers ------------------------------------------------


def _standin(name: str, impl: int, fail: bool = False) -> type[ModuleBase]:
    """A controller that records itself in MC_ATT_IMPL on start, as the real two do."""

    def _start(self: ModuleBase) -> None:
        if fail:
            raise ModuleError("refused")
        params = self.system.params
        if params is not None and params["MC_ATT_IMPL"] != impl:
            params.set("MC_ATT_IMPL", impl)

    return type(f"Standin_{name}", (ModuleBase,), {"NAME": name, "_start": _start})


def _selector_system(platform, fail_so3: bool = False) -> System:
    table = {"mc_att_select": "firmware.modules.mc_att_select:McAttSelectModule",
             "mc_att_control": _standin("mc_att_control", 0),
             "mc_att_control_so3": _standin("mc_att_control_so3", 1, fail_so3)}
    system = System(platform, Params(platform, SELECT_PARAMS), modules=table)
    for name in ("mc_att_control", "mc_att_select"):
        assert system.modules.start(name) == 0
    return system


def _settle(platform) -> None:
    k = platform.kernel
    k.run(k.now_ns + 10 * MS)


def test_selector_swaps_on_parameter_and_follows_a_shell_swap(platform):
    system = _selector_system(platform)
    sh = Shell(system, lambda _t: None)
    mods, params = system.modules, system.params
    assert sh.execute("param set MC_ATT_IMPL 1") == 0
    _settle(platform)
    assert mods.running() == ["mc_att_control_so3", "mc_att_select"]
    # a shell swap back: the controller records itself, so the parameter says 0 again...
    assert sh.execute("mc_att_control_so3 stop; mc_att_control start") == 0
    _settle(platform)
    assert params["MC_ATT_IMPL"] == 0 and mods.is_running("mc_att_control")
    # ...an unrelated parameter change keeps it, and the parameter swaps once more
    params.notify()
    _settle(platform)
    assert mods.is_running("mc_att_control") and not mods.is_running("mc_att_control_so3")
    assert sh.execute("param set MC_ATT_IMPL 1") == 0
    _settle(platform)
    assert mods.is_running("mc_att_control_so3") and not mods.is_running("mc_att_control")
    assert "2 swaps" in " ".join(mods.get("mc_att_select").status_lines())
    assert set(IMPLS.values()) == {"mc_att_control", "mc_att_control_so3", "mc_att_companion"}


def test_selector_ignores_a_value_naming_no_controller(platform):
    """MC_ATT_IMPL comes from outside (a GCS's PARAM_SET): a value out of its range is
    accepted by the parameter store, and the selector says so and keeps the controller."""
    system = _selector_system(platform)
    system.params.set("MC_ATT_IMPL", 7)
    _settle(platform)
    assert system.modules.is_running("mc_att_control")
    texts = [t for _t, _s, mod, t in platform.dmesg if mod == "mc_att_select"]
    assert "MC_ATT_IMPL 7: no such attitude controller, none swapped" in texts


def test_selector_restarts_the_old_controller_when_the_new_one_fails(platform):
    system = _selector_system(platform, fail_so3=True)
    system.params.set("MC_ATT_IMPL", 1)
    _settle(platform)
    assert system.modules.is_running("mc_att_control")
    assert system.params["MC_ATT_IMPL"] == 0           # the running one recorded itself again
    texts = [t for _t, _s, mod, t in platform.dmesg if mod == "mc_att_select"]
    assert "MC_ATT_IMPL: mc_att_control_so3 did not start, mc_att_control restarted" in texts


# -- the hand-over in the in-process rig ----------------------------------------------------


SWAP_MODULES = {
    "mc_att_control_so3": "firmware.modules.mc_att_control_so3:McAttControlSo3Module",
    "mc_att_select": "firmware.modules.mc_att_select:McAttSelectModule",
}


@pytest.fixture
def rig(monkeypatch):
    """The control-module rig with the second controller and the selector in its table."""
    for name, target in SWAP_MODULES.items():
        monkeypatch.setitem(truth_estimator.CONTROL_MODULES, name, target)
    return truth_estimator.FlightRig(
        F450_PARAMS, agl_m=40.0,
        modules=("mc_rate_control", "mc_att_control", "mc_att_select", "land_detector"))


class RatesRecorder:
    """Every vehicle_rates_setpoint, as (timestamp us, roll, pitch, yaw), every 1 ms step."""

    def __init__(self, rig) -> None:
        self.node = rig.platform.orb.node("vehicle_rates_setpoint")
        self.seen = self.node.generation
        self.rows: list[tuple[int, float, float, float]] = []
        rig.sil.hooks.append(self.step)

    def step(self, _sil) -> None:
        node = self.node
        if node.generation == self.seen:
            return
        # the queue holds the last few: read what was published since the last step
        n = min(node.generation - self.seen, node.queue_len)
        for g in range(node.generation - n + 1, node.generation + 1):
            m = node.buf[g % node.queue_len]
            self.rows.append((m.timestamp, m.roll, m.pitch, m.yaw))
        self.seen = node.generation

    def around(self, t_us: int, before_us: int, after_us: int):
        return [r for r in self.rows if t_us - before_us <= r[0] <= t_us + after_us]


def _handover_line(rig, module: str) -> tuple[float, float, float]:
    """(gap ms, step rad/s, laws' difference rad/s) from the newcomer's log line."""
    text = next(t for _t, _s, mod, t in reversed(rig.platform.dmesg) if mod == module
                and t.startswith("took over"))
    m = re.search(r"([\d.]+) ms after the last, step ([\d.]+) rad/s \(laws differ by "
                  r"([\d.]+)\)", text)
    assert m, text
    return float(m[1]), float(m[2]), float(m[3])


def _largest_step(rows) -> tuple[float, int]:
    """The largest change between consecutive rate setpoints, and the longest gap (us)."""
    step = max(math.dist(a[1:], b[1:]) for a, b in zip(rows, rows[1:]))
    gap = max(b[0] - a[0] for a, b in zip(rows, rows[1:]))
    return step, gap


def test_a_second_attitude_controller_does_not_start_beside_the_first(rig):
    out: list[str] = []
    sh = Shell(rig.system, out.append)
    assert sh.execute("mc_att_control_so3 start") == 1
    assert "mc_att_control is running: `mc_att_control stop; mc_att_control_so3 start` on one " \
        "line, or set MC_ATT_IMPL" in "".join(out)
    assert rig.system.modules.running() == ["land_detector", "mc_att_control", "mc_att_select",
                                            "mc_rate_control"]


def test_swap_during_a_roll_step_keeps_the_rate_setpoint_continuous(rig):
    """Stabilized at 40 m; a 17.5 degree roll step with a yaw stick; 80 ms into it, while the
    error is largest, the shell swaps to the SO(3) law, and 0.5 s later MC_ATT_IMPL swaps back.

    The rate setpoint arrives every 4 ms (the rig's 250 Hz attitude). At each swap: the two laws
    alone differ there by ~0.2 rad/s (asserted > 0.1, so the case is a real one); the
    newcomer's first output must come within those 4 ms (no pause: it answers the latest
    attitude at once) and within 0.001 rad/s of the old controller's last one, and in the 40 ms
    around the swap no change between two samples may reach a quarter of the laws' difference
    (what the step response itself makes, ~0.01-0.03 rad/s per sample, is allowed).
    """
    rec = RatesRecorder(rig)
    sh = Shell(rig.system, lambda _t: None)
    rig.set_mode("stabilized")
    rig.set_sticks(throttle=0.0)
    rig.run(0.2)
    rig.arm()
    rig.run(1.0)
    rig.set_sticks(roll=0.5, yaw=0.3)
    rig.run(0.08)
    t_shell = rig.now_us()
    assert sh.execute("mc_att_control stop; mc_att_control_so3 start") == 0
    rig.run(0.5)
    assert rig.system.modules.is_running("mc_att_control_so3")
    assert rig.system.params["MC_ATT_IMPL"] == 1
    t_param = rig.now_us()
    assert sh.execute("param set MC_ATT_IMPL 0") == 0
    rig.run(0.5)
    assert rig.system.modules.is_running("mc_att_control")
    assert not rig.system.modules.is_running("mc_att_control_so3")
    for t_swap, newcomer in ((t_shell, "mc_att_control_so3"), (t_param, "mc_att_control")):
        gap_ms, step, laws = _handover_line(rig, newcomer)
        near = rec.around(t_swap, 20_000, 20_000)
        largest, longest_gap_us = _largest_step(near)
        print(f"\n{newcomer}: gap {gap_ms:.1f} ms, step {step:.4f} rad/s (laws differ by "
              f"{laws:.4f}); around the swap: largest step {largest:.4f} rad/s, longest gap "
              f"{longest_gap_us / 1000:.1f} ms")
        assert gap_ms <= 4.5 and longest_gap_us <= 4_500
        assert step < 1e-3                     # the first output continues the last one
        assert laws > 0.1
        assert largest < 0.25 * laws
    # and the roll step is flown to its end by the controller swapped in and back
    roll = rig.sil.world.truth().euler_rad[0]
    assert abs(roll - 0.5 * math.radians(35.0)) < math.radians(1.5)
