"""Solve a joint and certify the answer: what :func:`dea_opt.solve` runs for a ``Joint``.

Methods (``formulations/joint.md``): ``"newton"`` (the joint's Newton, any law, what ``"auto"``
runs first), ``"qp"`` (linear elements only: Clarabel on the joint as one spring system, its duals
the forces), ``"nlp"`` (IPOPT on the energy, any law), ``"auto"`` (Newton, then the QP or IPOPT
when Newton's answer fails its certificate). As for two bodies, the loads no element can carry
are refused first (:class:`~dea_opt.errors.LoadNotSupportedError`, naming the dofs), and every
answer carries dea-opt's own certificate and validity report.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from .._checks.threads import single_threaded_blas
from ..errors import InputError, SolverError
from ..formulations._parts import joint_ipopt, joint_newton
from ..formulations._parts.resistance import require_finite
from ..formulations.joint import JointResult, law_stresses
from ..status import CERTIFIABLE, Status
from .certificate import body_forces, certify_joint
from .checks import check_joint_cone, check_joint_unresisted, finish, start_vector
from .elastic import elastic_results
from .model import Joint
from .results import JointSolution, body_results, layer_solutions, ligament_results
from .validity import assess_joint

__all__ = ["JOINT_METHODS", "solve_joint"]

#: The methods a joint is solved by.
JOINT_METHODS = ("auto", "newton", "qp", "nlp")
_OPTIONS = {
    "newton": {o.name for o in joint_newton.OPTIONS},
    "nlp": {o.name for o in joint_ipopt.NLP_OPTIONS},
}


def solve_joint(
    joint: Joint, method: str = "auto", *, certificate_tol: float = 1e-6, strict: bool = True, **options
) -> JointSolution:
    """The certified equilibrium of ``joint`` (see :func:`dea_opt.solve`).

    Parameters
    ----------
    joint : Joint
    method : {"auto", "newton", "qp", "nlp"}
    certificate_tol : float
        Bound on every residual of the certificate.
    strict : bool
        Raise :class:`SolverError` when the answer fails its certificate (default).
    **options
        The method's options (Newton: ``xtol``, ``gtol``, ``max_iter``, ``extended_start``; IPOPT:
        ``tol``, ``max_iter``, ``ipopt_options``; the QP: those of ``method="qp"``) and ``x0``,
        the start on the free dofs (``joint.free_names``).
    """
    if not isinstance(method, str) or method not in JOINT_METHODS:
        raise InputError(f"method must be one of {JOINT_METHODS} for a Joint, got {method!r}")
    if not isinstance(certificate_tol, (int, float)) or not (0 < certificate_tol < 1) or math.isnan(certificate_tol):
        raise InputError(f"certificate_tol must be a number in (0, 1), got {certificate_tol!r}")
    if joint.kinematics == "finite":
        from .finite import solve_finite_joint

        return solve_finite_joint(joint, method, certificate_tol=certificate_tol, strict=strict, **options)
    with single_threaded_blas():
        solution = _solve(joint, method, certificate_tol, dict(options))
    return finish(solution, strict)


def _split(method: str, options: dict, fallback: str) -> tuple[dict, dict]:
    """Options for Newton and the fallback under ``auto``: each to the first that declares it."""
    newton, rest = {}, {}
    for key, value in options.items():
        if key in _OPTIONS["newton"]:
            newton[key] = value
        elif fallback == "nlp" and key in _OPTIONS["nlp"] or fallback == "qp":
            rest[key] = value
        else:
            accepted = sorted(_OPTIONS["newton"] | _OPTIONS["nlp"] | {"x0"})
            raise InputError(f"method 'auto' takes the options {accepted}, got unknown option {key!r}")
    return newton, rest


def _solve(joint: Joint, method: str, tol: float, options: dict) -> JointSolution:
    system = joint.system()
    x0 = start_vector(joint, options.pop("x0", None))
    linear = joint_ipopt.linear(system)
    if method == "qp" and not linear:
        raise InputError(
            "method 'qp' needs linear elements only (LinearLaw springs and law='linear' ligaments): use "
            "'newton' or 'nlp' for this joint"
        )
    fallback = "qp" if linear else "nlp"
    trivial = _trivial(joint, system)
    if trivial is not None:
        return _certified(joint, trivial, method, tol)
    if not system.load.any():
        own = _split(method, options, fallback)[0] if method == "auto" else options if method == "newton" else {}
        result = joint_newton.solve(system, **own)
        if result.success:
            result.status = Status.PRELOADED
            result.message = (
                "no load: only the elements' initial overlap or stretch loads them; the bodies move until they "
                "balance (newton's answer, for every method)"
            )
        return _certified(joint, result, method, tol)
    if method == "auto":
        newton_options, rest = _split(method, options, fallback)
        solution = _certified(joint, joint_newton.solve(system, x0=x0, **newton_options), "newton", tol)
        if not solution.success:
            check_joint_cone(joint)
            reason = f"newton ended with status {str(solution.status)!r} and certificate residual {solution.certificate.worst()}"
            solution = _certified(joint, _run(fallback, system, None, rest), fallback, tol)
            solution.info["fallback"] = reason
        solution.info.setdefault("fallback", None)
        solution.info["requested"] = "auto"
        return solution
    if method in ("qp", "nlp"):
        check_joint_cone(joint)
    solution = _certified(joint, _run(method, system, x0, options), method, tol)
    if not solution.success and method == "newton":
        check_joint_cone(joint)
    return solution


def _run(method: str, system, x0, options: dict) -> JointResult:
    try:
        if method == "newton":
            return joint_newton.solve(system, x0=x0, **options)
        if method == "nlp":
            return joint_ipopt.solve_nlp(system, x0=x0, **options)
        return joint_ipopt.solve_qp(system, **options)
    except SolverError as exc:
        status = Status(exc.status) if exc.status else Status.SOLVER_ERROR
        nan = [np.full(g.size, np.nan) for g in system.groups]
        return JointResult(
            np.full(system.n_dofs, np.nan), nan, False, status, str(exc), info={"native_status": exc.native_status}
        )


def _trivial(joint: Joint, system) -> JointResult | None:
    """The answers without a solver: no free dof, nothing resisted (held), or no load and nothing
    stored at the start (unloaded); a load along unresisted directions is refused first."""
    m = system.n_dofs
    zero = np.zeros(m)
    if m == 0:
        return JointResult(
            zero, law_stresses(system, zero), True, Status.NO_FREE_DOFS, "every dof is fixed or prescribed"
        )
    require_finite("the load", system.load)
    if system.load.any():
        check_joint_unresisted(joint)
    if system.resistance.n_resisted == 0:
        return JointResult(
            zero,
            law_stresses(system, zero),
            True,
            Status.HELD,
            "no element resists any free dof: every free dof is held at zero motion (the minimum-norm answer)",
        )
    if not system.load.any() and system.e0_overlap() == 0.0:
        return JointResult(
            zero, law_stresses(system, zero), True, Status.UNLOADED, "no load and nothing stored at the start"
        )
    return None


def _certified(joint: Joint, result: JointResult, method: str, tol: float) -> JointSolution:
    """The :class:`JointSolution` of a formulation's raw answer, with dea-opt's certificate."""
    start = time.perf_counter()
    system = joint.system()
    x = np.asarray(result.x, dtype=float)
    finite = bool(np.isfinite(x).all())
    xs = x if finite else np.zeros(system.n_dofs)
    certificate = (
        certify_joint(joint, x, result.stresses, tol)
        if finite
        else certify_joint(joint, xs, [np.full(g.size, np.nan) for g in system.groups], tol)
    )
    success = bool(finite and certificate.passed)
    try:
        status = Status(result.status)
    except ValueError:
        status = Status.SOLVER_ERROR
    message = result.message
    native = result.info.get("native_status", str(result.status))
    if success and status not in CERTIFIABLE:
        status = Status.CONVERGED
    elif not success and status in CERTIFIABLE:
        status, message = Status.INACCURATE, f"{message}; the answer fails dea-opt's certificate"
    groups = system.groups
    with np.errstate(invalid="ignore", over="ignore"):
        law = [g.forces(s) for g, s in zip(groups, law_stresses(system, xs))]
    body_u = joint.body_u(xs if finite else np.full(system.n_dofs, np.nan))
    on_body = body_forces(joint, law)
    common = {
        "tolerance": tol,
        "method": method,
        "success": success,
        "status": status,
        "message": message,
        "iterations": result.iterations,
        "solve_time": result.solve_time,
        "certificate": certificate,
    }
    n = len(joint.contacts)
    strains = system.strains(xs) if finite else [np.full(g.size, np.nan) for g in groups[:n]]
    contacts = layer_solutions(joint, body_u, on_body, law[:n], strains[:n], common, own=joint.wrenches(law[:n]))
    ligaments = ligament_results(joint, body_u, law)
    validity = assess_joint(joint, body_u, ligaments, tuple(c.validity for c in contacts))
    info = dict(result.info, native_status=native, solver_success=result.success)
    held = system.resistance.describe(list(joint.free_names)) if system.n_dofs else []
    if held:
        info["held"] = held
    info["certify_time"] = time.perf_counter() - start
    first = n + len(joint.ligament_groups)
    answered = [
        replace(group, e0=np.asarray(strain, dtype=float))
        for group, strain in zip(joint.elastic_groups, (system.strains(xs) if finite else [])[first:])
    ]
    elastic = elastic_results(joint, answered, law[first:]) if finite else []
    return JointSolution(
        joint=joint,
        x=x,
        bodies=body_results(joint, body_u, on_body),
        contacts=contacts,
        ligaments=ligaments,
        certificate=certificate,
        validity=validity,
        method=method,
        success=success,
        status=status,
        message=message,
        iterations=result.iterations,
        solve_time=result.solve_time,
        info=info,
        elastic=elastic,
    )
