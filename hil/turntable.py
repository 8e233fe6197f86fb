"""A turntable for driver work without a flight: hold a board still, or spin it.

It sets the physical quantities a board's sensors experience (the board's
:class:`~peripherals.physics.Environment`) for an attitude, a constant body rate, a location
and an altitude: gravity as specific force in body axes, the earth's field rotated into the
body, ISA pressure and temperature. Spinning integrates the attitude in the board's own kernel
every ``update_us``, so the sensors see a consistent rotation.

    board = FmuV2Board(start_sensors=True)
    Turntable(board.kernel, board.env, roll_deg=10, rate_rad_s=(0, 0, 1.0))
    board.kernel.run(10 * 10**9)
"""

from __future__ import annotations

import math

from board.kernel import NS_PER_US, PRIO_HW, Kernel
from hil.world.atmosphere import KELVIN_0C, isa_pressure_pa, isa_temperature_k
from hil.world.magnetic import earth_field_ned_gauss
from common.truth import rotate_ned_to_body
from peripherals.physics import Environment
from common.units import G0_M_S2

__all__ = ["Turntable"]


class Turntable:
    def __init__(self, kernel: Kernel, env: Environment, roll_deg: float = 0.0,
                 pitch_deg: float = 0.0, yaw_deg: float = 0.0,
                 rate_rad_s: tuple[float, float, float] = (0.0, 0.0, 0.0),
                 lat_deg: float = 47.397742, lon_deg: float = 8.545594, alt_m: float = 488.0,
                 update_us: int = 1000) -> None:
        self.kernel = kernel
        self.env = env
        self.roll = math.radians(roll_deg)
        self.pitch = math.radians(pitch_deg)
        self.yaw = math.radians(yaw_deg)
        self.rate = rate_rad_s
        self.field_ned = earth_field_ned_gauss(lat_deg, lon_deg, alt_m)
        self.update_s = update_us * 1e-6
        env.lat_deg, env.lon_deg, env.alt_m = lat_deg, lon_deg, alt_m
        env.pressure_pa = isa_pressure_pa(alt_m)
        env.temperature_c = isa_temperature_k(alt_m) - KELVIN_0C
        env.vel_ned_m_s = (0.0, 0.0, 0.0)
        self._apply()
        if any(rate_rad_s):
            kernel.call_every(update_us * NS_PER_US, self._step, priority=PRIO_HW)

    def _apply(self) -> None:
        env = self.env
        # Specific force of a board at rest: the reaction to gravity, -g along NED down.
        env.accel_m_s2 = rotate_ned_to_body((0.0, 0.0, -G0_M_S2), self.roll, self.pitch, self.yaw)
        env.gyro_rad_s = self.rate
        env.mag_gauss = rotate_ned_to_body(self.field_ned, self.roll, self.pitch, self.yaw)
        env.t_ns = self.kernel.now_ns

    def _step(self) -> None:
        p, q, r = self.rate
        dt = self.update_s
        sr, cr = math.sin(self.roll), math.cos(self.roll)
        cp, tp = math.cos(self.pitch), math.tan(self.pitch)
        # Euler angle rates from body rates (fine away from pitch = +-90 deg).
        self.roll += (p + (q * sr + r * cr) * tp) * dt
        self.pitch += (q * cr - r * sr) * dt
        self.yaw = (self.yaw + (q * sr + r * cr) / cp * dt + math.pi) % (2 * math.pi) - math.pi
        self._apply()

    @property
    def attitude_deg(self) -> tuple[float, float, float]:
        return tuple(math.degrees(a) for a in (self.roll, self.pitch, self.yaw))  # type: ignore
