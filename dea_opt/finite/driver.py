"""Finite kinematics, the solve: targets, the equilibrium by Newton or IPOPT, re-casting, the certificate.

Written math: ``formulations/finite.md``. :func:`solve` is what ``dea_opt.solve`` runs for a
``ContactProblem(..., kinematics="finite")``: it resolves each spring's target, builds the arrays
of a :class:`~dea_opt.formulations.finite.FiniteSystem`, has the registry's formulation solve the
equilibrium of the free coordinates (:mod:`~dea_opt.formulations.finite`, Newton, or
:mod:`~dea_opt.formulations.finite.nlp`, IPOPT: arrays in, a raw answer out), keeps springs cast
from meshes up to date as body 2 moves (:mod:`~dea_opt.finite.tracker`), solving again
while a loaded spring changed, and certifies the answer at the solved pose
(:mod:`~dea_opt.finite.solution`).
"""

from __future__ import annotations

import time
import warnings
from dataclasses import replace

import numpy as np

from .. import formulations
from .._checks.threads import single_threaded_blas
from ..errors import InputError, SolverError, ValidityWarning
from ..formulations._parts.system import start_vector
from ..formulations.finite import evaluate, rms_radius, status_of
from ..mesh import SpringCast, check_pose
from . import fallback, means, verdict
from .arrays import build_system, check_bodies, plan, planes_note, remembered, resolve_targets, scaled_directions
from .outcome import crushed_at_start, crushed_far, crushed_through, ran_away, unsettled
from .solution import FiniteSolution, certificate
from .stability import leave_unstable, lengths_of, noted, softest
from .start import at_base, near_base, predicted, warm_start
from .tracker import MeshTracker

__all__ = ["build_system", "plan", "resolve_targets", "solve"]

_LOOSE = 1e-6  # the scaled residual a solve that an update of the springs follows stops at
#: mm the hits may move after a complete update for its springs to stand at the pose: an update
#: there could only move a hit across the edge of its face by this, changing its gap by less than
#: this times the kink between two faces (far below any tolerance), and measures no thickness
#: again (``recast_shift``, 0.01 mm by default, allows more).
_SETTLED = 1e-6


def solve(
    problem,
    method: str = "auto",
    *,
    certificate_tol: float = 1e-6,
    strict: bool = True,
    frame=None,
    tracker=None,
    unresisted=None,
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
        (``formulations/finite_nlp.md``); ``"auto"``: Newton, then, where its answer fails its
        certificate and nothing is proved about the load (:mod:`~dea_opt.finite.verdict`), the
        other means of :mod:`~dea_opt.finite.means` (more updates of the springs, other
        starts, a load continuation, IPOPT), ``solution.info["fallback"]`` saying what each found,
        in a time budget unless the options give ``max_time``
        (:mod:`~dea_opt.finite.fallback`). A verdict on the load (``crushed``, a
        :class:`~dea_opt.errors.LoadNotSupportedError`) is given where proved, by every method;
        a solve that met one unproved did not converge (``max_iterations``). ``"qp"`` is an
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
    unresisted : callable, optional
        ``dea_opt.solve``'s test of a load along directions no spring resists, ``f(problem, system)``
        raising :class:`~dea_opt.errors.LoadNotSupportedError`, run before any solve on the springs
        of the start (:func:`dea_opt.loadcheck.check_unresisted`). A load no spring the layer can
        have carries at any pose raises it too, proved (:mod:`~dea_opt.finite.verdict`).
    **options
        ``x0`` (free coordinates, mm and rad) and the options of the formulation
        (:data:`dea_opt.formulations.finite.OPTIONS`, :data:`dea_opt.formulations.finite.nlp.OPTIONS`).
    """
    if not (isinstance(certificate_tol, (int, float)) and 0 < certificate_tol < 1):
        raise InputError(f"certificate_tol must be a number in (0, 1), got {certificate_tol!r}")
    steps = plan(method, problem.law, options)
    problem = remembered(problem)  # a layer that is its cast's own: re-cast from it (targets=cast)
    run = _Run(problem, certificate_tol, frame, unresisted, steps[0][1])
    with single_threaded_blas():
        name, opts, x0 = steps[0]
        if name == "finite_nlp":  # a load proved not carried: said before IPOPT (minutes to fail)
            run.raise_unsupported()
        began = time.perf_counter()
        solution = run(name, opts, x0, tracker)
        if not solution.success and not _final(solution) and run.proof() is None and method == "auto":
            # no answer and nothing proved: the other means, in a time budget (dea_opt/finite/means.py)
            solution = means.rescue(run, steps, solution, options, time.perf_counter() - began)
        verdict.judge(solution, run.proof() if not solution.success else None, problem)
        if method == "auto":
            solution.info["requested"] = "auto"
            solution.info.setdefault("fallback", None)
        # assessed here, on one BLAS thread as the solve: a product over the springs that wakes a
        # second thread waits for it (milliseconds when the other core is busy)
        outside = solution.success and not solution.validity.valid
    if not solution.success and strict:
        raise SolverError(
            f"{solution.method} (finite kinematics) returned no certified answer (status '{solution.status}': "
            f"{solution.message}); {solution.failure}"
            + (f"; before it, {solution.info['fallback']}" if solution.info.get("fallback") else ""),
            status=solution.status,
            solution=solution,
        )
    if outside:
        warnings.warn(solution.validity.message(), ValidityWarning, stacklevel=3)
    return solution


def _final(solution) -> bool:
    """Whether a failed solution needs no other means: the springs of the given pose are none
    (``pose_error`` at body 2's base pose, a fact of the meshes), or its verdict is proved."""
    return bool(solution.info.get("proved")) or solution.info.get("at_base") is True


_UNKNOWN = object()  # a proof not looked for yet


class _Run:
    """The solves of one ``dea_opt.solve`` call: its problem and options, and the proof of a verdict on
    its load (:func:`~dea_opt.finite.verdict.prove`, computed once, when a solve needs it)."""

    def __init__(self, problem, certificate_tol, frame, unresisted, opts):
        self.problem, self.certificate_tol, self.frame, self.unresisted = problem, certificate_tol, frame, unresisted
        targets = problem.targets
        self.cast = targets if isinstance(targets, SpringCast) and opts.get("recast", True) else None
        self._proof: object = _UNKNOWN

    def proof(self):
        if self._proof is _UNKNOWN:
            self._proof = verdict.prove(self.problem, self.cast)
        return self._proof

    def raise_unsupported(self) -> None:
        verdict.raise_unsupported(self.proof(), self.problem)

    def __call__(self, method, opts, x0=None, tracker=None, problem=None, start="auto", resume=False) -> FiniteSolution:
        """One solve (``problem``: this one, or a continuation's with another load; ``start``: ``"auto"``,
        ``"predictor"`` or ``"zero"`` for a solve without ``x0``; ``resume``: ``tracker`` is that of
        a solve this one goes on from, whose events stay counted)."""
        own = problem is None
        return _solve(
            self.problem if own else problem,
            method,
            self.certificate_tol,
            opts,
            x0,
            self.frame,
            tracker,
            self.unresisted,
            start,
            self if own else None,
            resume,
        )


def _check_frame(frame) -> np.ndarray:
    checked = check_pose(frame, "frame")
    return np.eye(4) if checked is None else checked


def _solve(
    problem, method, certificate_tol, opts, x0, frame, tracker, unresisted, how, run, resume=False
) -> FiniteSolution:
    start = time.perf_counter()
    if problem.kinematics != "finite":
        raise InputError("this problem has kinematics='small': solve it with dea_opt.solve")
    check_bodies(problem)
    targets, cast = resolve_targets(problem)
    if tracker is None and cast is not None and opts["recast"]:
        tracker = MeshTracker(cast, recast_shift=opts["recast_shift"], full_shift=opts["full_shift"])
    if tracker is not None:
        tracker.begin(frame, resume=resume)
        targets = tracker.targets()
    elif frame is not None:
        targets = targets.with_frame(_check_frame(frame))
    system = build_system(problem, targets, tracker)
    law = problem.law
    T, E0, small = scaled_directions(system, law)
    loaded = bool(small.load.any() and small.n_dofs)
    if loaded and unresisted is not None:
        unresisted(problem, small)
    x0 = start_vector(small, x0)
    if x0 is not None and small.resistance.null.shape[1]:
        x0 = x0 - small.resistance.motion_part(x0)  # held directions take no motion, from any start
    build = time.perf_counter() - start
    cold = x0 is None
    x = np.zeros(len(system.free)) if cold else x0
    if not cold and tracker is not None and (start_system := warm_start(tracker, system, law, x)) is not system:
        system, (T, E0, small) = start_system, scaled_directions(start_system, law)
    first = tracker is not None  # the first solve, which may start again at the base pose
    began = "given" if not cold else "zero"
    # the small kinematics' answer starts springs that follow mesh 2 (or any solve asked to)
    if cold and loaded and (how == "predictor" or (how == "auto" and tracker is not None)):
        guess, unsolved = predicted(small, law, x, system)
        if tracker is not None and unsolved and not near_base(tracker, system):  # springs brought up to date
            system, failed = at_base(tracker, system, law)
            if failed is not None:
                failed.info["at_base"] = True
                return _solution(problem, system, small, law, failed, method, tracker, certificate_tol, build, 0, [])
            T, E0, small = scaled_directions(system, law)
        deepest = small.strain_at(guess).min()
        # springs that follow mesh 2 would leave the model through the layer: said before any solve
        # where proved (closed-form targets solve on; an answer past eps = -1 fails its validity)
        crushing = tracker is not None and not unsolved and deepest <= -1.0
        if crushing and run is not None and (proof := run.proof()) is not None:
            run.raise_unsupported()
            tracker.counts["stable"] = True
            crushed = crushed_at_start(system, law, guess, deepest, proof)
            return _solution(problem, system, small, law, crushed, method, tracker, certificate_tol, build, 0.0, [])
        x, cold = guess, unsolved
        began = "zero" if unsolved else "predictor"
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
        # once the updates are complete, every one checks a pose solved to the options' tolerance
        tight = not loose or (tracker is not None and tracker.complete)
        inner = _inner(method, system, law, T, E0, x, cold, opts if tight else loose_opts, start_state)
        inner.info["loose"] = not tight
        history.extend(inner.info.get("residual_history", []))
        x, cold = inner.u_free, False
        if first and not inner.success and not near_base(tracker, system):
            # The tangent planes, extrapolated from where the springs were to a base pose far from
            # it, gave no answer: the springs brought up to date at the base pose, and again.
            first = False
            system, failed = at_base(tracker, system, law)
            if failed is not None:
                inner = failed
                inner.info["at_base"] = True
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
        if not stable and inner.success:
            unsettled(inner, tracker.crushed_through)
        if tracker.crushed_through and not inner.success:  # (the springs lost on the way say why)
            crushed_through(tracker, inner, law, system, rms_radius(system))
    if not inner.success and inner.status not in ("crushed", "unbounded", "pose_error"):
        ran_away(system, inner, rms_radius(system))
    if inner.status == "crushed" and np.isfinite(inner.u_free).all():
        crushed_far(system, inner)
    inner.info["start"] = began
    elapsed = time.perf_counter() - start - build
    return _solution(problem, system, small, law, inner, method, tracker, certificate_tol, build, elapsed, history)


def _bring_up_to_date(tracker, system, inner, method, opts, rounds, tighten) -> tuple:
    """``(system, inner, resolve, stable)``: the springs brought up to date at ``inner``'s pose.

    Partial updates (the springs the solve has) while they change a loaded spring, then one
    complete update (also the faces next to the springs, :meth:`MeshTracker.update`) at the pose
    where a partial one changed nothing that carries load; ``resolve`` when the equilibrium must be
    solved again. Newton keeps its answer when only springs that carry nothing changed; IPOPT
    solves again after any change. A pose where a complete update changed nothing that carries
    load is solved to the options' tolerance (``tighten``: ``inner`` solved again from its answer
    when it stopped short), and its springs stand there where that moved the hits less than
    :data:`_SETTLED` since the update, else they are updated again; a complete update that
    changes a loaded spring is followed by a solve anyway, so the pose it checks need not be
    tightened first. At most ``max_recasts`` updates that changed the springs in a solve
    (``rounds``, a one-element list, counts them; ``stable`` False beyond: an equilibrium of these
    springs; another update might still change them).
    """
    max_recasts = opts["max_recasts"]
    # right after a solve, tracker.complete says that the last update was complete (within this
    # call it is also set before a complete update at the pose a partial one found unchanged)
    after_complete = tracker.complete

    def stands():  # inner solved to the tolerance; whether the last update's springs stand there
        nonlocal inner
        inner = tighten(system, inner)
        return not inner.success or tracker.moved_from_update(system.transform(inner.state.y)) <= _SETTLED

    while True:
        if rounds[0] >= max_recasts:
            inner = tighten(system, inner)
            inner.message += (
                f"; the springs still changed after {rounds[0]} updates (max_recasts)"
                if rounds[0]
                else "; the springs were not updated (max_recasts = 0)"
            )
            return system, inner, False, False
        pose = system.transform(inner.state.y)
        complete = tracker.complete or tracker.short_step(pose)
        if complete and after_complete and tracker.moved_from_update(pose) <= _SETTLED and stands():
            return system, inner, False, True  # the last update's springs stand here (_SETTLED)
        after_complete = False
        tracker.complete = complete
        update = tracker.update(system, inner.state, complete=complete)
        if update is not None and update.none_left:
            inner.success = False
            if not tracker.crushed_through:  # (else crushed, by _solve)
                inner.status = "pose_error"
            inner.message += f"; no spring is left at the solved pose ({update.none_left})"
            return system, inner, False, True
        if update is not None:
            rounds[0] += 1
            system = update.system
            # the new springs at the solved pose: where the next solve starts, or (when only springs
            # that carry nothing changed) the same equilibrium
            inner.state = update.state
            if update.resolve or method != "finite":
                return system, inner, True, True
        if not complete:
            tracker.complete = True  # nothing changed that carries load: now the whole of it
            continue
        if stands():
            return system, inner, False, True
        after_complete = True  # solving to the tolerance moved the hits: updated again there


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
    if tracker is None and targets.faces is not None:  # tangent planes of a cast, never re-cast
        message = f"{message}; {planes_note(problem)}"
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
