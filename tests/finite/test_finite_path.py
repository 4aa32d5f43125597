"""Finite kinematics through load paths, the registry and scenarios.

A load path with ``kinematics="finite"`` gives, frame by frame, the answer of an independent
finite solve (warm starts change the path, not the answer); with prescribed poses (the gait
set-up) the free dofs act on top of each frame's pose and the springs are re-cast as the mesh
moves. The registry says which formulations solve finite kinematics; a scenario asks for them
with one key, ``[solve] kinematics``.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest
from conftest import COARSE_KNEE_SCENARIO, KNEE_SCENARIO

import dea_opt as d
from dea_opt import finite, formulations
from dea_opt.formulations.finite import FiniteSystem, InnerResult, pose_matrix
from dea_opt.geometry import knee_meshes, plate_layer

H, THICK, SIDE = 10.0, 10.0, 6.0


def quiet(function, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return function(*args, **kw)


def _punch():
    layer = plate_layer(SIDE, SIDE, 30, 6, thickness=THICK)
    return layer, d.ContactProblem(
        layer, d.LinearLaw(H), reference=(0.0, 0.0, 0.0), free=("uz", "ry"), kinematics="finite"
    )


def test_a_path_of_tilting_moments_is_frame_by_frame_the_closed_form():
    layer, problem = _punch()
    k, I = H / THICK, float(layer.areas @ layer.points[:, 0] ** 2)
    force = 1.6 * k * layer.areas.sum() * (SIDE / 2) * np.tan(np.radians(25.0))
    degrees = np.linspace(0.0, 25.0, 11)
    loads = np.column_stack(
        [
            np.zeros(11),
            np.zeros(11),
            np.full(11, -force),
            np.zeros(11),
            k * I * np.tan(np.radians(degrees)),
            np.zeros(11),
        ]
    )
    result = quiet(d.solve_path, problem, loads, method="auto")
    assert result.table["success"].all()
    for k_frame, solution in enumerate(result.solutions):
        assert abs(np.degrees(solution.u[10]) - degrees[k_frame]) < 1e-9
    # the table reports the motion found, frame by frame: tan(theta) = M / (k I)
    assert list(result.table.columns).count("body2_ry_rad") == 1 and "body2_rx_rad" not in result.table
    assert np.abs(np.degrees(result.table["body2_ry_rad"].to_numpy()) - degrees).max() < 1e-9
    assert np.array_equal(result.table["body2_uz_mm"].to_numpy(), [s.u[8] for s in result.solutions])
    for k_frame, solution in enumerate(result.solutions):
        alone = quiet(d.solve, problem.with_load(force=loads[k_frame, :3], moment=loads[k_frame, 3:]))
        assert np.abs(alone.u - solution.u).max() < 1e-10
    # warm starts: after the first frame every frame needs fewer iterations than a cold start
    assert (
        result.table["iterations"][1:].max()
        <= quiet(d.solve, problem.with_load(force=loads[5, :3], moment=loads[5, 3:])).iterations
    )


def test_solve_path_takes_the_kinematics_and_checks_it():
    layer, problem = _punch()
    small = d.ContactProblem(layer, d.LinearLaw(H), reference=(0.0, 0.0, 0.0), free=("uz", "ry"))
    loads = np.array([[0.0, 0.0, -50.0, 0.0, 30.0, 0.0]] * 3)
    finite = quiet(d.solve_path, small, loads, kinematics="finite")
    assert all(s.method == "finite" for s in finite.solutions)
    with pytest.raises(d.InputError, match="kinematics must be one of"):
        d.solve_path(small, loads, kinematics="exact")
    with pytest.raises(d.InputError, match="method 'qp' cannot solve 'finite' kinematics"):
        quiet(d.solve_path, problem, loads, method="qp", stop_on_error=True)
    with pytest.raises(d.InputError, match="SpringCast"):
        d.solve_path(problem, loads, np.tile(np.eye(4), (3, 1, 1)))
    with pytest.raises(d.InputError, match="loads act on body 2"):
        d.solve_path(problem, loads, body=1)


@pytest.fixture(scope="module")
def gait():
    """A generated knee (two condyles on a plateau), flexion prescribed about an axis 20 mm above
    the plateau, uz and the varus-valgus ry found, a load with two peaks."""
    pair = knee_meshes()
    cast = quiet(d.mesh.cast_springs, pair.mesh1, pair.mesh2, **pair.options)
    problem = d.ContactProblem(
        cast.layer, d.LinearLaw(H), reference=pair.reference2, free=("uz", "ry"), kinematics="finite", targets=cast
    )
    frames = 9
    phase = np.linspace(0.0, 1.0, frames)
    loads = np.zeros((frames, 6))
    loads[:, 2] = -(300 + 500 * np.sin(np.pi * phase) ** 2)
    loads[:, 4] = 300 * np.sin(2 * np.pi * phase)
    flexion = np.radians(12.0) * np.sin(np.pi * phase)
    axis = np.array([0.0, 0.0, 20.0])
    poses = np.array([pose_matrix([0, 0, 0, f, 0, 0], axis) for f in flexion])
    result = quiet(d.solve_path, problem, loads, poses)
    return {"pair": pair, "cast": cast, "problem": problem, "loads": loads, "poses": poses, "result": result}


def test_a_gait_with_prescribed_flexion_finds_the_free_dofs_on_top_of_each_pose(gait):
    result, poses = gait["result"], gait["poses"]
    assert result.table["success"].all() and result.moving
    for k, solution in enumerate(result.solutions):
        # the frame's pose with the free motion on top: rx, rz and ux, uy stay zero
        assert solution.u[9] == 0.0 and solution.u[11] == 0.0 and solution.u[6] == 0.0 and solution.u[7] == 0.0
        motion = pose_matrix(solution.u[6:], gait["problem"].body2.reference)
        assert np.allclose(solution.pose, motion @ poses[k], atol=1e-12)
        # equilibrium by sums written here: the springs' push balances the load along uz, and
        # J^T of the moments about the reference where it is, along ry
        layer = solution.problem.layer
        push = (solution.pressure * layer.areas)[:, None] * layer.normals
        centre = np.asarray(gait["problem"].body2.reference) + solution.u[6:9]
        moment = np.cross(layer.points - centre, push).sum(axis=0) + gait["loads"][k, 3:]
        J = d.formulations.finite.left_jacobian(solution.u[9:12])
        assert abs(push.sum(axis=0)[2] + gait["loads"][k, 2]) <= 1e-8 * abs(gait["loads"][k, 2])
        assert abs((J.T @ moment)[1]) <= 1e-8 * abs(gait["loads"][k, 2]) * 20.0
    # the springs follow the flexing femur: the set changes from frame to frame
    assert result.table["n_springs"].nunique() > 1


def test_each_gait_frame_is_the_answer_of_a_cold_solve_at_its_pose(gait):
    result = gait["result"]
    for k in (3, 6):
        frame = gait["problem"].with_load(force=gait["loads"][k, :3], moment=gait["loads"][k, 3:])
        alone = quiet(finite.solve, frame, "auto", frame=gait["poses"][k])
        path = result.solutions[k]
        assert alone.success
        assert abs(alone.u[8] - path.u[8]) <= 1e-4 * abs(path.u[8])
        assert abs(alone.u[10] - path.u[10]) <= 1e-4 * max(abs(path.u[10]), 1e-3)
        assert abs(alone.peak_pressure - path.peak_pressure) <= 1e-3 * path.peak_pressure


def test_the_registry_knows_which_formulations_solve_finite_kinematics():
    law = d.LinearLaw(H)
    assert [n for n in formulations.names() if formulations.takes(n, law, "finite")] == ["finite", "finite_nlp"]
    assert [n for n in formulations.names() if formulations.takes(n, law)] == ["newton", "qp", "nlp"]
    # one function reads a method's name: what it runs in these kinematics, and why it cannot
    qp = formulations.resolve("qp", law, "finite")
    assert qp.name == "qp" and qp.reason.startswith("qp is a small-kinematics method")
    assert formulations.resolve("qp", law).reason is None and formulations.resolve("newton", law).note is None
    assert formulations.resolve("newton", law, "finite").name == "finite"
    assert formulations.resolve("nlp", law, "finite").note == "nlp stands for finite_nlp with finite kinematics"
    # the second contract: finite kinematics' formulations take a FiniteSystem and give an InnerResult
    assert formulations.contract("finite") == (FiniteSystem, InnerResult)
    assert formulations.contract("small") == (formulations.SpringSystem, formulations.FormulationResult)
    layer, problem = _punch()
    loaded = problem.with_load(force=(0, 0, -50.0), moment=(0, 30.0, 0))
    out = quiet(d.compare, loaded)
    assert set(out.solutions) == {"finite", "finite_nlp"} and out.displacement < 1e-6
    assert list(out.skipped) == ["qp"] and out.notes == ()  # newton and nlp stand for the finite ones
    # the small kinematics' names stand for the finite formulations
    assert quiet(d.solve, loaded, "newton").method == "finite"
    assert quiet(d.solve, loaded, "nlp").method == "finite_nlp"
    # the formulations see arrays: a FiniteSystem, never a problem
    with pytest.raises(d.InputError, match="the finite formulation solves a FiniteSystem"):
        formulations.get("finite").Model(d.ContactProblem(layer, law), law)
    system = finite.driver.build_system(loaded, finite.driver.resolve_targets(loaded)[0])
    assert isinstance(system, FiniteSystem)
    certified = quiet(d.solve, loaded)
    for name in ("finite", "finite_nlp"):
        model = formulations.get(name).Model(system, law, **({"form": "reduced"} if name == "finite_nlp" else {}))
        first = model.solve()
        again = model.solve(((0, 0, -60.0), (0, 30.0, 0)))
        # the raw answers: uz, ry free; more load, deeper; the first is dea_opt.solve's answer
        assert first.success and again.success and again.u_free[0] < first.u_free[0]
        assert np.abs(first.u_free - certified.u[[8, 10]]).max() <= 1e-6 * np.abs(certified.u).max()


def test_a_scenario_asks_for_finite_kinematics_with_one_key(tmp_path):
    from dea_opt.mesh import SpringCast
    from dea_opt.run import run_scenario
    from dea_opt.scenario import build_problem, load_scenario

    text = KNEE_SCENARIO
    path = tmp_path / "knee.toml"
    path.write_text(text)
    scenario = load_scenario(path)
    problem = build_problem(scenario)
    assert problem.kinematics == "finite" and isinstance(problem.targets, SpringCast)
    outcome = quiet(run_scenario, scenario, tmp_path / "out")
    solution = outcome.solution if hasattr(outcome, "solution") else None
    summary = (tmp_path / "out" / "contact.json").read_text()
    assert '"kinematics": "finite"' in summary and '"method": "finite"' in summary
    assert solution is None or solution.success
    small = load_scenario(path)
    assert (
        build_problem(
            small.model_copy(update={"solve": small.solve.model_copy(update={"kinematics": "small"})})
        ).kinematics
        == "small"
    )


def test_a_scenario_sets_max_recasts_for_finite_kinematics_only(tmp_path):
    """``[solve].max_recasts`` reaches the finite solve (none allowed: the springs are never brought
    up to date, so the run fails as max_iterations, exit 1); with small kinematics, or below 0, the
    scenario is refused naming the key (exit 2)."""
    from typer.testing import CliRunner

    from dea_opt.cli import app

    text = COARSE_KNEE_SCENARIO.replace('kinematics = "finite"', 'kinematics = "KIND"\nmax_recasts = COUNT')
    for kind, count, code, said in (
        ("finite", 0, 1, "max_iterations"),
        ("small", 2, 2, 'only kinematics = "finite" has'),
        ("finite", -1, 2, "solve.max_recasts"),
    ):
        path = tmp_path / f"{kind}{count}.toml"
        path.write_text(text.replace("KIND", kind).replace("COUNT", str(count)))
        result = CliRunner().invoke(app, ["run", str(path), "--output", str(tmp_path / f"out{kind}{count}")])
        assert result.exit_code == code and said in result.output, result.output
        assert "Traceback" not in result.output
    summary = json.loads((tmp_path / "outfinite0" / "contact.json").read_text())
    assert summary["status"] == "max_iterations" and summary["info"]["recast"]["stable"] is False


def test_labels_follow_the_faces_through_updates_and_whole_re_casts():
    """A layer relabelled (a scenario's regions: by the sign of x) keeps its labels on the springs
    of the solved pose, whether they came from updates or from a whole re-cast."""
    import dataclasses

    pair = knee_meshes()
    cast = quiet(d.mesh.cast_springs, pair.mesh1, pair.mesh2, **pair.options)
    side = np.where(cast.layer.points[:, 0] > 0, "east", "west")
    cast = dataclasses.replace(cast, layer=dataclasses.replace(cast.layer, labels=side))
    problem = d.ContactProblem(
        cast.layer,
        d.LinearLaw(H),
        force=(0, 0, -800.0),
        moment=(0, 2000.0, 0),
        reference=pair.reference2,
        free=("uz", "ry"),
        kinematics="finite",
        targets=cast,
    )
    for full_shift in (5.0, 1e-3):
        solution = quiet(d.solve, problem, full_shift=full_shift)
        counts = solution.info["recast"]
        assert counts["recasts" if full_shift < 1 else "updates"] >= 1
        layer = solution.problem.layer
        assert set(layer.labels) == {"east", "west"}
        assert (layer.labels == np.where(layer.points[:, 0] > 0, "east", "west")).all()


def test_an_answer_keeps_its_springs_when_the_next_frame_moves_them(gait):
    """The tracker hands its arrays to an answer read-only and copies them before its next update
    changes them: solving the next frame from the same tracker leaves the answer as it was."""
    problem, loads, poses = gait["problem"], gait["loads"], gait["poses"]
    first = quiet(finite.solve, problem.with_load(force=loads[2, :3], moment=loads[2, 3:]), "auto", frame=poses[2])
    layer, targets = first.problem.layer, first.problem.targets
    held = {
        name: np.array(getattr(layer, name))
        for name in (
            "points",
            "normals",
            "areas",
            "thickness",
            "gap",
            "target_points",
            "target_normals",
            "target_faces",
        )
    }
    held_targets = (np.array(targets.points), np.array(targets.normals))
    later = quiet(
        finite.solve,
        problem.with_load(force=loads[6, :3], moment=loads[6, 3:]),
        "auto",
        frame=poses[6],
        tracker=first.tracker,
    )
    assert later.success and later.info["recast"]["left_face"] > 0  # the next frame moved the springs
    for name, value in held.items():
        assert np.array_equal(getattr(layer, name), value), name
    assert np.array_equal(targets.points, held_targets[0]) and np.array_equal(targets.normals, held_targets[1])


def test_answers_problems_and_casts_pickle_for_another_process():
    """A researcher's pool of processes sends problems and casts out and answers back: each
    pickles (a cast after a finite solve too, whose mesh caches hold Embree scenes, built again
    where unpickled), and the unpickled cast solves to the same answer. A finite answer leaves
    its tracker behind (the meshes a load path would continue from)."""
    import pickle

    pair = knee_meshes()
    cast = quiet(d.mesh.cast_springs, pair.mesh1, pair.mesh2, **pair.options)
    body = d.Body(reference=pair.reference2, free=("uz", "ry"), force=(0, 0, -500.0), prescribed={"ux": 0.01})
    problem = d.ContactProblem(cast.layer, d.LinearLaw(H), body2=body, kinematics="finite", targets=cast)
    finite = quiet(d.solve, problem)
    small = quiet(d.solve, d.ContactProblem(cast.layer, d.LinearLaw(H), body2=body))
    assert finite.success and small.success and finite.tracker is not None
    for answer in (small, finite):
        again = pickle.loads(pickle.dumps(answer))
        assert np.array_equal(again.u, answer.u) and np.array_equal(again.pressure, answer.pressure)
        assert again.problem.body2 == answer.problem.body2 and again.success == answer.success
    assert pickle.loads(pickle.dumps(finite)).tracker is None
    assert dict(pickle.loads(pickle.dumps(problem)).body2.prescribed) == {"ux": 0.01}
    cast_again = pickle.loads(pickle.dumps(cast))
    elsewhere = quiet(
        d.solve, d.ContactProblem(cast_again.layer, d.LinearLaw(H), body2=body, kinematics="finite", targets=cast_again)
    )
    assert elsewhere.success and np.abs(elsewhere.u - finite.u).max() <= 1e-12 * max(np.abs(finite.u).max(), 1.0)
