"""``solve`` and ``compare``: dispatch a problem to a formulation and certify the answer."""

from __future__ import annotations

import math
import time
import warnings

import numpy as np

from . import formulations, loadcheck
from ._checks.threads import single_threaded_blas
from .agreement import Comparison, disagreement
from .certificate import certify
from .errors import InputError, SolverError, ValidityWarning
from .formulations._parts.crush import CRUSHED_MESSAGE, crushed
from .formulations._parts.system import failed_result, start_vector, trivial_result
from .loadcheck import check_load_supported
from .problem import ContactProblem
from .solution import Solution
from .status import CERTIFIABLE, Status

__all__ = [
    "Comparison",
    "certified_solution",
    "check_load_supported",
    "check_method",
    "compare",
    "formulation_plan",
    "formulation_result",
    "solve",
]


def _warn_validity(solution: Solution) -> None:
    """One :class:`ValidityWarning` naming every failed check of ``solution.validity``
    (value, limit and advice), or none when the answer is valid."""
    validity = solution.validity
    if not validity.valid:
        warnings.warn(validity.message(), ValidityWarning, stacklevel=4)


def check_method(method: str, law=None) -> None:
    """An :class:`InputError` unless ``method`` is ``"auto"`` or a registered formulation
    (:func:`dea_opt.formulations.names`) that takes ``law``."""
    if not isinstance(method, str) or (method != "auto" and method not in formulations.names()):
        raise InputError(f"method must be one of {('auto', *formulations.names())}, got {method!r}")
    if law is not None and method != "auto":
        formulations.resolve(method, law).check()


def formulation_plan(method: str, law, options: dict) -> list[tuple[str, dict, object]]:
    """``[(formulation, its options, x0), ...]`` in the order ``method`` tries them, options checked.

    One formulation, or for ``"auto"`` :data:`~dea_opt.formulations.DEFAULT` and then
    :func:`~dea_opt.formulations.fallback_for` the law. Under ``auto`` each option goes to the
    first of them that declares it (else to one that passes undeclared options on to its
    solver), and ``x0`` to the first. An unknown or bad option is an :class:`InputError`
    naming the accepted ones.
    """
    check_method(method, law)
    options = dict(options)
    x0 = options.pop("x0", None)
    if method != "auto":
        return [(method, formulations.check_options(method, options), x0)]
    chain = [formulations.DEFAULT]
    fallback = formulations.fallback_for(law)
    if fallback is not None and fallback != chain[0]:
        chain.append(fallback)
    parts: dict = {name: {} for name in chain}
    declared = {name: {option.name for option in formulations.options(name)} for name in chain}
    for key, value in options.items():
        home = next((n for n in chain if key in declared[n]), None)
        home = home or next((n for n in chain if formulations.extra_options(n)), None)
        if home is None:
            accepted = sorted(set().union(*declared.values()) | {"x0"})
            raise InputError(f"method 'auto' takes the options {accepted}, got unknown option {key!r}")
        parts[home][key] = value
    return [
        (name, formulations.check_options(name, parts[name]), x0 if i == 0 else None) for i, name in enumerate(chain)
    ]


def _run(problem: ContactProblem, name: str, certificate_tol: float, options: dict, x0=None) -> Solution:
    start = time.perf_counter()
    system = problem.system()
    build = time.perf_counter() - start
    result = formulation_result(
        problem, system, name, lambda: formulations.build(name, system, problem.law, **options), x0=x0
    )
    return certified_solution(problem, result, name, certificate_tol, build + result.build_time)


def formulation_result(problem: ContactProblem, system, name: str, model, *, x0=None, check_cone=None):
    """The raw answer of formulation ``name``, or of no solver where none is needed.

    Parameters
    ----------
    problem : ContactProblem
    system : SpringSystem
        ``problem.system()``.
    name : str
        A registered formulation.
    model : callable
        Returns the formulation's model for ``system`` (called only when a solver runs, so a
        load path can build it once and re-solve it).
    x0 : ndarray, shape (m,), optional
        The start (mm, rad).
    check_cone : bool, optional
        Run the cone test before the solver (default: the formulation's
        ``Capabilities.checks_load_first``).
    """
    law = problem.law
    if system.n_dofs == 0:
        return formulations.FormulationResult(
            u_free=np.zeros(0),
            stress=law.stress(np.minimum(system.e0, 0.0)),
            success=True,
            status=Status.NO_FREE_DOFS,
            message="every dof is fixed or prescribed",
            info={"native_status": None},
        )
    # Every method: a load along a direction no spring resists is never "solved" (the same
    # test as the scaling and the certificate).
    if system.load.any():
        loadcheck.check_unresisted(problem, system)
    trivial = trivial_result(system, law)
    if trivial is not None:
        return trivial
    if not system.load.any():
        # Overlapping springs with no load: they push the bodies apart until they no longer
        # touch (every separated position is then an equilibrium, an unbounded set for the
        # constrained formulations), or, where they surround a body, to the position where
        # they balance. One answer is returned for every method: the default formulation's.
        default = formulations.DEFAULT
        result = formulations.solve(default, system, law)
        _clear_of_rounding(problem, system, result)
        if result.success:
            result.status = Status.PRELOADED
            result.message = (
                f"no load: only the initial overlap compresses springs; the bodies move until the "
                f"springs balance each other ({default}'s answer, for every method)"
            )
        result.info["solved_by"] = default
        return result
    if check_cone is None:
        check_cone = formulations.capabilities(name).checks_load_first
    if check_cone:
        loadcheck.check_cone(problem, system)
    try:
        return model().solve(system.load, x0=x0)
    except SolverError as exc:
        # A solver that raised still yields a (failed) answer, so that auto can fall back and
        # strict=False and load paths can report it like any other failure.
        return failed_result(system, exc)


#: How far beyond its strain's rounding a preloaded answer opens the springs it leaves touching.
_CLEARANCE = 4.0


def _clear_of_rounding(problem: ContactProblem, system, result) -> None:
    """Move a preloaded answer whose springs merely touch on along its own motion, until each is open
    by :data:`_CLEARANCE` times its strain's rounding (``ContactProblem.strain_rounding``).

    With no load, every position where no spring is compressed is an equilibrium; the solver stops
    where the last springs just open, their strains zero to rounding, where the law gives forces of
    rounding's size that nothing else balances and no certificate can accept (there is nothing in
    equilibrium to measure them against). A step of the motion's rounding size (at most 1e-6 of it)
    further, none is within rounding of contact. Press fits whose springs stay compressed (real
    forces), motions that would close another spring, and failed answers are left as they are."""
    x = result.u_free
    if not (x.size and np.isfinite(x).all()):
        return
    u = problem.full_u(x)
    eps, delta = problem.strain(u), problem.strain_rounding(u)
    if (eps < -delta).any():
        return
    near = np.flatnonzero(eps < _CLEARANCE * delta)
    if not near.size:
        return
    rate = x @ system.AT[:, near]  # each strain's change per unit of the motion itself
    if not (rate > 0).all():
        return
    tau = float(np.max((_CLEARANCE * delta[near] - eps[near]) / rate))
    if not 0 < tau <= 1e-6:
        return
    result.u_free = x * (1.0 + tau)
    with np.errstate(invalid="ignore", over="ignore"):
        result.stress = problem.law.stress(np.minimum(system.strain_at(result.u_free), 0.0))


def _status(result) -> tuple[Status, object]:
    """The result's :class:`Status` and the solver's own; a status outside the vocabulary (a
    formulation of one's own) is a solver error that keeps its word as the native one."""
    native = result.info.get("native_status", result.status)
    try:
        return Status(result.status), native
    except ValueError:
        return Status.SOLVER_ERROR, result.status


def certified_solution(
    problem: ContactProblem, result, method: str, certificate_tol: float = 1e-6, build_time: float = 0.0
) -> Solution:
    """Turn a formulation's raw :class:`~dea_opt.formulations.FormulationResult` into a
    :class:`Solution` with dea_opt's own certificate (``success`` only if it passes).

    One status per situation, whichever method: a certified answer is
    :attr:`Status.CONVERGED` (or the status of an answer that needed no solver) even where
    the solver doubted it; an uncertified one whose springs reach ``eps = -1`` is
    :attr:`Status.CRUSHED`, and one the solver claimed is :attr:`Status.INACCURATE`.
    ``info["native_status"]`` and ``info["solver_success"]`` keep the solver's own word. Where
    some free directions are unresisted, ``info["held"]`` names them (they take no motion
    and carry no load) and the message says so. For callers that drive the formulation
    models themselves (load paths, studies).
    """
    u = problem.full_u(result.u_free)
    n = len(problem.layer)
    finite = bool(np.isfinite(u).all())
    strain = problem.strain(u) if finite else np.full(n, np.nan)
    with np.errstate(invalid="ignore", over="ignore"):
        # 0.0 - sigma keeps an unloaded spring at +0.0 MPa, not -0.0.
        pressure = 0.0 - problem.law.stress(np.minimum(strain, 0.0)) if finite else strain
    if finite:
        certificate = certify(problem, u, result.stress, certificate_tol, strain=strain)
    else:
        certificate = certify(problem, np.zeros(12), np.full(n, np.nan), certificate_tol)
    success = bool(finite and certificate.passed and np.isfinite(pressure).all())
    status, native = _status(result)
    info, message = dict(result.info, solver_success=result.success, native_status=native), result.message
    # The same situation, the same status from every method (formulations/energy.md, "Statuses").
    if success and status not in CERTIFIABLE:
        status = Status.CONVERGED  # certified although the solver doubted it (native_status says how)
    elif not success and status != Status.CRUSHED and crushed(problem.law, strain):
        status = Status.CRUSHED
        message = f"{message}; {CRUSHED_MESSAGE.format(eps=float(np.nanmin(strain)))}"
    elif not success and status in CERTIFIABLE:
        status = Status.INACCURATE
        message = f"{message}; the answer fails dea-opt's certificate"
    if not success and certificate.rounding > 0.5 * certificate_tol:
        message = (
            f"{message}; the rounding of the strains alone can move the springs' forces by "
            f"{certificate.rounding:.3g} of what is in equilibrium at the answer (the gaps and the motion "
            f"cancel to strains float64 does not resolve at this load)"
        )
    held = problem.system().resistance.describe(problem.free_names) if problem.free_indices.size else []
    if held:
        # Directions no spring resists carry no load (check_load_supported) and take no
        # motion: the answer is the minimum-norm one. Said, so that nobody reads u there.
        info["held"] = held
        if status != Status.HELD:
            message = f"{message}; held at zero motion, as no spring resists them: {', '.join(held)}"
    return Solution(
        problem=problem,
        u=u,
        strain=strain,
        pressure=pressure,
        method=method,
        success=success,
        status=status,
        message=message,
        iterations=result.iterations,
        build_time=build_time,
        solve_time=result.solve_time,
        certificate=certificate,
        info=info,
    )


def solve(problem, method: str = "auto", *, certificate_tol: float = 1e-6, strict: bool = True, **options):
    """Find the equilibrium of ``problem`` and certify it.

    Parameters
    ----------
    problem : ContactProblem or Joint
        A two-body problem, or a whole :class:`~dea_opt.joint.Joint` (several bodies, layers and
        ligaments), which :func:`dea_opt.joint.solve_joint` solves into a
        :class:`~dea_opt.joint.JointSolution` (methods ``"auto"``, ``"newton"``, ``"qp"``, ``"nlp"``).
    method : str
        ``"auto"`` or a registered formulation (:func:`dea_opt.formulations.names`: ``"newton"``,
        ``"qp"``, ``"nlp"``). ``"auto"`` runs the default formulation (Newton) and, if its
        answer does not pass the certificate, the formulation the registry picks for the
        law (:func:`~dea_opt.formulations.fallback_for`: ``qp`` for a linear law, ``nlp``
        otherwise); ``solution.info["fallback"]`` says why.
    certificate_tol : float
        Bound on every residual of the :class:`~dea_opt.certificate.Certificate`.
    strict : bool
        Raise :class:`SolverError` when the answer fails its certificate (default). With
        ``strict=False`` the uncertified solution is returned with ``success=False``.
    **options
        The formulation's options (:func:`dea_opt.formulations.options`, e.g. ``tol``,
        ``solver``, ``form``, ``max_iter``) and ``x0``, the start on the free dofs.

    Returns
    -------
    Solution, or JointSolution for a Joint

    Raises
    ------
    InputError, LoadNotSupportedError, SolverError
    """
    from .joint import Joint, solve_joint

    if isinstance(problem, Joint):
        return solve_joint(problem, method, certificate_tol=certificate_tol, strict=strict, **options)
    if not isinstance(problem, ContactProblem):
        raise InputError(f"problem must be a ContactProblem or a Joint, got {type(problem).__name__}")
    if problem.kinematics == "finite":
        from .finite import solve as solve_finite

        return solve_finite(
            problem,
            method,
            certificate_tol=certificate_tol,
            strict=strict,
            unresisted=loadcheck.check_unresisted,
            **options,
        )
    with single_threaded_blas():
        return _solve(problem, method, certificate_tol, strict, options)


def _solve(problem, method, certificate_tol, strict, options) -> Solution:
    check_method(method)
    if not isinstance(certificate_tol, (int, float)) or not (0 < certificate_tol < 1) or math.isnan(certificate_tol):
        raise InputError(f"certificate_tol must be a number in (0, 1), got {certificate_tol!r}")
    plan = formulation_plan(method, problem.law, options)
    start_vector(problem.system(), plan[0][2])
    name, first_options, x0 = plan[0]
    solution = _run(problem, name, certificate_tol, first_options, x0)
    if method == "auto":
        if not solution.success and len(plan) > 1 and not beyond_resolution(solution):
            _raise_if_unsupported(problem)
            fallback, fallback_options, _ = plan[1]
            reason = (
                f"{name} ended with status '{solution.status}' and certificate residual {solution.certificate.worst()}"
            )
            solution = _run(problem, fallback, certificate_tol, fallback_options)
            solution.info["fallback"] = reason
        solution.info.setdefault("fallback", None)
        solution.info["requested"] = "auto"
    elif not solution.success and not formulations.capabilities(name).checks_load_first:
        _raise_if_unsupported(problem)
    if not solution.success and strict:
        raise SolverError(
            f"{solution.method} returned no certified answer (status '{solution.status}': {solution.message}); "
            f"{solution.failure}. Try method='auto', a tighter "
            f"solver tolerance, or check the problem for loads no spring resists.",
            status=solution.status,
            solution=solution,
            native_status=solution.info.get("native_status"),
        )
    if solution.success:
        _warn_validity(solution)
    return solution


def beyond_resolution(solution: Solution) -> bool:
    """Whether ``solution`` failed its certificate only because its load is below what float64
    resolves against the gaps and motion its strains are summed from: ``Certificate.rounding`` above
    half the tolerance (the imbalance that rounding leaves in any computed answer takes the rest), a
    computed imbalance no larger than that rounding can make (the equilibrium residual adds the two),
    the other residuals within the tolerance. No formulation does better, so ``auto`` keeps that
    answer and its reason rather than fall back."""
    c = solution.certificate
    others = (c.tension, c.complementarity, c.consistency)
    return bool(
        np.isfinite(solution.u).all()
        and c.rounding > 0.5 * c.tolerance
        and c.equilibrium <= 2.0 * c.rounding + c.tolerance
        and all(v <= c.tolerance for v in others)
    )


def _raise_if_unsupported(problem: ContactProblem) -> None:
    if problem.free_indices.size:
        check_load_supported(problem)


def compare(problem: ContactProblem, methods=None, *, certificate_tol: float = 1e-6, **options) -> Comparison:
    """Solve with several methods and measure their largest disagreement.

    ``methods`` defaults to every registered formulation. The methods are chosen as by
    ``dea-opt compare`` (:func:`dea_opt.formulations.select`): for ``kinematics="finite"``
    ``newton`` and ``nlp`` stand for ``finite`` and ``finite_nlp`` (``notes`` says so), and a
    method that does not solve the problem (``qp`` for a nonlinear law, or for finite kinematics:
    the QP is a small-kinematics method) is skipped, ``skipped`` saying why. ``options`` may map a
    method to its options, ``compare(p, qp={"tol": 1e-10})`` (``nlp=`` reaches ``finite_nlp``).

    Returns
    -------
    Comparison
        The solutions by formulation, the largest pairwise difference of ``u`` relative to
        ``max |u|`` (``.displacement``) and of pressure relative to the peak pressure
        (``.pressure``; :func:`dea_opt.agreement.disagreement`, finite answers matched by mesh
        face), the methods ``.skipped`` and why, and ``.notes``.

    A :class:`~dea_opt.joint.Joint` is compared by :func:`dea_opt.joint.compare.compare_joint`
    (methods ``newton``, ``qp``, ``nlp``; its comparison also holds ``ligament_force``).

    Raises
    ------
    InputError
        A method that is not registered, or no method named solves the problem (e.g. ``qp``
        alone for finite kinematics).
    """
    from .joint import Joint

    if isinstance(problem, Joint):
        from .joint.compare import compare_joint

        return compare_joint(problem, methods, certificate_tol=certificate_tol, **options)
    if not isinstance(problem, ContactProblem):
        raise InputError(f"problem must be a ContactProblem, got {type(problem).__name__}")
    resolved = {n: formulations.resolve(n, None, problem.kinematics).name for n in formulations.names()}
    aliases = {n: to for n, to in resolved.items() if to != n}  # {"newton": "finite", ...} for finite kinematics
    if methods is None:  # every formulation, not twice under the names that stand for another
        methods = [name for name in formulations.names() if name not in aliases]
    chosen = formulations.select(methods, problem.law, problem.kinematics)
    solutions = {}
    for name in chosen.run:
        given = {k: v for alias, to in aliases.items() if to == name for k, v in options.get(alias, {}).items()}
        solutions[name] = solve(problem, name, certificate_tol=certificate_tol, **(given | options.get(name, {})))
    du, dp = disagreement(solutions.values())
    return Comparison(solutions, du, dp, skipped=chosen.skipped, notes=tuple(chosen.notes))
