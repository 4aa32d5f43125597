"""Solving on from an answer in that answer's own scale: the stages every small-kinematics
formulation takes where an overlap set the scale it solved in and opened under a smaller load
(``formulations/energy.md``, "Scaling", step 5).

A formulation's tolerances are relative to the size ``s`` of :func:`~dea_opt.formulations.energy.scaling`,
the larger of the load and the initial overlap. A layer that starts in deep overlap and separates
under a small load is solved in the overlap's units, where the load (and every force at the answer)
is below the solver's tolerances: the answer stops short. Moved to that answer
(:meth:`~dea_opt.formulations.energy.SpringSystem.recentred`), the problem has the answer's own size,
and solved again from there its tolerances are the answer's.
"""

from __future__ import annotations

import time

import numpy as np

from ...errors import SolverError
from ..energy import FormulationResult, SpringSystem, _norm, modulus_scale

#: A formulation solves on from its answer, in that answer's own scale (:meth:`~dea_opt.formulations.energy.SpringSystem.recentred`),
#: when what is in equilibrium there (the load, the springs' compression) is at most this fraction of
#: the scale ``s`` it solved in: an overlap that set ``s`` and opened under the load
#: (formulations/energy.md, "Scaling", step 5).
RECENTRE = 0.1


def answer_size(system: SpringSystem, modulus: float, u_free) -> float:
    """The size ``s`` of :func:`~dea_opt.formulations.energy.scaling` at the free-dof motion ``u_free`` (mm, rad): the larger of
    the load's ``|T1^T r|`` and the compression's ``sqrt(sum_i V_i H min(eps_i, 0)^2)`` there, both
    the square root of an energy (N^0.5 mm^0.5), 0 for neither."""
    T1 = system.resistance.basis(modulus)
    s_load = _norm(T1.T @ system.load) if system.load.size else 0.0
    eps = system.strain_at(u_free)
    s_compressed = _norm(np.sqrt(system.volume * modulus_scale(modulus)) * np.minimum(eps, 0.0))
    return max(s_load, s_compressed)


def recentred_solve(first: FormulationResult, system: SpringSystem, law, s: float, build) -> FormulationResult:
    """``first`` (a formulation's answer to ``system``, solved in a scaling of size ``s``), or, where
    that answer's own size (:func:`answer_size`) is at most :data:`RECENTRE` of ``s`` under a load,
    the answer of the model ``build(system.recentred(first.u_free))`` added to it: the problem solved
    again from ``first``'s answer, in the scale of what is in equilibrium there (that model's own
    ``solve`` goes on the same way; each stage divides the scale by ``1 / RECENTRE`` at least, down to
    the load's). ``first`` stays the answer where the second solve raises."""
    u = first.u_free
    if not (system.load.any() and np.isfinite(u).all()):
        return first
    if not answer_size(system, law.modulus, u) <= RECENTRE * s:
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
