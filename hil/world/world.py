"""The world: JSBSim vehicle, ESCs, battery and environment, stepped at a fixed rate.

The world owns an integer clock ``t_ns = steps * dt_ns`` (JSBSim's float time is never used for
it). One ``step()``:

1. every ESC applies the PWM inputs stamped at or before ``t_ns`` and runs its timers and lag;
   every servo input (hil/world/servo.py) applies its pulses and hands its position command to
   the model's servo actuator (lag and rate limit inside JSBSim);
2. each motor gets the ESC throttle times battery voltage (as a fraction of the JSBSim motor's
   rated voltage), so the motors weaken as the pack sags (an airframe with servos: the voltage
   behind the ESCs' bus capacitors, ``BUS_ALPHA``, which keeps several large loads stable);
3. JSBSim advances dt;
4. the battery integrates the current drawn (motor electrical power through the ESC efficiency,
   plus avionics) over dt;
5. ``t_ns += dt_ns``.

``truth()`` reads the state after the last step (built on demand, cached per step).
Same constructor arguments and same inputs give the same outputs: there is no wall clock, and
the only randomness is ``self.rng`` (a numpy Generator from ``seed`` unless one is passed in).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from .battery import Battery, BatteryParams
from .esc import Esc, EscParams
from .fdm import AIRFRAMES, FT, N_CHANNELS, N_MAIN, PSF_PA, Fdm, Servo
from .servo import ServoInput
from .magnetic import earth_field_ned_gauss
from common.truth import Truth

__all__ = ["World", "PX4_HOME"]

PX4_HOME = (47.397742, 8.545594, 488.0)  # lat deg, lon deg, ground altitude m AMSL

N_PWM_CHANNELS = N_MAIN  # MAIN1..8 (set_motor_pwm_us); AUX1..6 are world channels 8..13
#: current of a motor spinning without its propeller at full throttle (the E305's no-load
#: current at 11 V is about 0.5 A; a larger figure covers the ESC's own losses)
NOLOAD_CURRENT_A = 0.7
DEFAULT_PWM_PERIOD_NS = 2_500_000  # 400 Hz, PX4's default multicopter PWM rate
#: per 1 ms step, the ESC bus voltage's approach to the pack's (~3 ms, their capacitors)
BUS_ALPHA = 0.3

# WGS-84
_A = 6378137.0
_E2 = 6.69437999014e-3
_TWO_PI = 2.0 * math.pi


class World:
    """See the module docstring. Units: SI; frames: body FRD, NED."""

    def __init__(
        self,
        seed: int = 0,
        rate_hz: int = 1000,
        airframe: str = "f450",
        *,
        lat_deg: float = PX4_HOME[0],
        lon_deg: float = PX4_HOME[1],
        alt_m: float = PX4_HOME[2],
        heading_deg: float = 0.0,
        agl_m: float = 0.0,
        airspeed_m_s: float = 0.0,
        pitch_deg: float = 0.0,
        rng: np.random.Generator | None = None,
        esc_params: EscParams | None = None,
        battery_params: BatteryParams | None = None,
        mag_field_ned_gauss: tuple[float, float, float] | None = None,
    ) -> None:
        """Create a world.

        alt_m is the ground altitude AMSL at the start point; agl_m is the height of the landing
        gear above it (0: resting on the ground, motors off). heading_deg: 0 is north.
        airspeed_m_s: initial horizontal speed along the heading (a plane started in the air);
        pitch_deg: initial pitch, which is then also the initial angle of attack.
        battery_params: the airframe's pack (``Airframe.battery``) unless given.
        """
        if rate_hz <= 0 or 1_000_000_000 % rate_hz:
            raise ValueError("rate_hz must divide 1e9 (integer-ns step), e.g. 250, 400, 1000")
        try:
            af = AIRFRAMES[airframe.lower()]
        except KeyError:
            raise ValueError(f"unknown airframe {airframe!r}; known: {sorted(AIRFRAMES)}")
        self.airframe = af
        self.seed = seed
        self.rate_hz = rate_hz
        self.dt_ns = 1_000_000_000 // rate_hz
        self.dt_s = self.dt_ns * 1e-9
        self.t_ns = 0
        self.steps = 0
        self.rng = rng if rng is not None else np.random.default_rng(seed)

        self.fdm = Fdm(af, self.dt_s, lat_deg, lon_deg, alt_m, heading_deg, agl_m, seed,
                       airspeed_m_s=airspeed_m_s, pitch_deg=pitch_deg)
        #: the receiver on each world channel (MAIN1..8, AUX1..6): an :class:`Esc` for a motor
        #: (and for a channel wired to nothing, kept for inspection), a :class:`ServoInput`
        #: for a servo
        self.escs: list[Esc | ServoInput] = [
            ServoInput() if isinstance(out, Servo) else Esc(self.dt_ns, esc_params)
            for out in af.outputs
        ]
        assert len(self.escs) == N_CHANNELS
        self.channels = self.escs
        self.battery = Battery(battery_params or af.battery, self.dt_s)
        self._bp = self.battery.params
        self._motor_ch = af.motor_channels
        self._esc_updates = tuple(self.escs[ch].update for ch in self._motor_ch)
        setters = self.fdm.servo_setters
        self._servo_ch = af.servo_channels
        self._servo_updates = tuple(self.escs[ch].update for ch in self._servo_ch)
        self._servo_set = tuple(setters[ch] for ch in self._servo_ch)
        self._servo_cmd = [0.0] * len(self._servo_ch)
        self._stepped = frozenset(self._motor_ch + self._servo_ch)
        if self._servo_ch:  # a multicopter's step() does not even test for servos
            self.step = self._step_with_servos  # type: ignore[method-assign,assignment]
        #: the voltage the ESCs of an airframe with servos see (:meth:`_step_with_servos`);
        #: negative until the first step
        self._bus_v = -1.0
        self._throttle_set = self.fdm.throttle_setters
        self._current_get = self.fdm.current_getters
        self._vmax = af.motor_max_volts
        self._jsb_throttle = [0.0] * af.n_motors
        self.mag_field_ned_gauss = (
            tuple(mag_field_ned_gauss)
            if mag_field_ned_gauss is not None
            else earth_field_ned_gauss(lat_deg, lon_deg, alt_m)
        )

        # Settle so that every derived JSBSim output (specific force in particular, which lags
        # one step) is valid at t = 0: on the ground, let the gear take the load; in the air,
        # just two steps (2 ms of fall). The world clock starts after this.
        settle = max(2, round(0.2 / self.dt_s)) if agl_m <= 0.0 else 2
        for _ in range(settle):
            self.fdm.run()

        g = self.fdm.truth_getters
        self._lat0 = g[9]()
        self._lon0 = g[10]()
        self._alt0 = g[11]() * FT
        lat0 = math.radians(self._lat0)
        s2 = math.sin(lat0) ** 2
        rn = _A / math.sqrt(1.0 - _E2 * s2)  # prime vertical radius
        rm = rn * (1.0 - _E2) / (1.0 - _E2 * s2)  # meridian radius
        self._m_per_deg_n = math.radians(1.0) * (rm + self._alt0)
        self._m_per_deg_e = math.radians(1.0) * (rn + self._alt0) * math.cos(lat0)
        self._truth_getters = self.fdm.truth_getters
        self._truth_cache: Truth | None = None
        self._truth_step = -1
        #: faults in the physics (hil/faults/vehicle.py): motor -> (kind, thrust fraction)
        self.motor_faults: dict[int, tuple[str, float]] = {}
        self._freewheel_a = [0.0] * af.n_motors
        self._extra_a = 0.0
        #: magnetic disturbance at the vehicle: (constant body field, body field per amp of
        #: battery current), gauss; None when there is none
        self.mag_disturbance: tuple[tuple[float, float, float], tuple[float, float, float]] \
            | None = None

    # -- inputs ---------------------------------------------------------------------------
    def set_pwm(self, ch: int, t_ns: int, high_ns: int, period_ns: int) -> None:
        """From t_ns on, channel ch carries a pulse of high_ns every period_ns.

        high_ns = 0 is a line held low (no pulses, e.g. a dead IO). Inputs stamped in the past
        apply at the next step; inputs stamped ahead apply at the first step at or after them.
        Channels the airframe does not use are kept (for inspection) but drive nothing.
        Channels 0..7 are MAIN1..8, 8..13 AUX1..6.
        """
        esc = self.escs[ch]
        esc.set_signal(t_ns, high_ns, period_ns)
        if ch not in self._stepped:
            esc.update(self.t_ns)  # not stepped by step(): drain what is due

    def set_motor_pwm_us(
        self, widths_us: Sequence[float], period_ns: int = DEFAULT_PWM_PERIOD_NS
    ) -> None:
        """Set channels 0..len-1 to these pulse widths (us), effective now."""
        if not 1 <= len(widths_us) <= N_PWM_CHANNELS:
            raise ValueError(f"1..{N_PWM_CHANNELS} pulse widths expected")
        t = self.t_ns
        for ch, w in enumerate(widths_us):
            self.set_pwm(ch, t, round(w * 1000.0), period_ns)

    # -- stepping -------------------------------------------------------------------------
    def step(self, n: int = 1) -> None:
        """Advance n steps of dt. (An airframe with servos steps through
        :meth:`_step_with_servos` instead, bound over this method in ``__init__``.)"""
        battery = self.battery
        run = self.fdm.run
        drive = self._drive_motors
        load = self._load_battery
        vmax = self._vmax
        dt_ns = self.dt_ns
        for _ in range(n):
            t = self.t_ns
            drive(t, battery.voltage_v / vmax)
            run()
            load()
            self.t_ns = t + dt_ns
            self.steps += 1

    def _step_with_servos(self, n: int = 1) -> None:
        """:meth:`step` for an airframe with servos (kept apart so that a multicopter's loop
        does not pay for them)."""
        s_updates = self._servo_updates
        s_set = self._servo_set
        s_cmd = self._servo_cmd
        ns = len(s_updates)
        battery = self.battery
        run = self.fdm.run
        drive = self._drive_motors
        load = self._load_battery
        vmax = self._vmax
        dt_ns = self.dt_ns
        # The ESCs see the pack through their bus capacitors (BUS_ALPHA per step: ~3 ms). Fed
        # the pack voltage of the step before directly, the loop pack voltage -> motor
        # currents -> pack current -> pack voltage oscillates step by step and collapses once
        # the loads' gain (R0 * sum of u^2 / (efficiency * R_motor)) passes one: a VTOL's
        # pusher at full beside its four hovering rotors drew 280 A at 8 V instead of 56 A at
        # 15 V. The filter changes no steady state.
        bus = self._bus_v if self._bus_v >= 0.0 else battery.voltage_v
        for _ in range(n):
            t = self.t_ns
            for i in range(ns):
                c = s_updates[i](t)
                if c != s_cmd[i]:
                    s_cmd[i] = c
                    s_set[i](c)
            bus += BUS_ALPHA * (battery.voltage_v - bus)
            drive(t, bus / vmax)
            run()
            load()
            self.t_ns = t + dt_ns
            self.steps += 1
        self._bus_v = bus

    def _drive_motors(self, t: int, scale: float) -> None:
        """The ESCs' throttles at ``t`` (their commands times the supply they see, ``scale`` of
        full voltage), passed to JSBSim only when they change."""
        updates = self._esc_updates
        setters = self._throttle_set
        jsb = self._jsb_throttle
        for i in range(len(updates)):
            u = updates[i](t) * scale
            if u > 1.0:
                u = 1.0
            if u != jsb[i]:
                jsb[i] = u
                setters[i](u)

    def _load_battery(self) -> None:
        """One battery step under the motors' electrical power (u * Vmax * I_motor over the
        bus voltage) and the avionics."""
        currents = self._current_get
        jsb = self._jsb_throttle
        p = 0.0
        for i in range(len(self._esc_updates)):
            im = currents[i]()
            if im > 0.0:
                p += jsb[i] * im
        battery = self.battery
        v = battery.voltage_v
        battery.step(self._bp.avionics_a + self._extra_a
                     + (p * (self._vmax / self._bp.esc_efficiency) / v if v > 0.5 else 0.0))

    def run_until(self, t_ns: int) -> None:
        """Step while a whole step fits before t_ns (lockstep quantum end)."""
        n = (t_ns - self.t_ns) // self.dt_ns
        if n > 0:
            self.step(n)

    # -- outputs --------------------------------------------------------------------------
    def truth(self) -> Truth:
        """Ground truth after the last step (cached until the next step)."""
        if self._truth_step == self.steps and self._truth_cache is not None:
            return self._truth_cache
        (ax, ay, az, p, q, r, roll, pitch, yaw, lat, lon, h_ft, agl_ft, vn, ve, vd,
         p_psf, t_r, vt_fps, qbar_psf, aoa, beta) = [g() for g in self._truth_getters]
        if yaw > math.pi:  # JSBSim gives [0, 2 pi); PX4 uses (-pi, pi]
            yaw -= _TWO_PI
        alt = h_ft * FT
        # Quaternion from the half angles, then the NED->body rotation from the quaternion.
        cr, sr = math.cos(0.5 * roll), math.sin(0.5 * roll)
        cp, sp = math.cos(0.5 * pitch), math.sin(0.5 * pitch)
        cy, sy = math.cos(0.5 * yaw), math.sin(0.5 * yaw)
        qw = cr * cp * cy + sr * sp * sy
        qx = sr * cp * cy - cr * sp * sy
        qy = cr * sp * cy + sr * cp * sy
        qz = cr * cp * sy - sr * sp * cy
        if qw < 0.0:
            qw, qx, qy, qz = -qw, -qx, -qy, -qz
        mn, me, md = self.mag_field_ned_gauss
        # body = R(q)^T ned
        ww, xx, yy, zz = qw * qw, qx * qx, qy * qy, qz * qz
        xy, xz, yz = qx * qy, qx * qz, qy * qz
        wx, wy, wz = qw * qx, qw * qy, qw * qz
        mag = (
            (ww + xx - yy - zz) * mn + 2.0 * (xy + wz) * me + 2.0 * (xz - wy) * md,
            2.0 * (xy - wz) * mn + (ww - xx + yy - zz) * me + 2.0 * (yz + wx) * md,
            2.0 * (xz + wy) * mn + 2.0 * (yz - wx) * me + (ww - xx - yy + zz) * md,
        )
        if self.mag_disturbance is not None:
            (cx, cy, cz), (kx, ky, kz) = self.mag_disturbance
            amps = self.battery.current_a
            mag = (mag[0] + cx + kx * amps, mag[1] + cy + ky * amps, mag[2] + cz + kz * amps)
        tr = Truth(
            self.t_ns,
            (ax * FT, ay * FT, az * FT),
            (p, q, r),
            (qw, qx, qy, qz),
            (roll, pitch, yaw),
            mag,
            p_psf * PSF_PA,
            t_r * (5.0 / 9.0) - 273.15,
            lat,
            lon,
            alt,
            agl_ft * FT,
            (
                (lat - self._lat0) * self._m_per_deg_n,
                (lon - self._lon0) * self._m_per_deg_e,
                self._alt0 - alt,
            ),
            (vn * FT, ve * FT, vd * FT),
            vt_fps * FT,
            qbar_psf * PSF_PA,
            self.battery.voltage_v,
            self.battery.current_a,
            aoa,
            beta,
        )
        self._truth_cache = tr
        self._truth_step = self.steps
        return tr

    # -- faults in the physics (hil/faults/vehicle.py) ----------------------------------------

    def _motor_index(self, i: int) -> int:
        n = self.airframe.n_motors
        if type(i) is not int or not 0 <= i < n:
            raise ValueError(f"motor index must be 0..{n - 1} (PX4 order), got {i!r}")
        return i

    def fail_motor(self, i: int, kind: str = "motor", thrust_fraction: float = 0.0) -> None:
        """Motor ``i`` (0-based, PX4 quad-X order) fails from the next step, whatever its ESC
        is told:

        * ``"motor"``: the motor (or its ESC's power stage) stops driving: no torque, no current;
          ``thrust_fraction`` > 0 leaves a weak motor instead (a burnt winding, a slipping
          propeller): the drive is scaled so that thrust is about that fraction (thrust goes
          with the square of the drive, so the drive is scaled by its square root);
        * ``"propeller"``: the propeller comes off: no thrust and no rotor torque, and the
          motor spins free, drawing only its no-load current (:data:`NOLOAD_CURRENT_A` at full
          throttle, in proportion below).

        The ESC keeps running its own logic (arming, signal timeout). In JSBSim the rotor is
        unpowered, so its thrust decays with the rotor's spin-down (~50 ms) rather than in
        one step.
        """
        i = self._motor_index(i)
        if kind not in ("motor", "propeller"):
            raise ValueError(f"motor failure kind must be 'motor' or 'propeller', got {kind!r}")
        if not 0.0 <= thrust_fraction < 1.0:
            raise ValueError(f"thrust_fraction must be in [0, 1), got {thrust_fraction!r}")
        esc_update = self.escs[self._motor_ch[i]].update
        updates = list(self._esc_updates)
        if kind == "propeller":
            free = self._freewheel_a

            def update(t_ns: int) -> float:
                free[i] = NOLOAD_CURRENT_A * esc_update(t_ns)
                self._extra_a = sum(free)
                return 0.0
        elif thrust_fraction > 0.0:
            gain = math.sqrt(thrust_fraction)

            def update(t_ns: int) -> float:
                return esc_update(t_ns) * gain
        else:
            def update(t_ns: int) -> float:
                esc_update(t_ns)
                return 0.0
        updates[i] = update
        self._esc_updates = tuple(updates)
        self.motor_faults[i] = (kind, thrust_fraction)

    def restore_motor(self, i: int) -> None:
        """Undo :meth:`fail_motor` (a motor that was only stalled, a loose connector)."""
        i = self._motor_index(i)
        updates = list(self._esc_updates)
        updates[i] = self.escs[self._motor_ch[i]].update
        self._esc_updates = tuple(updates)
        self.motor_faults.pop(i, None)
        self._freewheel_a[i] = 0.0
        self._extra_a = sum(self._freewheel_a)

    def set_wind(self, north_m_s: float = 0.0, east_m_s: float = 0.0, down_m_s: float = 0.0
                 ) -> None:
        """Steady wind (the air moves towards north/east/down at these speeds)."""
        x = self.fdm.exec
        x["atmosphere/wind-north-fps"] = north_m_s / FT
        x["atmosphere/wind-east-fps"] = east_m_s / FT
        x["atmosphere/wind-down-fps"] = down_m_s / FT

    def set_turbulence(self, wind_20ft_m_s: float, severity: int = 3) -> None:
        """JSBSim's MIL-F-8785C / MIL-HDBK-1797 Dryden turbulence (``atmosphere/turb-type``
        4) for a wind of ``wind_20ft_m_s`` at 20 ft AGL and a probability-of-exceedance
        ``severity`` 1..7 (3 moderate); 0 m/s switches it off. JSBSim draws it from its own
        generator seeded with ``simulation/randomseed`` (the world's seed)."""
        if wind_20ft_m_s < 0 or not 0 <= int(severity) <= 7:
            raise ValueError(f"turbulence needs wind >= 0 and severity 0..7, got "
                             f"{wind_20ft_m_s!r}, {severity!r}")
        x = self.fdm.exec
        if wind_20ft_m_s == 0:
            x["atmosphere/turb-type"] = 0
            return
        x["atmosphere/turb-type"] = 4
        x["atmosphere/turbulence/milspec/windspeed_at_20ft_AGL-fps"] = wind_20ft_m_s / FT
        x["atmosphere/turbulence/milspec/severity"] = int(severity)

    def gust(self, north_m_s: float, east_m_s: float, down_m_s: float = 0.0,
             rise_s: float = 1.0, hold_s: float = 1.0, fall_s: float = 1.0) -> None:
        """A discrete 1-cosine gust (JSBSim's cosine gust, local NED frame) starting now: the
        extra wind rises along a half cosine over ``rise_s``, holds, and falls over
        ``fall_s``."""
        mag = math.sqrt(north_m_s ** 2 + east_m_s ** 2 + down_m_s ** 2)
        if mag == 0 or min(rise_s, hold_s, fall_s) < 0:
            raise ValueError("a gust needs a non-zero velocity and non-negative durations")
        x = self.fdm.exec
        x["atmosphere/cosine-gust/frame"] = 3  # local NED
        x["atmosphere/cosine-gust/X-velocity-ft_sec"] = north_m_s / mag
        x["atmosphere/cosine-gust/Y-velocity-ft_sec"] = east_m_s / mag
        x["atmosphere/cosine-gust/Z-velocity-ft_sec"] = down_m_s / mag
        x["atmosphere/cosine-gust/magnitude-ft_sec"] = mag / FT
        x["atmosphere/cosine-gust/startup-duration-sec"] = rise_s
        x["atmosphere/cosine-gust/steady-duration-sec"] = hold_s
        x["atmosphere/cosine-gust/end-duration-sec"] = fall_s
        x["atmosphere/cosine-gust/start"] = 1

    def wind_ned_m_s(self) -> tuple[float, float, float]:
        """The total wind JSBSim applies now (steady + turbulence + gust), m/s NED."""
        x = self.fdm.exec
        return (x["atmosphere/total-wind-north-fps"] * FT,
                x["atmosphere/total-wind-east-fps"] * FT,
                x["atmosphere/total-wind-down-fps"] * FT)

    def motor_rpm(self, i: int) -> float:
        """Propeller speed of motor i (rpm), e.g. for ESC telemetry."""
        return self.fdm.motor_rpm(i)

    def motor_thrust_n(self, i: int) -> float:
        return self.fdm.motor_thrust_n(i)

    @property
    def t_s(self) -> float:
        return self.t_ns * 1e-9
