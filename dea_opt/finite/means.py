"""``method="auto"`` with finite kinematics: the other means tried before a failure is said.

Written math: ``formulations/finite.md`` ("What auto tries"; its budget: ``formulations/finite_nlp.md``,
"Limits"). Where Newton from the given start
finds no certified answer and :mod:`~dea_opt.finite.verdict` proves nothing about the
load, an answer may still be reached from elsewhere: :func:`rescue` tries, in a time budget
(:func:`~dea_opt.finite.fallback.budget`), Newton continued from where it stopped with
:data:`RECASTS` times the updates where the springs did not settle, Newton from the other starts (the small kinematics' answer, and
zero), Newton along a load continuation from a load the contact carries
(:func:`continuation`), and IPOPT from the nearest pose that continuation certified. The first
certified answer whose equilibrium is stable is the answer; a certified unstable one is kept
while the others run. Used by :mod:`~dea_opt.finite.driver`.
"""

from __future__ import annotations

import math
import time

import numpy as np

from . import fallback

__all__ = ["ANCHORS", "RECASTS", "STEPS", "continuation", "rescue"]

#: The loads (fractions of the given one) a continuation starts from, in order: the load halved
#: down to a thousandth (a contact crushed or tipped from a cold start carries less), then ten to a
#: thousand times it (a tiny load on a few springs, where the start has nothing to stand on).
ANCHORS = (0.5, 0.1, 0.01, 0.001, 10.0, 100.0, 1000.0)
#: Newton solves a continuation takes at most, anchors included.
STEPS = 40
#: Times the default ``max_recasts`` a solve whose springs did not settle is given again.
RECASTS = 4
#: The share of the budget the Newton means may use; IPOPT has the rest.
_NEWTON_SHARE = 0.5


class _Clock:
    """The budget's deadline (None: the user's ``max_time`` rules IPOPT, the Newton means are bounded
    by their counts)."""

    def __init__(self, limit):
        self.began = time.perf_counter()
        self.limit = limit
        self.deadline = None if limit is None else self.began + limit["max_time"]

    def left(self, share: float = 1.0) -> float:
        if self.deadline is None:
            return math.inf
        return self.began + share * self.limit["max_time"] - time.perf_counter()


class _Best:
    """The answers found: the first stable certified one ends the search."""

    def __init__(self):
        self.stable = None
        self.unstable = None

    def take(self, solution) -> bool:
        if not solution.success:
            return False
        if solution.validity["stability"].passed is False:
            self.unstable = self.unstable or solution
            return False
        self.stable = solution
        return True


def _free(problem, solution) -> np.ndarray:
    return np.asarray(solution.u, dtype=float)[problem.free_indices]


def _said(what: str, solution, began: float) -> str:
    return f"{what}: {solution.status.value} ({time.perf_counter() - began:.2g} s)"


def continuation(run, name, opts, problem, clock, story) -> tuple:
    """``(answer, nearest)``: Newton along a load continuation, ``(None, x)`` where it did not reach the
    load (``x`` the free coordinates of the largest fraction of it certified, or None).

    From the first of :data:`ANCHORS` whose load Newton certifies from a cold start, the load is
    scaled back toward the given one (its fraction ``lam`` on a log scale, each solve started at the
    last certified pose: a warm start), the step halved where a solve fails and grown by half where
    it succeeds, within :data:`STEPS` solves and the Newton means' share of the budget.
    """
    force = np.asarray(problem.body2.force, dtype=float)
    moment = np.asarray(problem.body2.moment, dtype=float)

    def solve_at(lam, x0):
        if lam == 1.0:  # the given load: the problem itself
            return run(name, opts, x0=x0)
        scaled = problem.with_load(force=tuple(lam * force), moment=tuple(lam * moment))
        return run(name, opts, x0=x0, problem=scaled)

    used, anchor, x = 0, None, None
    for lam in ANCHORS:
        if used >= STEPS or clock.left(_NEWTON_SHARE) <= 0:
            return None, None
        began = time.perf_counter()
        solution, used = solve_at(lam, None), used + 1
        if solution.success:
            anchor, x = lam, _free(problem, solution)
            story.append(_said(f"a continuation from {lam:g} x the load", solution, began))
            break
    if anchor is None:
        story.append(f"a continuation: no load from {ANCHORS[0]:g} to {ANCHORS[-1]:g} x the given one certified")
        return None, None
    level, step, nearest = math.log(anchor), -math.log(anchor) / 2.0, x
    began = time.perf_counter()
    while used < STEPS and clock.left(_NEWTON_SHARE) > 0:
        target = 0.0 if abs(step) >= abs(level) else level + step
        solution, used = solve_at(math.exp(target), x), used + 1
        if solution.success:
            level, x = target, _free(problem, solution)
            nearest = x
            if target == 0.0:
                story.append(_said(f"  then back to the given load in {used} solves", solution, began))
                return solution, nearest
            step *= 1.5
        else:
            step *= 0.5
            if abs(step) < 1e-3 * abs(math.log(anchor)):
                break
    story.append(f"  then stopped at {math.exp(level):.4g} x the load after {used} solves")
    return None, nearest


def rescue(run, steps, first, options: dict, newton_time: float):
    """The answer of ``method="auto"`` after Newton's ``first`` failed: the first stable certified
    answer of the other means (:mod:`this module <dea_opt.finite.means>`), else a certified
    unstable one, else the last failure, its message and ``info["fallback"]`` saying what was
    tried and how each ended.

    Parameters
    ----------
    run : callable
        ``run(method, opts, x0=None, tracker=None, problem=None, start="auto")``: one solve
        (:class:`dea_opt.finite.driver._Run`).
    steps : list
        :func:`~dea_opt.finite.arrays.plan`'s ``[(name, opts, x0), ...]``: Newton, then IPOPT.
    first : FiniteSolution
        Newton's failed answer from the given start.
    options : dict
        The options of the solve as given (whether the user set ``max_time``).
    newton_time : float
        Seconds Newton took (:func:`~dea_opt.finite.fallback.budget`).
    """
    (newton, n_opts, x0), (ipopt, i_opts, _) = steps[0], steps[1]
    problem = run.problem
    limit = fallback.budget(newton_time, options, i_opts)
    clock = _Clock(limit)
    story = [fallback.why(newton, first)]
    best = _Best()
    used = first.info.get("start")

    def more_updates(solution, **start):
        """Where the springs still changed at the last update allowed: the same solve continued from
        where it stopped (its pose and its springs, brought up to date there), with more updates.
        (Started again, it made the same updates once more: a third of the time of the flexed knee.)"""
        if solution.info.get("recast", {}).get("stable") is not False or "max_recasts" in options:
            return None
        began = time.perf_counter()
        more = {**n_opts, "max_recasts": RECASTS * n_opts["max_recasts"]}
        tracker, u = getattr(solution, "tracker", None), np.asarray(solution.u, dtype=float)
        if tracker is not None and np.isfinite(u).all():
            again = run(newton, more, x0=u[problem.free_indices], tracker=tracker, resume=True)
        else:
            again = run(newton, more, **start)
        story.append(_said(f"  the same continued with max_recasts = {more['max_recasts']}", again, began))
        return again if best.take(again) else None

    if (found := more_updates(first, x0=x0)) is not None:
        return _found(found, story)
    for start in ("predictor", "zero"):
        if start == used or clock.left(_NEWTON_SHARE) <= 0:
            continue
        began = time.perf_counter()
        solution = run(newton, n_opts, start=start)
        if solution.info.get("start") == used:  # no small-kinematics answer: the start it already had
            continue
        where = "the small kinematics' answer" if start == "predictor" else "the zero pose"
        story.append(_said(f"{newton} from {where}", solution, began))
        if best.take(solution) or (solution := more_updates(solution, start=start)) is not None:
            return _found(solution, story)
    solution, nearest = continuation(run, newton, n_opts, problem, clock, story)
    if solution is not None and best.take(solution):
        return _found(solution, story)
    began = time.perf_counter()
    opts = fallback.deadline(i_opts, None if limit is None else {**limit, "max_time": clock.left()}, began)
    last = run(ipopt, opts, x0=nearest)
    where = "the continuation's nearest pose" if nearest is not None else "its own start"
    story.append(_said(f"{ipopt} from {where}", last, began))
    spent = time.perf_counter() - clock.began
    reason = fallback.out_of_time(last, limit, spent, "; ".join(story))
    if best.take(last):
        return _found(last, story, reason)
    answer = best.unstable or last
    answer.info["fallback"] = reason
    if answer is last and not last.success:
        object.__setattr__(last, "message", f"{last.message}; method='auto' tried before it: {'; '.join(story)}")
    return answer


def _found(solution, story, reason=None):
    solution.info["fallback"] = reason or "; ".join(story)
    return solution
