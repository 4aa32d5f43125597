"""``method="auto"`` with finite kinematics: the time of the means tried after a failed Newton.

Written math: ``formulations/finite_nlp.md`` ("Limits"; ``formulations/finite.md``, "What auto
tries"). :func:`dea_opt.finite.driver.solve` runs Newton, then, where its answer fails its
certificate and no verdict on the load is proved, the other means of
:mod:`~dea_opt.finite.means`: other starts, a load continuation, IPOPT (``finite_nlp``).
Unless the user gave ``max_time``, they have :func:`budget` seconds together (IPOPT what the
Newton means left, :func:`within`): IPOPT took 28 to 34 s wherever it succeeded on the knee
(Newton there: 0.03 to 0.09 s, and 0.3 s for the 100 iterations of a failed solve), up to 6 s on
the hip meshes of :func:`dea_opt.geometry.hip_meshes` and at most about 1 s on the closed-form
layers of ``tests/finite/test_finite.py``. An IPOPT stopped at the budget fails, saying so
(:func:`out_of_time`).
"""

from __future__ import annotations

import time

__all__ = ["CEILING", "FLOOR", "MULTIPLE", "budget", "deadline", "out_of_time", "why", "within"]

#: Seconds IPOPT has at least after a failed Newton: twice the longest it took to succeed on the
#: knee (34 s), however quickly Newton failed (a Newton that fails at its first iteration tells
#: nothing of how long IPOPT needs).
FLOOR = 60.0
#: IPOPT's budget in multiples of the time Newton took, for problems larger than the knee: twice
#: the knee's IPOPT (28 to 34 s) over its Newton's 100 iterations (0.3 s).
MULTIPLE = 200.0
#: Seconds the means after a failed Newton have at most, however long Newton took (a Newton that
#: scanned whole turns on the knee took 3 s, which made the multiple 10 minutes).
CEILING = 180.0


def why(name: str, solution) -> str:
    """How Newton (``name``) ended: the start of ``info["fallback"]`` of the answer auto gives after it."""
    return (
        f"{name} ended with status '{solution.status}' ({solution.message}) and certificate "
        f"residual {solution.certificate.worst()}"
    )


def budget(newton_time: float, given: dict, declared) -> dict | None:
    """``{"max_time": s, "newton_time": s}``: the seconds the means have after a Newton that took
    ``newton_time`` s, the larger of :data:`FLOOR` and :data:`MULTIPLE` times it, at most
    :data:`CEILING`; None when the user gave ``max_time`` (``given``: the options of the solve) or
    the fallback does not declare it (``declared``: its options' names)."""
    if "max_time" in given or "max_time" not in declared:
        return None
    return {"max_time": min(CEILING, max(FLOOR, MULTIPLE * newton_time)), "newton_time": newton_time}


def deadline(opts: dict, limit: dict | None, start: float) -> dict:
    """The fallback's options ``opts`` with the deadline of its budget ``limit`` from ``start``
    (``time.perf_counter()``), read by :func:`within`; ``opts`` without a budget."""
    return opts if limit is None else {**opts, "_deadline": start + limit["max_time"]}


def within(opts: dict) -> dict:
    """``opts`` for one solve of the fallback: ``max_time`` the seconds left before its deadline
    (``opts["_deadline"]``, set by the driver for a budget; dropped here), so that all the
    solves of its sets of springs share the budget. Each IPOPT solve, and the outer iterations,
    stop at it: a solve ends within about twice the time left."""
    if "_deadline" not in opts:
        return opts
    opts = dict(opts)
    left = opts.pop("_deadline") - time.perf_counter()
    opts["max_time"] = min(opts["max_time"], max(left, 1e-3))
    return opts


def out_of_time(solution, limit: dict | None, spent: float, reason: str) -> str:
    """The fallback's reason, ``reason`` (how Newton ended, :func:`why`), with what the budget
    ``limit`` did; a failed ``solution`` that used it up says so in its message too (``spent``:
    IPOPT's seconds). ``info["fallback_budget"]``: the budget, Newton's time and IPOPT's."""
    if limit is None:
        return reason
    limit = {**limit, "spent": spent}
    solution.info["fallback_budget"] = limit
    if solution.success or spent < limit["max_time"]:
        return reason
    seconds = f"{limit['max_time']:.3g} s"
    said = (
        f"IPOPT, run by method='auto' after Newton failed (info['fallback'] says how), was stopped at the time "
        f"auto gives it, {seconds} (the larger of {FLOOR:g} s and {MULTIPLE:g} times Newton's "
        f"{limit['newton_time']:.3g} s, at most {CEILING:g} s; it ran {spent:.3g} s), without a certified answer: "
        f"give it more with max_time= (seconds)"
    )
    object.__setattr__(solution, "message", f"{solution.message}; {said}")
    return f"{reason}; then IPOPT stopped at its time budget of {seconds} (max_time= gives it more)"
