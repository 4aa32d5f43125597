"""Finite kinematics, the start of a solve: the small kinematics' answer as the start of a cold Newton
solve, whether it may call the layer crushed before any solve, the springs brought up to date
at body 2's base pose when a solve from far away gave no answer, and at a warm start far from
where they were.

Written math: ``formulations/finite.md`` ("Newton", "Re-casting"). Used by
:mod:`~dea_opt.finite.driver`.
"""

from __future__ import annotations

import numpy as np

__all__ = ["at_base", "near_base", "predicted", "warm_start"]

_PREDICTOR_TOL = 1e-2  # the small kinematics' answer as a start (it is off by the rotation squared)

#: mm the springs' hits move from their last update to body 2's base pose (a prescribed motion, a
#: load path's frame) past which the small kinematics on their tangent planes, extrapolated that
#: far, say too little of the meshes to call the layer crushed before any solve.
_BASE_SHIFT = 1.0


def near_base(tracker, system) -> bool:
    """Whether body 2's base pose (the free coordinates at zero) lies within :data:`_BASE_SHIFT` of
    where the springs were last brought up to date: the small kinematics' answer on them may then
    call the layer crushed before any solve (:func:`~dea_opt.finite.outcome.crushed_at_start`).
    Farther, the solve and its updates find it out (springs lost through the layer, or none left)."""
    y = system.coordinates(np.zeros(len(system.free)))
    return not tracker.moved_from_update(system.transform(y)) > _BASE_SHIFT


def warm_start(tracker, system, law, x):
    """The system whose springs start a solve from the given start ``x`` (free coordinates): brought
    up to date at its pose (:func:`at_base`'s update) when that lies more than :data:`_BASE_SHIFT`
    from where they last were, so that Newton does not start on tangent planes extrapolated that
    far (they can read a layer crushed that is not); the same system where it lies near, or where
    no spring is left there (the solve then finds out from the start it was given)."""
    if not tracker.moved_from_update(system.transform(system.coordinates(x))) > _BASE_SHIFT:
        return system
    moved, failed = at_base(tracker, system, law, x)
    return system if failed is not None else moved


def at_base(tracker, system, law, x=None) -> tuple:
    """``(system, failed)``: the springs brought up to date at body 2's base pose (the free
    coordinates at zero, or at ``x``), by a complete update there (a whole re-cast when that is
    far from the last one); ``failed`` an :class:`~dea_opt.formulations.finite.InnerResult`
    (``pose_error``) when no spring is left there, else None."""
    from ..formulations.finite import InnerResult

    zero = np.zeros(len(system.free)) if x is None else np.asarray(x, dtype=float)
    y = system.coordinates(zero)
    state = system.state(y, law)
    update = tracker.update(system, state, complete=True)
    tracker.complete = False  # the solve's own updates start partial again
    if update is None:
        return system, None
    if update.none_left:
        tracker.counts["stable"] = True
        tracker.crushed_faces.clear()  # no solve loaded them: the pose was given
        message = (
            f"no spring is left at body 2's base pose (its prescribed motion or the frame's pose): {update.none_left}"
        )
        return system, InnerResult(zero, state, False, "pose_error", message)
    return update.system, None


def predicted(small, law, x, system):
    """``(x, cold)``: the start of a cold Newton solve of springs that follow mesh 2, the answer of the
    small kinematics (their equilibrium to first order in the rotation) when it has one that
    does not move body 2 beyond reach (:func:`~dea_opt.finite.outcome.beyond_reach`: ran
    away along a free dof, where it is no start and no measure of the load), else ``x``.

    The first finite solve on the springs of the start pose only says where body 2 goes; the
    small kinematics says it in a third of the time, and the first update of the springs
    (:mod:`~dea_opt.finite.tracker`) starts from there (``formulations/finite.md``, "Newton")."""
    from ..formulations import newton as small_newton

    guess = small_newton.solve(small, law, gtol=_PREDICTOR_TOL, xtol=_PREDICTOR_TOL)  # a start: no finer
    from ..formulations.finite import rms_radius
    from .outcome import beyond_reach

    if guess.success and guess.u_free.shape == x.shape and not beyond_reach(system, guess.u_free, rms_radius(system)):
        return np.array(guess.u_free, dtype=float), False
    return x, True
