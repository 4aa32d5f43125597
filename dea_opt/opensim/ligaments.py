"""Ligament bundles at a pose: length, strain and force as OpenSim's ``Blankevoort1991Ligament``.

OpenSim's law (``formulations/opensim.md``, "Ligaments"), with the strain
``eps = L / L0 - 1`` (``L0`` the slack length), the stiffness ``k`` (N per unit strain) and the
transition strain ``eps_t``::

    f = 0                      eps <= 0
    f = k eps^2 / (2 eps_t)    0 < eps < eps_t
    f = k (eps - eps_t / 2)    eps >= eps_t

plus, when the bundle lengthens (strain rate ``eps_dot = L_dot / L0 > 0``) in tension, the
damping ``c eps_dot`` faded in over the first 1 % of strain by Simbody's smooth step; the total
is never negative. dea-opt's bundle is the straight line between the first and the last path
point (:func:`lengths`); :func:`path_lengths` is the polyline through every fixed path point,
which is OpenSim's length once the wrap objects are removed (what the recorded OpenSim
reference checks).
"""

from __future__ import annotations

import numpy as np

__all__ = ["blankevoort_force", "lengths", "path_lengths", "point_positions", "segment_crosses_wrap"]


def blankevoort_force(strain, stiffness, transition_strain, strain_rate=None, damping=None) -> np.ndarray:
    """The bundle force (N) of OpenSim's ``Blankevoort1991Ligament``, elementwise.

    Parameters
    ----------
    strain : array_like
        ``L / L0 - 1``.
    stiffness : array_like
        ``k``, N per unit strain.
    transition_strain : array_like
        ``eps_t`` (> 0), where the toe region ends.
    strain_rate, damping : array_like, optional
        ``L_dot / L0`` (1/s) and the damping coefficient (N s per unit strain): the damping term
        is added only when both are given (a quasi-static solve has no speeds).
    """
    e = np.asarray(strain, dtype=float)
    k = np.asarray(stiffness, dtype=float)
    et = np.asarray(transition_strain, dtype=float)
    toe = 0.5 * k / et * e**2
    linear = k * (e - 0.5 * et)
    f = np.where(e <= 0.0, 0.0, np.where(e < et, toe, linear))
    if strain_rate is not None and damping is not None:
        rate = np.asarray(strain_rate, dtype=float)
        x = np.clip(e / 0.01, 0.0, 1.0)
        step = x**3 * (10.0 + x * (6.0 * x - 15.0))  # SimTK::Function::Step(0, 1, 0, 0.01)
        f = f + np.where((e > 0.0) & (rate > 0.0), np.asarray(damping, dtype=float) * rate * step, 0.0)
    return np.maximum(f, 0.0)


def point_positions(model, ligament, poses: dict) -> np.ndarray:
    """The ligament's fixed path points in ground (P, 3, mm) for the body ``poses``
    (``{body: X_G_body}``)."""
    out = np.empty((len(ligament.points), 3))
    for i, point in enumerate(ligament.points):
        T = poses[point.body] @ model.frame_in_body(point.frame)
        out[i] = T[:3, :3] @ point.location + T[:3, 3]
    return out


def lengths(model, poses: dict, ligaments=None) -> dict:
    """``{name: L}`` (mm): the straight line between each bundle's first and last point."""
    chosen = model.ligaments.values() if ligaments is None else [model.ligaments[n] for n in ligaments]
    result = {}
    for lig in chosen:
        x = point_positions(model, lig, poses)
        result[lig.name] = float(np.linalg.norm(x[-1] - x[0]))
    return result


def path_lengths(model, poses: dict, ligaments=None) -> dict:
    """``{name: L}`` (mm): the polyline through each bundle's fixed path points, in order."""
    chosen = model.ligaments.values() if ligaments is None else [model.ligaments[n] for n in ligaments]
    result = {}
    for lig in chosen:
        x = point_positions(model, lig, poses)
        result[lig.name] = float(np.sum(np.linalg.norm(np.diff(x, axis=0), axis=1)))
    return result


def segment_crosses_wrap(a, b, wrap, T_G_wrap) -> bool | None:
    """Whether the segment ``a``-``b`` (ground, mm) passes inside the wrap object at the pose
    ``T_G_wrap``: for an ellipsoid, a sphere or a cylinder (of its length), else None (not
    checked). A segment that stays outside leaves OpenSim's path straight there; one that
    crosses is wrapped around it by OpenSim, longer than the line."""
    inv = np.linalg.inv(T_G_wrap)
    p = inv[:3, :3] @ np.asarray(a, float) + inv[:3, 3]
    q = inv[:3, :3] @ np.asarray(b, float) + inv[:3, 3]
    d = q - p
    dims = wrap.dimensions
    if wrap.kind in ("WrapEllipsoid", "WrapSphere"):
        radii = np.asarray(dims["radii"], float) if "radii" in dims else np.full(3, float(dims["radius"]))
        u, v = p / radii, d / radii
        return _segment_meets_unit_ball(u, v)
    if wrap.kind == "WrapCylinder":
        r, half = float(dims["radius"]), 0.5 * float(dims["length"])
        # |x y| < r and |z| < half along t in [0, 1]: the interval where both hold is not empty
        lo, hi = 0.0, 1.0
        lo, hi = _clip_slab(p[2], d[2], -half, half, lo, hi)
        A = d[0] ** 2 + d[1] ** 2
        B = 2.0 * (p[0] * d[0] + p[1] * d[1])
        C = p[0] ** 2 + p[1] ** 2 - r * r
        lo, hi = _clip_quadratic(A, B, C, lo, hi)
        return bool(lo < hi)
    return None


def _segment_meets_unit_ball(u, v) -> bool:
    lo, hi = _clip_quadratic(float(v @ v), 2.0 * float(u @ v), float(u @ u) - 1.0, 0.0, 1.0)
    return bool(lo < hi)


def _clip_slab(p: float, d: float, low: float, high: float, lo: float, hi: float) -> tuple:
    """Narrow ``[lo, hi]`` to the ``t`` with ``low < p + t d < high``."""
    if d == 0.0:
        return (lo, hi) if low < p < high else (1.0, 0.0)
    t1, t2 = sorted(((low - p) / d, (high - p) / d))
    return max(lo, t1), min(hi, t2)


def _clip_quadratic(A: float, B: float, C: float, lo: float, hi: float) -> tuple:
    """Narrow ``[lo, hi]`` to the ``t`` with ``A t^2 + B t + C < 0`` (``A >= 0``)."""
    if A == 0.0:
        if B == 0.0:
            return (lo, hi) if C < 0.0 else (1.0, 0.0)
        t = -C / B
        return (lo, min(hi, t)) if B > 0.0 else (max(lo, t), hi)
    disc = B * B - 4.0 * A * C
    if disc <= 0.0:
        return (1.0, 0.0)
    s = np.sqrt(disc)
    return max(lo, (-B - s) / (2.0 * A)), min(hi, (-B + s) / (2.0 * A))
