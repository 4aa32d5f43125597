"""Finite kinematics, rotations: the exact rotation of a rotation vector, its left Jacobian and
the derivative of its transpose against a moment, and a body's 4x4 pose.

Written math: ``formulations/finite.md`` ("Pose"); rad. Body 2 moves by
``x' = c + t + R(theta) (x - c)``: ``t`` (3,) the translation of its reference ``c`` (3,), ``R``
(3, 3) the exact rotation of the rotation vector ``theta`` (3,) (Rodrigues), ``J(theta)`` the
left Jacobian that maps a rate of ``theta`` to the angular velocity.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["jacobian_transpose_derivative", "left_jacobian", "pose_matrix", "rotation", "rotation_and_jacobian"]


def _coefficients(theta):
    """``(a, b, c)`` = ``(sin t / t, (1 - cos t) / t^2, (t - sin t) / t^3)`` of ``t = |theta|``.

    Written in ``tau = theta . theta`` (each is an even, entire function of ``t``), so that a
    complex ``theta`` (the complex-step derivative of :func:`left_jacobian`) is exact too; the
    Taylor series below ``tau = 1e-6`` avoid the cancellation of the closed forms.
    """
    tau = theta @ theta
    if abs(tau) < 1e-6:
        a = 1 - tau / 6 + tau**2 / 120
        b = 0.5 - tau / 24 + tau**2 / 720
        c = 1 / 6 - tau / 120 + tau**2 / 5040
        return a, b, c
    if np.iscomplexobj(theta):
        t = np.sqrt(tau + 0j)
        s, co = np.sin(t), np.cos(t)
    else:  # (the C library's sine: the same digits on every x86 machine, where numpy's may vectorise)
        t = math.sqrt(tau)
        s, co = math.sin(t), math.cos(t)
    return s / t, (1 - co) / tau, (t - s) / (tau * t)


def _hat(v) -> np.ndarray:
    """``[v]x``, the matrix of ``v x``."""
    return np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]], dtype=np.result_type(v, float))


def rotation(theta) -> np.ndarray:
    """``R = exp([theta]x) = I + a [theta]x + b [theta]x^2`` (Rodrigues), shape (3, 3), of the
    rotation vector ``theta`` (3,): the turn ``|theta|`` (rad) about the axis ``theta / |theta|``."""
    theta = np.asarray(theta)
    a, b, _ = _coefficients(theta)
    W = _hat(theta)
    return np.eye(3) + a * W + b * (W @ W)


def left_jacobian(theta) -> np.ndarray:
    """``J(theta) = I + b [theta]x + c [theta]x^2``: ``dR R^T = [J dtheta]x`` (3, 3).

    The angular velocity of body 2 is ``w = J(theta) dtheta/dt`` for a rate of its rotation
    vector; ``J^T M`` is the generalized force of a moment ``M`` on the rotation vector.
    """
    theta = np.asarray(theta)
    _, b, c = _coefficients(theta)
    W = _hat(theta)
    return np.eye(3) + b * W + c * (W @ W)


def rotation_and_jacobian(theta) -> tuple[np.ndarray, np.ndarray]:
    """``(R, J)`` of :func:`rotation` and :func:`left_jacobian`, from one evaluation of the coefficients.

    For a real ``theta`` in plain floats, ``[theta]x^2 = theta theta^T - tau I`` written out
    (every Newton iteration makes one: eleven 3 x 3 numpy operations cost three times as much);
    a complex one (a complex-step derivative) through the matrices."""
    theta = np.asarray(theta)
    if np.iscomplexobj(theta):
        a, b, c = _coefficients(theta)
        W = _hat(theta)
        W2 = W @ W
        return np.eye(3) + a * W + b * W2, np.eye(3) + b * W + c * W2
    a, b, c = _coefficients(theta)
    x, y, z = float(theta[0]), float(theta[1]), float(theta[2])
    xx, yy, zz, xy, xz, yz, tau = x * x, y * y, z * z, x * y, x * z, y * z, x * x + y * y + z * z
    R, J = (
        np.array(
            [
                [1.0 + q * (xx - tau), -p * z + q * xy, p * y + q * xz],
                [p * z + q * xy, 1.0 + q * (yy - tau), -p * x + q * yz],
                [-p * y + q * xz, p * x + q * yz, 1.0 + q * (zz - tau)],
            ]
        )
        for p, q in ((a, b), (b, c))
    )
    return R, J


def _coefficient_slopes(tau: float) -> tuple[float, float, float, float]:
    """``(b, c, db/dtau, dc/dtau)`` of :func:`_coefficients` at ``tau = theta . theta`` (real):
    the Taylor series below ``tau = 0.1`` (the closed forms cancel there), else the closed forms."""
    if tau < 0.1:
        # b = sum_k (-tau)^k / (2k + 2)!, c = sum_k (-tau)^k / (2k + 3)!; d(-tau)^k/dtau = -k (-tau)^(k-1)
        b = c = db = dc = 0.0
        term_b, term_c, power, previous = 0.5, 1.0 / 6.0, 1.0, 0.0
        for k in range(9):
            b += term_b * power
            c += term_c * power
            db -= k * term_b * previous
            dc -= k * term_c * previous
            previous, power = power, power * -tau
            term_b /= (2 * k + 3) * (2 * k + 4)
            term_c /= (2 * k + 4) * (2 * k + 5)
        return b, c, db, dc
    t = math.sqrt(tau)
    a, co = math.sin(t) / t, math.cos(t)
    b, c = (1.0 - co) / tau, (1.0 - a) / tau
    return b, c, (0.5 * a - b) / tau, -((co - a) / (2.0 * tau) + c) / tau


def jacobian_transpose_derivative(theta, moment) -> np.ndarray:
    """``D[:, j] = d/dtheta_j (J(theta)^T moment)`` (3, 3), in closed form.

    With ``W = [theta]x``, ``J^T M = M - b theta x M + c (theta (theta . M) - tau M)``, so
    ``D = b [M]x + c ((theta . M) I + theta M^T - 2 M theta^T)
    + 2 (c' (theta (theta . M) - tau M) - b' theta x M) theta^T`` (``'``: the derivative in ``tau``).
    """
    t0, t1, t2 = (float(v) for v in theta)
    m0, m1, m2 = (float(v) for v in moment)
    tau = t0 * t0 + t1 * t1 + t2 * t2
    b, c, db, dc = _coefficient_slopes(tau)
    tm = t0 * m0 + t1 * m1 + t2 * m2
    th, mo = (t0, t1, t2), (m0, m1, m2)
    cross = (t1 * m2 - t2 * m1, t2 * m0 - t0 * m2, t0 * m1 - t1 * m0)
    v = [dc * (th[i] * tm - tau * mo[i]) - db * cross[i] for i in range(3)]
    hm = ((0.0, -m2, m1), (m2, 0.0, -m0), (-m1, m0, 0.0))  # [M]x
    # in plain floats: a dozen 3 x 3 numpy operations cost as much as the tangent's pass over 1e4 springs
    return np.array(
        [
            [b * hm[i][j] + c * ((tm if i == j else 0.0) + th[i] * mo[j] - 2.0 * mo[i] * th[j]) + 2.0 * v[i] * th[j]
             for j in range(3)]
            for i in range(3)
        ]
    )  # fmt: skip


def pose_matrix(u6, reference) -> np.ndarray:
    """The 4x4 pose of a body displaced by ``u6 = (ux, uy, uz, rx, ry, rz)`` about ``reference``:
    ``x' = c + t + R(theta) (x - c)`` with the exact rotation of the rotation vector."""
    u6 = np.asarray(u6, dtype=float)
    c = np.asarray(reference, dtype=float)
    T = np.eye(4)
    T[:3, :3] = rotation(u6[3:6])
    T[:3, 3] = c + u6[:3] - T[:3, :3] @ c
    return T
