"""A calibration jig: the operator's hands holding a disarmed vehicle in a given attitude.

Accelerometer, level and gyro calibrations need the vehicle held still, turned onto each of
its sides, or shaken. The jig is the world for that: a host device that owns the ``truth``
port and sends the physical quantities the FMU's sensors experience for its attitude (gravity
as specific force in body axes, the body rates while it turns, the earth's field rotated into
the body, ISA pressure at the site), exactly as the JSBSim world sends them in flight. It acts
on the world only; the firmware sees nothing but its sensors.

* lone FMU board: ``CalibrationJig()`` in the hub, with :data:`TRUTH_WIRE`;
* whole system: ``CalibrationJig(world=WorldPorts(...))`` wraps the world: the world keeps
  running (battery, ESC inputs) and its truth records leave with the jig's attitude.

:class:`SideTurner` is the operator QGroundControl's page asks for: it reads the vehicle's
STATUSTEXT through a :class:`~hil.gcs.GcsClient`, turns the jig to a pending side whenever
the vehicle asks for one ("[cal] pending: ...") and spins it once about the vertical when a
magnetometer calibration says "[cal] Rotate vehicle around the detected orientation".
"""

from __future__ import annotations

import math
from typing import Any

from board.wiring import WORLD, Wire
from hil.world.atmosphere import KELVIN_0C, isa_pressure_pa, isa_temperature_k
from hil.world.magnetic import earth_field_ned_gauss
from common.quaternion import q_from_euler
from common.truth import Truth
from hil.worldlink import TRUTH_FIELDS, truth_record
from common.units import G0_M_S2

__all__ = ["SIDE_ATTITUDES_DEG", "TRUTH_WIRE", "CalibrationJig", "SideTurner", "statustexts"]

Mat = list[list[float]]
Vec = tuple[float, float, float]

#: the wire from the jig to the FMU's sensors (a lone board's orchestrator)
TRUTH_WIRE = Wire((WORLD, "truth"), ("fmu", "truth"), "the calibration jig's attitude")

#: the truth record's fields that follow the jig's attitude
_ATTITUDE_FIELDS = tuple(TRUTH_FIELDS.index(k) for k in (
    "accel_body_m_s2", "gyro_rad_s", "q_nb", "euler_rad", "mag_body_gauss"))

#: (roll, pitch) in degrees that put each of PX4's sides down
SIDE_ATTITUDES_DEG = {"down": (0.0, 0.0), "up": (180.0, 0.0), "back": (0.0, 90.0),
                      "front": (0.0, -90.0), "left": (-90.0, 0.0), "right": (90.0, 0.0)}


def _euler_dcm(roll: float, pitch: float, yaw: float) -> Mat:
    """Body -> NED rotation Rz(yaw) Ry(pitch) Rx(roll), radians."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return [[cp * cy, -cr * sy + sr * sp * cy, sr * sy + cr * sp * cy],
            [cp * sy, cr * cy + sr * sp * sy, -sr * cy + cr * sp * sy],
            [-sp, sr * cp, cr * cp]]


def _mul(a: Mat, b: Mat) -> Mat:
    return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]


def _t(a: Mat) -> Mat:
    return [[a[j][i] for j in range(3)] for i in range(3)]


def _axis_angle(axis: Vec, angle: float) -> Mat:
    """Rodrigues: the rotation by ``angle`` about the unit ``axis``."""
    x, y, z = axis
    c, s = math.cos(angle), math.sin(angle)
    v = 1.0 - c
    return [[c + x * x * v, x * y * v - z * s, x * z * v + y * s],
            [y * x * v + z * s, c + y * y * v, y * z * v - x * s],
            [z * x * v - y * s, z * y * v + x * s, c + z * z * v]]


def _log(r: Mat) -> tuple[Vec, float]:
    """Axis and angle of a rotation matrix."""
    angle = math.acos(max(-1.0, min(1.0, (r[0][0] + r[1][1] + r[2][2] - 1.0) / 2.0)))
    if angle < 1e-9:
        return (1.0, 0.0, 0.0), 0.0
    if math.pi - angle < 1e-6:  # half turn: axis from the diagonal
        d = [math.sqrt(max(0.0, (r[i][i] + 1.0) / 2.0)) for i in range(3)]
        i = max(range(3), key=lambda k: d[k])
        axis = [0.0, 0.0, 0.0]
        axis[i] = d[i]
        for j in range(3):
            if j != i:
                axis[j] = (r[i][j] + r[j][i]) / (4.0 * d[i])
        n = math.sqrt(sum(a * a for a in axis))
        return (axis[0] / n, axis[1] / n, axis[2] / n), angle
    s = 2.0 * math.sin(angle)
    return ((r[2][1] - r[1][2]) / s, (r[0][2] - r[2][0]) / s, (r[1][0] - r[0][1]) / s), angle


def _rotate_t(r: Mat, v: Vec) -> Vec:
    """r^T v: a NED vector in body axes."""
    return (r[0][0] * v[0] + r[1][0] * v[1] + r[2][0] * v[2],
            r[0][1] * v[0] + r[1][1] * v[1] + r[2][1] * v[2],
            r[0][2] * v[0] + r[1][2] * v[1] + r[2][2] * v[2])


class CalibrationJig:
    """Holds, turns and shakes the vehicle; sends truth every ``1 / rate_hz``."""

    def __init__(self, world: Any = None, roll_deg: float = 0.0, pitch_deg: float = 0.0,
                 yaw_deg: float = 0.0, rate_hz: float = 500.0, lat_deg: float = 47.397742,
                 lon_deg: float = 8.545594, alt_m: float = 488.0) -> None:
        self.world = world
        self.ports = tuple(world.ports) if world is not None else ("truth",)
        self.wired: set[str] | None = None
        self.period_ns = int(1e9 / rate_hz)
        self.lat_deg, self.lon_deg, self.alt_m = lat_deg, lon_deg, alt_m
        self.field_ned = earth_field_ned_gauss(lat_deg, lon_deg, alt_m)
        self.pressure_pa = isa_pressure_pa(alt_m)
        self.temperature_c = isa_temperature_k(alt_m) - KELVIN_0C
        self.r_bn = _euler_dcm(*(math.radians(a) for a in (roll_deg, pitch_deg, yaw_deg)))
        self._motion: tuple[str, int, int, Mat, Vec, float, float] | None = None
        self._end_target: Mat = self.r_bn  # where the current turn ends
        self._t_ns = 0
        self._next_ns = 0
        self._out: list = []

    # -- what the operator does ------------------------------------------------------------------

    @property
    def busy(self) -> bool:
        """A turn or a shake is under way."""
        return self._motion is not None

    def hold(self, roll_deg: float, pitch_deg: float, yaw_deg: float = 0.0) -> None:
        """Put the vehicle in this attitude at once (and stop any motion)."""
        self._motion = None
        self.r_bn = _euler_dcm(*(math.radians(a) for a in (roll_deg, pitch_deg, yaw_deg)))

    def turn_to(self, roll_deg: float, pitch_deg: float, yaw_deg: float = 0.0,
                duration_s: float = 1.0) -> None:
        """Turn at a constant body rate to this attitude over ``duration_s``."""
        target = _euler_dcm(*(math.radians(a) for a in (roll_deg, pitch_deg, yaw_deg)))
        axis, angle = _log(_mul(_t(self.r_bn), target))
        dur_ns = max(1, int(duration_s * 1e9))
        self._motion = ("turn", self._t_ns, dur_ns, self.r_bn, axis, angle, 0.0)
        self._end_target = target

    def turn_to_side(self, side: str, duration_s: float = 1.0) -> None:
        roll, pitch = SIDE_ATTITUDES_DEG[side]
        self.turn_to(roll, pitch, 0.0, duration_s)

    def spin(self, turns: float = 1.0, duration_s: float = 2.0) -> None:
        """Turn about the vertical (a magnetometer calibration's rotation), ``turns`` times
        round, at a constant rate, ending where it started (after whole turns)."""
        r = self.r_bn
        axis = (r[2][0], r[2][1], r[2][2])  # NED down in body axes
        angle = 2.0 * math.pi * turns
        self._motion = ("turn", self._t_ns, max(1, int(duration_s * 1e9)), r, axis, angle, 0.0)
        self._end_target = _mul(r, _axis_angle(axis, angle))

    def shake(self, amplitude_rad_s: float = 0.5, freq_hz: float = 2.0,
              duration_s: float = 1.0) -> None:
        """Rock about the body z axis (rate ``amplitude sin(2 pi f t)``), back where it was."""
        self._motion = ("shake", self._t_ns, int(duration_s * 1e9), self.r_bn, (0.0, 0.0, 1.0),
                        amplitude_rad_s, freq_hz)

    # -- host device ---------------------------------------------------------------------------

    def _state(self, t_ns: int) -> tuple[Mat, Vec]:
        m = self._motion
        if m is None:
            return self.r_bn, (0.0, 0.0, 0.0)
        kind, t0, dur, r0, axis, a, f = m
        tau = (t_ns - t0) * 1e-9
        if tau >= dur * 1e-9:
            self._motion = None
            self.r_bn = self._end_target if kind == "turn" else r0
            return self.r_bn, (0.0, 0.0, 0.0)
        if kind == "turn":
            rate = a / (dur * 1e-9)
            return _mul(r0, _axis_angle(axis, rate * tau)), (axis[0] * rate, axis[1] * rate,
                                                           axis[2] * rate)
        w = 2.0 * math.pi * f
        angle = a / w * (1.0 - math.cos(w * tau))
        rate = a * math.sin(w * tau)
        return _mul(r0, _axis_angle(axis, angle)), (axis[0] * rate, axis[1] * rate,
                                                    axis[2] * rate)

    def _truth(self, t_ns: int) -> tuple:
        r, rates = self._state(t_ns)
        roll = math.atan2(r[2][1], r[2][2])
        pitch = -math.asin(max(-1.0, min(1.0, r[2][0])))
        yaw = math.atan2(r[1][0], r[0][0])
        return truth_record(Truth(
            t_ns=t_ns, accel_body_m_s2=_rotate_t(r, (0.0, 0.0, -G0_M_S2)), gyro_rad_s=rates,
            q_nb=q_from_euler(roll, pitch, yaw), euler_rad=(roll, pitch, yaw),
            mag_body_gauss=_rotate_t(r, self.field_ned), pressure_pa=self.pressure_pa,
            temperature_c=self.temperature_c, lat_deg=self.lat_deg, lon_deg=self.lon_deg,
            alt_m=self.alt_m, agl_m=0.0, pos_ned_m=(0.0, 0.0, 0.0),
            vel_ned_m_s=(0.0, 0.0, 0.0), airspeed_m_s=0.0, diff_pressure_pa=0.0,
            battery_v=16.2, battery_a=0.5))

    def _override(self, t_ns: int, world_rec: tuple) -> tuple:
        """The world's truth record with the jig's attitude: specific force, rates,
        quaternion, Euler angles and field; position, pressure, battery stay the world's."""
        mine = self._truth(t_ns)
        rec = list(world_rec)
        for i in _ATTITUDE_FIELDS:
            rec[i] = mine[i]
        return tuple(rec)

    def run_until(self, t_ns: int) -> None:
        if self.world is not None:
            self.world.wired = self.wired
            self.world.run_until(t_ns)
            for rec in self.world.outputs(t_ns):
                if rec[0] == "truth":
                    self._t_ns = rec[1]
                    rec = ("truth", rec[1], self._override(rec[1], rec[2]))
                self._out.append(rec)
        else:
            while self._next_ns <= t_ns:
                self._t_ns = self._next_ns
                self._out.append(("truth", self._next_ns, self._truth(self._next_ns)))
                self._next_ns += self.period_ns
        self._t_ns = t_ns

    def outputs(self, until_ns: int) -> list:
        out, self._out = self._out, []
        return out

    def input(self, port: str, t_ns: int, payload: Any) -> None:
        if self.world is None:
            raise ValueError(f"the calibration jig has no input port {port!r}")
        self.world.input(port, t_ns, payload)


def statustexts(messages: list[Any]) -> list[str]:
    """The texts of STATUSTEXT messages, chunks joined (MAVLink 2: a text longer than 50
    characters goes in chunks sharing an ``id``, ``chunk_seq`` counting; the last is shorter
    than 50), as QGroundControl shows them."""
    out: list[str] = []
    partial: dict[int, list[str]] = {}
    for m in messages:
        text = m.text.split("\0", 1)[0] if isinstance(m.text, str) else str(m.text)
        if not getattr(m, "id", 0):
            out.append(text)
            continue
        parts = partial.setdefault(m.id, [])
        parts.append(text)
        if not _chunk_open(m):
            out.append("".join(partial.pop(m.id)))
    return out


def _chunk_open(m: Any) -> bool:
    """A chunk of a longer STATUSTEXT that more chunks follow."""
    return bool(getattr(m, "id", 0)) and len(m.text.rstrip("\0")) >= 50


class SideTurner:
    """The operator of a six-sided calibration: each "[cal] pending: ..." turns the jig to
    the first pending side it has not just been put on (``order``: the sides to prefer)."""

    def __init__(self, gcs: Any, jig: CalibrationJig, turn_s: float = 1.0,
                 order: tuple[str, ...] = ("down", "up", "back", "front", "left", "right"),
                 spin_s: float = 2.0) -> None:
        self.gcs = gcs
        self.jig = jig
        self.turn_s = turn_s
        self.spin_s = spin_s
        self.order = order
        self.mark = gcs.mark()
        self.texts: list[str] = []
        self.current = ""

    def poll(self) -> list[str]:
        """Read new STATUSTEXTs and act on them; the new texts."""
        msgs = self.gcs.messages("STATUSTEXT", self.mark)
        held = 0  # a text still missing chunks is read again next time, whole
        while held < len(msgs) and _chunk_open(msgs[-1 - held]):
            held += 1
        self.mark = self._cursor_at(msgs[-held]) if held else self.gcs.mark()
        new = statustexts(msgs[:len(msgs) - held])
        for text in new:
            self.texts.append(text)
            if text == "[cal] Rotate vehicle around the detected orientation":
                self.jig.spin(1.0, self.spin_s)
            elif text.startswith("[cal] pending:"):
                side = self.choose(text.split(":", 1)[1].split())
                if side and side != self.current:
                    self.jig.turn_to_side(side, self.turn_s)
                    self.current = side
        return new

    def _cursor_at(self, message: Any) -> int:
        """The GCS log cursor just before ``message``."""
        log = self.gcs.log
        for k in range(len(log) - 1, -1, -1):
            if log[k][1] is message:
                return self.gcs._base + k
        return self.gcs.mark()

    def choose(self, pending: list[str]) -> str:
        """The side to turn to when these are pending ('' to stay)."""
        return next((s for s in self.order if s in pending and s != self.current),
                    pending[0] if pending else "")

    def run(self, timeout_s: float, step_s: float = 0.05) -> list[str]:
        """Play the operator until the calibration ends; every STATUSTEXT seen."""
        t = 0.0
        while t < timeout_s:
            self.gcs.step(step_s)
            t += step_s
            for text in self.poll():
                if text.startswith(("[cal] calibration done", "[cal] calibration failed",
                                    "[cal] calibration cancelled")):
                    return self.texts
        raise TimeoutError(f"calibration not finished in {timeout_s} s: {self.texts[-5:]}")
