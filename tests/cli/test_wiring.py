"""The pieces wired end to end through ``dea-opt run``/``sweep``/``demo`` and the API:
load paths streamed frame by frame with every frame's status, the anatomical frame from the scenario,
size checks before resampling, sweep statuses, the demo's regions, and a folder a killed run left
behind (the re-cast at the solved pose and the unsupported-load diagnostic: test_wiring_recast.py)."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import COARSE_SOCKET, KNEE, scenario_text
from typer.testing import CliRunner

from dea_opt.cli import app
from dea_opt.errors import InputError, SizeLimitError
from dea_opt.files.atomic import TEMPORARY_NAME
from dea_opt.run.publish import check_outputs, read_manifest
from dea_opt.scenario import load_scenario, parse_scenario, read_load_path, schema_text
from dea_opt.status import RunStatus

ROOT = Path(__file__).resolve().parents[2]
GUIDE = {page.stem: page.read_text(encoding="utf-8") for page in (ROOT / "docs" / "guide").glob("*.md")}
KNEE_EXAMPLES = ROOT / "examples" / "scenarios" / "knee"
KNEE_FILES = ("femoral_cartilage.stl", "medial_tibial_cartilage.stl", "lateral_tibial_cartilage.stl")
needs_knee = pytest.mark.skipif(not all((KNEE / f).is_file() for f in KNEE_FILES), reason="no knee meshes")
runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


SOCKET = COARSE_SOCKET


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
    assert "1 of 5 frames without a certified answer: frame 2 (0.2 s, 1 of 5) load_not_supported: the frame pulls" in (
        message
    )
    assert "failed their certificate" not in message  # not a certificate failure
    frames = pd.read_csv(tmp_path / "out" / "frames.csv")
    assert frames["success"].tolist() == [True, True, False, True, True]
    assert frames.loc[2, "status"] == "load_not_supported" and np.isnan(frames.loc[2, "peak_pressure_MPa"])
    # every frame has its .vtu, written while solving, and the manifest lists each
    manifest = read_manifest(tmp_path / "out")
    series = sorted(name for name in manifest["files"] if name.startswith("series_frames/"))
    assert series == [f"series_frames/frame_{k:04d}.vtu" for k in range(5)]
    # the manifest says why precisely: the frame's load cannot be carried, no certificate failed
    assert manifest["status"] == RunStatus.LOAD_NOT_SUPPORTED and manifest["exit_code"] == 1
    assert manifest["failures"] == {"load_not_supported": 1}
    assert check_outputs(tmp_path / "out") == []


def region_parts(text) -> dict:
    """``{region: (share, part in N, contact force in N, resultant in N)}`` of the terminal's lines."""
    pattern = r"region (\w+): ([\d.]+)% of the contact force \(([\d.]+) N of ([\d.]+) N along it; its springs' resultant ([\d.]+) N\)"
    return {m[1]: tuple(float(v) for v in m.groups()[1:]) for m in re.finditer(pattern, text)}


def test_regions_report_their_resultants_everywhere(tmp_path):
    """A ball pushed into a socket split in two: its springs push along the radii, so their force
    magnitudes add up to far more than the load. The terminal, contact.json and contact.csv give
    each half's resultant and its part of the contact force (the parts add up to it); the sum of
    magnitudes is kept, named for what it is."""
    load = np.array([400.0, 0.0, -1500.0])
    text = (
        SOCKET + '[regions]\nsplit = "x"\n[load]\nforce = [400.0, 0.0, -1500.0]\n[output]\nformats = ["json", "csv"]\n'
    )
    (tmp_path / "socket.toml").write_text(text)
    result = invoke("run", tmp_path / "socket.toml", "-o", tmp_path / "out")
    assert result.exit_code == 0, result.stderr
    size = float(np.linalg.norm(load))
    parts = region_parts(result.stdout)
    assert set(parts) == {"medial", "lateral"} and "nan" not in result.stdout
    assert sum(p[1] for p in parts.values()) == pytest.approx(size, rel=2e-3)  # the parts add up to the load
    assert all(total == pytest.approx(size, rel=1e-3) for _, _, total, _ in parts.values())
    # the springs, read back from the CSV and summed here
    springs = pd.read_csv(tmp_path / "out" / "contact.csv")
    force = (springs["pressure_MPa"] * springs["area_mm2"]).to_numpy()[:, None] * springs[["nx", "ny", "nz"]].to_numpy()
    np.testing.assert_allclose(force.sum(axis=0), -load, rtol=0, atol=1e-6 * size)  # equilibrium
    summary = json.loads((tmp_path / "out" / "contact.json").read_text())
    for name, (share, part, _, resultant) in parts.items():
        mine = (springs["label"] == name).to_numpy()
        vector = force[mine].sum(axis=0)
        region = summary["regions"][name]
        np.testing.assert_allclose(region["force_vector_N"], vector, rtol=1e-9, atol=1e-9 * size)
        assert region["resultant_N"] == pytest.approx(np.linalg.norm(vector), rel=1e-9)
        assert region["share"] == pytest.approx(vector @ -load / size**2, rel=1e-6)
        assert share == pytest.approx(100 * region["share"], abs=0.06) and resultant == pytest.approx(
            region["resultant_N"], rel=1e-3
        )
        assert part == pytest.approx(region["share"] * size, rel=1e-3)
        magnitudes = float((springs["pressure_MPa"] * springs["area_mm2"])[mine].sum())
        assert region["force_magnitude_sum_N"] == pytest.approx(magnitudes, rel=1e-9) and "force" not in region
    magnitudes = sum(r["force_magnitude_sum_N"] for r in summary["regions"].values())
    assert magnitudes == pytest.approx(summary["force_magnitude_sum_N"], rel=1e-9) and magnitudes > 1.1 * size


def test_a_path_s_regions_report_their_resultants_in_the_table_the_summary_and_the_plot(tmp_path):
    from dea_opt.io import cycle

    rows = [(0.0, 300.0, 0.0, -1200.0), (0.5, -200.0, 100.0, -900.0)]
    scenario = socket_path(tmp_path, rows, '[regions]\nsplit = "x"\n[output]\nformats = ["csv", "png", "json"]\n')
    result = invoke("run", scenario, "-o", tmp_path / "out")
    assert result.exit_code == 0, result.stderr
    frames = pd.read_csv(tmp_path / "out" / "frames.csv")
    for _, row in frames.iterrows():
        vectors = {n: np.array([row[f"{n}_force_{c}_N"] for c in "xyz"]) for n in ("medial", "lateral")}
        total = vectors["medial"] + vectors["lateral"]
        np.testing.assert_allclose(total, -np.array([row["Fx_N"], row["Fy_N"], row["Fz_N"]]), rtol=0, atol=1e-6 * 1500)
        for n, v in vectors.items():
            assert row[f"{n}_force_share"] == pytest.approx(v @ total / (total @ total), rel=1e-9)
            assert row[f"{n}_resultant_N"] == pytest.approx(np.linalg.norm(v), rel=1e-9)
            assert row[f"{n}_force_magnitude_sum_N"] > row[f"{n}_resultant_N"]
        assert row["medial_force_share"] + row["lateral_force_share"] == pytest.approx(1.0, rel=1e-9)
        assert "medial_force" not in frames.columns
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["regions"]["medial"]["max_force_share"] == pytest.approx(frames["medial_force_share"].max())
    assert re.search(r"region medial: [\d.]+% of the contact force on average", result.stdout)
    assert (tmp_path / "out" / "cycle.png").is_file()
    # the cycle plot (cycle.png, drawn by another process) draws the same shares, in percent, under
    # a label that says of what: drawn here again from the table
    figure = cycle.cycle_figure(frames)
    panel = next(ax for ax in figure.axes if ax.get_ylabel().startswith("share"))
    assert panel.get_ylabel() == "share of the\ncontact force (%)"
    drawn = {line.get_label(): line.get_ydata() for line in panel.get_lines()}
    np.testing.assert_allclose(drawn["medial"], 100 * frames["medial_force_share"], rtol=1e-12)


def test_a_path_without_a_certified_frame_gives_no_verdict_and_no_shares(tmp_path):
    """Every frame pulls the head out of the socket: no frame is certified, so there is nothing
    to call valid and no share of a force to give."""
    # the check before solving off: it would stop a path whose every frame pulls apart
    extra = '[regions]\nsplit = "x"\n[solve]\ncheck_inputs = false\n'
    scenario = socket_path(tmp_path, [(0.0, 0.0, 0.0, 800.0), (0.5, 0.0, 0.0, 900.0)], extra)
    result = invoke("run", scenario, "-o", tmp_path / "out")
    assert result.exit_code == 1, result.stderr
    text = result.stdout + result.stderr
    assert "validity: not judged: none of the 2 frames has a certified answer" in text
    assert "validity: valid" not in text and "nan" not in text.lower()
    assert "region " not in text and "share" not in text
    manifest = read_manifest(tmp_path / "out")
    assert manifest["status"] == RunStatus.LOAD_NOT_SUPPORTED and manifest["valid"] is None
    frames = pd.read_csv(tmp_path / "out" / "frames.csv")
    assert not frames["success"].any() and frames["lateral_force_share"].isna().all()


def test_run_path_outputs_keeps_nothing_per_frame(tmp_path):
    from dea_opt.run import run_scenario

    scenario = load_scenario(socket_path(tmp_path, [(0.1 * k, 0.0, 0.0, -500.0 - 200.0 * k) for k in range(4)]))
    outcome = run_scenario(scenario, tmp_path / "out")
    assert outcome.exit_code == 0 and outcome.result.solutions is None and outcome.result.pressures is None
    assert outcome.result.frame_files is not None and len(outcome.result.frame_files.files) == 4
    # the table still holds each frame's answer: the resultant equals the applied force (own sum)
    table = outcome.result.table
    applied = np.linalg.norm(table[["Fx_N", "Fy_N", "Fz_N"]].to_numpy(), axis=1)
    assert np.allclose(table["resultant_N"], applied, rtol=1e-6)


# --- 2. the anatomical frame from the scenario ------------------------------------------------------

PLATE = scenario_text(size=(40.0, 10.0), ny=10, point=(5.0, 0.0, 0.0))
ANATOMY = '[output]\nanatomy = {medial = [0.0, 1.0, 0.0], proximal = [0.0, 0.0, 1.0], side = "left"}\n'


def test_the_scenario_anatomy_reaches_the_json_and_the_map(tmp_path):
    (tmp_path / "plate.toml").write_text(PLATE + ANATOMY)
    result = invoke("run", tmp_path / "plate.toml", "-o", tmp_path / "out")
    assert result.exit_code == 0, result.stderr
    summary = json.loads((tmp_path / "out" / "contact.json").read_text())
    springs = pd.read_csv(tmp_path / "out" / "contact.csv", comment="#")
    points, area, pressure = (
        springs[["x_mm", "y_mm", "z_mm"]].to_numpy(),
        springs["area_mm2"].to_numpy(),
        springs["pressure_MPa"],
    )
    centroid = area @ points / area.sum()
    cop = (pressure * area).to_numpy() @ points / (pressure * area).sum()
    # a left limb: anterior x proximal is the right, lateral; so anterior = proximal x medial... = -x here
    medial, proximal = np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])
    anterior = np.cross(proximal, medial)
    got = summary["center_of_pressure_anatomical"]
    expected = (cop - centroid) @ np.array([medial, anterior, proximal]).T
    assert np.allclose([got["medial_mm"], got["anterior_mm"], got["proximal_mm"]], expected, atol=1e-9)
    assert summary["anatomy"]["side"] == "left" and np.allclose(summary["anatomy"]["anterior"], anterior)
    assert (tmp_path / "out" / "contact.png").read_bytes()[:4] == b"\x89PNG"


def test_a_path_summary_carries_the_anatomy(tmp_path):
    scenario = socket_path(
        tmp_path,
        [(0.0, 0.0, 0.0, -500.0), (0.1, 0.0, 0.0, -900.0)],
        '[output]\nanatomy = {medial = [1.0, 0.0, 0.0], proximal = [0.0, 0.0, -1.0], side = "right"}\n',
    )
    assert invoke("run", scenario, "-o", tmp_path / "out").exit_code == 0
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert np.allclose(summary["anatomy"]["anterior"], [0.0, 1.0, 0.0])  # medial x... right limb: +y


@pytest.mark.parametrize(
    "value, words",
    [
        ('{medial = [1.0, 0.0, 0.0], proximal = [0.0, 0.0, 1.0], side = "up"}', "output.anatomy.side must be"),
        (
            '{medial = [0.0, 0.0, 0.0], proximal = [0.0, 0.0, 1.0], side = "right"}',
            "output.anatomy.medial must be a nonzero direction",
        ),
        (
            '{medial = [1.0, 0.0, 0.0], proximal = [1.0, 0.1, 0.0], side = "right"}',
            "output.anatomy.proximal and output.anatomy.medial must be far from parallel",
        ),
        ("{medial = [1.0, 0.0, 0.0], up = [0.0, 0.0, 1.0]}", "output.anatomy: unknown key up"),
        ('{medial = [1.0, "a", 0.0], proximal = [0.0, 0.0, 1.0], side = "right"}', "output.anatomy.medial must be"),
        (
            "{landmarks = {medial = [1.0, 0.0, 0.0], lateral = [-1.0, 0.0, 0.0], proximal = [0.0, 0.0, 9.0]}}",
            "output.anatomy.landmarks: side",
        ),
        ('"right"', "output.anatomy (line 16)"),
    ],
)
def test_a_bad_anatomy_names_its_key(tmp_path, value, words):
    (tmp_path / "plate.toml").write_text(PLATE + f"[output]\nanatomy = {value}\n")
    result = invoke("run", tmp_path / "plate.toml", "-o", tmp_path / "out")
    assert result.exit_code == 2 and result.stderr.startswith("dea-opt: error:")
    assert words in result.stderr and "Traceback" not in result.stderr
    assert not (tmp_path / "out").exists()


def test_the_anatomy_key_is_documented():
    assert "# anatomy = ...  # optional; the anatomical frame" in schema_text()
    assert "[output] anatomy" in GUIDE["scenarios"] and "anatomy = {medial" in GUIDE["scenarios"]
    knee = (KNEE_EXAMPLES / "knee.toml").read_text()
    assert 'anatomy = { medial = [1.0, 0.0, 0.0], proximal = [0.0, 0.0, 1.0], side = "right" }' in knee


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
    from dea_opt._checks.memory import check_memory
    from dea_opt.geometry import hip_meshes

    with pytest.raises(SizeLimitError) as info:
        hip_meshes(step=0.01)
    assert "hip_meshes(step=0.01)" in str(info.value) and info.value.needed > info.value.available
    with pytest.raises(SizeLimitError, match="a request would need about 1e\\+03 PB"):
        check_memory(1e18, "a request", "ask for less")


# --- 5. sweep statuses --------------------------------------------------------------------------


def test_a_sweep_case_outside_validity_is_not_ok(tmp_path):
    (tmp_path / "plate.toml").write_text(PLATE + '[output]\nformats = ["json"]\n')
    args = ["sweep", tmp_path / "plate.toml", "--set", "law.H=5,10", "--scheduler", "synchronous"]
    result = invoke(*args, "-o", tmp_path / "s")
    assert result.exit_code == 3 and "1 case(s) solved outside validity" in result.stderr
    table = pd.read_csv(tmp_path / "s" / "sweep.csv").set_index("law.H_MPa")
    strain = table["peak_pressure_MPa"] / table.index  # the linear law: strain = pressure / H, computed here
    assert strain[5] > 0.3 > strain[10]
    assert table.loc[5, "status"] == "outside_validity" and table.loc[5, "validity_failed"] == "strain"
    assert table.loc[10, "status"] == "ok" and table.loc[5, "exit_code"] == 3
    # a rerun and --retry-failed keep the row: it is a finished computation, not a failure
    again = invoke(*args, "-o", tmp_path / "s", "--retry-failed")
    assert again.exit_code == 3 and "0 case(s) run, 2 already finished" in again.stdout
    # allowed by the scenario: exit 0, the row still says so
    allowed = invoke(*args, "-o", tmp_path / "a", "--set", "solve.allow_outside_validity=true")
    assert allowed.exit_code == 0, allowed.stderr
    table = pd.read_csv(tmp_path / "a" / "sweep.csv").set_index("law.H_MPa")
    assert table.loc[5, "status"] == "outside_validity" and table.loc[5, "exit_code"] == 0


def test_the_guide_documents_the_sweep_statuses():
    from dea_opt.sweep.cases import RETRIED, STATUSES

    assert set(STATUSES) == set(RunStatus) and set(RETRIED) == {s for s in RunStatus if s.exit_code in (1, 2)}
    for status in STATUSES:
        assert f"| `{status}` |" in GUIDE["concepts"]


# --- 7. the demo: validity and compartments ----------------------------------------------------


def test_hip_regions_label_the_dome_and_the_walls():
    from dea_opt.geometry import socket_layer
    from dea_opt.run.demo import hip_regions

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
        assert re.search(rf"region {region}: [\d.]+% of the contact force on average", out)
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
    process = subprocess.Popen(
        _dea_opt("run", scenario, "-o", folder, "-q"), env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE
    )
    try:
        deadline = time.monotonic() + 120
        while not any(TEMPORARY_NAME.match(p.name) for p in folder.rglob("*")) and time.monotonic() < deadline:
            time.sleep(0.01)
        assert process.poll() is None, "the run finished before it could be killed"
        process.send_signal(signal.SIGKILL)
    finally:
        process.communicate(timeout=60)
    assert read_manifest(folder) is None  # nothing was published
    done = subprocess.run(
        _dea_opt("run", scenario, "-o", folder, "-q"), env=env, capture_output=True, text=True, timeout=300, check=False
    )
    assert done.returncode == 0, done.stderr
    assert check_outputs(folder) == [] and not [p for p in folder.rglob("*") if TEMPORARY_NAME.match(p.name)]
    assert len(pd.read_csv(folder / "frames.csv")) == 400


def test_two_runs_into_one_folder_at_once(tmp_path):
    from dea_opt.run.publish import output_run

    scenario = socket_path(tmp_path, [(0.0, 0.0, 0.0, -500.0)])
    with output_run(tmp_path / "out"):  # another run holds the folder
        result = invoke("run", scenario, "-o", tmp_path / "out")
    assert result.exit_code == 2 and "another dea-opt run" in result.stderr
    assert invoke("run", scenario, "-o", tmp_path / "out").exit_code == 0


@pytest.mark.parametrize("cell, got", [("nan", "got 'nan'"), ("inf", "got 'inf'"), ("", "got an empty cell")])
def test_a_load_path_cell_that_is_no_finite_number_is_quoted(tmp_path, cell, got):
    (tmp_path / "path.csv").write_text(f"time,Fx,Fy,Fz\n0,0,0,-500\n0.1,0,0,{cell}\n")
    (tmp_path / "path.toml").write_text(SOCKET + '[load_path]\nfile = "path.csv"\n')
    result = invoke("run", tmp_path / "path.toml", "-o", tmp_path / "out")
    assert result.exit_code == 2
    assert f"path.csv, line 3, column Fz: expected a finite number, {got}" in result.stderr
