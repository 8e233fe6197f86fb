"""A DroneCAN magnetometer node (a CAN compass on a mast): ``uavcan.equipment.ahrs.
MagneticFieldStrength2`` at 20 Hz once it has a node ID.

The field is the world's (the board's :class:`~peripherals.physics.Environment`, body axes,
gauss) with the HMC5883L model's seeded noise and per-axis errors
(:class:`~peripherals.errors.ImuErrorModel`), sent as float16 gauss in the node's frame, which
is the vehicle's (the module is mounted aligned).
"""

from __future__ import annotations

from typing import Any, Final

import numpy as np

from board.can import CanBus
from board.kernel import PRIO_HW, Kernel
from firmware.lib.uavcan.transfer import types
from peripherals.dronecan.node import DronecanNode
from peripherals.errors import AxisErrors, ImuErrorModel
from peripherals.physics import Environment

__all__ = ["MAG_DTID", "MagNode"]

MAG_DTID: Final = 1002
PERIOD_NS: Final = 50_000_000   # 20 Hz
RATE_HZ: Final = 20.0
MAG_NOISE_GA: Final = 0.0005     # per sqrt(Hz): ~2 mGa at 20 Hz


class MagNode(DronecanNode):
    """Magnetometer on CAN: ``MagNode(kernel, bus, env, rng, node_id=0)``."""

    HW_NAME = "org.hil.mag"
    SW_VERSION = (1, 2)

    def __init__(self, kernel: Kernel, bus: CanBus, env: Environment, rng: np.random.Generator,
                 node_id: int = 0, name: str = "can_mag", seed: int = 0,
                 sensor_id: int = 0) -> None:
        self.env = env
        self.errors = ImuErrorModel(AxisErrors(noise_density=MAG_NOISE_GA), rng)
        self.sensor_id = sensor_id
        self.samples_tx = 0
        self._timer2: Any = None
        super().__init__(kernel, bus, node_id, name=name, rng=rng, seed=seed)

    def _on_ready(self) -> None:
        self._timer2 = self.kernel.call_every(PERIOD_NS, self._sample, priority=PRIO_HW)

    def _sample(self) -> None:
        if self.silent:
            return
        now = self.kernel.now_ns
        x, y, z = self.errors.apply(now, self.env.mag_gauss, odr_hz=RATE_HZ)
        m = types().uavcan.equipment.ahrs.MagneticFieldStrength2()
        m.sensor_id = self.sensor_id
        m.magnetic_field_ga = [x, y, z]
        self.send(m, MAG_DTID, now + PERIOD_NS)
        self.samples_tx += 1

    def stats(self) -> dict[str, Any]:
        return super().stats() | {"samples_tx": self.samples_tx}
