"""``dea-opt run`` with finite kinematics re-casts the springs at the solved pose and reports it:
a load path with prescribed poses at its peak frame (``dea_opt.run.path.peak_recast``), and a
scenario whose springs are split by ``[regions]`` with those labels. The numbers are checked
against what is computed here: the spring forces summed from the written per-spring outputs, and
a fresh cast with :mod:`dea_opt.mesh` at the solved pose (the written one, or the frame solved
again here)."""

from __future__ import annotations

import json
import re
import textwrap
import warnings

import numpy as np
import pandas as pd
import pytest
from conftest import KNEE, KNEE_SCENARIO, real_knee
from typer.testing import CliRunner

import dea_opt as d
from dea_opt import mesh as M
from dea_opt.cli import app
from dea_opt.geometry import knee_meshes
from dea_opt.io import label_codes, read_vtk
from dea_opt.scenario import build_problem_cast, load_scenario, read_load_path

POSE_COLUMNS = "time,Fx,Fy,Fz,Mx,My,Mz,pose_tx,pose_ty,pose_tz,pose_rx,pose_ry,pose_rz\n"
H = 10.0  # MPa, the linear law of every scenario here


def invoke(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


def write_poses(path, rows) -> None:
    """A load path with poses: one row ``(Fz, My, tx, rx, ry)`` per frame, 0.1 s apart."""
    lines = [f"{0.1 * k},0,0,{fz},0,{my},0,{tx},0,0,{rx},{ry},0\n" for k, (fz, my, tx, rx, ry) in enumerate(rows)]
    path.write_text(POSE_COLUMNS + "".join(lines))


def law_force(layer) -> np.ndarray:
    """The force (N) the springs of ``layer`` carry at their gaps under the linear law, on body 2."""
    pressure = -d.LinearLaw(H).stress(np.minimum(layer.gap / layer.thickness, 0.0))
    return ((pressure * layer.areas)[:, None] * layer.normals).sum(axis=0)


def written_force(cells: dict, mask=None) -> np.ndarray:
    """The force (N) summed from per-spring outputs (pressure x area along the normal)."""
    force = (np.asarray(cells["pressure"]) * np.asarray(cells["area"]))[:, None] * np.asarray(cells["normal"])
    return force[slice(None) if mask is None else mask].sum(axis=0)


def check_recast_report(recast: dict, solution_force) -> None:
    """The re-cast check as reported: nothing dropped, and its force error is the relative
    difference of the two forces it lists, below 1 %."""
    assert "error" not in recast, recast
    assert recast["dropped"] == 0 and recast["rejected"] == 0 and recast["kept"] > 0
    # the frame solved once more for the re-cast is the written one: to 1e-5 along the fixed dofs,
    # where the springs kept up to date along the path may differ from a cold solve's at the margin
    scale = np.linalg.norm(solution_force)
    np.testing.assert_allclose(recast["solution_force_N"], solution_force, rtol=0, atol=1e-4 * scale)
    difference = np.subtract(recast["force_N"], recast["solution_force_N"])
    error = np.linalg.norm(difference) / np.linalg.norm(recast["solution_force_N"])
    assert recast["force_error"] == pytest.approx(error, rel=1e-9, abs=1e-15) and error < 0.01


def solve_frame(toml, k):
    """Frame ``k`` of the scenario's load path solved here, at its pose, as ``dea-opt run`` does."""
    scenario = load_scenario(toml)
    data = read_load_path(scenario.load_path)
    problem, _ = build_problem_cast(scenario)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        return d.solve(problem.with_load(data.load_objects()[k], body=data.body), frame=data.poses[k])


def check_peak_frame(out, stdout: str, loads) -> tuple[int, dict]:
    """The path's re-cast is of its peak frame and gives that frame's dropped_springs;
    its reported force balances that frame's load along the free dofs (uz, ry) and is the sum of
    that frame's written spring forces. Returns ``(k, summary)``."""
    summary = json.loads((out / "summary.json").read_text())
    frames = pd.read_csv(out / "frames.csv")
    assert frames["success"].all() and frames["valid"].all()
    k = int(frames["peak_pressure_MPa"].idxmax())
    recast = summary["recast"]
    assert recast["frame"] == k == summary["peak_frame"] and recast["time_s"] == pytest.approx(frames.loc[k, "time_s"])
    # every finite frame counts what its own updates dropped; the peak frame's is the whole re-cast's
    assert frames.loc[k, "validity_dropped_springs"] == recast["dropped"] == 0
    assert f"re-cast at the solved pose of the peak frame {k}: " in stdout
    cells = read_vtk(out / "series_frames" / f"frame_{k:04d}.vtu").cell_data
    own = written_force(cells)
    check_recast_report(recast, own)
    fz, my = loads[k]
    assert own[2] == pytest.approx(-fz, rel=1e-9) and recast["solution_force_N"][2] == pytest.approx(-fz, rel=1e-9)
    assert recast["solution_moment_Nmm"][1] == pytest.approx(-my, abs=1e-6)
    return k, summary


def check_fresh_cast(recast, solution, frames_row, mesh1, mesh2, **options) -> None:
    """The re-cast force is what a fresh cast at the frame's solved pose carries (computed here
    with a window wide enough to drop nothing), for the answer ``dea-opt run`` wrote."""
    # (to 1e-4: springs kept up to date along the path and a cold solve's differ within recast_shift)
    assert solution.success and solution.peak_pressure == pytest.approx(frames_row["peak_pressure_MPa"], rel=1e-4)
    fresh = M.cast_springs(mesh1, mesh2, pose=solution.pose, **options)
    assert fresh.dropped.counts["overlap"] == 0 and fresh.dropped.counts["through_layer"] == 0
    assert len(fresh.layer) == recast["springs"]
    np.testing.assert_allclose(recast["force_N"], law_force(fresh.layer), rtol=1e-9, atol=1e-6)


# --- a load path with prescribed poses (generated knee: no data needed) -----------------------------

#: conftest's generated knee with finite kinematics, its load a path (loads and poses from a CSV)
GENERATED_KNEE_PATH = KNEE_SCENARIO.replace(
    "[load]\nforce = [0, 0, -600.0]\nmoment = [0, 1500.0, 0]\n", '[load_path]\nfile = "poses.csv"\n'
).replace('formats = ["json"]', 'formats = ["json", "csv", "vtk"]')
assert "[load_path]" in GENERATED_KNEE_PATH and '"vtk"' in GENERATED_KNEE_PATH


def test_a_finite_path_with_poses_recasts_its_peak_frame_at_that_frame_s_solved_pose(tmp_path):
    # the peak (800 N) is a middle frame, under a tilted and shifted pose of the condyles
    rows = [(-400.0, 0.0, 0.0, 0.0, 0.0), (-800.0, 900.0, 1.0, 4.0, -2.0), (-500.0, 500.0, 1.5, 6.0, -3.0)]
    write_poses(tmp_path / "poses.csv", rows)
    (tmp_path / "knee.toml").write_text(GENERATED_KNEE_PATH)
    result = invoke("run", tmp_path / "knee.toml", "-o", tmp_path / "out")
    assert result.exit_code == 0, result.stderr
    k, summary = check_peak_frame(tmp_path / "out", result.stdout, [(fz, my) for fz, my, *_ in rows])
    assert k == 1
    pair = knee_meshes()
    frames = pd.read_csv(tmp_path / "out" / "frames.csv")
    solution = solve_frame(tmp_path / "knee.toml", k)
    assert np.degrees(np.arccos((np.trace(solution.pose[:3, :3]) - 1) / 2)) > 4.0  # a pose, not the start
    options = {**pair.options, "max_overlap": 3.0}
    check_fresh_cast(summary["recast"], solution, frames.loc[k], pair.mesh1, pair.mesh2, **options)


# --- [regions] on the real knee: one tibial mesh split medial/lateral -------------------------------


@pytest.fixture(scope="module")
def knee_regions(tmp_path_factory):
    """The real knee's two tibial plateaus written as one mesh (so that ``[regions]`` labels it),
    with the meshes and their own medial/lateral labels."""
    knee = real_knee()
    folder = tmp_path_factory.mktemp("knee_regions")
    knee["mesh1"].export(folder / "tibia.stl")
    return {**knee, "folder": folder}


def regions_scenario(knee, tail: str) -> str:
    femur = (KNEE / "femoral_cartilage.stl").as_posix()
    return textwrap.dedent(f"""
        [geometry]
        kind = "meshes"
        mesh1 = "tibia.stl"
        mesh2 = "{femur}"
        max_gap = 2.0
        [regions]
        split = "x"
        names = ["lateral", "medial"]
        [law]
        kind = "linear"
        H = 10.0
        [body2]
        reference = [{", ".join(f"{c:.4f}" for c in knee["reference"])}]
        free = ["uz", "ry"]
        [solve]
        kinematics = "finite"
    """) + textwrap.dedent(tail)


def check_labels(knee, labels, faces) -> None:
    """``[regions]`` split at the start springs' area centroid along x gives, on the real knee, the
    plateaus' own labels (the medial plateau lies at larger x): every spring, by its source face."""
    assert set(np.unique(labels)) == {"lateral", "medial"}
    assert np.array_equal(np.asarray(labels), np.asarray(knee["options"]["labels"])[np.asarray(faces)])


def test_a_finite_run_with_regions_recasts_with_their_labels_and_the_regions_add_up(knee_regions):
    knee, folder = knee_regions, knee_regions["folder"]
    (folder / "static.toml").write_text(
        regions_scenario(knee, '[load]\nforce = [0.0, 0.0, -1000.0]\n[output]\nformats = ["json", "csv"]\n')
    )
    result = invoke("run", folder / "static.toml", "-o", folder / "static")
    assert result.exit_code == 0, result.stderr
    assert "re-cast at the solved pose: " in result.stdout
    for name in ("lateral", "medial"):
        assert re.search(rf"region {name}: [\d.]+% of the contact force \([\d.]+ N of [\d.]+ N along it", result.stdout)
    summary = json.loads((folder / "static" / "contact.json").read_text())
    springs = pd.read_csv(folder / "static" / "contact.csv", comment="#")
    cells = {"pressure": springs["pressure_MPa"], "area": springs["area_mm2"], "normal": springs[["nx", "ny", "nz"]]}
    own = written_force(cells)
    assert own[2] == pytest.approx(1000.0, rel=1e-9)
    check_recast_report(summary["recast"], own)
    assert summary["validity"]["checks"]["dropped_springs"]["status"] == "passed"
    # the re-cast force is a fresh cast's at the written pose, labelled by the same cut
    fresh = M.cast_springs(knee["mesh1"], knee["mesh2"], max_gap=2.0, max_overlap=2.0, pose=np.array(summary["pose"]))
    assert fresh.dropped.counts["overlap"] == 0 and len(fresh.layer) == summary["recast"]["springs"]
    np.testing.assert_allclose(summary["recast"]["force_N"], law_force(fresh.layer), rtol=1e-9, atol=1e-6)
    # per region: the labels are the plateaus', each region's force is its springs' sum, and they add up
    check_labels(knee, springs["label"], springs["source_face"])
    regions = summary["regions"]
    assert set(regions) == {"lateral", "medial"}
    for name, region in regions.items():
        mine = (springs["label"] == name).to_numpy()
        np.testing.assert_allclose(region["force_vector_N"], written_force(cells, mine), rtol=1e-9, atol=1e-6)
        assert region["n_springs"] == mine.sum() and 0.3 < region["share"] < 0.7
    np.testing.assert_allclose(sum(np.array(r["force_vector_N"]) for r in regions.values()), own, rtol=1e-9)
    magnitudes = sum(r["force_magnitude_sum_N"] for r in regions.values())
    assert magnitudes == pytest.approx(summary["force_magnitude_sum_N"], rel=1e-9)
    assert sum(r["share"] for r in regions.values()) == pytest.approx(1.0, rel=1e-12)


def test_a_finite_path_with_poses_and_regions_recasts_its_peak_frame_with_their_labels(knee_regions):
    knee, folder = knee_regions, knee_regions["folder"]
    rows = [(-600.0, 0.0, 0.0, 0.0, 0.0), (-800.0, -2000.0, 0.3, 0.5, -1.0), (-500.0, -1000.0, 0.3, 0.5, -1.0)]
    write_poses(folder / "poses.csv", rows)
    (folder / "path.toml").write_text(
        regions_scenario(knee, '[load_path]\nfile = "poses.csv"\n[output]\nformats = ["json", "csv", "vtk"]\n')
    )
    result = invoke("run", folder / "path.toml", "-o", folder / "path")
    assert result.exit_code == 0, result.stderr
    out = folder / "path"
    k, summary = check_peak_frame(out, result.stdout, [(fz, my) for fz, my, *_ in rows])
    assert k == 1
    frames = pd.read_csv(out / "frames.csv")
    solution = solve_frame(folder / "path.toml", k)
    check_fresh_cast(
        summary["recast"], solution, frames.loc[k], knee["mesh1"], knee["mesh2"], max_gap=2.0, max_overlap=2.0
    )
    # the peak frame's springs carry the plateaus' labels; per region they add up to the frame's force
    cells = read_vtk(out / "series_frames" / f"frame_{k:04d}.vtu").cell_data
    names = {code: name for name, code in label_codes(["lateral", "medial"]).items()}
    labels = np.array([names[int(code)] for code in cells["label"]])
    check_labels(knee, labels, cells["source_face"].astype(int))
    forces = {name: written_force(cells, labels == name) for name in ("lateral", "medial")}
    total = written_force(cells)
    np.testing.assert_allclose(forces["lateral"] + forces["medial"], total, rtol=1e-12)
    assert set(summary["regions"]) == {"lateral", "medial"}
    assert np.allclose(frames["lateral_force_share"] + frames["medial_force_share"], 1.0)
    for name in ("lateral", "medial"):
        magnitudes = (cells["pressure"] * cells["area"])[labels == name].sum()
        assert frames.loc[k, f"{name}_force_magnitude_sum_N"] == pytest.approx(magnitudes, rel=1e-9)
        written = [frames.loc[k, f"{name}_force_{c}_N"] for c in "xyz"]
        np.testing.assert_allclose(written, forces[name], rtol=1e-9, atol=1e-9 * np.linalg.norm(total))
