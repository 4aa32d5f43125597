"""``method="auto"`` with finite kinematics: whether IPOPT follows a failed Newton, and its time.

Written math: ``formulations/finite_nlp.md`` ("Limits"; ``formulations/finite.md`` says where
``auto`` does not run IPOPT). :func:`dea_opt.largemotion.driver.solve` runs Newton, then IPOPT
(``finite_nlp``) when Newton's answer fails its certificate, except where Newton found what
IPOPT would meet too, in minutes (:func:`not_tried`). Unless the user gave ``max_time``, IPOPT
then has :func:`budget` seconds for all its solves (:func:`within`): IPOPT took 28 to 34 s
wherever it succeeded on the knee (Newton there: 0.03 to 0.09 s, and 0.3 s for the 100
iterations of a failed solve), up to 6 s on the hip meshes of
:func:`dea_opt.geometry.hip_meshes` and at most about 1 s on the closed-form layers of
``tests/test_finite.py``. An IPOPT stopped at its budget fails, saying so (:func:`out_of_time`).
"""

from __future__ import annotations

import time

from ..status import Status

__all__ = ["FLOOR", "MULTIPLE", "budget", "deadline", "not_tried", "out_of_time", "why", "within"]

#: Seconds IPOPT has at least after a failed Newton: twice the longest it took to succeed on the
#: knee (34 s), however quickly Newton failed (a Newton that fails at its first iteration tells
#: nothing of how long IPOPT needs).
FLOOR = 60.0
#: IPOPT's budget in multiples of the time Newton took, for problems larger than the knee: twice
#: the knee's IPOPT (28 to 34 s) over its Newton's 100 iterations (0.3 s).
MULTIPLE = 200.0


def not_tried(solution) -> str | None:
    """Why ``auto`` does not run IPOPT after Newton's ``solution``, or None (IPOPT runs if it failed)."""
    if solution.success:
        return None
    if solution.status is Status.CRUSHED:  # the model's limit: IPOPT would meet it too, slowly
        return "not tried: the layer is crushed through, a limit of the model"
    if solution.status is Status.UNBOUNDED:  # IPOPT chases the same motion (9 minutes on the knee)
        return "not tried: no stable equilibrium near the start carries the load"
    if solution.status is Status.POSE_ERROR:  # the meshes' geometry: the same for IPOPT
        return "not tried: no spring is left at the pose"
    if solution.info.get("recast", {}).get("stable") is False:  # IPOPT's springs are updated alike
        return "not tried: the springs did not settle within max_recasts updates"
    return None


def why(name: str, solution) -> str:
    """How Newton (``name``) ended: ``info["fallback"]`` of the answer IPOPT gives after it."""
    return (
        f"{name} ended with status '{solution.status}' ({solution.message}) and certificate "
        f"residual {solution.certificate.worst()}"
    )


def budget(newton_time: float, given: dict, declared) -> dict | None:
    """``{"max_time": s, "newton_time": s}``: the seconds IPOPT has after a Newton that took
    ``newton_time`` s, the larger of :data:`FLOOR` and :data:`MULTIPLE` times it; None when the
    user gave ``max_time`` (``given``: the options of the solve) or the fallback does not declare
    it (``declared``: its options' names)."""
    if "max_time" in given or "max_time" not in declared:
        return None
    return {"max_time": max(FLOOR, MULTIPLE * newton_time), "newton_time": newton_time}


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
        f"{limit['newton_time']:.3g} s; it ran {spent:.3g} s), without a certified answer: give it more with "
        f"max_time= (seconds)"
    )
    object.__setattr__(solution, "message", f"{solution.message}; {said}")
    return f"{reason}; then IPOPT stopped at its time budget of {seconds} (max_time= gives it more)"
