"""Finite kinematics on the real knee with ``uz, rz`` free under 1000 N and a torsion ``Mz``: the
articular surfaces alone (no ligaments in the model) hold a torsion up to a limit, turning the
femur as it grows, and past that limit no equilibrium is found near the start.

Up to about 4300 N mm the femur turns 13-15 deg and rides up the tibial plateau; the springs at
the solved pose balance the load (summed here). The small kinematics on the start pose's springs
read eps = -1 at such a turn: they may not call the layer crushed (they once did, refusing an
answer that exists). Past the limit the iterates run away, and the answer says so: a solve that
did not converge (``max_iterations``), for nothing proves that no equilibrium carries that load
(``formulations/finite.md``, "What the layer can carry"). Reads ``../shared/data/knee``; skips
without it."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
from conftest import real_knee, real_knee_scenario

import dea_opt as d

LOAD = 1000.0  # N along -z


@pytest.fixture(scope="module")
def knee():
    return real_knee()


def torsion(knee, moment):
    return d.ContactProblem(
        knee["cast"].layer,
        d.LinearLaw(10.0),
        force=(0.0, 0.0, -LOAD),
        moment=(0.0, 0.0, moment),
        reference=tuple(knee["reference"]),
        free=("uz", "rz"),
        kinematics="finite",
        targets=knee["cast"],
    )


def quiet(function, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return function(*args, **kw)


def springs_on_femur(solution):
    """The springs' force (N) on the femur and its moment (N mm) about its reference at the solved
    pose, summed from each spring's pressure, area and direction (the tibia's normal)."""
    layer = solution.problem.layer
    push = (solution.pressure * layer.areas)[:, None] * layer.normals
    centre = np.asarray(solution.problem.body2.reference) + solution.u[6:9]
    return push.sum(axis=0), np.cross(layer.points - centre, push).sum(axis=0)


def test_a_torsion_the_knee_holds_turns_the_femur_13_degrees_and_converges_from_a_cold_start(knee):
    problem = torsion(knee, 4000.0)
    solution = quiet(d.solve, problem)
    assert solution.success and solution.status is d.Status.CONVERGED
    force, moment = springs_on_femur(solution)
    # equilibrium along the free dofs, summed here: the springs carry the 1000 N and the torsion
    # (a turn about z alone: the rotation vector's component is the moment's)
    assert force[2] == pytest.approx(LOAD, rel=1e-6)
    assert moment[2] == pytest.approx(-4000.0, rel=1e-6)
    turn = np.degrees(solution.u[11])
    assert 12.0 < turn < 14.5
    assert solution.validity["stability"].passed  # the femur rides up the plateau: it stays there
    # the small kinematics on the start pose's springs crush the layer through at that turn
    small = quiet(d.solve, d.ContactProblem(knee["cast"].layer, d.LinearLaw(10.0), **_small_kw(knee, 4000.0)))
    assert small.strain.min() <= -0.95 and np.degrees(small.u[11]) > 10.0


def test_a_warm_start_far_from_the_cast_starts_on_springs_brought_up_to_date_there(knee):
    """A start 13 deg away (another law's answer): on the start cast's tangent planes, extrapolated
    that far, the stiffer law read the layer crushed; on springs brought up to date at the start it
    finds the cold start's answer."""
    far = quiet(d.solve, torsion(knee, 4000.0)).u[[8, 11]]
    assert np.degrees(far[1]) > 12.0
    law = d.AteshianLaw(10.0, 0.3)
    problem = dataclasses.replace(torsion(knee, 3000.0), law=law)
    cold = quiet(d.solve, problem)
    warm = quiet(d.solve, problem, x0=far)
    assert cold.success and warm.success and warm.status is d.Status.CONVERGED
    assert np.allclose(warm.u[[8, 11]], cold.u[[8, 11]], atol=1e-5) and warm.validity.valid
    force, moment = springs_on_femur(warm)
    assert force[2] == pytest.approx(LOAD, rel=1e-6) and moment[2] == pytest.approx(-3000.0, rel=1e-6)


def _small_kw(knee, moment):
    return {
        "force": (0.0, 0.0, -LOAD),
        "moment": (0.0, 0.0, moment),
        "reference": tuple(knee["reference"]),
        "free": ("uz", "rz"),
    }


def test_a_torsion_past_the_largest_the_knee_holds_did_not_converge_and_says_the_iterates_ran(knee):
    problem = torsion(knee, 5000.0)
    solution = quiet(d.solve, problem, "newton", strict=False)
    assert not solution.success and solution.status is d.Status.MAX_ITERATIONS
    assert solution.info["unproved"] == "unbounded" and solution.message.startswith("did not converge: ")
    assert "ligaments" in solution.message and "crushed" not in solution.message
    # the run-away pose's strains and pressures fail their checks, which say that it is no
    # equilibrium, not that the layer is crushed or the units are wrong
    failed = solution.validity.failed
    assert failed and not solution.validity.valid
    for check in failed:
        assert "no equilibrium" in check.advice and "units" not in check.advice and "bounded law" not in check.advice
    assert solution.validity["stability"].passed is None
    with pytest.raises(d.SolverError) as caught:
        quiet(d.solve, problem, "newton")
    assert caught.value.status is d.Status.MAX_ITERATIONS


@pytest.mark.slow  # a minute: the continuation's 26 solves and IPOPT's updates
def test_auto_follows_the_torsion_up_to_the_largest_the_knee_holds_before_it_fails(knee):
    """``auto`` tries the other starts, a load continuation and IPOPT before it fails: the
    continuation from a tenth of the load (100 N, 500 N mm) holds it up to about two thirds of it
    (the articular surfaces' limit grows with the force that presses them together), and IPOPT,
    given 2 s here (``max_time``), gets no further."""
    solution = quiet(d.solve, torsion(knee, 5000.0), strict=False, max_time=2.0)
    assert not solution.success and solution.status not in (d.Status.CRUSHED, d.Status.UNBOUNDED)
    story = solution.info["fallback"]
    assert story.startswith("finite ended with status 'unbounded'") and "a continuation from 0.1 x the load" in story
    reached = float(story.split("then stopped at ")[1].split(" x the load")[0])
    assert 0.5 < reached < 0.95
    assert "finite_nlp from the continuation's nearest pose" in story


def test_a_growing_torsion_along_a_load_path_turns_the_femur_then_does_not_converge_nor_crush(knee):
    moments = np.array([0.0, 1000.0, 2000.0, 3000.0, 4000.0, 5000.0, 6000.0])
    loads = np.zeros((len(moments), 6))
    loads[:, 2], loads[:, 5] = -LOAD, moments
    result = quiet(d.solve_path, torsion(knee, 0.0), loads, method="newton")
    table = result.table
    held = moments <= 4000.0
    assert table["success"].to_numpy()[held].all()
    turns = table["body2_rz_rad"].to_numpy()[held]
    assert (np.diff(turns) > 0).all() and np.all(np.diff(np.diff(turns)) > 0)  # softening toward the limit
    assert list(table["status"][~held]) == ["max_iterations", "max_iterations"]
    first = result.failures()[0]
    assert "from the previous frame's pose" in first["message"] or "ran away" in first["message"]
    for solution in result.solutions:
        if solution is not None and solution.success:
            force, moment = springs_on_femur(solution)
            assert force[2] == pytest.approx(LOAD, rel=1e-6)
            assert moment[2] == pytest.approx(-solution.problem.load_vector[11], rel=1e-6, abs=1e-6)


def test_the_cli_says_why_a_torsion_past_the_limit_has_no_answer(knee, tmp_path):
    """``dea-opt run`` (Newton): exit 1 (no certified answer), with the reason in its last line."""
    from typer.testing import CliRunner

    from dea_opt.cli import app

    scenario = tmp_path / "torsion.toml"
    text = real_knee_scenario(["uz", "rz"], (0.0, 0.0, 5000.0))
    scenario.write_text(text.replace('kinematics = "finite"', 'kinematics = "finite"\nmethod = "newton"'))
    result = CliRunner().invoke(app, ["run", str(scenario), "-o", str(tmp_path / "out")])
    assert result.exit_code == 1, result.output
    last = result.output.strip().splitlines()[-1]
    assert "status 'max_iterations': did not converge" in last and "the energy decreases without bound" in last
    assert "Traceback" not in result.output


@pytest.mark.parametrize(
    ("force", "free"),
    [
        ((-81.016, 13.911, -56.947), ("ux", "uy", "uz")),  # 100 N tilted 45 deg: the femur slides off
        ((499.147, 534.949, -681.676), ("ux", "uy", "uz")),  # 1000 N tilted 47 deg
    ],
)
def test_a_femur_that_slides_off_along_free_dofs_did_not_converge_and_is_not_crushed(knee, force, free):
    """Where nothing holds a free dof, the iterates run away: the small kinematics' strains of -2.5
    to -5000 at a pose 160 mm to 250 m off say nothing of what the layer bears (they once called
    it crushed, advising the load's units and H). Newton's answer did not converge, its advice the
    free dofs; holding the slide (``uz`` alone) carries the same load, its springs balancing it
    (summed here)."""
    reference = tuple(knee["reference"])
    kw = {"force": force, "reference": reference, "kinematics": "finite", "targets": knee["cast"]}
    law = d.LinearLaw(10.0)
    solution = quiet(d.solve, d.ContactProblem(knee["cast"].layer, law, free=free, **kw), "newton", strict=False)
    assert not solution.success and solution.status is d.Status.MAX_ITERATIONS and solution.info["unproved"]
    assert "hold those dofs" in solution.message and "beyond what this layer can bear" not in solution.message
    held = quiet(d.solve, d.ContactProblem(knee["cast"].layer, law, free=("uz",), **kw))
    pushed, _ = springs_on_femur(held)
    assert held.success and pushed[2] == pytest.approx(-force[2], rel=1e-6)
