"""Solving on from an answer in that answer's own scale: the stages every small-kinematics
formulation takes where an overlap set the scale it solved in and opened under a smaller load
(``formulations/energy.md``, "Scaling", step 5).

A formulation's tolerances are relative to the size ``s`` of :func:`~dea_opt.formulations._parts.scaling.scaling`,
the larger of the load and the initial overlap. A layer that starts in deep overlap and separates
under a small load is solved in the overlap's units, where the load (and every force at the answer)
is below the solver's tolerances: the answer stops short. Moved to that answer
(:meth:`~dea_opt.formulations._parts.system.SpringSystem.recentred`), the problem has the answer's own size,
and solved again from there its tolerances are the answer's.
"""

from __future__ import annotations

import time

import numpy as np

from ...errors import SolverError
from .resistance import modulus_scale
from .scaling import norm as _norm
from .system import FormulationResult, SpringSystem

#: A formulation solves on from its answer, in that answer's own scale (:meth:`~dea_opt.formulations._parts.system.SpringSystem.recentred`),
#: when what is in equilibrium there (the load, the springs' compression) is at most this fraction of
#: the scale ``s`` it solved in: an overlap that set ``s`` and opened under the load
#: (formulations/energy.md, "Scaling", step 5).
RECENTRE = 0.1


def answer_size(system: SpringSystem, modulus: float, u_free) -> float:
    """The size ``s`` of :func:`~dea_opt.formulations._parts.scaling.scaling` at the free-dof motion ``u_free`` (mm, rad): the larger of
    the load's ``|T1^T r|`` and the compression's ``sqrt(sum_i V_i H min(eps_i, 0)^2)`` there, both
    the square root of an energy (N^0.5 mm^0.5), 0 for neither."""
    T1 = system.resistance.basis(modulus)
    s_load = _norm(T1.T @ system.load) if system.load.size else 0.0
    eps = system.strain_at(u_free)
    s_compressed = _norm(np.sqrt(system.volume * modulus_scale(modulus)) * np.minimum(eps, 0.0))
    return max(s_load, s_compressed)


#: A first answer whose residual is at most this fraction of its own size is kept as it is: the
#: certificate asks for 1e-6 of the load, and no second solve would do better.
SETTLED = 1e-10


def residual_size(system: SpringSystem, law, u_free) -> float:
    """``|T1^T g|`` at ``u_free``: the equilibrium residual ``g = A^T (V sigma) - r`` in the same
    measure as :func:`answer_size` (the square root of an energy, N^0.5 mm^0.5); ``inf`` where the
    law gives no finite stress."""
    with np.errstate(invalid="ignore", over="ignore"):
        sigma = law.stress(np.minimum(system.strain_at(u_free), 0.0))
        g = system.AT @ (system.volume * sigma) - system.load
    if not np.isfinite(g).all():
        return float("inf")
    return _norm(system.resistance.basis(law.modulus).T @ g)


def recentred_solve(first: FormulationResult, system: SpringSystem, law, s: float, build) -> FormulationResult:
    """``first`` (a formulation's answer to ``system``, solved in a scaling of size ``s``), or, where
    that answer's own size (:func:`answer_size`) is at most :data:`RECENTRE` of ``s`` under a load and
    its residual more than :data:`SETTLED` of that size, the answer of the model
    ``build(system.recentred(first.u_free))`` added to it: the problem solved again from ``first``'s
    answer, in the scale of what is in equilibrium there (that model's own ``solve`` goes on the same
    way; each stage divides the scale by ``1 / RECENTRE`` at least, down to the load's). Of the two,
    the one with the smaller residual (:func:`residual_size`) is kept; ``first`` also where the second
    solve raises or ends without an answer."""
    u = first.u_free
    if not (system.load.any() and np.isfinite(u).all()):
        return first
    # The load's part of the size first: it alone settles the common case (no overlap, so ``s`` is
    # the load's size) without the strains at the answer, a pass over every spring.
    if not _norm(system.resistance.basis(law.modulus).T @ system.load) <= RECENTRE * s:
        return first
    size = answer_size(system, law.modulus, u)
    if not size <= RECENTRE * s:
        return first
    before = residual_size(system, law, u)
    if before <= SETTLED * size:
        return first
    start = time.perf_counter()
    try:
        model = build(system.recentred(u))
        second = model.solve()
    except SolverError as exc:
        first.message = f"{first.message}; solving again from this answer in its own scale raised: {exc}"
        return first
    elapsed = time.perf_counter() - start
    if not np.isfinite(second.u_free).all():
        first.message = f"{first.message}; solving again from this answer in its own scale failed: {second.message}"
        return first
    if not residual_size(system, law, u + second.u_free) < before:
        first.message = f"{first.message}; solving again from this answer in its own scale did no better"
        return first
    return FormulationResult(
        u_free=u + second.u_free,
        stress=second.stress,
        success=second.success,
        status=second.status,
        message=second.message,
        iterations=first.iterations + second.iterations,
        build_time=first.build_time,
        solve_time=first.solve_time + elapsed,
        info={**second.info, "stages": 1 + second.info.get("stages", 1)},
    )
