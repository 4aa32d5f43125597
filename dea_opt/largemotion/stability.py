"""Finite kinematics, the answer's stability: whether body 2 stays at its equilibrium when disturbed.

Written math: ``formulations/validity.md`` (section 7) and ``formulations/finite.md``
("Stability"). The small kinematics' energy is convex, so each of its equilibria is stable; with
exact rotations it is not: a moment can tip body 2 over the contact (a pencil on its point), and
the equations then have equilibria that body 2 leaves at the smallest disturbance. IPOPT, which
finds any point where the forces balance, can return one; Newton, which descends the energy,
leaves it. The consistent tangent ``K = dr/dy`` on the free coordinates tells them apart: a
disturbance ``dy`` is met by the net force ``-K dy``, and the quasi-static motion
``dy' = -K dy`` grows along an eigenvector of ``K`` whose eigenvalue has a negative real part.
Used by :mod:`~dea_opt.largemotion.driver`; the check is :func:`dea_opt.validity.assess`'s
``stability``.
"""

from __future__ import annotations

import numpy as np

from ..kinematics import DOFS

__all__ = ["softest"]


def softest(state, lengths) -> tuple[float, str]:
    """``(value, along)``: how unstable the equilibrium ``state`` is, and along which free coordinates.

    Parameters
    ----------
    state : State
        The springs at the solved pose (its :meth:`tangent` is ``dr/dy`` on the free coordinates).
    lengths : ndarray (m,)
        The free coordinates' lengths (1 mm for a translation, the layer's radius for a rotation),
        so that every entry of the scaled tangent ``diag(lengths) K diag(lengths)`` is in N mm.

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
    free = state.system.free
    if not len(free):
        return 0.0, ""
    K = state.tangent()
    scaled = K * lengths[:, None] * lengths[None, :]
    if not np.isfinite(scaled).all():
        return float("nan"), ""
    values, vectors = np.linalg.eig(scaled)
    largest = float(np.abs(values).max())
    if largest == 0.0:
        return 0.0, ""  # nothing resists any free coordinate there (held directions take no motion)
    k = int(np.argmin(values.real))
    scaled_direction = vectors[:, k].real
    scaled_direction = scaled_direction / scaled_direction[np.argmax(np.abs(scaled_direction))]
    parts = []
    for index, z, length in zip(free, scaled_direction, lengths):
        if abs(z) < 1e-3:
            continue
        name = DOFS[int(index)]
        parts.append(f"{name} {z:+.3g} mm" if index < 3 else f"{name} {np.degrees(z / length):+.3g} deg")
    return float(-values.real[k] / largest) + 0.0, ", ".join(parts)  # + 0.0: no "-0"
