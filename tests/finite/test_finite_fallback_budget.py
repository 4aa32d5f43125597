"""``method="auto"`` with finite kinematics: the IPOPT that follows a failed Newton has a time budget.

On the real knee under a load of micro-newtons with all six dofs free, Newton stopped at its
iteration limit in 0.4 s and IPOPT, its fallback, then ran for minutes (``max_time``: an hour by
default) and failed too. ``auto`` gives IPOPT the larger of ``FLOOR`` seconds and ``MULTIPLE``
times Newton's time (``dea_opt/finite/fallback.py``), unless the user gave ``max_time``; an
IPOPT stopped at it is no success and says so. Newton is made to fail here (as in
``tests/finite/test_finite_reliability.py``), and IPOPT is either replaced by a stand-in that records
the ``max_time`` it is given and answers by Newton, or run for real on a budget of nothing.
Nothing here measures time.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import dea_opt as d
from dea_opt import formulations
from dea_opt import mesh as M
from dea_opt.finite import fallback
from dea_opt.geometry import hip_meshes, plate_layer
from dea_opt.status import CERTIFIABLE


def quiet(function, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return function(*args, **kw)


@pytest.fixture(scope="module")
def hip_problem():
    """The embedded hip's head pressed into its socket, turned 10 deg: the springs are re-cast
    after the first solve, so the fallback solves more than one set of springs."""
    pair = hip_meshes(step=3.0)
    cast = quiet(M.cast_springs, pair.mesh1, pair.mesh2)
    body2 = d.Body(reference=(0.0, 0.0, -0.5), free=("uz",), force=(0.0, 0.0, -300.0), prescribed={"rx": 0.17})
    return d.ContactProblem(cast.layer, d.LinearLaw(10.0), body2=body2, kinematics="finite", targets=cast)


def punch_problem():
    """A closed-form punch on a bed, lifted on one side by a moment (no meshes)."""
    layer = plate_layer(6.0, 6.0, 20, 4, thickness=10.0)
    return d.ContactProblem(
        layer,
        d.LinearLaw(10.0),
        force=(0.0, 0.0, -20.0),
        moment=(0.0, 36.0, 0.0),
        free=("uz", "ry"),
        kinematics="finite",
    )


@pytest.fixture
def newton_fails(monkeypatch):
    """Newton ends every solve at its iteration limit, from where it started."""
    newton = formulations.get("finite")
    real = newton.solve

    def stops(system, law, T, E0, **kw):
        inner = real(system, law, T, E0, **{**kw, "max_iter": 1})
        inner.success, inner.status, inner.message = False, "max_iterations", "no convergence (made up here)"
        return inner

    monkeypatch.setattr(newton, "solve", stops)
    return real


@pytest.fixture
def ipopt_records(monkeypatch, newton_fails):
    """IPOPT replaced by a stand-in that answers by the real Newton: the ``max_time`` of each of
    its solves, in order."""
    given: list = []

    def stand_in(system, law, T, E0, **kw):
        given.append(kw["max_time"])
        return newton_fails(system, law, T, E0, **kw)  # Newton ignores IPOPT's options

    monkeypatch.setattr(formulations.get("finite_nlp"), "solve", stand_in)
    return given


def test_the_budget_is_the_larger_of_a_floor_and_a_multiple_of_newton_s_time_unless_max_time_is_given():
    declared = {option.name for option in formulations.options("finite_nlp")}
    assert fallback.budget(1e-3, {}, declared)["max_time"] == fallback.FLOOR
    slow = 2.0 * fallback.FLOOR / fallback.MULTIPLE
    assert fallback.budget(slow, {}, declared) == {"max_time": 2.0 * fallback.FLOOR, "newton_time": slow}
    assert fallback.budget(10.0, {}, declared)["max_time"] == fallback.CEILING >= 2.0 * fallback.FLOOR
    assert fallback.budget(1e-3, {"max_time": 5.0}, declared) is None  # the user's own
    assert fallback.budget(1e-3, {}, declared - {"max_time"}) is None  # a fallback without a clock
    assert 0 < fallback.FLOOR < math.inf and 0 < fallback.MULTIPLE < math.inf


def test_the_fallback_gets_a_finite_budget_its_solves_share(hip_problem, ipopt_records):
    solution = quiet(d.solve, hip_problem)
    assert solution.method == "finite_nlp" and solution.success  # the stand-in found the equilibrium
    budget = solution.info["fallback_budget"]
    assert budget["max_time"] == max(fallback.FLOOR, fallback.MULTIPLE * budget["newton_time"])
    assert budget["spent"] < budget["max_time"]
    # the springs were brought up to date: more than one solve, each given the time left of one budget
    assert solution.info["recast"]["updates"] + solution.info["recast"]["recasts"] >= 1
    assert len(ipopt_records) >= 2
    assert all(0 < t <= budget["max_time"] for t in ipopt_records)
    assert ipopt_records == sorted(ipopt_records, reverse=True) and ipopt_records[-1] < ipopt_records[0]
    assert solution.info["fallback"].startswith("finite ended with status 'max_iterations'")
    assert "time budget" not in solution.info["fallback"] and "stopped at the time" not in solution.message


@pytest.mark.parametrize("max_time", [7.5, 3600.0])
def test_a_max_time_the_user_gives_is_the_fallback_s_own(hip_problem, ipopt_records, max_time):
    # 3600 s is the option's default: given explicitly, it is the user's choice all the same
    solution = quiet(d.solve, hip_problem, max_time=max_time)
    assert solution.method == "finite_nlp" and solution.success
    assert ipopt_records and all(t == max_time for t in ipopt_records)  # each set of springs anew
    assert "fallback_budget" not in solution.info


def test_a_fallback_stopped_at_its_budget_fails_and_says_what_newton_did_and_how_to_give_more(
    monkeypatch, newton_fails
):
    # a budget of nothing: the real IPOPT stops at its clock (Newton's time times 0, at least 0 s)
    monkeypatch.setattr(fallback, "FLOOR", 0.0)
    monkeypatch.setattr(fallback, "MULTIPLE", 0.0)
    problem = punch_problem()
    solution = quiet(d.solve, problem, strict=False)
    assert solution.method == "finite_nlp" and solution.info["requested"] == "auto"
    assert not solution.success and solution.status is d.Status.MAX_ITERATIONS
    assert solution.status not in CERTIFIABLE and not solution.certificate.passed
    assert "IPOPT, run by method='auto' after Newton failed" in solution.message
    assert "was stopped at the time auto gives it, 0 s" in solution.message
    assert "give it more with max_time=" in solution.message
    said = solution.info["fallback"]
    assert said.startswith("finite ended with status 'max_iterations' (no convergence (made up here))")
    assert said.endswith("then IPOPT stopped at its time budget of 0 s (max_time= gives it more)")
    assert solution.info["fallback_budget"]["spent"] >= solution.info["fallback_budget"]["max_time"] == 0.0
    with pytest.raises(d.SolverError, match="stopped at the time auto gives it") as raised:
        quiet(d.solve, problem)
    assert raised.value.status is d.Status.MAX_ITERATIONS
    assert "before it, finite ended with status 'max_iterations'" in str(raised.value)


def test_the_user_s_max_time_is_not_overruled_by_the_budget(monkeypatch, newton_fails):
    # the same budget of nothing, but the user's max_time: IPOPT runs to its answer
    monkeypatch.setattr(fallback, "FLOOR", 0.0)
    monkeypatch.setattr(fallback, "MULTIPLE", 0.0)
    solution = quiet(d.solve, punch_problem(), max_time=600.0)
    assert solution.method == "finite_nlp" and solution.success and solution.status is d.Status.CONVERGED
    assert "fallback_budget" not in solution.info and "time budget" not in solution.info["fallback"]


def test_a_certified_newton_runs_no_fallback_and_no_budget():
    solution = quiet(d.solve, punch_problem())
    assert solution.method == "finite" and solution.success
    assert solution.info["fallback"] is None and "fallback_budget" not in solution.info
    ipopt = quiet(d.solve, punch_problem(), method="finite_nlp")  # asked for by name: no budget either
    assert ipopt.success and "fallback_budget" not in ipopt.info
    assert np.allclose(ipopt.u, solution.u, atol=1e-6 * np.abs(solution.u).max())
