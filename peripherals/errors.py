"""Seeded error models of MEMS sensors: what makes a reading differ from the truth.

Each model is built from datasheet-typical figures and a numpy Generator derived from the board
seed, so the same seed gives the same noise. Applied per sample in SI units, before the chip
quantises to counts and clips at its full scale (which the chip model does).

Per axis: ``out = M @ ((1 + scale) * true) + bias + drift(t) + temp_coeff * (T - 25) + noise``
where ``noise ~ N(0, density * sqrt(odr / 2))`` (white noise density over the output
bandwidth), ``drift`` is a random walk with ``bias_instability`` per sqrt(s), and ``M`` is a
small misalignment (cross-axis) matrix.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["AxisErrors", "ImuErrorModel", "ScalarErrorModel", "rng_for"]


def rng_for(seed: int, name: str) -> np.random.Generator:
    """A generator per (board seed, device name): adding a device never shifts another's noise."""
    key = [seed & 0xFFFFFFFF] + [ord(c) for c in name]
    return np.random.default_rng(np.random.SeedSequence(key))


@dataclass
class AxisErrors:
    noise_density: float = 0.0        # unit / sqrt(Hz)
    bias: float = 0.0                 # constant offset, unit (per axis spread drawn at start)
    bias_instability: float = 0.0     # random-walk rate, unit / sqrt(s)
    scale_error: float = 0.0          # fractional, per axis spread drawn at start
    misalignment_rad: float = 0.0     # cross-axis coupling spread
    temp_coeff: float = 0.0           # unit / degC away from 25 degC


class ImuErrorModel:
    """Errors of a 3-axis sensor (accelerometer, gyroscope, magnetometer)."""

    def __init__(self, params: AxisErrors, rng: np.random.Generator) -> None:
        self.p = params
        self.rng = rng
        self.bias = tuple(float(x) for x in rng.normal(0.0, 1.0, 3) * params.bias)
        self.scale = tuple(1.0 + float(x) for x in rng.normal(0.0, 1.0, 3) * params.scale_error)
        m = rng.normal(0.0, 1.0, (3, 3)) * params.misalignment_rad
        np.fill_diagonal(m, 0.0)
        self.cross = tuple(tuple(float(v) for v in row) for row in m)
        self.drift = [0.0, 0.0, 0.0]
        self._last_t_ns: int | None = None
        # Extra errors a test or a fault sets: a bias step, stuck output, saturation.
        self.extra_bias = (0.0, 0.0, 0.0)
        self.noise_scale = 1.0
        self.extra_sigma = 0.0      # extra white noise per sample (a noise-burst fault), SI
        # Normal draws as a Python list: indexing a list is several times cheaper than slicing
        # a numpy array, and the values are the same doubles (drawn in the same blocks).
        self._buf: list[float] = []
        self._pos = 0

    def _normals(self, n: int) -> list[float]:
        """The next ``n`` N(0, 1) draws. Drawn in blocks of 4096 * 3: one numpy call per 4096
        samples instead of one per sample (a new block whenever the rest is too short)."""
        pos = self._pos
        if pos + n > len(self._buf):
            self._buf = self.rng.standard_normal(4096 * 3).tolist()
            pos = 0
        self._pos = pos + n
        return self._buf[pos:pos + n]

    def apply(self, t_ns: int, true: tuple[float, float, float], odr_hz: float,
              temperature_c: float = 25.0) -> tuple[float, float, float]:
        """The reading of one sample at ``t_ns`` for the physical value ``true``.

        Runs per sample for the ST chips (thousands per virtual second), so the block buffer is
        read inline; the arithmetic and the order of the draws (drift first, then noise) are
        what they always were, so results are bit for bit the same.
        """
        p = self.p
        x, y, z = true
        c = self.cross
        sx, sy, sz = self.scale
        c0, c1, c2 = c
        vx = sx * x + c0[1] * y + c0[2] * z
        vy = c1[0] * x + sy * y + c1[2] * z
        vz = c2[0] * x + c2[1] * y + sz * z
        sigma = p.noise_density * math.sqrt(odr_hz * 0.5) * self.noise_scale
        if self.extra_sigma:
            sigma = math.hypot(sigma, self.extra_sigma)
        d = self.drift
        last_t = self._last_t_ns
        if p.bias_instability and last_t is not None:
            dt = (t_ns - last_t) * 1e-9
            if dt > 0:
                step = p.bias_instability * math.sqrt(dt)
                buf, pos = self._buf, self._pos
                if pos + 3 > len(buf):
                    buf = self._buf = self.rng.standard_normal(4096 * 3).tolist()
                    pos = 0
                self._pos = pos + 3
                d[0] += step * buf[pos]
                d[1] += step * buf[pos + 1]
                d[2] += step * buf[pos + 2]
        self._last_t_ns = t_ns
        b = self.bias
        e = self.extra_bias
        tc = p.temp_coeff * (temperature_c - 25.0)
        if sigma:
            buf, pos = self._buf, self._pos
            if pos + 3 > len(buf):
                buf = self._buf = self.rng.standard_normal(4096 * 3).tolist()
                pos = 0
            self._pos = pos + 3
            return (vx + b[0] + e[0] + d[0] + tc + sigma * buf[pos],
                    vy + b[1] + e[1] + d[1] + tc + sigma * buf[pos + 1],
                    vz + b[2] + e[2] + d[2] + tc + sigma * buf[pos + 2])
        return (vx + b[0] + e[0] + d[0] + tc, vy + b[1] + e[1] + d[1] + tc,
                vz + b[2] + e[2] + d[2] + tc)


class ScalarErrorModel:
    """Errors of a scalar sensor (pressure, temperature)."""

    def __init__(self, noise_sigma: float, bias_sigma: float, rng: np.random.Generator) -> None:
        self.rng = rng
        self.sigma = noise_sigma
        self.bias = float(rng.normal(0.0, 1.0)) * bias_sigma
        self.extra_bias = 0.0

    def apply(self, true: float) -> float:
        n = float(self.rng.standard_normal()) if self.sigma else 0.0
        return true + self.bias + self.extra_bias + self.sigma * n
