"""``solve`` and ``compare``: dispatch a problem to a formulation and certify the answer."""

from __future__ import annotations

import inspect
import math
import time
import warnings

import numpy as np

from . import formulations
from .errors import InputError, LoadNotSupportedError, SolverError, ValidityWarning
from .formulations.energy import single_threaded_blas
from .kinematics import DOF_NAMES
from .problem import ContactProblem
from .solution import Solution, certify

__all__ = ["solve", "compare", "check_load_supported", "certified_solution", "METHODS"]

METHODS = ("auto", *formulations.FORMULATIONS)

#: Relative residual of the cone test above which a load counts as not carried.
_CONE_TOL = 1e-7


def _describe_direction(names, vector, load_vector) -> str:
    vector = np.asarray(vector, dtype=float)
    big = np.abs(vector) >= 1e-3 * np.abs(vector).max()
    parts = []
    for name, value, r in zip(names, vector, load_vector):
        if not big[names.index(name)]:
            continue
        body, dof = name.split(".")
        kind = "force" if dof[0] == "u" else "moment"
        axis = dof[1]
        unit = "N" if kind == "force" else "N mm"
        parts.append(f"{kind} {value:+.4g} {unit} along {axis} on {body}")
    return ", ".join(parts)


def check_load_supported(problem: ContactProblem) -> None:
    """Raise :class:`LoadNotSupportedError` when compression-only springs cannot carry the load.

    A solution exists iff the load lies in the cone of the spring directions,
    ``r = -A^T lambda`` with ``lambda >= 0`` (``formulations/energy.md``). Tested with
    non-negative least squares; the unbalanced remainder names the direction.
    """
    system = problem.system()
    r = system.load
    names = list(problem.free_names)
    if not names:
        return
    rnorm = np.linalg.norm(r)
    if rnorm == 0:
        return
    if system.n_springs == 0:
        raise LoadNotSupportedError(
            f"no spring resists the free dofs {tuple(names)}, so the load cannot be carried: "
            f"{_describe_direction(names, r, r)}; add springs or fix these dofs",
            direction=dict(zip(names, r.tolist())),
        )
    from scipy.optimize import nnls

    from .formulations.energy import bonded_basis

    # A load along a direction no spring resists at all: named exactly, before the cone test
    # (which could balance a nearly unresisted direction only with enormous forces).
    _, null = bonded_basis(system)
    unresisted = null @ (null.T @ r)
    if np.linalg.norm(unresisted) > _CONE_TOL * rnorm:
        raise LoadNotSupportedError(
            f"no spring resists part of this load: {_describe_direction(names, unresisted, r)} "
            f"({np.linalg.norm(unresisted) / rnorm:.3g} of the load) acts along a direction the springs "
            f"cannot push back on. Fix that dof, remove that part of the load, or add springs.",
            direction=dict(zip(names, unresisted.tolist())),
        )

    # Columns scaled to unit length so that nnls sees a well-conditioned cone.
    columns = -system.A.T
    norms = np.linalg.norm(columns, axis=0)
    keep = norms > 0
    columns = columns[:, keep] / norms[keep]
    try:
        _, residual_norm = nnls(columns, r, maxiter=50 * max(len(r), 1) + 100)
    except RuntimeError:
        return  # undecided: leave it to the solver and its certificate
    if residual_norm <= _CONE_TOL * rnorm:
        return
    lam, _ = nnls(columns, r, maxiter=50 * max(len(r), 1) + 100)
    remainder = r - columns @ lam
    pulls = "pulls the bodies apart or loads a direction no spring resists"
    raise LoadNotSupportedError(
        f"compression-only springs cannot carry this load: it {pulls}. "
        f"Unbalanced part: {_describe_direction(names, remainder, r)} "
        f"({residual_norm / rnorm:.3g} of the load). Check the load's sign (body 2 is pushed "
        f"toward body 1 by a load along -normal), fix the unresisted dofs, or add springs.",
        direction=dict(zip(names, remainder.tolist())),
    )


def _warn_validity(solution: Solution) -> None:
    """One :class:`ValidityWarning` naming every failed check of ``solution.validity``
    (value, limit and advice), or none when the answer is valid."""
    validity = solution.validity
    if not validity.valid:
        warnings.warn(validity.message(), ValidityWarning, stacklevel=4)


def _check_options(module, method: str, options: dict) -> None:
    """Unknown options are an InputError naming the accepted ones (solver-specific
    pass-through options are accepted where the formulation takes ``**kwargs``)."""
    params = inspect.signature(module.solve).parameters
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()):
        return
    accepted = [n for n, p in params.items() if p.kind is inspect.Parameter.KEYWORD_ONLY]
    for key in options:
        if key not in accepted:
            raise InputError(f"method {method!r} takes the options {accepted}, got unknown option {key!r}")


def _run(problem: ContactProblem, method: str, certificate_tol: float, options: dict) -> Solution:
    module = formulations.get(method)
    _check_options(module, method, options)
    if module.LINEAR_ONLY and not problem.law.is_linear:
        raise InputError(
            f"method {method!r} needs a LinearLaw, got {problem.law.describe()}: "
            f"use method='nlp' or method='newton' for nonlinear laws"
        )
    start = time.perf_counter()
    system = problem.system()
    build = time.perf_counter() - start
    if system.n_dofs == 0:
        result = formulations.FormulationResult(
            x=np.zeros(0), stress=problem.law.stress(np.minimum(system.e0, 0.0)), success=True,
            status="no_free_dofs", message="every dof is fixed or prescribed",
        )
    elif not system.load.any() and system.e0.min(initial=0.0) >= 0:
        # Nothing pushes the bodies together: the springs stay as they are.
        result = formulations.FormulationResult(
            x=np.zeros(system.n_dofs), stress=np.zeros(system.n_springs), success=True,
            status="unloaded", message="no load and no overlap: nothing to carry",
        )
    elif not system.load.any():
        # Overlapping springs with no load only push the bodies apart until they no longer
        # touch; every separated position is an equilibrium, so the constrained formulations
        # face an unbounded optimal set. One answer is returned for every method: Newton's.
        result = formulations.get("newton").solve(system, problem.law)
        result.status = "unloaded"
        result.message = ("no load: the overlap only pushes the bodies apart, and every separated "
                          "position is an equilibrium (Newton's is returned)")
    else:
        if method != "newton":
            check_load_supported(problem)
        try:
            result = module.solve(system, problem.law, **options)
        except SolverError as exc:
            # A solver that raised still yields a (failed) Solution, so that auto can fall
            # back and strict=False can report it like any other failure.
            nan = np.full(system.n_dofs, np.nan)
            result = formulations.FormulationResult(
                x=nan, stress=np.full(system.n_springs, np.nan), success=False,
                status=exc.status or "solver_error", message=str(exc),
            )
    return certified_solution(problem, result, method, certificate_tol, build + result.build_time)


def certified_solution(problem: ContactProblem, result, method: str, certificate_tol: float = 1e-6,
                       build_time: float = 0.0) -> Solution:
    """Turn a formulation's raw :class:`~dea_opt.formulations.FormulationResult` into a
    :class:`Solution` with dea_opt's own certificate (``success`` only if it passes).

    For callers that drive the formulation models themselves (load paths, studies).
    """
    u = problem.full_u(result.x)
    n = len(problem.layer)
    finite = bool(np.isfinite(u).all())
    strain = problem.strain(u) if finite else np.full(n, np.nan)
    with np.errstate(invalid="ignore", over="ignore"):
        # 0.0 - sigma keeps an unloaded spring at +0.0 MPa, not -0.0.
        pressure = 0.0 - problem.law.stress(np.minimum(strain, 0.0)) if finite else strain
    if finite:
        certificate = certify(problem, u, result.stress, certificate_tol)
    else:
        certificate = certify(problem, np.zeros(12), np.full(n, np.nan), certificate_tol)
    success = bool(finite and certificate.passed and np.isfinite(pressure).all())
    return Solution(
        problem=problem, u=u, strain=strain, pressure=pressure, method=method, success=success,
        status=result.status, message=result.message, iterations=result.iterations,
        build_time=build_time, solve_time=result.solve_time,
        certificate=certificate, info=dict(result.info, solver_success=result.success),
    )


def solve(problem: ContactProblem, method: str = "auto", *, certificate_tol: float = 1e-6,
          strict: bool = True, **options) -> Solution:
    """Find the equilibrium of ``problem`` and certify it.

    Parameters
    ----------
    problem : ContactProblem
    method : {"auto", "newton", "qp", "nlp"}
        ``"auto"`` runs Newton and, if its answer does not pass the certificate, the
        constrained formulation that fits the law (``qp`` for a linear law, ``nlp``
        otherwise); ``solution.info["fallback"]`` says why.
    certificate_tol : float
        Bound on every residual of the :class:`~dea_opt.solution.Certificate`.
    strict : bool
        Raise :class:`SolverError` when the answer fails its certificate (default). With
        ``strict=False`` the uncertified solution is returned with ``success=False``.
    **options
        Passed to the formulation (e.g. ``tol``, ``solver``, ``form``, ``x0``, ``max_iter``).

    Returns
    -------
    Solution

    Raises
    ------
    InputError, LoadNotSupportedError, SolverError
    """
    if not isinstance(problem, ContactProblem):
        raise InputError(f"problem must be a ContactProblem, got {type(problem).__name__}")
    with single_threaded_blas():
        return _solve(problem, method, certificate_tol, strict, options)


def _solve(problem, method, certificate_tol, strict, options) -> Solution:
    if method not in METHODS:
        raise InputError(f"method must be one of {METHODS}, got {method!r}")
    if not isinstance(certificate_tol, (int, float)) or not (0 < certificate_tol < 1) or math.isnan(certificate_tol):
        raise InputError(f"certificate_tol must be a number in (0, 1), got {certificate_tol!r}")
    if method == "auto":
        newton_options = {k: v for k, v in options.items() if k in ("x0", "max_iter")}
        solution = _run(problem, "newton", certificate_tol, newton_options)
        if not solution.success:
            _raise_if_unsupported(problem)
            fallback = "qp" if problem.law.is_linear else "nlp"
            reason = (f"newton ended with status {solution.status!r} and certificate residual "
                      f"{solution.certificate.worst()}")
            fallback_options = {k: v for k, v in options.items() if k not in ("x0", "max_iter")}
            solution = _run(problem, fallback, certificate_tol, fallback_options)
            solution.info["fallback"] = reason
        solution.info.setdefault("fallback", None)
        solution.info["requested"] = "auto"
    else:
        solution = _run(problem, method, certificate_tol, options)
        if not solution.success and method == "newton":
            _raise_if_unsupported(problem)
    if not solution.success and strict:
        name, value = solution.certificate.worst()
        raise SolverError(
            f"{solution.method} returned no certified answer (status {solution.status!r}: {solution.message}); "
            f"certificate residual {name} = {value:.3g} > {certificate_tol:g}. Try method='auto', a tighter "
            f"solver tolerance, or check the problem for loads no spring resists.",
            status=solution.status,
            solution=solution,
        )
    if solution.success:
        _warn_validity(solution)
    return solution


def _raise_if_unsupported(problem: ContactProblem) -> None:
    if problem.free_indices.size:
        check_load_supported(problem)


def compare(problem: ContactProblem, methods=("qp", "nlp", "newton"), *, certificate_tol: float = 1e-6,
            **options) -> dict:
    """Solve with several methods and measure their largest disagreement.

    Methods that do not apply (``qp`` for a nonlinear law) are skipped. ``options`` may
    map a method name to its own options, e.g. ``compare(p, qp={"tol": 1e-10})``.

    Returns
    -------
    dict
        ``{"solutions": {method: Solution}, "displacement": float, "pressure": float,
        "skipped": {method: reason}}``: the largest pairwise difference of ``u`` relative
        to ``max |u|`` and of pressure relative to the peak pressure.
    """
    solutions, skipped = {}, {}
    for method in methods:
        if method not in METHODS or method == "auto":
            raise InputError(f"methods must be taken from {METHODS[1:]}, got {method!r}")
        module = formulations.get(method)
        if module.LINEAR_ONLY and not problem.law.is_linear:
            skipped[method] = f"{method} needs a linear law"
            continue
        solutions[method] = solve(problem, method, certificate_tol=certificate_tol, **options.get(method, {}))
    du = dp = 0.0
    items = list(solutions.values())
    for i, a in enumerate(items):
        for b in items[i + 1:]:
            su = max(np.abs(a.u).max(), np.abs(b.u).max(), 1e-300)
            sp = max(a.peak_pressure, b.peak_pressure, 1e-300)
            du = max(du, float(np.abs(a.u - b.u).max() / su))
            dp = max(dp, float(np.abs(a.pressure - b.pressure).max() / sp))
    return {"solutions": solutions, "displacement": du, "pressure": dp, "skipped": skipped}
