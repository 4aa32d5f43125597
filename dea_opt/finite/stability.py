"""Finite kinematics, the answer's stability: whether body 2 stays at its equilibrium when disturbed.

Written math: ``formulations/validity.md`` (section 7) and ``formulations/finite.md``
("Stability"). The small kinematics' energy is convex, so each of its equilibria is stable; with
exact rotations it is not: a moment can tip body 2 over the contact (a pencil on its point), and
the equations then have equilibria that body 2 leaves at the smallest disturbance. IPOPT, which
finds any point where the forces balance, can return one; Newton, which descends the energy,
leaves it. The consistent tangent ``K = dr/dy`` on the free coordinates tells them apart: a
disturbance ``dy`` is met by the net force ``-K dy``, and the quasi-static motion
``dy' = -K dy`` grows along an eigenvector of ``K`` whose eigenvalue has a negative real part.
Used by :mod:`~dea_opt.finite.driver`; the check is :func:`dea_opt.validity.assess`'s
``stability``.
"""

from __future__ import annotations

import numpy as np

from ..formulations.finite import escape_step, rms_radius
from ..kinematics import DOFS
from ..validity import DEFAULT_LIMITS

__all__ = ["leave_unstable", "lengths_of", "noted", "softest", "softest_mode"]

#: The unstable equilibria a solve leaves before it keeps the one it is at (the check fails it).
MAX_ESCAPES = 3


def lengths_of(system) -> np.ndarray:
    """The free coordinates' lengths (m,): 1 mm for a translation, the springs' RMS radius about
    body 2's reference for a rotation (a turn of 1/radius moves them 1 mm)."""
    return np.where(system.free < 3, 1.0, max(rms_radius(system), 1e-12))


def leave_unstable(system, law, inner, energy_scale, escapes: list) -> np.ndarray | None:
    """Where Newton starts again, away from the unstable equilibrium it converged to, or None.

    ``inner`` is a converged Newton solve (:class:`~dea_opt.formulations.finite.InnerResult`);
    its stability is measured (:func:`softest_mode`, kept in ``inner.info["softest"]`` for the
    answer's check) and, where a disturbance grows (beyond ``DEFAULT_LIMITS.stability``), the
    energy's lowest point along the motion that gives way is the new start
    (:func:`~dea_opt.formulations.finite.escape_step`); ``escapes`` records each, at most
    :data:`MAX_ESCAPES`. None where the equilibrium is stable, the energy has no lower point along
    that motion within a quarter turn, or the escapes are spent: the answer is kept.
    """
    state = inner.state
    lengths = lengths_of(system)
    value, along, motion = softest_mode(state, lengths)
    inner.info["softest"] = (state, value, along)
    if motion is None or not value > DEFAULT_LIMITS.stability or len(escapes) >= MAX_ESCAPES:
        return None
    start = escape_step(system, law, inner.u_free, motion, energy_scale, rms_radius(system))
    if start is None:
        return None
    escapes.append(f"left an unstable equilibrium (stability {value:.3g}, giving way along {along})")
    return start


def noted(inner, escapes: list) -> None:
    """Say in ``inner``'s message and info (``"escapes"``) which unstable equilibria the solve left."""
    if escapes:
        inner.info["escapes"] = list(escapes)
        inner.message += f"; {'; '.join(escapes)} along the energy's descent"


def softest(state, lengths) -> tuple[float, str]:
    """``(value, along)``: how unstable the equilibrium ``state`` is, and along which free coordinates.

    Parameters
    ----------
    state : State
        The springs at the solved pose (its :meth:`tangent` is ``dr/dy`` on the free coordinates).
    lengths : ndarray (m,)
        The free coordinates' lengths (1 mm for a translation, the layer's radius for a rotation):
        in the coordinates ``w = diag(lengths) dy`` (the springs' motion, mm) the tangent is
        ``diag(1/lengths) K diag(1/lengths)``, every entry in N/mm.

    Returns
    -------
    value : float
        ``-min Re(lambda) / max |lambda|`` over the eigenvalues of the scaled tangent: 0 or below
        when every direction resists a disturbance (stable), above 0 when one gives way. NaN
        without a finite tangent; 0 without free coordinates.
    along : str
        The eigenvector of that eigenvalue as a motion whose largest part moves the springs 1 mm
        (a rotation at the layer's radius): translations in mm, rotations in degrees
        (``"uz -0.1 mm, ry +2.7 deg"``); empty without free coordinates.
    """
    value, along, _ = softest_mode(state, lengths)
    return value, along


def softest_mode(state, lengths) -> tuple[float, str, np.ndarray | None]:
    """``(value, along, motion)``: :func:`softest`, and the motion that gives way most readily.

    ``motion`` (m,) is in the free coordinates (mm, rad), its largest part moving the springs 1 mm
    (a rotation at the layer's radius): the eigenvector of the most negative eigenvalue of the
    scaled tangent's symmetric part, along which the energy falls on both sides of the equilibrium
    (``d^T K d < 0``, :func:`~dea_opt.formulations.finite.escape_step`); None where every direction
    resists (no eigenvalue of that part below 0) or without a finite tangent.
    """
    free = state.system.free
    if not len(free):
        return 0.0, "", None
    K = state.tangent()
    scaled = K / lengths[:, None] / lengths[None, :]  # in w = lengths * dy
    if not np.isfinite(scaled).all():
        return float("nan"), "", None
    values, vectors = np.linalg.eig(scaled)
    largest = float(np.abs(values).max())
    if largest == 0.0:
        return 0.0, "", None  # nothing resists any free coordinate there (held directions take no motion)
    k = int(np.argmin(values.real))
    along = _motion_text(free, _unit(vectors[:, k].real), lengths)
    value = float(-values.real[k] / largest) + 0.0  # + 0.0: no "-0"
    symmetric, basis = np.linalg.eigh(0.5 * (scaled + scaled.T))
    motion = _unit(basis[:, 0]) / lengths if symmetric[0] < 0 else None
    return value, along, motion


def _unit(scaled_direction) -> np.ndarray:
    """The direction scaled so that its largest part is 1 (the springs move 1 mm)."""
    return scaled_direction / scaled_direction[np.argmax(np.abs(scaled_direction))]


def _motion_text(free, scaled_direction, lengths) -> str:
    parts = []
    for index, z, length in zip(free, scaled_direction, lengths):
        if abs(z) < 1e-3:
            continue
        name = DOFS[int(index)]
        parts.append(f"{name} {z:+.3g} mm" if index < 3 else f"{name} {np.degrees(z / length):+.3g} deg")
    return ", ".join(parts)
