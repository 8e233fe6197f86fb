"""``mc_att_companion`` in-process (issue 24): on a booted FMU with the test standing in for
the estimator, the commander, the land detector and the companion (publishing their topics
every 4 ms, the 250 Hz attitude rate), the module must forward the companion's rates while
fresh and safe, fall back to the FMU's law on each failure at the stated time, latch, never
let a NaN through, and switch both ways without a step. The whole system flying with the
companion is tests/system/test_flight.py (seed 2).
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from firmware.modules.mc_att_control.handover import HANDOVER_TAU_S
from firmware.platform.uorb import Subscription
from firmware.platform.workqueue import WorkItem
from tests.helpers import booted_fmu, publish

MS = 1_000_000
WARN = 4                            # dmesg severity of PX4_WARN
PERIOD_US = 4_000
TIMEOUT_MS = 20                     # MC_CMP_TIMEOUT's default
#: the attitude setpoint: 10 degrees of roll; the vehicle level, so the FMU's law commands
#: ~MC_ROLL_P * 0.17 = 1.1 rad/s of roll, far from what the companion sends
SP_ROLL = math.radians(10.0)
Q_SP = (math.cos(SP_ROLL / 2), math.sin(SP_ROLL / 2), 0.0, 0.0)
LEVEL = (1.0, 0.0, 0.0, 0.0)
CMP = (0.3, -0.2, 0.1, -0.55)       # the companion: roll, pitch, yaw rad/s, thrust_body z
FADE_STEPS = int(5 * HANDOVER_TAU_S * 1e6 / PERIOD_US) + 2   # until a hand-over fade is over


@pytest.fixture(scope="module")
def board():
    b = booted_fmu({"SYS_AUTOSTART": 0, "SDLOG_MODE": -1})
    assert b.ctl_shell("mc_att_select start")[0] == 0
    b.standin = StandIn(b)
    b.standin.schedule_on_interval(PERIOD_US)
    return b


class StandIn(WorkItem):
    """The estimator and the companion: every 4 ms (on a queue of its own, so nothing delays it and each attitude passes the
    controller's 250 Hz interval limit), the companion's
    rate setpoint (if it speaks) and then the attitude, as the real ones arrive."""

    def __init__(self, board) -> None:
        super().__init__(board.platform, "att_standin", "wq:test1")
        self.b = board
        self.q = LEVEL
        self.cmp: tuple[float, float, float, float] | None = None
        self.cmp_last_us = -1
        self.q_sent: tuple[float, float, float, float] | None = None
        self.q_since_us = -1      # when the attitude last changed

    def run(self) -> None:
        b = self.b
        now = self.platform.hrt.absolute_time()
        if self.q != self.q_sent:
            self.q_sent, self.q_since_us = self.q, now
        if self.cmp is not None:
            c = self.cmp
            publish(b, "companion_rates_setpoint", roll=c[0], pitch=c[1], yaw=c[2],
                    thrust_body=[0.0, 0.0, c[3]])
            self.cmp_last_us = now
        publish(b, "vehicle_attitude", q=list(self.q), timestamp_sample=now)


class Rig:
    """Drives the module in 4 ms steps and records every rate setpoint it publishes."""

    def __init__(self, board, standin: StandIn) -> None:
        self.b = board
        self.src = standin
        self.out = Subscription(board.platform.orb, "vehicle_rates_setpoint")
        self.out.update_all()
        self.rows: list[tuple[int, tuple[float, float, float], float]] = []
        self.t0_us = self.now_us()

    @property
    def q(self) -> tuple[float, float, float, float]:
        return self.src.q

    @q.setter
    def q(self, q: tuple[float, float, float, float]) -> None:
        self.src.q = q

    @property
    def cmp_last_us(self) -> int:
        return self.src.cmp_last_us

    def now_us(self) -> int:
        return self.b.kernel.now_ns // 1000

    def state(self, armed: bool, landed: bool) -> None:
        b = self.b
        publish(b, "vehicle_control_mode", flag_armed=armed, flag_control_attitude_enabled=True,
                flag_control_auto_enabled=True, flag_control_position_enabled=True,
                flag_control_velocity_enabled=True, flag_control_altitude_enabled=True,
                flag_control_climb_rate_enabled=True)
        publish(b, "actuator_armed", armed=armed)
        publish(b, "vehicle_land_detected", landed=landed, maybe_landed=landed)
        publish(b, "vehicle_attitude_setpoint", q_d=list(Q_SP), thrust_body=[0.0, 0.0, -0.5],
                roll_body=SP_ROLL)

    def step(self, n: int = 1, cmp: tuple[float, float, float, float] | None = None) -> None:
        """``n`` attitude periods; the companion sends ``cmp`` in each one (None: silent)."""
        self.src.cmp = cmp
        k = self.b.kernel
        for _ in range(n):
            k.run(k.now_ns + PERIOD_US * 1000)
            for m in self.out.update_all():
                self.rows.append((m.timestamp, (m.roll, m.pitch, m.yaw), m.thrust_body[2]))

    def last(self) -> tuple[float, float, float]:
        return self.rows[-1][1]

    def thrust(self) -> float:
        return self.rows[-1][2]

    def messages(self, level: int | None = None) -> list[str]:
        return [t for ts, lvl, mod, t in self.b.platform.dmesg
                if mod == "mc_att_companion" and ts >= self.t0_us
                and (level is None or lvl == level)]

    def status(self) -> str:
        status, out = self.b.ctl_shell("mc_att_companion status")
        assert status == 0
        return out


@pytest.fixture
def rig(board):
    """A freshly started mc_att_companion on the ground, its FMU law's output recorded."""
    board.ctl_shell("mc_att_companion stop; mc_att_control stop; mc_att_control_so3 stop")
    board.standin.q = LEVEL
    r = Rig(board, board.standin)
    r.state(armed=False, landed=True)
    r.step(8)                     # the last test's companion is silent, its message stale
    r.t0_us = r.now_us()
    assert board.ctl_shell("mc_att_companion start")[0] == 0
    r.step(2)
    return r


def fmu_law(r: Rig) -> tuple[float, float, float]:
    """What the FMU's law alone gives here: its output before the companion's first message."""
    r.state(armed=True, landed=False)
    r.step(2)
    return r.last()


def dist(a, b) -> float:
    return math.dist(a, b)


def largest_step(rows) -> float:
    return max(dist(a[1], b[1]) for a, b in zip(rows, rows[1:]))


def test_flies_the_fmu_law_until_the_companion_speaks_then_forwards_it_while_fresh(rig):
    fmu = fmu_law(rig)
    assert fmu[0] > 0.8                           # the FMU's law at work, not waiting
    assert "flying the FMU law until the companion's first rate setpoint" in rig.messages()
    rig.step(FADE_STEPS, cmp=CMP)
    assert rig.last() == pytest.approx(CMP[:3], abs=1e-6)
    assert rig.thrust() == pytest.approx(CMP[3], abs=1e-6)
    assert any(t.startswith("first rate setpoint from the companion") for t in rig.messages())
    s = rig.status()
    assert "source: companion" in s and "fallbacks: 0" in s
    assert f"{FADE_STEPS} forwarded" in s
    assert not rig.messages(WARN)


def test_engaging_the_companion_in_flight_has_no_step(rig):
    fmu = fmu_law(rig)
    n0 = len(rig.rows)
    rig.step(FADE_STEPS, cmp=CMP)
    rows = rig.rows[n0 - 1:]
    assert dist(fmu, CMP[:3]) > 0.8               # the two sources differ much
    assert dist(rows[1][1], rows[0][1]) < 0.05    # the first forwarded output continues
    assert largest_step(rows) < 0.05
    assert rows[-1][1] == pytest.approx(CMP[:3], abs=1e-6)


def test_stale_companion_falls_back_within_one_attitude_period_of_the_timeout(rig):
    fmu = fmu_law(rig)
    rig.step(FADE_STEPS, cmp=CMP)
    t_last = rig.cmp_last_us
    n0 = len(rig.rows)
    rig.step(10)                                   # the companion is silent for 40 ms
    after = rig.rows[n0:]
    # outputs at most MC_CMP_TIMEOUT after its last message still forward it
    kept = [r for r in after if r[0] - t_last <= TIMEOUT_MS * 1000]
    assert kept and all(r[1] == pytest.approx(CMP[:3], abs=1e-6) for r in kept)
    first_fmu = next(r for r in after if r[0] - t_last > TIMEOUT_MS * 1000)
    took_us = first_fmu[0] - t_last
    assert TIMEOUT_MS * 1000 < took_us <= TIMEOUT_MS * 1000 + PERIOD_US + 500
    warn = rig.messages(WARN)
    assert len(warn) == 1 and warn[0].startswith(
        "FMU law flies (latched): stale: no companion rate setpoint for 2") \
        and warn[0].endswith(" ms (MC_CMP_TIMEOUT 20 ms)")
    # the whole line fits the log's message (log_message.text: 127 characters)
    assert len(f"[mc_att_companion] {warn[0]}") <= 127
    # bumpless: the first FMU output continues the last forwarded one
    assert dist(first_fmu[1], CMP[:3]) < 0.05
    # latched: the companion is back, fresh and sane, and is not taken again
    rig.step(FADE_STEPS, cmp=CMP)
    assert rig.last() == pytest.approx(fmu, abs=1e-5)
    assert rig.thrust() == pytest.approx(-0.5, abs=1e-6)       # the FMU's setpoint's thrust
    s = rig.status()
    assert "fallback, latched" in s and "stale" in s and "fallbacks: 1 (stale)" in s


@pytest.mark.parametrize("cmp, reason", [
    ((4.0, 0.0, 0.0, -0.5), "envelope: roll rate +4.00 rad/s beyond MC_ROLLRATE_MAX (220 deg/s)"),
    ((0.0, -4.0, 0.0, -0.5), "envelope: pitch rate -4.00 rad/s beyond MC_PITCHRATE_MAX (220 deg/s)"),
    ((0.0, 0.0, 3.6, -0.5), "envelope: yaw rate +3.60 rad/s beyond MC_YAWRATE_MAX (200 deg/s)"),
    ((0.0, 0.0, 0.0, 0.3), "envelope: thrust_body (0.00, 0.00, 0.30) outside 0..1 up"),
    ((0.0, 0.0, 0.0, -1.5), "envelope: thrust_body (0.00, 0.00, -1.50) outside 0..1 up"),
    ((math.nan, 0.0, 0.0, -0.5), "envelope: non-finite roll rate (nan)"),
    ((0.0, math.inf, 0.0, -0.5), "envelope: non-finite pitch rate (inf)"),
    ((0.0, 0.0, -math.inf, -0.5), "envelope: non-finite yaw rate (-inf)"),
    ((0.0, 0.0, 0.0, math.nan), "envelope: non-finite thrust_body[2] (nan)"),
])
def test_each_envelope_rule_falls_back_at_once_bumpless_and_nothing_bad_gets_through(
        rig, cmp, reason):
    fmu = fmu_law(rig)
    rig.step(FADE_STEPS, cmp=CMP)
    n0 = len(rig.rows)
    rig.step(1, cmp=cmp)
    rig.step(FADE_STEPS, cmp=CMP)                 # good again: latched all the same
    warn = rig.messages(WARN)
    assert len(warn) == 1 and warn[0] == f"FMU law flies (latched): {reason}", warn
    assert len(f"[mc_att_companion] {warn[0]}") <= 127
    rows = rig.rows[n0 - 1:]
    # the bad setpoint never reached the rate controller, the switch had no step
    assert all(math.isfinite(v) for r in rows for v in (*r[1], r[2]))
    assert all(-1.0 <= r[2] <= 0.0 for r in rows)
    assert dist(rows[1][1], CMP[:3]) < 0.05
    assert largest_step(rows) < 0.05
    assert rig.last() == pytest.approx(fmu, abs=1e-5)


def test_a_companion_at_its_own_rate_limit_is_inside_the_envelope(rig):
    """Found in the mission: the companion's mc_att_control clamps to the same MC_YAWRATE_MAX,
    and its float32 message rounds 200 deg/s (3.4906585 rad/s) up by 1e-7: that is the limit,
    not beyond it."""
    lim = float(np.float32(math.radians(200.0)))
    assert lim > math.radians(200.0)
    fmu_law(rig)
    rig.step(FADE_STEPS, cmp=(0.0, 0.0, lim, -0.5))
    assert not rig.messages(WARN)
    assert rig.last()[2] == pytest.approx(lim, abs=1e-6)


def test_tilt_error_beyond_the_limit_falls_back_after_the_allowed_time(rig):
    """The vehicle 45 degrees off its setpoint's tilt (MC_CMP_ERR_MAX 30) while the companion
    keeps sending: fallback once the error lasted beyond MC_CMP_ERR_TM (200 ms), not before;
    a shorter excursion is tolerated."""
    fmu_law(rig)
    rig.step(FADE_STEPS, cmp=CMP)
    off = math.radians(45.0 + 10.0)               # roll 55 against a 10 degree setpoint
    rig.q = (math.cos(off / 2), math.sin(off / 2), 0.0, 0.0)
    rig.step(30, cmp=CMP)                         # 120 ms: tolerated
    assert not rig.messages(WARN)
    rig.q = LEVEL
    rig.step(5, cmp=CMP)
    rig.q = (math.cos(off / 2), math.sin(off / 2), 0.0, 0.0)
    n0 = len(rig.rows)
    rig.step(70, cmp=CMP)
    t0 = rig.src.q_since_us                       # the first attitude this far off
    warn = rig.messages(WARN)
    assert len(warn) == 1 and re.fullmatch(
        r"FMU law flies \(latched\): envelope: tilt error 45.0 deg beyond MC_CMP_ERR_MAX "
        r"\(30 deg\) for 20\d ms", warn[0]), warn
    assert len(f"[mc_att_companion] {warn[0]}") <= 127
    t_warn = next(ts for ts, lvl, mod, _t in rig.b.platform.dmesg
                  if mod == "mc_att_companion" and lvl == WARN and ts >= rig.t0_us)
    assert 200_000 < t_warn - t0 <= 200_000 + PERIOD_US + 500
    # bumpless here too: the FMU's law wants ~4 rad/s more (at MC_ROLLRATE_MAX), and gets
    # there by the hand-over fade (2 % of the difference per 4 ms), not in one step
    rig.step(FADE_STEPS, cmp=CMP)
    assert rig.last()[0] == pytest.approx(-math.radians(220.0), abs=1e-5)
    assert largest_step(rig.rows[n0:]) < 0.12


def test_on_the_ground_it_is_mc_att_control_and_a_late_or_broken_companion_is_no_fault(rig):
    fmu = fmu_law(rig)
    rig.state(armed=False, landed=True)
    rig.step(3, cmp=(math.nan, 0.0, 0.0, -0.5))   # garbage on the ground: not flown, no latch
    rig.step(20)                                   # and silence
    assert all(math.isfinite(v) for r in rig.rows for v in r[1])
    assert not rig.messages(WARN) and "disarmed or landed" in rig.status()
    rig.state(armed=True, landed=False)
    rig.step(FADE_STEPS, cmp=CMP)                  # takes off with a fresh companion
    assert rig.last() == pytest.approx(CMP[:3], abs=1e-6)
    assert dist(fmu, CMP[:3]) > 0.8


def test_a_stale_companion_at_takeoff_falls_back_at_once(rig):
    rig.step(2, cmp=CMP)                           # heard on the ground, then silent
    rig.step(10)
    fmu = fmu_law(rig)
    warn = rig.messages(WARN)
    assert len(warn) == 1 and "stale" in warn[0]
    assert fmu[0] > 0.8


def test_the_latch_ends_with_a_restart_or_mc_att_impl_set_again(rig, board):
    fmu = fmu_law(rig)
    rig.step(FADE_STEPS, cmp=CMP)
    rig.step(8)                                    # stale: latched
    rig.step(FADE_STEPS, cmp=CMP)
    assert rig.last() == pytest.approx(fmu, abs=1e-5)
    # MC_ATT_IMPL to the FMU's controller and back: mc_att_select restarts the module
    assert board.ctl_shell("param set MC_ATT_IMPL 0")[0] == 0
    rig.step(2, cmp=CMP)
    assert board.system.modules.is_running("mc_att_control")
    assert board.ctl_shell("param set MC_ATT_IMPL 2")[0] == 0
    rig.step(FADE_STEPS, cmp=CMP)
    assert board.system.modules.is_running("mc_att_companion")
    assert rig.last() == pytest.approx(CMP[:3], abs=1e-6)
    assert "source: companion" in rig.status()
    # and a restart from the shell clears it too
    rig.step(8)
    assert "fallback, latched" in rig.status()
    assert board.ctl_shell("mc_att_companion stop; mc_att_companion start")[0] == 0
    rig.step(FADE_STEPS, cmp=CMP)
    assert rig.last() == pytest.approx(CMP[:3], abs=1e-6)
