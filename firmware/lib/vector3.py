"""A three-vector of floats (PX4's ``matrix::Vector3f``), for the control libraries.

Only what the controllers use: sums, differences, element-wise products (``emult``), scaling
and a per-axis clamp. Each operation returns a new vector, as matrix::Vector3f's operators do,
so a control law reads as PX4 writes it (``P.emult(e) + i - D.emult(a)``).

Why a small class with ``__slots__`` and three float attributes rather than tuples, lists or
numpy: the rate controller runs this on every gyro publication (400 Hz), where a numpy call
costs more than the arithmetic; a slotted class is as cheap as a tuple to build in CPython, and
mypyc compiles it to a native class whose float fields are read without a dictionary lookup.
Each component is computed with the same operations in the same order as the scalar form it
replaced, so results are bit-identical (IEEE sums and products are commutative, not
associative: ``a.emult(b) + c`` is ``a.x * b.x + c.x`` per axis, nothing reordered).
"""

from __future__ import annotations

__all__ = ["Vector3"]


class Vector3:
    """``(x, y, z)``; for body rates and torques x, y, z are roll, pitch and yaw."""

    __slots__ = ("x", "y", "z")

    def __init__(self, x: float = 0.0, y: float = 0.0, z: float = 0.0) -> None:
        self.x = x
        self.y = y
        self.z = z

    def __add__(self, o: Vector3) -> Vector3:
        return Vector3(self.x + o.x, self.y + o.y, self.z + o.z)

    def __sub__(self, o: Vector3) -> Vector3:
        return Vector3(self.x - o.x, self.y - o.y, self.z - o.z)

    def __mul__(self, k: float) -> Vector3:
        return Vector3(self.x * k, self.y * k, self.z * k)

    def emult(self, o: Vector3) -> Vector3:
        """Element-wise product (matrix::Vector::emult)."""
        return Vector3(self.x * o.x, self.y * o.y, self.z * o.z)

    def constrain(self, lo: float, hi: float) -> Vector3:
        """Each component clamped to [lo, hi] (math::constrain per axis)."""
        x, y, z = self.x, self.y, self.z
        return Vector3(lo if x < lo else (min(x, hi)), lo if y < lo else (min(y, hi)),
                       lo if z < lo else (min(z, hi)))

    def copy(self) -> Vector3:
        return Vector3(self.x, self.y, self.z)

    def xyz(self) -> tuple[float, float, float]:
        return self.x, self.y, self.z

    def __repr__(self) -> str:
        return f"Vector3({self.x!r}, {self.y!r}, {self.z!r})"
