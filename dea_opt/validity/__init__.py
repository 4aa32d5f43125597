"""Is a solved answer inside the model it solved? The validity report of every result.

The certificate (:mod:`dea_opt.solution`) says the answer solves the equations; this module
says whether those equations still describe cartilage at that answer: the strain within the
law's range and short of crushing, rotations small enough for the linearised kinematics of
Eq. (9)-(11) (with the gap error they imply at the springs, computed exactly), sizes and
pressures that a human joint has (so meshes in metres or loads in the wrong unit are caught),
the springs the proximity window dropped at the solved pose, and, for finite kinematics, the
loaded springs lost through the layer (an overlap deeper than mesh 1's cartilage) and whether
the equilibrium is stable (a moment can tip body 2 over the contact). The
formulas, the limits and their sources are in ``formulations/validity.md``; the report's types
are in :mod:`~dea_opt.validity.report`, the checks in :mod:`~dea_opt.validity.checks`.

Every check is one :class:`Check` (name, value, limit, unit, passed, advice); a
:class:`Validity` holds them all and is valid only if every evaluated check passed. Limits are
the documented defaults of :class:`ValidityLimits`; pass your own to :func:`assess`.
Everything is O(N) NumPy: no solve, no mesh query.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..problem import ContactProblem
from .checks import (
    _dropped_check,
    _pressure_check,
    _rotation_checks,
    _size_checks,
    _stability_check,
    _strain_check,
    _through_layer_check,
    rotation_gap_error,
)
from .report import CHECK_UNITS, DEFAULT_LIMITS, Check, Validity, ValidityLimits, check_column

__all__ = [
    "CHECK_UNITS",
    "DEFAULT_LIMITS",
    "Check",
    "Validity",
    "ValidityLimits",
    "assess",
    "check_column",
    "rotation_gap_error",
]


def assess(
    problem,
    u,
    strain=None,
    pressure=None,
    *,
    limits: ValidityLimits = DEFAULT_LIMITS,
    dropped: int | None = None,
    lost_through_layer: int | None = None,
    stability: float | None = None,
    softest: str = "",
    plane_error: tuple[float, float] | None = None,
) -> Validity:
    """The validity report of ``u`` as an answer to ``problem``.

    Parameters
    ----------
    problem : ContactProblem
    u : array_like, shape (12,)
        The displacement (mm, rad), body 1 then body 2.
    strain, pressure : array_like, shape (N,), optional
        The springs' strain and pressure (MPa) at ``u``; computed from ``problem`` if omitted.
    limits : ValidityLimits
        The limits of the checks (documented defaults).
    dropped : int, optional
        Springs that carry load at the solved pose but lie outside the proximity window
        (counted by re-casting at that pose); the check is not evaluated without it.
    lost_through_layer : int, optional
        For finite kinematics: springs that carried load and were lost through the layer, still
        behind mesh 1's far side at the solved pose
        (:meth:`~dea_opt.finite.MeshTracker.lost_through_layer`); without it the check is
        not evaluated for finite kinematics and passes for small kinematics, which loses no spring.
    stability : float, optional
        For finite kinematics: ``-min Re(lambda) / max |lambda|`` over the eigenvalues of the
        tangent stiffness on the free coordinates at the solved pose
        (:func:`~dea_opt.finite.stability.softest`), above 0 when the equilibrium is unstable;
        without it the check is not evaluated (the small kinematics' equilibria are all stable:
        their energy is convex).
    softest : str, optional
        The direction that gives way, for the advice (``"uz -0.1 mm, ry +2.7 deg"``).
    plane_error : (float, float), optional
        For finite kinematics on springs cast from meshes and not re-cast (``recast=False``): the
        largest error of their tangent planes' compression against mesh 2 at the solved pose, as a
        strain and in mm (:func:`~dea_opt.finite.solution.plane_error`), the ``gap_error``
        check; without it ``gap_error`` is not evaluated for finite kinematics.

    Returns
    -------
    Validity
        The checks ``strain``, ``rotation``, ``gap_error``, ``extent``, ``layer_area``,
        ``thickness``, ``peak_pressure``, ``dropped_springs``, ``lost_through_layer`` and
        ``stability``, in that order.
    """
    if not isinstance(problem, ContactProblem):
        raise InputError(f"problem must be a ContactProblem, got {type(problem).__name__}")
    if not isinstance(limits, ValidityLimits):
        raise InputError(f"limits must be a dea_opt.validity.ValidityLimits, got {type(limits).__name__}")
    u = np.asarray(u, dtype=float)
    if u.shape != (12,):
        raise InputError(f"u must have shape (12,), got shape {u.shape}")
    n = len(problem.layer)
    finite = bool(np.isfinite(u).all())
    if strain is None:
        strain = problem.strain(u) if finite else np.full(n, np.nan)
    strain = np.asarray(strain, dtype=float)
    if pressure is None:
        with np.errstate(invalid="ignore", over="ignore"):
            pressure = -problem.law.stress(np.minimum(strain, 0.0))
    pressure = np.asarray(pressure, dtype=float)
    for name, arr in (("strain", strain), ("pressure", pressure)):
        if arr.shape != (n,):
            raise InputError(f"{name} must have shape ({n},), one value per spring, got shape {arr.shape}")
    checks = (
        _strain_check(problem.law, strain, limits),
        *_rotation_checks(problem, u, limits, plane_error),
        *_size_checks(problem.layer, limits),
        _pressure_check(pressure, limits),
        _dropped_check(dropped, limits),
        _through_layer_check(problem, lost_through_layer, limits),
        _stability_check(problem, stability, softest, limits),
    )
    return Validity(checks, limits)
