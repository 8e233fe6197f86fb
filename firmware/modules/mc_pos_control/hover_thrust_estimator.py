"""Hover thrust estimator: a one-state Kalman filter on the vertical acceleration.

Why: the thrust that holds altitude changes with battery voltage, payload and air density; the
position controller maps acceleration to thrust through it, so a wrong value is a steady
altitude error (until the integrator catches up) and a wrong loop gain.

Model: with vertical thrust ``T`` (normalised, positive up) and hover thrust ``h``, the vertical
acceleration (NED, down positive) is ``a_z = g (1 - T / h)``. The state ``h`` is a random walk
(process noise ``HTE_HT_NOISE``), the measurement is ``a_z`` from the estimator, with a fixed
noise; innovations beyond ``HTE_ACC_GATE`` standard deviations are rejected (a bump, a landing).
Linearised about the estimate, H = g T / h^2.
"""

from __future__ import annotations

from typing import Final
from common.units import G0_M_S2

__all__ = ["HoverThrustEstimator"]



class HoverThrustEstimator:
    """One state (hover thrust) and its variance."""

    def __init__(self, hover: float = 0.5, std_init: float = 0.1, noise: float = 0.0036,
                 gate: float = 3.0, acc_noise: float = 1.0) -> None:
        self.std_init = std_init
        self.noise = noise
        self.gate = gate
        self.acc_var = acc_noise * acc_noise
        self.hover = hover
        self.var = std_init * std_init
        self.innov = 0.0
        self.innov_var = 0.0
        self.test_ratio = 0.0
        self.valid = False

    def reset(self, hover: float) -> None:
        self.hover = hover
        self.var = self.std_init * self.std_init
        self.valid = False

    def update(self, dt: float, az: float, thrust_up: float) -> None:
        """One predict + update with the measured ``az`` (NED) and the applied vertical thrust."""
        self.var += self.noise * self.noise * dt
        h = self.hover
        hh = G0_M_S2 * thrust_up / (h * h)
        pred = G0_M_S2 * (1.0 - thrust_up / h)
        innov = az - pred
        s = hh * hh * self.var + self.acc_var
        ratio = innov * innov / (self.gate * self.gate * s)
        self.innov, self.innov_var, self.test_ratio = innov, s, ratio
        if ratio > 1.0:
            return
        k = self.var * hh / s
        h += k * innov
        self.hover = 0.1 if h < 0.1 else (min(h, 0.9))
        self.var = max((1.0 - k * hh) * self.var, 1e-8)
        # usable once the standard deviation is below a fifth of its initial value
        self.valid = self.var < 0.04 * self.std_init * self.std_init
