"""Finite kinematics, the solve: targets, the equilibrium by Newton or IPOPT, re-casting, the certificate.

Written math: ``formulations/finite.md``. :func:`solve` is what ``dea_opt.solve`` runs for a
``ContactProblem(..., kinematics="finite")``: it resolves each spring's target, builds the arrays
of a :class:`~dea_opt.formulations.finite.FiniteSystem`, has the registry's formulation solve the
equilibrium of the free coordinates (:mod:`~dea_opt.formulations.finite`, Newton, or
:mod:`~dea_opt.formulations.finite_nlp`, IPOPT: arrays in, a raw answer out), keeps springs cast
from meshes up to date as body 2 moves (:mod:`~dea_opt.largemotion.tracker`), solving again
while a loaded spring changed, and certifies the answer at the solved pose
(:mod:`~dea_opt.largemotion.solution`).
"""

from __future__ import annotations

import time
import warnings
from dataclasses import replace

import numpy as np

from .. import formulations
from .._checks.threads import single_threaded_blas
from ..errors import InputError, SolverError, ValidityWarning
from ..formulations.finite import (
    ALIASES,
    SHARED,
    FiniteSystem,
    Targets,
    evaluate,
    rms_radius,
    scale,
    small_system,
    status_of,
)
from ..formulations.system import SpringSystem, start_vector
from ..kinematics import DOFS
from ..mesh import SpringCast, check_pose
from . import fallback
from .outcome import crushed_at_start, crushed_far, crushed_through, far_from_start, ran_away, unsettled
from .solution import FiniteSolution, certificate
from .stability import leave_unstable, lengths_of, noted, softest
from .start import at_base, near_base, predicted, warm_start
from .tracker import MeshTracker

__all__ = ["plan", "solve"]

_GAP_TOL = 1e-6  # mm per mm of the layer's size: targets must reproduce the layer's gaps
_LOOSE = 1e-6  # the scaled residual a solve that an update of the springs follows stops at


def resolve_targets(problem) -> tuple[Targets, object]:
    """``(targets, cast)``: the springs' targets at zero displacement, and the SpringCast to re-cast
    from (None without meshes). Checked to reproduce the layer's gaps."""
    layer, given = problem.layer, problem.targets
    cast = None
    if given is None:
        targets = Targets.from_layer(layer) if layer.has_targets else Targets.facing(layer)
    elif isinstance(given, SpringCast):
        cast = given
        if len(cast.layer) != len(layer) or not np.array_equal(
            np.asarray(cast.layer.source_face), np.asarray(layer.source_face)
        ):
            raise InputError(
                f"targets is a SpringCast of {len(cast.layer)} springs, but the problem's layer has "
                f"{len(layer)}: pass the cast the layer came from (ContactProblem(cast.layer, ..., "
                f"targets=cast))"
            )
        if layer is cast.layer:  # the cast's own targets give its gaps (they are where its rays met)
            own = cast.layer
            pose = np.asarray(cast.pose, dtype=float)
            return Targets.cast_planes(own.target_points, own.target_normals, pose, own.target_faces), cast
        targets = Targets.from_layer(cast.layer, pose=cast.pose)
    else:
        targets = given
        if len(targets) != len(layer):
            raise InputError(f"targets has {len(targets)} entries, the layer {len(layer)} springs: give one per spring")
    s0 = evaluate(targets, layer.points, layer.normals, targets.frame).s
    size = max(float(np.abs(layer.points).max(initial=0.0)), 1.0)
    error = np.abs(s0 - layer.gap)
    if len(error) and not (error.max() <= _GAP_TOL * size):
        i = int(np.nanargmax(np.where(np.isfinite(error), error, np.inf)))
        raise InputError(
            f"targets must reproduce the layer's gaps at zero displacement: spring {i} has gap "
            f"{layer.gap[i]:.6g} mm, its target gives {s0[i]:.6g} mm; build the targets from the same "
            f"geometry (Targets.from_layer(layer), the SpringCast, or planes/spheres through the gaps)"
        )
    return targets, cast


def check_bodies(problem) -> None:
    """Finite kinematics move body 2 against a fixed body 1 (only the relative pose matters)."""
    body1 = problem.body1
    moved = [d for d, v in body1.prescribed.items() if v != 0.0]
    if body1.free or moved:
        what = f"free dofs {body1.free}" if body1.free else f"prescribed motion {moved}"
        raise InputError(
            f"kinematics='finite' moves body 2 against a fixed body 1, but body1 has {what}: fix body 1 "
            f"and give the motion to body 2 (only the relative pose matters)"
        )


def build_system(problem, targets, tracker=None) -> FiniteSystem:
    """The :class:`FiniteSystem` of ``problem``'s springs and ``targets``, or of ``tracker``'s springs
    (a load path's previous frame's, or the cast's) with the problem's body 2 and load."""
    layer, body2 = problem.layer, problem.body2
    free = np.array([DOFS.index(d) for d in body2.free], dtype=int)
    base = np.zeros(6)
    for dof, value in body2.prescribed.items():
        base[DOFS.index(dof)] = value
    if tracker is not None:
        s = tracker.springs
        return FiniteSystem.of_rows(
            s.points,
            s.normals,
            s.areas,
            tracker.thickness,
            tracker.targets(),
            s.pT,
            s.nT,
            s.arms,
            s.mT,
            s.qm,
            np.asarray(body2.reference, dtype=float),
            free,
            base,
            np.asarray(body2.force, dtype=float),
            np.asarray(body2.moment, dtype=float),
        )
    springs = (layer.points, layer.normals, layer.areas, layer.thickness, targets)
    return FiniteSystem(
        *springs,
        np.asarray(body2.reference, dtype=float),
        free,
        base,
        np.asarray(body2.force, dtype=float),
        np.asarray(body2.moment, dtype=float),
    )


def scaled_directions(system, law) -> tuple[np.ndarray, float, SpringSystem]:
    """``(T, E0, small)``: the scaled directions of :func:`~dea_opt.formulations.scaling.scaling`,
    from the resistance of the springs' small system at zero displacement (held directions left
    out; :func:`~dea_opt.formulations.finite.small_system`: the springs of this solve at body 2's
    base pose, exact gaps), sized by the larger of the load and the overlap of those gaps."""
    small = small_system(system, law)
    T, E0 = scale(small.resistance.basis(law.modulus), small.load, system, law, small.e0)
    return T, E0, small


def plan(method, law, options: dict) -> list[tuple[str, dict, object]]:
    """``[(formulation, its options, x0), ...]`` in the order ``method`` tries them, for finite kinematics.

    ``method`` is ``"auto"`` (the registered formulations that solve finite kinematics for
    ``law``, in order: ``finite``, then ``finite_nlp``), one of them, or ``"newton"``/``"nlp"``
    (:data:`ALIASES`). Any other is an :class:`~dea_opt.errors.InputError` from the registry
    (``qp``: a small-kinematics method). Options are checked by the registry; under ``auto``
    each goes to the first formulation that declares it, the re-casting ones to both.
    """
    from ..formulations import check_options, check_takes, names, takes
    from ..formulations import options as declared

    name = ALIASES.get(method, method) if isinstance(method, str) else method
    options = dict(options)
    x0 = options.pop("x0", None)
    if name != "auto":
        if not isinstance(name, str) or name not in names():
            raise InputError(f"method must be one of {('auto', *names())}, got {method!r}")
        check_takes(name, law, "finite")
        return [(name, check_options(name, options), x0)]
    chain = [n for n in names() if takes(n, law, "finite")][:2]
    parts: dict = {n: {} for n in chain}
    known = {n: {option.name for option in declared(n)} for n in chain}
    for key, value in options.items():
        homes = [n for n in chain if key in known[n]]
        if not homes:
            accepted = sorted(set().union(*known.values()) | {"x0"})
            raise InputError(f"method 'auto' takes the options {accepted}, got unknown option {key!r}")
        for home in homes if key in SHARED else homes[:1]:
            parts[home][key] = value
    return [(n, check_options(n, parts[n]), x0 if i == 0 else None) for i, n in enumerate(chain)]


def solve(
    problem,
    method: str = "auto",
    *,
    certificate_tol: float = 1e-6,
    strict: bool = True,
    frame=None,
    tracker=None,
    load_checks=None,
    **options,
) -> FiniteSolution:
    """Solve a ``kinematics="finite"`` problem and certify it at the solved pose.

    Parameters
    ----------
    problem : ContactProblem
        With ``kinematics="finite"``.
    method : str
        ``"finite"`` (or ``"newton"``): Newton with the consistent tangent; ``"finite_nlp"``
        (or ``"nlp"``): IPOPT on a conservative surrogate re-centred at each outer iteration
        (``formulations/finite_nlp.md``); ``"auto"``: Newton, then IPOPT if Newton's answer
        fails its certificate (``solution.info["fallback"]`` says why; not where Newton found the
        layer crushed, no spring left, springs that do not settle, or no stable equilibrium near the
        start: IPOPT meets the same, in minutes), in a time budget unless the options give
        ``max_time``: the larger of 60 s and 200 times Newton's time, shared by its solves
        (:mod:`~dea_opt.largemotion.fallback`); an IPOPT stopped by it fails (``max_iterations``),
        its message and ``info["fallback"]`` saying so. ``"qp"`` is an
        :class:`~dea_opt.errors.InputError`: the QP is a small-kinematics method.
    certificate_tol : float
    strict : bool
        Raise :class:`SolverError` when the answer fails its certificate.
    frame : array_like (4, 4), optional
        Body 2's pose at zero displacement (mesh 2's pose in body 1's frame), replacing the pose
        its targets were cast at: a load path's prescribed pose of this frame, the free
        coordinates acting on top of it.
    tracker : MeshTracker, optional
        The re-casting state of a load path's previous frame (``solution.tracker``).
    load_checks : (callable, callable), optional
        ``dea_opt.solve``'s tests of a load the springs cannot carry, ``(unresisted, cone)``, each
        ``f(problem, system)`` raising :class:`~dea_opt.errors.LoadNotSupportedError`: the first
        before any solve, the second before IPOPT and after a failed Newton (at zero displacement).
    **options
        ``x0`` (free coordinates, mm and rad) and the options of the formulation
        (:data:`dea_opt.formulations.finite.OPTIONS`, :data:`dea_opt.formulations.finite_nlp.OPTIONS`).
    """
    if not (isinstance(certificate_tol, (int, float)) and 0 < certificate_tol < 1):
        raise InputError(f"certificate_tol must be a number in (0, 1), got {certificate_tol!r}")
    steps = plan(method, problem.law, options)
    with single_threaded_blas():
        name, opts, x0 = steps[0]
        began = time.perf_counter()
        solution = _solve(problem, name, certificate_tol, opts, x0, frame, tracker, load_checks)
        if method == "auto":
            skipped = fallback.not_tried(solution)
            if skipped is None and not solution.success and len(steps) > 1:
                reason, newton_time = fallback.why(name, solution), time.perf_counter() - began
                name, opts, _ = steps[1]
                limit = fallback.budget(newton_time, options, opts)  # None: the user's max_time
                began = time.perf_counter()
                opts = fallback.deadline(opts, limit, began)
                solution = _solve(problem, name, certificate_tol, opts, None, frame, None, load_checks)
                skipped = fallback.out_of_time(solution, limit, time.perf_counter() - began, reason)
            solution.info["fallback"] = skipped
            solution.info["requested"] = "auto"
    if not solution.success and strict:
        raise SolverError(
            f"{solution.method} (finite kinematics) returned no certified answer (status '{solution.status}': "
            f"{solution.message}); {solution.failure}"
            + (f"; before it, {solution.info['fallback']}" if solution.method != steps[0][0] else ""),
            status=solution.status,
            solution=solution,
        )
    if solution.success and not solution.validity.valid:
        warnings.warn(solution.validity.message(), ValidityWarning, stacklevel=3)
    return solution


def _check_frame(frame) -> np.ndarray:
    checked = check_pose(frame, "frame")
    return np.eye(4) if checked is None else checked


def _solve(problem, method, certificate_tol, opts, x0, frame, tracker, load_checks) -> FiniteSolution:
    start = time.perf_counter()
    if problem.kinematics != "finite":
        raise InputError("this problem has kinematics='small': solve it with dea_opt.solve")
    check_bodies(problem)
    targets, cast = resolve_targets(problem)
    if tracker is None and cast is not None and opts["recast"]:
        tracker = MeshTracker(cast, recast_shift=opts["recast_shift"], full_shift=opts["full_shift"])
    if tracker is not None:
        tracker.begin(frame)
        targets = tracker.targets()
    elif frame is not None:
        targets = targets.with_frame(_check_frame(frame))
    system = build_system(problem, targets, tracker)
    law = problem.law
    T, E0, small = scaled_directions(system, law)
    unresisted, cone = load_checks or (None, None)
    loaded = bool(small.load.any() and small.n_dofs)
    if loaded and unresisted is not None:
        unresisted(problem, small)
        if method == "finite_nlp" and cone is not None:
            cone(problem, small)
    x0 = start_vector(small, x0)
    if x0 is not None and small.resistance.null.shape[1]:
        x0 = x0 - small.resistance.motion_part(x0)  # held directions take no motion, from any start
    build = time.perf_counter() - start
    cold = x0 is None
    x = np.zeros(len(system.free)) if cold else x0
    if not cold and tracker is not None and (start_system := warm_start(tracker, system, law, x)) is not system:
        system, (T, E0, small) = start_system, scaled_directions(start_system, law)
    first = tracker is not None  # the first solve, which may start again at the base pose
    if cold and loaded and tracker is not None:
        guess, unsolved = predicted(small, law, x, system)
        if unsolved and not near_base(tracker, system):  # no measure of the springs there: brought up to date
            system, failed = at_base(tracker, system, law)
            if failed is not None:
                return _solution(problem, system, small, law, failed, method, tracker, certificate_tol, build, 0, [])
            T, E0, small = scaled_directions(system, law)
        deepest = small.strain_at(guess).min()
        crushing = not unsolved and deepest <= -1.0
        if crushing and near_base(tracker, system) and not far_from_start(system, guess):
            tracker.counts["stable"] = True
            crushed = crushed_at_start(system, law, guess, deepest)
            return _solution(problem, system, small, law, crushed, method, tracker, certificate_tol, build, 0.0, [])
        if method == "finite":
            x, cold = guess, unsolved
    inner, history = None, []
    stable, rounds = True, [0]
    # Solves that the springs' update follows stop at _LOOSE: it moves the springs, and the solve
    # after it starts there; the pose the last update checks is solved to the options' tolerance.
    loose = tracker is not None and method == "finite"
    loose_opts = {**opts, "gtol": max(opts["gtol"], _LOOSE), "xtol": max(opts["xtol"], _LOOSE)} if loose else opts

    def tighten(system, inner):
        reached = inner.info.get("residual_history") or [np.inf]
        if inner.info.get("loose") and inner.success and not reached[-1] <= opts["gtol"]:
            inner = _inner(method, system, law, T, E0, inner.u_free, False, opts, inner.state)
            history.extend(inner.info.get("residual_history", []))
        return inner

    start_state = None  # the state at x of the springs an update brought, which it computed
    escapes: list = []  # the unstable equilibria Newton converged to and left
    while True:
        inner = _inner(method, system, law, T, E0, x, cold, loose_opts, start_state)
        inner.info["loose"] = loose
        history.extend(inner.info.get("residual_history", []))
        x, cold = inner.u_free, False
        if first and not inner.success and not near_base(tracker, system):
            # The tangent planes, extrapolated from where the springs were to a base pose far from
            # it, gave no answer: the springs brought up to date at the base pose, and again.
            first = False
            system, failed = at_base(tracker, system, law)
            if failed is not None:
                inner = failed
                break
            T, E0, small = scaled_directions(system, law)
            x, cold, start_state = np.zeros(len(system.free)), True, None
            continue
        first = False
        if tracker is not None and inner.success:
            system, inner, resolve, stable = _bring_up_to_date(tracker, system, inner, method, opts, rounds, tighten)
            x, start_state = inner.u_free, inner.state
            if resolve and method != "finite" and tracker.crushed_through:
                # IPOPT would take minutes to find that the springs left cannot carry the load; its
                # forces were those of the springs before the update
                inner.success = False
                inner.info.pop("stress", None)
                break
            if resolve:
                continue
        if stable and inner.success and method == "finite":  # Newton's answer: left if unstable
            if (away := leave_unstable(system, law, inner, E0, escapes)) is not None:
                x, start_state = away, None
                continue
        break
    noted(inner, escapes)
    if tracker is not None:
        tracker.counts["stable"] = stable
        if tracker.crushed_through and not inner.success:
            crushed_through(tracker, inner, law, system, rms_radius(system))
        elif not stable and inner.success:
            unsettled(inner)
    if not inner.success and inner.status not in ("crushed", "unbounded", "pose_error"):
        ran_away(system, inner, rms_radius(system))
    if inner.status == "crushed" and np.isfinite(inner.u_free).all():
        crushed_far(system, inner)
    if method == "finite" and not inner.success and loaded and cone is not None:
        cone(problem, small)
    elapsed = time.perf_counter() - start - build
    return _solution(problem, system, small, law, inner, method, tracker, certificate_tol, build, elapsed, history)


def _bring_up_to_date(tracker, system, inner, method, opts, rounds, tighten) -> tuple:
    """``(system, inner, resolve, stable)``: the springs brought up to date at ``inner``'s pose.

    Partial updates (the springs the solve has) while they change a loaded spring, then one
    complete update (also the faces next to the springs, :meth:`MeshTracker.update`) at the pose
    where a partial one changed nothing that carries load; ``resolve`` when the equilibrium must be
    solved again. Newton keeps its answer when only springs that carry nothing changed; IPOPT
    solves again after any change. A complete update checks a pose solved to the options'
    tolerance (``tighten``: ``inner`` solved again from its answer when it stopped short). At
    most ``max_recasts`` updates that changed the springs in a solve (``rounds``, a one-element
    list, counts them; ``stable`` False beyond: an equilibrium of these springs; another update
    might still change them).
    """
    max_recasts = opts["max_recasts"]
    while True:
        if rounds[0] >= max_recasts:
            inner = tighten(system, inner)
            inner.message += (
                f"; the springs still changed after {rounds[0]} updates (max_recasts)"
                if rounds[0]
                else "; the springs were not updated (max_recasts = 0)"
            )
            return system, inner, False, False
        complete = tracker.complete or tracker.short_step(system.transform(inner.state.y))
        if complete:
            inner = tighten(system, inner)
            if not inner.success:
                return system, inner, False, True
        tracker.complete = complete
        update = tracker.update(system, inner.state, complete=complete)
        if update is not None and update.none_left:
            inner.success = False
            if not tracker.crushed_through:  # (else crushed, by _solve)
                inner.status = "pose_error"
            inner.message += f"; no spring is left at the solved pose ({update.none_left})"
            return system, inner, False, True
        if update is None:
            if complete:
                return system, inner, False, True
            tracker.complete = True  # nothing changed that carries load: now the whole of it
            continue
        rounds[0] += 1
        system = update.system
        # the new springs at the solved pose: where the next solve starts, or (when only springs
        # that carry nothing changed) the same equilibrium
        inner.state = update.state
        if update.resolve or method != "finite":
            return system, inner, True, True
        if complete:
            return system, inner, False, True
        tracker.complete = True


def _inner(method, system, law, T, E0, x, cold, opts, start_state=None):
    """The registry's formulation ``method`` on the arrays: its raw answer for these targets
    (``start_state``: the springs' state at ``x``, when known)."""
    opts = fallback.within(opts)  # auto's fallback: the time left of its budget
    return formulations.get(method).solve(system, law, T, E0, x0=x, cold=cold, start_state=start_state, **opts)


def _solution(problem, system, small, law, inner, method, tracker, certificate_tol, build, solve_time, history):
    state = inner.state
    targets = system.targets
    if tracker is not None:  # the tracker's arrays: read-only now, its next update copies them first
        for held in (targets.points, targets.normals, targets.faces):
            if held is not None:
                held.setflags(write=False)
    final = problem
    if tracker is not None and (tracker.changed_from(problem.layer) or targets.frame is not tracker.cast.pose):
        # The springs of the solved pose, with their gaps at zero displacement (from the same targets).
        s0 = evaluate(targets, system.points, system.normals, targets.frame).s
        s0 = np.clip(np.where(np.isfinite(s0), s0, 1e9), -1e9, 1e9)
        final = replace(problem, layer=tracker.layer_with_gap(s0), targets=targets)
    layer = final.layer
    u = np.zeros(12)
    u[6:] = system.coordinates(inner.u_free)
    finite = bool(np.isfinite(u).all() and state.finite)
    with np.errstate(invalid="ignore", over="ignore"):
        pressure = 0.0 - law.stress(np.minimum(state.eps, 0.0))
    reported = -pressure if inner.info.get("stress") is None else inner.info["stress"]
    lengths = lengths_of(system)  # a rotation's: final.layer_radius[1], from the springs' rows
    stiffness = float(np.sum(layer.areas / layer.thickness))
    cert = certificate(state, law, final.layer, lengths, stiffness, u, reported, certificate_tol)
    # springs cast from meshes are updated only at a converged pose: an unconverged answer stands on old ones
    settled = tracker is None or (tracker.counts.get("stable", True) and inner.success)
    crushed = inner.status == "crushed"
    # the driver's own verdicts on the meshes, which no certificate of these springs overrules
    judged = inner.status in ("crushed", "unbounded", "pose_error")
    success = bool(finite and cert.passed and np.isfinite(pressure).all() and settled and not judged)
    info = {k: v for k, v in inner.info.items() if k not in ("stress", "loose", "softest")}
    info.update(solver_success=inner.success, native_status=inner.status, kinematics="finite", residual_history=history)
    if cert.passed and not settled:
        why = "max_recasts" if inner.success else f"{method} ended '{inner.status}' short of it"
        info["failure"] = f"its certificate passed for springs not brought up to date at the solved pose ({why})"
    elif cert.passed and crushed:
        info["failure"] = "its certificate passed, but the layer is crushed: the load is beyond what it can bear"
    status = status_of(inner.status, success, system, state)
    if tracker is not None:
        info["recast"] = {**tracker.counts, "lost_by_reason": dict(tracker.lost)}
    dropped = None if tracker is None else tracker.counts["dropped"]
    # closed-form targets (no tracker) lose no spring through a layer
    through = 0 if tracker is None else tracker.lost_through_layer(system.transform(state.y)) if finite else None
    if through:
        info["recast"]["lost_through_layer"] = through
    # stability is a property of an equilibrium: of a certified answer only
    if not (finite and cert.passed):
        stability, along = None, ""
    else:  # measured already for Newton's answer (leave_unstable)
        known = inner.info.get("softest")
        stability, along = known[1:] if known and known[0] is state else softest(state, lengths)
    if along:
        info["softest_direction"] = along
    message = inner.message
    held = small.resistance.describe(problem.free_names) if len(system.free) else []
    if held:
        # As for the small kinematics: directions no spring resists at zero displacement take no
        # motion and carry no load (the minimum-norm answer).
        info["held"] = held
        message = f"{message}; held at zero motion, as no spring resists them: {', '.join(held)}"
    return FiniteSolution(
        problem=final,
        u=u,
        strain=state.eps,
        pressure=pressure,
        method=method,
        success=success,
        status=status,
        message=message,
        iterations=inner.iterations,
        build_time=build,
        solve_time=solve_time,
        certificate=cert,
        info=info,
        targets=targets,
        dropped=dropped,
        lost_through_layer=through,
        stability=stability,
        tracker=tracker,
    )
