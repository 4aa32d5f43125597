"""The pieces wired end to end through ``dea-opt run``/``sweep``/``demo`` and the API (issues 10, 11):
load paths streamed frame by frame with every frame's status, the anatomical frame from the scenario,
size checks before resampling, springs re-cast at the solved pose, sweep statuses, the unsupported-load
diagnostic in commensurate units, the demo's regions, and a folder a killed run left behind."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import KNEE
from typer.testing import CliRunner

import dea_opt as d
from dea_opt.cli import app
from dea_opt.errors import InputError, SizeLimitError
from dea_opt.io.atomic import TEMPORARY_NAME
from dea_opt.io.publish import check_outputs, read_manifest
from dea_opt.scenario import load_scenario, parse_scenario, read_load_path, schema_text

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")
KNEE_EXAMPLES = ROOT / "examples" / "scenarios" / "knee"
KNEE_FILES = ("femoral_cartilage.stl", "medial_tibial_cartilage.stl", "lateral_tibial_cartilage.stl")
needs_knee = pytest.mark.skipif(not all((KNEE / f).is_file() for f in KNEE_FILES), reason="no knee meshes")
runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


SOCKET = """\
[geometry]
kind = "socket"
radius = 25.0
thickness = 3.0
coverage = 80.0
gap = 0.1
n_rings = 10
n_sectors = 30
[law]
kind = "linear"
H = 10.0
[body2]
free = ["ux", "uy", "uz"]
"""


def socket_path(tmp_path, rows, extra="") -> Path:
    """A socket scenario with a load path of ``rows`` ``(time, Fx, Fy, Fz)``."""
    (tmp_path / "path.csv").write_text("time,Fx,Fy,Fz\n" + "".join(f"{t},{x},{y},{z}\n" for t, x, y, z in rows))
    scenario = tmp_path / "path.toml"
    scenario.write_text(SOCKET + '[load_path]\nfile = "path.csv"\n' + extra)
    return scenario


# --- 1. load paths through dea-opt run: streamed, every frame recorded, exit 1 / 3 ----------------

def test_a_path_is_streamed_and_a_frame_that_cannot_be_carried_is_recorded(tmp_path):
    # frame 2 pulls the head out of the socket (+z): no spring can carry it; the others push it in
    rows = [(0.1 * k, 0.0, 0.0, 800.0 if k == 2 else -800.0 - 100.0 * k) for k in range(5)]
    scenario = socket_path(tmp_path, rows)
    result = invoke("run", scenario, "-o", tmp_path / "out")
    assert result.exit_code == 1, result.stderr
    message = result.stderr.strip().splitlines()[-1]
    assert "1 of 5 frames have no certified answer: frame 2 (0.2 s) load_not_supported" in message
    assert "failed their certificate" not in message  # not a certificate failure
    frames = pd.read_csv(tmp_path / "out" / "frames.csv")
    assert frames["success"].tolist() == [True, True, False, True, True]
    assert frames.loc[2, "status"] == "load_not_supported" and np.isnan(frames.loc[2, "peak_pressure"])
    # every frame has its .vtu, written while solving, and the manifest lists each
    manifest = read_manifest(tmp_path / "out")
    series = sorted(name for name in manifest["files"] if name.startswith("series_frames/"))
    assert series == [f"series_frames/frame_{k:04d}.vtu" for k in range(5)]
    assert manifest["status"] == "certificate failed" and manifest["exit_code"] == 1
    assert check_outputs(tmp_path / "out") == []


def test_run_path_outputs_keeps_nothing_per_frame(tmp_path):
    from dea_opt.run import run_scenario

    scenario = load_scenario(socket_path(tmp_path, [(0.1 * k, 0.0, 0.0, -500.0 - 200.0 * k) for k in range(4)]))
    outcome = run_scenario(scenario, tmp_path / "out")
    assert outcome.exit_code == 0 and outcome.result.solutions is None and outcome.result.pressures is None
    assert outcome.result.frame_files is not None and len(outcome.result.frame_files.files) == 4
    # the table still holds each frame's answer: the resultant equals the applied force (own sum)
    table = outcome.result.table
    applied = np.linalg.norm(table[["Fx", "Fy", "Fz"]].to_numpy(), axis=1)
    assert np.allclose(table["resultant"], applied, rtol=1e-6)


# --- 2. the anatomical frame from the scenario ------------------------------------------------------

PLATE = """\
[geometry]
kind = "plate"
length = 40.0
width = 10.0
nx = 40
ny = 10
[law]
kind = "linear"
H = 10.0
[body2]
free = ["uz", "rx", "ry"]
[load]
force = [0.0, 0.0, -500.0]
point = [5.0, 0.0, 0.0]
"""
ANATOMY = '[output]\nanatomy = {medial = [0.0, 1.0, 0.0], proximal = [0.0, 0.0, 1.0], side = "left"}\n'


def test_the_scenario_anatomy_reaches_the_json_and_the_map(tmp_path):
    (tmp_path / "plate.toml").write_text(PLATE + ANATOMY)
    result = invoke("run", tmp_path / "plate.toml", "-o", tmp_path / "out")
    assert result.exit_code == 0, result.stderr
    summary = json.loads((tmp_path / "out" / "contact.json").read_text())
    springs = pd.read_csv(tmp_path / "out" / "contact.csv", comment="#")
    points, area, pressure = springs[["x", "y", "z"]].to_numpy(), springs["area"].to_numpy(), springs["pressure"]
    centroid = area @ points / area.sum()
    cop = (pressure * area).to_numpy() @ points / (pressure * area).sum()
    # a left limb: anterior x proximal is the right, lateral; so anterior = proximal x medial... = -x here
    medial, proximal = np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])
    anterior = np.cross(proximal, medial)
    got = summary["center_of_pressure_anatomical"]
    expected = (cop - centroid) @ np.array([medial, anterior, proximal]).T
    assert np.allclose([got["medial"], got["anterior"], got["proximal"]], expected, atol=1e-9)
    assert summary["anatomy"]["side"] == "left" and np.allclose(summary["anatomy"]["anterior"], anterior)
    assert (tmp_path / "out" / "contact.png").read_bytes()[:4] == b"\x89PNG"


def test_a_path_summary_carries_the_anatomy(tmp_path):
    scenario = socket_path(tmp_path, [(0.0, 0.0, 0.0, -500.0), (0.1, 0.0, 0.0, -900.0)],
                           '[output]\nanatomy = {medial = [1.0, 0.0, 0.0], proximal = [0.0, 0.0, -1.0], '
                           'side = "right"}\n')
    assert invoke("run", scenario, "-o", tmp_path / "out").exit_code == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert np.allclose(summary["anatomy"]["anterior"], [0.0, 1.0, 0.0])  # medial x... right limb: +y


@pytest.mark.parametrize("value, words", [
    ('{medial = [1.0, 0.0, 0.0], proximal = [0.0, 0.0, 1.0], side = "up"}', "output.anatomy.side must be"),
    ('{medial = [0.0, 0.0, 0.0], proximal = [0.0, 0.0, 1.0], side = "right"}',
     "output.anatomy.medial must be a nonzero direction"),
    ('{medial = [1.0, 0.0, 0.0], proximal = [1.0, 0.1, 0.0], side = "right"}',
     "output.anatomy.proximal and output.anatomy.medial must be far from parallel"),
    ('{medial = [1.0, 0.0, 0.0], up = [0.0, 0.0, 1.0]}', "output.anatomy: unknown key up"),
    ('{medial = [1.0, "a", 0.0], proximal = [0.0, 0.0, 1.0], side = "right"}', "output.anatomy.medial must be"),
    ('{landmarks = {medial = [1.0, 0.0, 0.0], lateral = [-1.0, 0.0, 0.0], proximal = [0.0, 0.0, 9.0]}}',
     "output.anatomy.landmarks: side"),
    ('"right"', "output.anatomy (line 16)"),
])
def test_a_bad_anatomy_names_its_key(tmp_path, value, words):
    (tmp_path / "plate.toml").write_text(PLATE + f"[output]\nanatomy = {value}\n")
    result = invoke("run", tmp_path / "plate.toml", "-o", tmp_path / "out")
    assert result.exit_code == 2 and result.stderr.startswith("dea-opt: error:")
    assert words in result.stderr and "Traceback" not in result.stderr
    assert not (tmp_path / "out").exists()


def test_the_anatomy_key_is_documented():
    assert "# anatomy = ...  # optional; the anatomical frame" in schema_text()
    assert "[output] anatomy" in README and "anatomy = {medial" in README
    knee = (KNEE_EXAMPLES / "knee.toml").read_text()
    assert "anatomy = { medial = [1.0, 0.0, 0.0], proximal = [0.0, 0.0, 1.0], side = \"right\" }" in knee


# --- 3. sizes checked before allocating ----------------------------------------------------------

def test_a_billion_frames_is_a_named_size_error_with_the_estimate(tmp_path):
    text = SOCKET + '[load_path]\nbuiltin = "hip_gait"\nframes = 1000000000\n'
    with pytest.raises(SizeLimitError) as info:
        read_load_path(parse_scenario(text).load_path)
    error = info.value
    assert isinstance(error, InputError) and error.what == "load_path.frames = 1000000000"
    assert error.needed > 1e12 and error.needed > error.available  # a TB-sized table, more than there is
    (tmp_path / "big.toml").write_text(text)
    result = invoke("run", tmp_path / "big.toml", "-o", tmp_path / "out")
    assert result.exit_code == 2 and "load_path.frames = 1000000000 would need about" in result.stderr
    assert "TB of memory" in result.stderr


def test_the_mesh_memory_guard_is_a_size_limit_error():
    from dea_opt.geometry import hip_meshes
    from dea_opt.mesh.budget import check_memory

    with pytest.raises(SizeLimitError) as info:
        hip_meshes(step=0.01)
    assert "hip_meshes(step=0.01)" in str(info.value) and info.value.needed > info.value.available
    with pytest.raises(SizeLimitError, match="a request would need about 1e\\+03 PB"):
        check_memory("a request", 1e18, "ask for less")


# --- 4. springs re-cast at the solved pose --------------------------------------------------------

def test_with_validity_returns_a_new_solution_and_checks_its_arguments():
    from dea_opt.geometry import plate_layer
    from dea_opt.validity import ValidityLimits, assess

    problem = d.ContactProblem(plate_layer(40.0, 10.0, 20, 5, 2.0), d.LinearLaw(10.0), force=(0.0, 0.0, -400.0),
                               free=("uz",))
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
    return ((springs["pressure"] * springs["area"]).to_numpy()[:, None] * springs[["nx", "ny", "nz"]].to_numpy()).sum(0)


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
    assert np.allclose(recast["solution_force"], own, rtol=1e-9, atol=1e-6) and own[2] == pytest.approx(1000.0)
    error = np.linalg.norm(np.subtract(recast["force"], own)) / np.linalg.norm(own)
    assert recast["force_error"] == pytest.approx(error, rel=1e-9) and 0.0 < error < 0.05
    assert summary["center_of_pressure_anatomical"]["medial"] < 0  # the lateral plateau carries more


@needs_knee
def test_springs_dropped_at_the_solved_pose_make_the_run_exit_3(tmp_path):
    # H = 3 MPa: strain about 0.6, the femur sinks past the proximity window of the start cast
    result = invoke("run", KNEE_EXAMPLES / "knee.toml", "-o", tmp_path / "out", "-q", "--set", "law.H=3",
                    "--set", 'output.formats=["json"]')
    assert result.exit_code == 3, result.stderr
    summary = json.loads((tmp_path / "out" / "contact.json").read_text())
    dropped = summary["recast"]["dropped"]
    assert dropped > 0 and summary["validity"]["checks"]["dropped_springs"]["value"] == dropped
    assert "dropped_springs" in summary["validity"]["failed"]
    assert f"dropped_springs {dropped} > 0 springs" in result.stderr


@needs_knee
@pytest.mark.parametrize("name", ["knee_walk", "knee_opensim"])
def test_the_knee_path_recasts_its_peak_frame(tmp_path, name):
    result = invoke("run", KNEE_EXAMPLES / f"{name}.toml", "-o", tmp_path / "out", "-q")
    assert result.exit_code == 0, result.stderr
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    frames = pd.read_csv(tmp_path / "out" / "frames.csv")
    assert len(frames) == 51 and frames["success"].all()
    peak = int(frames["peak_pressure"].idxmax())
    assert summary["recast"]["frame"] == peak == summary["peak_frame"]
    evaluated = frames.index[frames["validity_dropped_springs"].notna()].tolist()
    assert evaluated == [peak] and frames.loc[peak, "validity_dropped_springs"] == summary["recast"]["dropped"] == 0
    # per-region columns: the two plateaus share the load in every frame (own sum)
    assert np.allclose(frames["medial_force_share"] + frames["lateral_force_share"], 1.0)
    assert 0.0 < summary["recast"]["force_error"] < 0.1  # the small-kinematics error, a few per cent


@needs_knee
def test_the_csv_and_the_sto_load_paths_give_the_same_frames(tmp_path):
    tables = {}
    for name in ("knee_walk", "knee_opensim"):
        scenario = load_scenario(KNEE_EXAMPLES / f"{name}.toml")
        tables[name] = read_load_path(scenario.load_path)
    csv, sto = tables["knee_walk"], tables["knee_opensim"]
    assert np.allclose(csv.times, sto.times) and np.allclose(csv.loads, sto.loads, atol=1e-3)
    # the synthetic stance of make_examples.py, written out here
    phase = csv.times / 0.6
    fz = -(200.0 + 1000.0 * (0.6 * np.sin(np.pi * phase) + 0.4 * np.sin(2 * np.pi * phase) ** 2))
    assert len(csv) == 51 and np.allclose(csv.loads[:, 2], fz, atol=1e-2)
    assert np.allclose(csv.loads[:, 4], 8000.0 * np.sin(2 * np.pi * phase), atol=1e-2)


# --- 5. sweep statuses --------------------------------------------------------------------------

def test_a_sweep_case_outside_validity_is_not_ok(tmp_path):
    (tmp_path / "plate.toml").write_text(PLATE + '[output]\nformats = ["json"]\n')
    args = ["sweep", tmp_path / "plate.toml", "--set", "law.H=5,10", "--scheduler", "synchronous"]
    result = invoke(*args, "-o", tmp_path / "s")
    assert result.exit_code == 3 and "1 case(s) solved outside validity" in result.stderr
    table = pd.read_csv(tmp_path / "s" / "sweep.csv").set_index("law.H")
    strain = table["peak_pressure"] / table.index  # the linear law: strain = pressure / H, computed here
    assert strain[5] > 0.3 > strain[10]
    assert table.loc[5, "status"] == "outside_validity" and table.loc[5, "validity_failed"] == "strain"
    assert table.loc[10, "status"] == "ok" and table.loc[5, "exit_code"] == 3
    # a rerun and --retry-failed keep the row: it is a finished computation, not a failure
    again = invoke(*args, "-o", tmp_path / "s", "--retry-failed")
    assert again.exit_code == 3 and "0 case(s) run, 2 already finished" in again.stdout
    # allowed by the scenario: exit 0, the row still says so
    allowed = invoke(*args, "-o", tmp_path / "a", "--set", "solve.allow_outside_validity=true")
    assert allowed.exit_code == 0, allowed.stderr
    table = pd.read_csv(tmp_path / "a" / "sweep.csv").set_index("law.H")
    assert table.loc[5, "status"] == "outside_validity" and table.loc[5, "exit_code"] == 0


def test_the_readme_documents_the_sweep_statuses():
    from dea_opt.sweep.cases import STATUSES

    assert STATUSES == ("ok", "outside_validity", "failed", "error")
    for status in STATUSES:
        assert f"| `{status}` |" in README


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
    return d.ContactProblem(layer, d.LinearLaw(10.0), force=force, moment=moment, reference=tuple(reference),
                            free=free), layer, reference, free


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


# --- 7. the demo: validity and compartments ----------------------------------------------------

def test_hip_regions_label_the_dome_and_the_walls():
    from dea_opt.demo import hip_regions
    from dea_opt.geometry import socket_layer

    layer = socket_layer(25.0, 3.0, 80.0, 16, 36)
    frame = {"medial": (1.0, 0.0, 0.0), "proximal": (0.0, 0.0, -1.0), "side": "right"}
    labels = hip_regions(layer, frame, dome=35.0)
    polar = np.degrees(np.arccos(-layer.points[:, 2] / 25.0))  # from the socket's pole, computed here
    assert (labels[polar < 35.0 - 1e-9] == "superior").all() and (labels[polar > 35.0 + 1e-9] != "superior").all()
    walls = polar > 35.0
    assert (labels[walls & (layer.points[:, 1] > 0)] == "anterior").all()
    assert (labels[walls & (layer.points[:, 1] < 0)] == "posterior").all()


def test_the_demo_shows_validity_and_the_regions(tmp_path):
    result = invoke("demo", "--coarse", "--frames", "6", "--no-compare", "-o", tmp_path)
    assert result.exit_code == 0, result.stderr
    out = result.stdout
    assert "validity: valid (every one of the 6 certified frames)" in out
    for region in ("anterior", "posterior", "superior"):
        assert f"region {region}: force share" in out
    frames = pd.read_csv(tmp_path / "frames.csv")
    shares = frames[["anterior_force_share", "posterior_force_share", "superior_force_share"]].sum(axis=1)
    assert np.allclose(shares, 1.0)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert set(summary["regions"]) == {"anterior", "posterior", "superior"}
    assert np.allclose(summary["anatomy"]["anterior"], [0.0, 1.0, 0.0]) and summary["anatomy"]["side"] == "right"


# --- the attack: a folder a killed run left, two runs at once ------------------------------------

def test_a_folder_left_by_a_first_run_killed_mid_path_is_taken_by_the_next(tmp_path):
    folder = tmp_path / "out"
    (folder / "series_frames").mkdir(parents=True)  # what kill -9 leaves before anything was published
    (folder / ".dea-opt.lock").write_text("123\n")
    staged = folder / "series_frames" / ".frame_0000.vtu.0123abcd.tmp.vtu"
    staged.write_text("half a frame")
    scenario = socket_path(tmp_path, [(0.0, 0.0, 0.0, -500.0), (0.1, 0.0, 0.0, -900.0)])
    result = invoke("run", scenario, "-o", folder)
    assert result.exit_code == 0, result.stderr
    assert not staged.exists() and check_outputs(folder) == []
    (tmp_path / "mine").mkdir()
    (tmp_path / "mine" / "notes").mkdir()
    (tmp_path / "mine" / "notes" / "thesis.txt").write_text("mine")  # a user's folder is still refused
    assert invoke("run", scenario, "-o", tmp_path / "mine").exit_code == 2


def _dea_opt(*args) -> list[str]:
    return [sys.executable, "-m", "dea_opt.cli", *map(str, args)]


@pytest.mark.slow
def test_kill_9_of_a_first_run_mid_path_then_rerun(tmp_path):
    rows = [(0.01 * k, 0.0, 0.0, -500.0 - 2.0 * k) for k in range(400)]
    scenario = socket_path(tmp_path, rows, '[output]\nformats = ["vtk", "csv", "json"]\n')
    folder = tmp_path / "out"
    env = {**os.environ, "MPLBACKEND": "Agg"}
    process = subprocess.Popen(_dea_opt("run", scenario, "-o", folder, "-q"), env=env, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE)
    try:
        deadline = time.monotonic() + 120
        while not any(TEMPORARY_NAME.match(p.name) for p in folder.rglob("*")) and time.monotonic() < deadline:
            time.sleep(0.01)
        assert process.poll() is None, "the run finished before it could be killed"
        process.send_signal(signal.SIGKILL)
    finally:
        process.communicate(timeout=60)
    assert read_manifest(folder) is None  # nothing was published
    done = subprocess.run(_dea_opt("run", scenario, "-o", folder, "-q"), env=env, capture_output=True, text=True,
                          timeout=300, check=False)
    assert done.returncode == 0, done.stderr
    assert check_outputs(folder) == [] and not [p for p in folder.rglob("*") if TEMPORARY_NAME.match(p.name)]
    assert len(pd.read_csv(folder / "frames.csv")) == 400


def test_two_runs_into_one_folder_at_once(tmp_path):
    from dea_opt.io.publish import output_run

    scenario = socket_path(tmp_path, [(0.0, 0.0, 0.0, -500.0)])
    with output_run(tmp_path / "out"):  # another run holds the folder
        result = invoke("run", scenario, "-o", tmp_path / "out")
    assert result.exit_code == 2 and "another dea-opt run" in result.stderr
    assert invoke("run", scenario, "-o", tmp_path / "out").exit_code == 0


def test_no_raw_warning_from_a_recast(tmp_path):
    from dea_opt.geometry import hip_meshes
    from dea_opt.run import recast_solution

    pair = hip_meshes(step=6.0)
    cast = pair.cast(max_gap=2.0)
    problem = d.ContactProblem(cast.layer, d.LinearLaw(10.0), force=(0.0, 0.0, -1000.0), reference=pair.reference2,
                               free=("ux", "uy", "uz"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        solution, report = recast_solution(d.solve(problem), cast)
    assert report["dropped"] == solution.validity["dropped_springs"].value == 0
    assert np.allclose(report["solution_force"], [0.0, 0.0, 1000.0], atol=1e-6)
    failed = d.solve(problem, "newton", strict=False, certificate_tol=1e-30)
    same, report = recast_solution(failed, cast)
    assert same is failed and "not certified" in report["error"]


@needs_knee
def test_the_readme_recast_example_runs_on_the_knee_with_its_numbers():
    import re

    from dea_opt.mesh import concatenate_meshes, load_mesh

    block = next(b for b in re.findall(r"```python\n(.*?)```", README, re.DOTALL) if "recast_at_solution(" in b)
    tibia, labels = concatenate_meshes({"medial": load_mesh(KNEE / KNEE_FILES[1]),
                                        "lateral": load_mesh(KNEE / KNEE_FILES[2])})
    namespace = {"dea": d, "tibia": tibia, "labels": labels, "femur": load_mesh(KNEE / KNEE_FILES[0]),
                 "x": -69.0242, "y": -5.9006, "z": -18.8433}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        exec(compile(block, "README.md", "exec"), namespace)  # noqa: S102 - the README's own example
    again, solution = namespace["again"], namespace["solution"]
    assert (again.kept, len(again.start.layer), again.dropped, again.rejected) == (13223, 13306, 0, 0)
    assert solution.validity["dropped_springs"].value == 0 and solution.validity.valid
    assert again.force[2] == pytest.approx(1023.8, abs=0.05)  # the README's number


@pytest.mark.parametrize("cell, got", [("nan", "got 'nan'"), ("inf", "got 'inf'"), ("", "got an empty cell")])
def test_a_load_path_cell_that_is_no_finite_number_is_quoted(tmp_path, cell, got):
    (tmp_path / "path.csv").write_text(f"time,Fx,Fy,Fz\n0,0,0,-500\n0.1,0,0,{cell}\n")
    (tmp_path / "path.toml").write_text(SOCKET + '[load_path]\nfile = "path.csv"\n')
    result = invoke("run", tmp_path / "path.toml", "-o", tmp_path / "out")
    assert result.exit_code == 2
    assert f"path.csv, line 3, column Fz: expected a finite number, {got}" in result.stderr


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
    (tmp_path / "poses.csv").write_text("time,Fx,Fy,Fz,Mx,My,Mz,pose_tx,pose_ty,pose_tz,pose_rx,pose_ry,pose_rz\n" + rows)
    (tmp_path / "hip.toml").write_text(HIP_GENERATOR + '[load_path]\nfile = "poses.csv"\n')
    result = invoke("run", tmp_path / "hip.toml", "-o", tmp_path / "out", "-q")
    assert result.exit_code == 0, result.stderr
    frames = pd.read_csv(tmp_path / "out" / "frames.csv")
    recast = json.loads((tmp_path / "out" / "summary.json").read_text())["recast"]
    peak = int(frames["peak_pressure"].idxmax())
    assert recast["frame"] == peak and frames["validity_dropped_springs"].notna().tolist() == [
        k == peak for k in range(4)]
    # that frame's answer balances its load (summed from its row here): the re-cast compares with it
    assert np.allclose(recast["solution_force"], -frames.loc[peak, ["Fx", "Fy", "Fz"]].to_numpy(float), atol=1e-6)
    assert recast["kept"] <= frames.loc[peak, "n_springs"] and 0 < recast["force_error"] < 0.1


def test_a_recast_that_cannot_be_made_is_a_warning_not_a_silence(tmp_path):
    (tmp_path / "hip.toml").write_text(HIP_GENERATOR + '[load]\nforce = [0.0, 0.0, -1000.0]\n'
                                       '[output]\nformats = ["json"]\n')
    result = invoke("run", tmp_path / "hip.toml", "-o", tmp_path / "out", "-q", "-m", "newton",
                    "--set", "solve.certificate_tol=1e-30")
    assert result.exit_code == 1
    assert "dea-opt: warning: springs not re-cast at the solved pose: the answer is not certified" in result.stderr
    summary = json.loads((tmp_path / "out" / "contact.json").read_text())
    assert "not certified" in summary["recast"]["error"]
    assert summary["validity"]["checks"]["dropped_springs"]["status"] == "not evaluated"
