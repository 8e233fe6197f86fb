"""A DroneCAN GNSS node (a Here/CUAV-NEO-like CAN GPS): ``uavcan.equipment.gnss.Fix2`` at
5 Hz and ``uavcan.equipment.gnss.Auxiliary`` at 1 Hz once it has a node ID.

The navigation solution is the u-blox model's (:class:`peripherals.ublox.solution.SolutionModel`:
the world's truth through the board's :class:`~peripherals.physics.Environment`, a seeded
Gauss-Markov error, time to first fix, loss of sky), so a CAN GPS and a serial one behave
alike; only the wire differs. Fix2 carries the position as 1e-8 degrees and millimetres, the
NED velocity, the fix status, UTC time (``gnss_time_standard`` UTC, 18 leap seconds) and a
six-element diagonal covariance (north, east, down position variances from hAcc/vAcc, then the
three velocity variances from sAcc), as ArduPilot's and PX4's CAN GNSS firmware fill it.
"""

from __future__ import annotations

from typing import Any, Final

import numpy as np

from board.can import CanBus
from board.kernel import PRIO_HW, Kernel
from firmware.lib.uavcan.transfer import types
from peripherals.dronecan.node import DronecanNode
from peripherals.physics import Environment
from peripherals.ublox.solution import LEAP_SECONDS, Solution, SolutionModel

__all__ = ["FIX2_DTID", "AUXILIARY_DTID", "GnssNode"]

FIX2_DTID: Final = 1063
AUXILIARY_DTID: Final = 1061
FIX_PERIOD_NS: Final = 200_000_000      # 5 Hz
AUX_EVERY: Final = 5                    # Auxiliary with every fifth fix: 1 Hz
GNSS_TIME_STANDARD_UTC: Final = 2
#: float16 saturates here; an unknown accuracy (4e6 m) is reported as this variance
_F16_MAX: Final = 65504.0


def _var(sigma: float) -> float:
    return min(_F16_MAX, sigma * sigma)


class GnssNode(DronecanNode):
    """GNSS receiver on CAN: ``GnssNode(kernel, bus, env, rng, node_id=0)``."""

    HW_NAME = "org.hil.gnss"
    SW_VERSION = (1, 4)

    def __init__(self, kernel: Kernel, bus: CanBus, env: Environment, rng: np.random.Generator,
                 node_id: int = 0, name: str = "can_gnss", seed: int = 0) -> None:
        self.env = env
        self.model = SolutionModel(env, rng)
        self.fixes_tx = 0
        self._fix_timer: Any = None
        self._count = 0
        super().__init__(kernel, bus, node_id, name=name, rng=rng, seed=seed)

    def _on_ready(self) -> None:
        self._fix_timer = self.kernel.call_every(FIX_PERIOD_NS, self._epoch, priority=PRIO_HW)

    def _epoch(self) -> None:
        if self.silent:
            return
        now = self.kernel.now_ns
        sol = self.model.step(now)
        self.send(self._fix2(sol, now), FIX2_DTID, now + FIX_PERIOD_NS)
        self.fixes_tx += 1
        self._count += 1
        if self._count % AUX_EVERY == 0:
            self.send(self._aux(sol), AUXILIARY_DTID, now + FIX_PERIOD_NS)

    def _fix2(self, sol: Solution, now_ns: int) -> Any:
        g = types().uavcan.equipment.gnss
        f = g.Fix2()
        f.timestamp.usec = now_ns // 1000
        f.gnss_timestamp.usec = sol.utc_ns // 1000 if sol.time_valid else 0
        f.gnss_time_standard = GNSS_TIME_STANDARD_UTC if sol.time_valid else 0
        f.num_leap_seconds = LEAP_SECONDS
        f.latitude_deg_1e8 = round(sol.lat_deg * 1e8)
        f.longitude_deg_1e8 = round(sol.lon_deg * 1e8)
        f.height_msl_mm = round(sol.hmsl_m * 1000)
        f.height_ellipsoid_mm = round(sol.height_m * 1000)
        f.ned_velocity = [float(v) for v in sol.vel_ned_m_s]
        f.sats_used = min(63, sol.num_sv)
        f.status = sol.fix_type if sol.fix_ok else (1 if sol.time_valid else 0)
        f.mode = 0
        f.sub_mode = 0
        h2 = _var(sol.h_acc_m) / 2.0
        f.covariance = [h2, h2, _var(sol.v_acc_m)] + [_var(sol.s_acc_m_s)] * 3
        f.pdop = min(_F16_MAX, sol.pdop)
        return f

    def _aux(self, sol: Solution) -> Any:
        a = types().uavcan.equipment.gnss.Auxiliary()
        a.hdop, a.vdop, a.pdop = sol.hdop, sol.vdop, sol.pdop
        a.sats_visible = min(127, len(sol.sats))
        a.sats_used = min(63, sol.num_sv)
        return a

    def stats(self) -> dict[str, Any]:
        return super().stats() | {"fixes_tx": self.fixes_tx}
