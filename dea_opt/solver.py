"""``solve`` and ``compare``: dispatch a problem to a formulation and certify the answer."""

from __future__ import annotations

import inspect
import math
import time
import warnings

import numpy as np

from . import formulations
from .errors import InputError, LoadNotSupportedError, SolverError, ValidityWarning
from .formulations.energy import (
    check_options,
    require_finite,
    single_threaded_blas,
    start_vector,
    trivial_result,
    unresisted,
)
from .problem import ContactProblem
from .solution import Solution, certify

__all__ = ["solve", "compare", "check_load_supported", "certified_solution", "METHODS"]

METHODS = ("auto", *formulations.FORMULATIONS)

#: Relative residual of the cone test above which a load counts as not carried.
_CONE_TOL = 1e-7


def _describe_direction(problem: ContactProblem, names, vector) -> str:
    """The large components of a generalized force in words, each in its own units: a force
    in N, a moment in N mm about the body's reference point."""
    vector = np.asarray(vector, dtype=float)
    top = float(np.abs(vector).max(initial=0.0))
    parts = []
    for name, value in zip(names, vector):
        if top == 0.0 or abs(value) < 1e-3 * top:
            continue
        body, dof = name.split(".")
        reference = (problem.body1 if body == "body1" else problem.body2).reference
        if dof[0] == "u":
            parts.append(f"force {value:+.4g} N along {dof[1]} on {body}")
        else:
            point = ", ".join(f"{c:.4g}" for c in reference)
            parts.append(f"moment {value:+.4g} N mm along {dof[1]} on {body} (about its reference point "
                         f"({point}) mm)")
    return ", ".join(parts) or "none"


def check_load_supported(problem: ContactProblem) -> None:
    """Raise :class:`LoadNotSupportedError` when compression-only springs cannot carry the load.

    Two tests (``formulations/energy.md``, "When is there a solution?"): a part of the load
    along directions no spring resists (:func:`_check_unresisted`, the same test as the
    formulations' scaling and the certificate), then the cone test: a solution exists iff the
    load lies in the cone of the spring directions, ``r = -A^T lambda`` with ``lambda >= 0``,
    tested with non-negative least squares over the resisted directions; the unbalanced
    remainder names the direction.
    """
    system = problem.system()
    if not system.n_dofs or not system.load.any():
        return
    _check_unresisted(problem, system)
    _check_cone(problem, system)


def _check_unresisted(problem: ContactProblem, system) -> None:
    """Raise when more than ``_CONE_TOL`` of the load acts along directions no spring resists."""
    r = system.load
    require_finite("the load", r)
    res = system.resistance
    fraction = res.load_fraction(r)
    if fraction <= _CONE_TOL:
        return
    names = list(problem.free_names)
    part = res.load_part(r)
    if res.n_resisted == 0:
        reason = f"no spring resists any of the free dofs {tuple(names)}"
        if not system.n_springs:
            reason += " (the layer has no springs)"
        message = (f"{reason}, so the load along them cannot be carried: {_describe_direction(problem, names, part)}. "
                   f"Fix these dofs, remove this load, or add springs that resist them.")
    else:
        message = (f"no spring resists part of this load: {_describe_direction(problem, names, part)} "
                   f"({fraction:.3g} of the load) acts along a direction the springs cannot push back on "
                   f"({'; '.join(res.describe(names))}). Fix that dof, remove that part of the load, or add springs.")
    raise LoadNotSupportedError(message, direction=dict(zip(names, part.tolist())))


def _check_cone(problem: ContactProblem, system) -> None:
    """The cone test over the resisted directions, in arc lengths (moments over the radius)."""
    from scipy.optimize import nnls

    res = system.resistance
    D, Q = res.lengths, res.range
    rhs = Q.T @ (system.load / D)
    rnorm = float(np.linalg.norm(rhs))
    if rnorm == 0.0:
        return
    # Each spring's generalized force direction, restricted to what the springs resist; a
    # spring whose direction there is no stiffness at all (by the one test) joins no cone.
    columns = -(Q.T @ (system.AT / D[:, None]))
    norms = np.linalg.norm(columns, axis=0)
    keep = ~unresisted(system.volume * norms**2, res.scale) & (norms > 0)
    columns = columns[:, keep] / norms[keep]
    names = list(problem.free_names)
    if columns.shape[1]:
        # nnls is compiled code: never hand it an empty or non-finite matrix (it aborts the
        # process on an m x 0 one).
        require_finite("the spring directions", columns, rhs)
        try:
            lam, residual_norm = nnls(columns, rhs, maxiter=50 * max(len(rhs), 1) + 100)
        except RuntimeError:
            return  # undecided: leave it to the solver and its certificate
        if residual_norm <= _CONE_TOL * rnorm:
            return
        remainder = rhs - columns @ lam
    else:
        remainder, residual_norm = rhs, rnorm
    remainder = D * (Q @ remainder)
    pulls = "pulls the bodies apart or loads a direction no spring resists"
    raise LoadNotSupportedError(
        f"compression-only springs cannot carry this load: it {pulls}. "
        f"Unbalanced part: {_describe_direction(problem, names, remainder)} "
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
    _check_common_options(system, options)
    result = _formulation_result(problem, system, method, module, options)
    return certified_solution(problem, result, method, certificate_tol, build + result.build_time)


def _formulation_result(problem: ContactProblem, system, method: str, module, options: dict):
    """The raw answer of ``method``, or of no solver where none is needed."""
    if system.n_dofs == 0:
        return formulations.FormulationResult(
            x=np.zeros(0), stress=problem.law.stress(np.minimum(system.e0, 0.0)), success=True,
            status="no_free_dofs", message="every dof is fixed or prescribed",
        )
    # Every method, Newton included: a load along a direction no spring resists is never
    # "solved" (the same test as the scaling and the certificate).
    if system.load.any():
        _check_unresisted(problem, system)
    trivial = trivial_result(system, problem.law)
    if trivial is not None:
        return trivial
    if not system.load.any():
        # Overlapping springs with no load: they push the bodies apart until they no longer
        # touch (every separated position is then an equilibrium, an unbounded set for the
        # constrained formulations), or, where they surround a body, to the position where
        # they balance. One answer is returned for every method: Newton's.
        result = formulations.get("newton").solve(system, problem.law)
        if result.success:
            result.status = "preloaded"
            result.message = ("no load: only the initial overlap compresses springs; the bodies move until "
                              "the springs balance each other (Newton's answer, for every method)")
        result.info["solved_by"] = "newton"
        return result
    if method != "newton":
        _check_cone(problem, system)
    try:
        return module.solve(system, problem.law, **options)
    except SolverError as exc:
        # A solver that raised still yields a (failed) Solution, so that auto can fall
        # back and strict=False can report it like any other failure.
        return formulations.FormulationResult(
            x=np.full(system.n_dofs, np.nan), stress=np.full(system.n_springs, np.nan), success=False,
            status=exc.status or "solver_error", message=str(exc),
        )


def _check_common_options(system, options: dict) -> None:
    """The options every formulation shares, validated before anything is solved (also for
    problems that need no solver, so that a bad option never passes silently)."""
    check_options(**{k: v for k, v in options.items() if k in ("tol", "xtol", "gtol", "max_iter")})
    start_vector(system, options.get("x0"))


def certified_solution(problem: ContactProblem, result, method: str, certificate_tol: float = 1e-6,
                       build_time: float = 0.0) -> Solution:
    """Turn a formulation's raw :class:`~dea_opt.formulations.FormulationResult` into a
    :class:`Solution` with dea_opt's own certificate (``success`` only if it passes).

    Where some free directions are unresisted, ``info["held"]`` names them (they take no
    motion and carry no load) and the message says so. For callers that drive the formulation
    models themselves (load paths, studies).
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
    info, message = dict(result.info, solver_success=result.success), result.message
    held = problem.system().resistance.describe(problem.free_names) if problem.free_indices.size else []
    if held:
        # Directions no spring resists carry no load (check_load_supported) and take no
        # motion: the answer is the minimum-norm one. Said, so that nobody reads u there.
        info["held"] = held
        if result.status != "held":
            message = f"{message}; held at zero motion, as no spring resists them: {', '.join(held)}"
    return Solution(
        problem=problem, u=u, strain=strain, pressure=pressure, method=method, success=success,
        status=result.status, message=message, iterations=result.iterations,
        build_time=build_time, solve_time=result.solve_time,
        certificate=certificate, info=info,
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
    _check_common_options(problem.system(), options)
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
