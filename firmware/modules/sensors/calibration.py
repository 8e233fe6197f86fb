"""Per-device calibration: offsets, scales (soft iron), and the rotation into the vehicle body.

One :class:`Calibration` per physical sensor. It finds its slot by device id among the
``CAL_<KIND>n_*`` parameters and folds everything into one 3x3 matrix and one offset, so the hot
path is ``M (raw - offset)``: nine multiplies. With the defaults (no slot, no board rotation)
``identity`` is set and callers skip the multiply altogether.

Frames: drivers publish in the board frame (their mounting rotation already applied, as PX4's
do). Internal sensors then go through the board rotation (``SENS_BOARD_ROT`` and the fine trims
``SENS_BOARD_{X,Y,Z}_OFF``) into the vehicle body frame; an external sensor is mounted on the
vehicle, not the board, so it uses its own ``CAL_<KIND>n_ROT`` instead.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Final

from common.rotation import euler_matrix, rotation_matrix

__all__ = ["Calibration", "Matrix", "board_rotation"]

Matrix = tuple[tuple[float, float, float], tuple[float, float, float],
               tuple[float, float, float]]
_I: Matrix = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))

#: priority of a sensor without a configured one (PX4: uninitialized -> medium / high)
PRIORITY_INTERNAL: Final = 50
PRIORITY_EXTERNAL: Final = 75


def _mul(a: Matrix, b: Matrix) -> Matrix:
    return tuple(tuple(sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3))
                 for i in range(3))  # type: ignore[return-value]


def board_rotation(get: Callable[[str], float]) -> Matrix:
    """Board -> body: the trim rotation (roll, pitch, yaw offsets) times SENS_BOARD_ROT."""
    rot = rotation_matrix(int(get("SENS_BOARD_ROT"))) or _I
    trim = euler_matrix(float(get("SENS_BOARD_X_OFF")), float(get("SENS_BOARD_Y_OFF")),
                        float(get("SENS_BOARD_Z_OFF")))
    return _mul(trim, rot)


class Calibration:
    """Calibration of one sensor (kind ``ACC``, ``GYRO``, ``MAG`` or ``BARO``)."""

    __slots__ = (
        "device_id",
        "external",
        "identity",
        "kind",
        "matrix",
        "n_slots",
        "offset",
        "pressure_offset_pa",
        "priority",
        "slot",
    )

    def __init__(self, kind: str, n_slots: int, device_id: int = 0,
                 external: bool = False) -> None:
        self.kind = kind
        self.n_slots = n_slots
        self.device_id = device_id
        self.external = external
        self.slot = -1
        self.offset = (0.0, 0.0, 0.0)
        self.matrix: Matrix = _I
        self.identity = True
        self.priority = PRIORITY_EXTERNAL if external else PRIORITY_INTERNAL
        self.pressure_offset_pa = 0.0

    def find_slot(self, get: Callable[[str], float]) -> int:
        for n in range(self.n_slots):
            if self.device_id and int(get(f"CAL_{self.kind}{n}_ID")) == self.device_id:
                return n
        return -1

    def load(self, get: Callable[[str], float], board_rot: Matrix) -> None:
        """(Re)compute from the parameters (``get(name)``) and the board rotation."""
        self.slot = n = self.find_slot(get)
        p = f"CAL_{self.kind}{n}_"
        prio = int(get(p + "PRIO")) if n >= 0 else -1
        self.priority = (prio if prio >= 0 else
                         PRIORITY_EXTERNAL if self.external else PRIORITY_INTERNAL)
        if self.kind == "BARO":
            self.pressure_offset_pa = float(get(p + "OFF")) if n >= 0 else 0.0
            self.identity = self.pressure_offset_pa == 0.0
            return
        rot: Matrix = board_rot
        if self.external:
            code = int(get(p + "ROT")) if n >= 0 else -1
            rot = (rotation_matrix(code) or _I) if code >= 0 else _I
        offset = (0.0, 0.0, 0.0)
        scale: Matrix = _I
        if n >= 0:
            offset = (float(get(p + "XOFF")), float(get(p + "YOFF")), float(get(p + "ZOFF")))
            if self.kind in ("ACC", "MAG"):
                sx, sy, sz = (float(get(p + "XSCALE")), float(get(p + "YSCALE")),
                              float(get(p + "ZSCALE")))
                ox = oy = oz = 0.0
                if self.kind == "MAG":
                    ox, oy, oz = (float(get(p + "XODIAG")), float(get(p + "YODIAG")),
                                  float(get(p + "ZODIAG")))
                scale = ((sx, ox, oy), (ox, sy, oz), (oy, oz, sz))
        self.offset = offset
        self.matrix = _mul(rot, scale)
        self.identity = self.matrix == _I and offset == (0.0, 0.0, 0.0)

    def apply(self, x: float, y: float, z: float) -> tuple[float, float, float]:
        """Calibrated vector in the vehicle body frame."""
        if self.identity:
            return x, y, z
        ox, oy, oz = self.offset
        x -= ox
        y -= oy
        z -= oz
        (a, b, c), (d, e, f), (g, h, i) = self.matrix
        return a * x + b * y + c * z, d * x + e * y + f * z, g * x + h * y + i * z
