"""Springs re-cast at the solved pose through ``dea-opt run`` and the API:
``Solution.with_validity``, the re-cast of a static answer and of a load path's peak frame (the
real knee, a path with poses), the guide's example with the knee's numbers, and the
unsupported-load diagnostic in commensurate units."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import KNEE
from typer.testing import CliRunner

import dea_opt as d
from dea_opt.cli import app
from dea_opt.errors import InputError
from dea_opt.scenario import load_scenario, read_load_path

ROOT = Path(__file__).resolve().parents[2]
MESHES_PAGE = (ROOT / "docs" / "guide" / "meshes.md").read_text(encoding="utf-8")
KNEE_EXAMPLES = ROOT / "examples" / "scenarios" / "knee"
KNEE_FILES = ("femoral_cartilage.stl", "medial_tibial_cartilage.stl", "lateral_tibial_cartilage.stl")
needs_knee = pytest.mark.skipif(not all((KNEE / f).is_file() for f in KNEE_FILES), reason="no knee meshes")


def invoke(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


# --- 4. springs re-cast at the solved pose --------------------------------------------------------


def test_with_validity_returns_a_new_solution_and_checks_its_arguments():
    from dea_opt.geometry import plate_layer
    from dea_opt.validity import ValidityLimits, assess

    problem = d.ContactProblem(
        plate_layer(40.0, 10.0, 20, 5, 2.0), d.LinearLaw(10.0), force=(0.0, 0.0, -400.0), free=("uz",)
    )
    solution = d.solve(problem)
    assert solution.validity["dropped_springs"].passed is None  # not evaluated by default
    counted = solution.with_validity(dropped=3)
    assert counted is not solution and solution.validity["dropped_springs"].passed is None
    check = counted.validity["dropped_springs"]
    assert check.value == 3 and check.passed is False and not counted.validity.valid
    assert counted.with_validity(dropped=3, limits=ValidityLimits(dropped_springs=5)).validity.valid
    assert np.array_equal(counted.u, solution.u) and counted.certificate is solution.certificate
    given = assess(problem, solution.u, dropped=0)
    assert solution.with_validity(given).validity is given
    with pytest.raises(InputError, match="validity must be"):
        solution.with_validity("valid")
    with pytest.raises(InputError, match="not both"):
        solution.with_validity(given, dropped=1)
    with pytest.raises(InputError, match="dropped must be a count"):
        solution.with_validity(dropped=-1)


def _own_force(springs: pd.DataFrame) -> np.ndarray:
    """The springs' force on body 2 (N), summed here from the per-spring table."""
    return (
        (springs["pressure_MPa"] * springs["area_mm2"]).to_numpy()[:, None] * springs[["nx", "ny", "nz"]].to_numpy()
    ).sum(0)


@needs_knee
def test_the_knee_run_recasts_at_its_solved_pose(tmp_path):
    result = invoke("run", KNEE_EXAMPLES / "knee.toml", "-o", tmp_path / "out")
    assert result.exit_code == 0, result.stderr
    assert "re-cast at the solved pose: 15747 springs at the new pose: 13223 of 13306 kept" in result.stdout
    assert "region medial:" in result.stdout and "region lateral:" in result.stdout
    summary = json.loads((tmp_path / "out" / "contact.json").read_text())
    recast = summary["recast"]
    assert recast["dropped"] == 0 and recast["rejected"] == 0 and recast["kept"] == 13223
    check = summary["validity"]["checks"]["dropped_springs"]
    assert check["value"] == 0 and check["status"] == "passed"
    # the solution's own force, summed here, is what the re-cast is compared with; and it balances the load
    own = _own_force(pd.read_csv(tmp_path / "out" / "contact.csv", comment="#"))
    assert np.allclose(recast["solution_force_N"], own, rtol=1e-9, atol=1e-6) and own[2] == pytest.approx(1000.0)
    error = np.linalg.norm(np.subtract(recast["force_N"], own)) / np.linalg.norm(own)
    assert recast["force_error"] == pytest.approx(error, rel=1e-9) and 0.0 < error < 0.05
    assert summary["center_of_pressure_anatomical"]["medial_mm"] < 0  # the lateral plateau carries more


@needs_knee
def test_springs_dropped_at_the_solved_pose_make_the_run_exit_3(tmp_path):
    # H = 3 MPa: strain about 0.6, the femur sinks past the proximity window of the start cast
    result = invoke(
        "run",
        KNEE_EXAMPLES / "knee.toml",
        "-o",
        tmp_path / "out",
        "-q",
        "--set",
        "law.H=3",
        "--set",
        'output.formats=["json"]',
    )
    assert result.exit_code == 3, result.stderr
    summary = json.loads((tmp_path / "out" / "contact.json").read_text())
    dropped = summary["recast"]["dropped"]
    assert dropped > 0 and summary["validity"]["checks"]["dropped_springs"]["value"] == dropped
    assert "dropped_springs" in summary["validity"]["failed"]
    assert f"dropped_springs {dropped} > 0 springs" in result.stderr


@needs_knee
def test_the_knee_path_recasts_its_peak_frame(tmp_path):
    """knee_walk.toml; knee_opensim.toml is the same run with its load path from an STO file
    (the next test: the same scenario, the same frames)."""
    result = invoke("run", KNEE_EXAMPLES / "knee_walk.toml", "-o", tmp_path / "out", "-q")
    assert result.exit_code == 0, result.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    frames = pd.read_csv(tmp_path / "out" / "frames.csv")
    assert len(frames) == 51 and frames["success"].all()
    peak = int(frames["peak_pressure_MPa"].idxmax())
    assert summary["recast"]["frame"] == peak == summary["peak_frame"]
    evaluated = frames.index[frames["validity_dropped_springs"].notna()].tolist()
    assert evaluated == [peak] and frames.loc[peak, "validity_dropped_springs"] == summary["recast"]["dropped"] == 0
    # per-region columns: the two plateaus share the load in every frame (own sum)
    assert np.allclose(frames["medial_force_share"] + frames["lateral_force_share"], 1.0)
    assert 0.0 < summary["recast"]["force_error"] < 0.1  # the small-kinematics error, a few per cent


@needs_knee
def test_the_csv_and_the_sto_load_paths_give_the_same_frames(tmp_path):
    """knee_opensim.toml runs what knee_walk.toml runs (the test above): the same scenario but for
    its load path's file, title and output folder, and the same loads in every frame."""
    walk, opensim = (load_scenario(KNEE_EXAMPLES / f"{name}.toml") for name in ("knee_walk", "knee_opensim"))
    for field in ("geometry", "law", "body1", "body2", "load", "regions", "solve"):
        assert getattr(walk, field) == getattr(opensim, field), field
    assert walk.output.model_copy(update={"directory": opensim.output.directory}) == opensim.output
    assert Path(opensim.load_path.file).name == "knee_walk.sto" and opensim.load_path.units == "SI"
    csv, sto = read_load_path(walk.load_path), read_load_path(opensim.load_path)
    assert np.allclose(csv.times, sto.times) and np.allclose(csv.loads, sto.loads, atol=1e-3)
    # the synthetic stance of make_examples.py, written out here
    phase = csv.times / 0.6
    fz = -(200.0 + 1000.0 * (0.6 * np.sin(np.pi * phase) + 0.4 * np.sin(2 * np.pi * phase) ** 2))
    assert len(csv) == 51 and np.allclose(csv.loads[:, 2], fz, atol=1e-2)
    assert np.allclose(csv.loads[:, 4], 8000.0 * np.sin(2 * np.pi * phase), atol=1e-2)


# --- 6. the unsupported-load diagnostic in commensurate units -----------------------------------


def _generalized(layer, reference, free) -> np.ndarray:
    """Each spring's push on body 2 as a generalized force over the free dofs (N, N mm), here."""
    arm = layer.points - np.asarray(reference)
    full = np.hstack([layer.normals, np.cross(arm, layer.normals)])
    return full[:, [d.kinematics.DOF_NAMES.index(f"body2.{f}") - 6 for f in free]]


def _random_problem(rng):
    from dea_opt.geometry import plate_layer, socket_layer, sphere_on_bed_layer

    kind = rng.integers(3)
    if kind == 0:
        layer, free = plate_layer(40.0, 10.0, 20, 5, 2.0), ("uz", "rx", "ry")
    elif kind == 1:
        layer, free = socket_layer(25.0, 2.0, 70.0, 8, 24), ("ux", "uy", "uz")
    else:
        layer, free = sphere_on_bed_layer(25.0, 2.0, 7.0, 10, 16), ("ux", "uy", "uz", "rx", "ry")
        free = tuple(rng.choice(free, size=rng.integers(1, 4), replace=False))
        free = free if "uz" in free else ("uz", *free)
    reference = rng.normal(scale=5.0, size=3)
    force = rng.normal(scale=1000.0, size=3)
    moment = rng.normal(scale=10.0 ** rng.uniform(2, 6), size=3)
    return (
        d.ContactProblem(layer, d.LinearLaw(10.0), force=force, moment=moment, reference=tuple(reference), free=free),
        layer,
        reference,
        free,
    )


def test_the_unbalanced_part_is_the_smallest_and_never_larger_than_the_load():
    rng = np.random.default_rng(20261124)
    raised = 0
    for _ in range(120):
        problem, layer, reference, free = _random_problem(rng)
        try:
            d.check_load_supported(problem)
            continue
        except d.LoadNotSupportedError as exc:
            error = exc
        if "no spring resists" in str(error):
            continue  # the other test (directions no spring resists), not the cone
        raised += 1
        names = [f"body2.{f}" for f in free]
        u = np.array([error.direction[n] for n in names])
        load = problem.load_vector[[d.kinematics.DOF_NAMES.index(n) for n in names]]
        # the certificate's lengths, computed here: 1 mm, or the RMS distance of the springs from the reference
        radius = np.sqrt(np.mean(np.sum((layer.points - reference) ** 2, axis=1)))
        L = np.array([1.0 if f[0] == "u" else radius for f in free])
        assert np.linalg.norm(u / L) <= np.linalg.norm(load / L) * (1 + 1e-9)
        # smallest: no spring's push reduces it further, and what is carried is orthogonal to it
        # (the optimality conditions of the nearest point of the cone, in the scaled measure)
        A = _generalized(layer, reference, free) / L
        scale = np.linalg.norm(u / L) * np.linalg.norm(A, axis=1).max()
        assert (A @ (u / L) >= -1e-6 * scale).all()
        carried = (load - u) / L
        assert abs(carried @ (u / L)) <= 1e-6 * np.linalg.norm(load / L) ** 2
    assert raised >= 20  # the draws do reach the cone test


@needs_knee
def test_the_knee_moment_diagnostic_names_its_cause_and_the_nearest_carried_load(tmp_path):
    from dea_opt.scenario import build_problem

    problem = build_problem(load_scenario(KNEE_EXAMPLES / "knee.toml"))
    problem = problem.with_load(d.Load(force=(0.0, 0.0, -1000.0), moment=(0.0, 2e6, 0.0)))
    with pytest.raises(d.LoadNotSupportedError) as info:
        d.solve(problem)
    text = str(info.value)
    assert "its moment is more than the springs can balance with that force" in text
    assert "moments counted over the layer's radius, 23.95 mm about body2's reference point" in text
    assert "the nearest load the springs can carry is force" in text
    u = info.value.direction
    assert np.hypot(u["body2.uz"], u["body2.ry"] / 23.948) < np.hypot(1000.0, 2e6 / 23.948)


def test_no_raw_warning_from_a_recast(tmp_path):
    from dea_opt.geometry import hip_meshes
    from dea_opt.run import recast_solution

    pair = hip_meshes(step=6.0)
    cast = pair.cast(max_gap=2.0)
    problem = d.ContactProblem(
        cast.layer, d.LinearLaw(10.0), force=(0.0, 0.0, -1000.0), reference=pair.reference2, free=("ux", "uy", "uz")
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        solution, report = recast_solution(d.solve(problem), cast)
    assert report["dropped"] == solution.validity["dropped_springs"].value == 0
    assert np.allclose(report["solution_force_N"], [0.0, 0.0, 1000.0], atol=1e-6)
    failed = d.solve(problem, "newton", strict=False, certificate_tol=1e-30)
    same, report = recast_solution(failed, cast)
    assert same is failed and "not certified" in report["error"]


@needs_knee
def test_the_guide_recast_example_runs_on_the_knee_with_its_numbers():
    import re

    from dea_opt.mesh import concatenate_meshes, load_mesh

    block = next(b for b in re.findall(r"```python\n(.*?)```", MESHES_PAGE, re.DOTALL) if "recast_at_solution(" in b)
    tibia, labels = concatenate_meshes(
        {"medial": load_mesh(KNEE / KNEE_FILES[1]), "lateral": load_mesh(KNEE / KNEE_FILES[2])}
    )
    namespace = {
        "dea": d,
        "tibia": tibia,
        "labels": labels,
        "femur": load_mesh(KNEE / KNEE_FILES[0]),
        "x": -69.0242,
        "y": -5.9006,
        "z": -18.8433,
    }
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        exec(compile(block, "meshes.md", "exec"), namespace)  # noqa: S102 - the guide's own example
    again, solution = namespace["again"], namespace["solution"]
    assert (again.kept, len(again.start.layer), again.dropped, again.rejected) == (13223, 13306, 0, 0)
    assert solution.validity["dropped_springs"].value == 0 and solution.validity.valid
    assert again.force[2] == pytest.approx(1023.8, abs=0.05)  # the guide's number


HIP_GENERATOR = """\
[geometry]
kind = "generator"
function = "hip_meshes"
parameters = { step = 6.0 }
[law]
kind = "linear"
H = 10.0
[body2]
free = ["ux", "uy", "uz"]
"""


def test_a_path_with_poses_recasts_its_peak_frame_at_that_frame_s_pose(tmp_path):
    rows = "".join(f"{0.1 * k},0,0,{-600 - 300 * k},0,0,0,0,{0.2 * k},0,0,0,0\n" for k in range(4))
    (tmp_path / "poses.csv").write_text(
        "time,Fx,Fy,Fz,Mx,My,Mz,pose_tx,pose_ty,pose_tz,pose_rx,pose_ry,pose_rz\n" + rows
    )
    (tmp_path / "hip.toml").write_text(HIP_GENERATOR + '[load_path]\nfile = "poses.csv"\n')
    result = invoke("run", tmp_path / "hip.toml", "-o", tmp_path / "out", "-q")
    assert result.exit_code == 0, result.stderr
    frames = pd.read_csv(tmp_path / "out" / "frames.csv")
    recast = json.loads((tmp_path / "out" / "summary.json").read_text())["recast"]
    peak = int(frames["peak_pressure_MPa"].idxmax())
    assert recast["frame"] == peak and frames["validity_dropped_springs"].notna().tolist() == [
        k == peak for k in range(4)
    ]
    # that frame's answer balances its load (summed from its row here): the re-cast compares with it
    assert np.allclose(
        recast["solution_force_N"], -frames.loc[peak, ["Fx_N", "Fy_N", "Fz_N"]].to_numpy(float), atol=1e-6
    )
    assert recast["kept"] <= frames.loc[peak, "n_springs"] and 0 < recast["force_error"] < 0.1


def test_a_recast_that_cannot_be_made_is_a_warning_not_a_silence(tmp_path):
    (tmp_path / "hip.toml").write_text(
        HIP_GENERATOR + '[load]\nforce = [0.0, 0.0, -1000.0]\n[output]\nformats = ["json"]\n'
    )
    result = invoke(
        "run",
        tmp_path / "hip.toml",
        "-o",
        tmp_path / "out",
        "-q",
        "-m",
        "newton",
        "--set",
        "solve.certificate_tol=1e-30",
    )
    assert result.exit_code == 1
    assert "dea-opt: warning: springs not re-cast at the solved pose: the answer is not certified" in result.stderr
    summary = json.loads((tmp_path / "out" / "contact.json").read_text())
    assert "not certified" in summary["recast"]["error"]
    assert summary["validity"]["checks"]["dropped_springs"]["status"] == "not evaluated"
