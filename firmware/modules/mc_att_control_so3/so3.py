"""The geometric attitude error on SO(3) and its rate law, as pure functions.

Lee, Leok and McClamroch, "Geometric tracking control of a quadrotor UAV on SE(3)", CDC 2010:
the attitude error is ``e_R = 1/2 vee(R_d^T R - R^T R_d)``, the body vector ``sin(angle) * axis``
of the rotation from the desired attitude to the current one. As a rate command (the inner
rate loop is PX4's ``mc_rate_control``) the law is ``omega_sp = -K e_R + K_I int(-e_R) dt +
R^T R_d omega_d``, with the integral of Goodarzi, Lee and Lee, "Geometric nonlinear PID control
of a quadrotor UAV on SE(3)", ECC 2013.

What differs from PX4's quaternion controller (``mc_att_control``): the whole rotation is
corrected at once, without splitting tilt from heading and weighting the heading down
(``MC_YAW_WEIGHT``), and the error grows as ``sin(angle)`` (largest at 90 degrees, none at
180), not as ``2 sin(angle / 2)``. For small errors both are the rotation vector.

With ``qe = q^-1 * q_d`` (Hamilton, PX4's frames) ``R^T R_d`` is ``R(qe)`` and
``-e_R = sin(angle) * axis = 2 qe_w * qe_xyz``: no trigonometry, and the same for ``qe`` and
``-qe`` (SO(3) has no double cover to pick a side of).
"""

from __future__ import annotations

from common.quaternion import Quat

__all__ = ["so3_error", "yaw_feed_forward_body"]


def so3_error(q: Quat, qd: Quat) -> tuple[float, float, float]:
    """``-e_R``: body-frame ``sin(angle) * axis`` of the rotation from ``q`` toward ``qd``."""
    w, x, y, z = q
    dw, dx, dy, dz = qd
    # qe = conj(q) * qd
    ew = w * dw + x * dx + y * dy + z * dz
    ex = w * dx - x * dw - y * dz + z * dy
    ey = w * dy + x * dz - y * dw - z * dx
    ez = w * dz - x * dy + y * dx - z * dw
    k = 2.0 * ew
    return k * ex, k * ey, k * ez


def yaw_feed_forward_body(q: Quat, yaw_rate: float) -> tuple[float, float, float]:
    """``R^T R_d omega_d`` for a desired rotation about the world's down axis at ``yaw_rate``:
    ``R_d omega_d`` is that rotation in NED, ``R^T`` brings it into the body (third row of R)."""
    w, x, y, z = q
    return (yaw_rate * 2.0 * (x * z - w * y), yaw_rate * 2.0 * (y * z + w * x),
            yaw_rate * (w * w - x * x - y * y + z * z))
