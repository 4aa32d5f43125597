"""The joint's energy minimised by IPOPT (any law), and the QP of a joint of linear elements.

Written math: ``formulations/joint.md`` ("IPOPT" and "The QP"). IPOPT minimises the reduced
energy ``sum_g V_g w_g(clip(e0_g + A_g x)) - r . x`` over the scaled free dofs, built in CasADi
from the same law expressions as the two-body NLP (:mod:`dea_opt.formulations.nlp`); the element
forces are the laws' at its answer. The QP is the joint as one compression-only spring system
(:meth:`~dea_opt.formulations.joint.JointSystem.flat`: every bundle a spring in reverse) handed to
the two-body QP formulation (:mod:`dea_opt.formulations.qp`, Clarabel), whose duals are the
element forces.
"""

from __future__ import annotations

import time

import numpy as np

from ...errors import InputError, SolverError
from ...laws import LinearLaw
from ...status import Status
from ..joint import JointResult, JointSystem, joint_scaling, law_stresses
from ..nlp import NATIVE_STATUS, _casadi, ipopt_solver
from .options import Option, validate
from .resistance import require_finite

#: IPOPT's options for a joint.
NLP_OPTIONS = (
    Option("tol", float, 1e-14, "IPOPT's tol", range=(0, 1), tolerance=True),
    Option("max_iter", int, 3000, "IPOPT's iteration limit", range=(1, None)),
    Option("ipopt_options", dict, None, "IPOPT option names to values"),
)


def solve_nlp(system: JointSystem, *, x0=None, **options) -> JointResult:
    """Minimise the joint's energy by IPOPT from ``x0`` (mm, rad; default zero)."""
    checked = validate("nlp", NLP_OPTIONS, options)
    ca = _casadi()
    scale = joint_scaling(system)
    T, E0 = scale.T, scale.energy_scale
    k = T.shape[1]
    xi = ca.MX.sym("xi", k)
    x = ca.mtimes(ca.DM(T), xi)
    stored = 0
    for g in system.groups:
        require_finite(f"the NLP's data ({g.name})", g.matrix, g.e0, g.volume)
        dofs = [int(j) for j in g.dofs]
        eps = ca.DM(g.e0) + ca.mtimes(ca.DM(g.matrix.T), ca.vertcat(*[x[j] for j in dofs]))
        V = ca.DM(g.volume / E0)
        if g.contact:
            stored = stored + ca.dot(V, g.law.energy(ca.fmin(eps, 0)))
        elif g.two_sided:
            stored = stored + 0.5 * ca.dot(V, eps * eps)
        else:
            stored = stored + ca.dot(V, g.law.casadi_energy(eps, g.law.transition))
    r = ca.DM(T.T @ system.load / E0)
    nlp = {"x": xi, "f": stored - ca.dot(r, xi)}
    solver = ipopt_solver("dea_joint_nlp", nlp, checked["tol"], checked["max_iter"], checked["ipopt_options"])
    start = time.perf_counter()
    xi0 = np.zeros(k) if x0 is None else scale.to_xi(x0)
    try:
        out = solver(x0=xi0)
    except RuntimeError as exc:
        raise SolverError(f"IPOPT raised: {exc}", status=Status.SOLVER_ERROR, native_status="exception") from exc
    stats = solver.stats()
    x_free = T @ np.asarray(out["x"], dtype=float).reshape(-1)
    native = str(stats.get("return_status", "unknown"))
    return JointResult(
        x=x_free,
        stresses=law_stresses(system, x_free),
        success=bool(stats.get("success", False)),
        status=NATIVE_STATUS.get(native, Status.SOLVER_ERROR),
        message=f"IPOPT (reduced): {native}",
        iterations=int(stats.get("iter_count", 0)),
        solve_time=time.perf_counter() - start,
        info={"native_status": native},
    )


def linear(system: JointSystem) -> bool:
    """Whether every element is linear: springs of a :class:`~dea_opt.laws.LinearLaw`, bundles of
    the linear tension-only law (then the joint's energy is a QP)."""
    return all(
        getattr(g.law, "is_linear", False) if g.contact else g.two_sided or g.law.kind == "linear"
        for g in system.groups
    )


def solve_qp(system: JointSystem, **options) -> JointResult:
    """The joint of linear elements as the two-body QP of its flat spring system (Clarabel by
    default; the options of :mod:`dea_opt.formulations.qp`). The element forces are its duals."""
    from .. import qp

    if not linear(system):
        raise InputError(
            "method 'qp' needs linear elements only (LinearLaw springs and law='linear' ligaments): "
            "use 'newton' or 'nlp' for this joint"
        )
    flat, convert = system.flat()
    model = qp.QPModel(flat, LinearLaw(1.0), **options)
    result = model.solve()
    stresses = [
        sign * modulus * result.stress[part] - (0.0 if minus is None else modulus * result.stress[minus])
        for part, sign, modulus, minus in convert
    ]
    return JointResult(
        x=result.u_free,
        stresses=stresses,
        success=result.success,
        status=result.status,
        message=result.message,
        iterations=result.iterations,
        solve_time=result.solve_time,
        info=dict(result.info),
    )
