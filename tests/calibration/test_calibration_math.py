"""The pure parts: the per-axis offset/scale fit, PX4's side detector, and the jig's physics
(each side's specific force is the one the detector expects; a turn's body rates integrate to
the turn)."""

from __future__ import annotations

from common.units import G0_M_S2
import math

import pytest

from common.truth import TRUTH_FIELDS
from firmware.modules.commander.calibration.accel import fit_axis
from firmware.modules.commander.calibration.level import tilt_deg
from firmware.modules.commander.calibration.orientation import (
    MOTION,
    NOTHING,
    REST,
    SIDE_GRAVITY,
    OrientationDetector,
)
from firmware.modules.commander.calibration.messages import SIDE_NAMES
from hil.calibration_jig import CalibrationJig

ACC = TRUTH_FIELDS.index("accel_body_m_s2")
GYRO = TRUTH_FIELDS.index("gyro_rad_s")
PRESSURE = TRUTH_FIELDS.index("pressure_pa")


def test_fit_axis_recovers_offset_and_scale():
    true = [g[0] for g in SIDE_GRAVITY]
    raw = [0.3 + t * 1.02 for t in true]
    offset, scale = fit_axis(true, raw)
    assert offset == pytest.approx(0.3)
    assert scale == pytest.approx(1 / 1.02)
    assert all(math.isnan(v) for v in fit_axis([1.0] * 6, raw))  # no +-g on this axis


def test_detector_names_each_side_after_rest():
    for side, g in enumerate(SIDE_GRAVITY):
        det = OrientationDetector()
        events = [det.feed(i * 2500, g) for i in range(800)]  # 2 s at 400 Hz
        assert REST in events
        assert side in events, SIDE_NAMES[side]
        assert events.index(REST) < events.index(side)


def test_detector_reports_motion_and_no_side_while_moving():
    det = OrientationDetector()
    events = [det.feed(i * 2500, (0.0, 0.0, -G0_M_S2)) for i in range(200)]
    assert events.count(REST) == 1
    moving = [det.feed((200 + i) * 2500, (3.0 * math.sin(i / 10), 0.0, -G0_M_S2))
              for i in range(800)]
    assert MOTION in moving
    assert not any(e >= 0 for e in moving)
    assert events[0] == NOTHING


def test_tilt_of_a_level_and_a_rolled_body():
    assert tilt_deg((0.0, 0.0, -G0_M_S2)) == pytest.approx((0.0, 0.0))
    r = math.radians(10)
    roll, pitch = tilt_deg((0.0, -G0_M_S2 * math.sin(r), -G0_M_S2 * math.cos(r)))
    assert roll == pytest.approx(10.0) and pitch == pytest.approx(0.0, abs=1e-9)


def test_jig_sides_give_the_detectors_specific_force():
    jig = CalibrationJig(rate_hz=100)
    for name, g in zip(SIDE_NAMES, SIDE_GRAVITY):
        jig.turn_to_side(name, duration_s=0.01)
        jig.run_until(jig._t_ns + 50_000_000)
        rec = jig.outputs(0)[-1][2]
        assert rec[ACC] == pytest.approx(g, abs=1e-9), name
        assert rec[GYRO] == (0.0, 0.0, 0.0)


def test_jig_turn_rates_integrate_to_the_turn():
    jig = CalibrationJig(rate_hz=1000)
    jig.turn_to(0.0, 90.0, 0.0, duration_s=0.5)
    jig.run_until(600_000_000)
    recs = [r[2] for r in jig.outputs(0)]
    angle = sum(r[GYRO][1] for r in recs) * 1e-3
    assert angle == pytest.approx(math.pi / 2, rel=0.01)
    assert recs[-1][ACC] == pytest.approx((G0_M_S2, 0.0, 0.0), abs=1e-9)


class _StubWorld:
    """The port interface of hil.worldlink.WorldPorts, with a level vehicle's truth."""

    ports = ("truth", "battery", "esc1")

    def __init__(self):
        self.wired = None
        self.inputs = []
        self.t_ns = 0
        self._out = []

    def run_until(self, t_ns):
        while self.t_ns + 1_000_000 <= t_ns:
            self.t_ns += 1_000_000
            rec = [None] * len(TRUTH_FIELDS)
            rec[TRUTH_FIELDS.index("t_ns")] = self.t_ns
            rec[ACC] = (0.0, 0.0, -G0_M_S2)
            rec[GYRO] = (0.0, 0.0, 0.0)
            rec[PRESSURE] = 95_000.0
            self._out.append(("truth", self.t_ns, tuple(rec)))
        self._out.append(("battery", self.t_ns, (16.0, 1.0)))

    def outputs(self, until_ns):
        out, self._out = self._out, []
        return out

    def input(self, port, t_ns, payload):
        self.inputs.append((port, t_ns, payload))


def test_jig_over_a_world_replaces_only_the_attitude():
    """Wrapping the world (whole system): the world keeps stepping and its other ports pass
    through; its truth records leave with the jig's attitude, at the world's own times."""
    world = _StubWorld()
    jig = CalibrationJig(world=world)
    assert set(jig.ports) == set(world.ports)
    jig.turn_to_side("left", duration_s=0.01)
    jig.run_until(20_000_000)
    out = jig.outputs(0)
    truths = [r for r in out if r[0] == "truth"]
    assert [r[1] for r in truths] == [i * 1_000_000 for i in range(1, 21)]
    assert truths[-1][2][ACC] == pytest.approx((0.0, G0_M_S2, 0.0), abs=1e-9)
    assert all(r[2][PRESSURE] == 95_000.0 for r in truths)  # the world's, not the jig's
    assert ("battery", 20_000_000, (16.0, 1.0)) in out
    jig.input("esc1", 5, (1500, 2500))
    assert world.inputs == [("esc1", 5, (1500, 2500))]
