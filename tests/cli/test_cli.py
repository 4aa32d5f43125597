"""The dea-opt command: demo, run, schema, version, help, and one-paragraph errors with exit code 2."""

from __future__ import annotations

import json
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import invoke, one_paragraph_error, scenario_text
from typer.testing import CliRunner

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
runner = CliRunner()


@pytest.mark.parametrize("command", [[], ["run"], ["compare"], ["sweep"], ["demo"], ["schema"], ["version"]])
def test_help(command):
    result = invoke(*command, "--help")
    assert result.exit_code == 0 and "Usage" in result.stdout


def test_version():
    result = invoke("version")
    assert result.exit_code == 0 and result.stdout.startswith("dea-opt ")


def test_schema():
    result = invoke("schema")
    assert result.exit_code == 0 and "[load_path]" in result.stdout and "exposure_threshold" in result.stdout
    schema = json.loads(invoke("schema", "--json").stdout)
    assert "geometry" in schema["properties"]


# --- acceptance 1: the demo -------------------------------------------------------------


@pytest.mark.slow
def test_demo_writes_table_series_plots_and_exposure_map(tmp_path):
    result = invoke("demo", "--coarse", "--frames", "6", "-o", tmp_path)
    assert result.exit_code == 0, result.stderr
    assert "ateshian" in result.stdout and "newton" in result.stdout and "nlp" in result.stdout
    comparison = pd.read_csv(tmp_path / "comparison.csv")
    assert len(comparison) == 5 and comparison["success"].all()
    linear = comparison[comparison["law"].str.startswith("linear")]
    assert np.allclose(linear["peak_pressure_MPa"], linear["peak_pressure_MPa"].iloc[0], rtol=1e-6)
    frames = pd.read_csv(tmp_path / "frames.csv")
    assert len(frames) == 6 and frames["success"].all()
    datasets = ET.parse(tmp_path / "series.pvd").getroot().find("Collection").findall("DataSet")
    assert len(datasets) == 6 and all((tmp_path / x.get("file")).is_file() for x in datasets)
    for picture in ("cycle.png", "exposure.png"):
        assert (tmp_path / picture).read_bytes()[:4] == b"\x89PNG"
    assert (tmp_path / "exposure.vtu").is_file()
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["frames"] == 6 and len(summary["comparison"]) == 5 and summary["success"]


# --- acceptance 2: run ------------------------------------------------------------------


def test_run_plate_springs_reproduces_the_closed_form(tmp_path):
    result = invoke("run", EXAMPLES / "plate_springs.toml", "-o", tmp_path)
    assert result.exit_code == 0, result.stderr
    summary = json.loads((tmp_path / "contact.json").read_text())
    P, B, L, e = 500.0, 40.0, 10.0, 5.0
    closed = P / (B * L) * (1 + 6 * e / B)
    assert summary["peak_pressure_MPa"] == pytest.approx(closed, rel=0.005)
    assert summary["n_springs"] == 4000 and summary["success"]
    for name in ("contact.vtu", "contact.csv", "contact.png"):
        assert (tmp_path / name).is_file()


def test_run_on_a_mesh_scenario_writes_every_output(tmp_path):
    import meshio

    result = invoke("run", EXAMPLES / "hip_meshes.toml", "-o", tmp_path)
    assert result.exit_code == 0, result.stderr
    mesh = meshio.read(tmp_path / "contact.vtu")
    for field in ("pressure", "strain", "gap", "thickness", "in_contact", "spring_force"):
        assert field in mesh.cell_data
    assert mesh.cells[0].type == "triangle"
    springs = pd.read_csv(tmp_path / "contact.csv", comment="#")
    assert len(springs) == len(mesh.cell_data["pressure"][0])
    summary = json.loads((tmp_path / "contact.json").read_text())
    assert summary["success"] and summary["peak_pressure_MPa"] > 0
    assert np.allclose(summary["contact_force_N"], [-820.85, 0.0, 2255.26], rtol=1e-6)
    assert (tmp_path / "contact.png").read_bytes()[:4] == b"\x89PNG"


def test_run_a_load_path_with_overrides(tmp_path):
    scenario = tmp_path / "scenarios" / "hip.toml"
    scenario.parent.mkdir()
    scenario.write_text((EXAMPLES / "hip_gait.toml").read_text())
    result = invoke(
        "run",
        scenario,
        "--set",
        "load_path.frames=4",
        "--set",
        "geometry.n_rings=8",
        "--set",
        "geometry.n_sectors=24",
        "--set",
        'output.formats=["csv"]',
        "-m",
        "qp",
        "--set",
        "solve.tol=1e-12",
    )
    assert result.exit_code == 0, result.stderr
    out = tmp_path / "output" / "hip_gait"  # [output].directory is relative to the scenario
    frames = pd.read_csv(out / "frames.csv")
    assert len(frames) == 4 and frames["success"].all()
    assert not (out / "series.pvd").exists()


def test_uncertified_answer_exits_1_with_outputs_written(tmp_path):
    result = invoke(
        "run", EXAMPLES / "plate_springs.toml", "-o", tmp_path, "--set", "solve.certificate_tol=1e-30", "-m", "newton"
    )
    assert result.exit_code == 1
    assert "no certified answer" in result.stderr
    assert (tmp_path / "contact.json").is_file()


# --- acceptance 5: bad input ------------------------------------------------------------

PLATE = scenario_text(nx=20, ny=2, law=None)
PATH = PLATE.replace("[load]\nforce = [0.0, 0.0, -500.0]\n", '[load_path]\nfile = "loads.csv"\n')


@pytest.mark.parametrize(
    "name, toml, loads, extra, expected",
    [
        ("malformed TOML", PLATE.replace("H = 10.0", "H = 10.0 ]"), None, [], "line 6"),
        ("unknown key", PLATE.replace("H = 10.0", "H = 10.0\nmodulus = 3"), None, [], "law.modulus"),
        ("string for a number", PLATE.replace("nx = 20", 'nx = "20"'), None, [], "geometry.nx"),
        (
            "missing mesh",
            PLATE.replace(
                'kind = "plate"\nnx = 20\nny = 2', 'kind = "meshes"\nmesh1 = "femur.stl"\nmesh2 = "tibia.stl"'
            ),
            None,
            [],
            "femur.stl",
        ),
        ("load CSV without Fz", PATH, "time,Fx,Fy\n0,0,0\n", [], "missing column Fz"),
        ("non-numeric cell", PATH, "time,Fx,Fy,Fz\n0,0,0,-1\n1,0,zero,-1\n", [], "line 3, column Fy"),
        ("empty load path", PATH, "time,Fx,Fy,Fz\n", [], "no rows"),
        ("empty load file", PATH, "", [], "is empty"),
        ("unknown method", PLATE, None, ["--method", "simplex"], "must be one of auto, newton, qp, nlp"),
        ("unknown method in the file", PLATE + '[solve]\nmethod = "simplex"\n', None, [], "solve.method"),
        ("unknown solver", PLATE + '[solve]\nsolver = "NOSUCH"\n', None, ["--method", "qp"], "NOSUCH"),
        ("missing scenario", None, None, [], "scenario file not found"),
        ("bad --set", PLATE, None, ["--set", "law.H"], "--set must look like"),
        ("load pulling apart", PLATE.replace("-500.0]", "500.0]"), None, [], "cannot carry"),
    ],
)
def test_bad_input_exits_2_with_one_paragraph(tmp_path, name, toml, loads, extra, expected):
    scenario = tmp_path / "case.toml"
    if toml is not None:
        scenario.write_text(toml)
    if loads is not None:
        (tmp_path / "loads.csv").write_text(loads)
    text = one_paragraph_error(invoke("run", scenario, "-o", tmp_path / "out", *extra))
    assert expected in text


def test_unknown_solver_in_compare(tmp_path):
    scenario = tmp_path / "case.toml"
    scenario.write_text(PLATE)
    out = tmp_path / "out"
    text = one_paragraph_error(invoke("compare", scenario, "--solvers", "CLARABEL,NOSUCH", "-o", out))
    assert "NOSUCH is not available" in text and "installed QP solvers" in text
    text = one_paragraph_error(invoke("compare", scenario, "--methods", "newton,simplex", "-o", out))
    assert "simplex" in text
    text = one_paragraph_error(invoke("compare", scenario, "--accuracy", "extreme", "-o", out))
    assert "extreme" in text
    # the scenario's own folder holds case.toml: compare refuses to write there
    text = one_paragraph_error(invoke("compare", scenario, "-o", tmp_path))
    assert str(tmp_path) in text and "case.toml" in text and "--force" in text


def test_console_script_reports_errors_without_traceback(tmp_path):
    scenario = tmp_path / "case.toml"
    scenario.write_text(PLATE.replace("H = 10.0", 'H = "ten"'))
    script = Path(sys.executable).with_name("dea-opt")
    command = [str(script)] if script.exists() else [sys.executable, "-m", "dea_opt.cli"]
    done = subprocess.run(command + ["run", str(scenario)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert done.stderr.startswith("dea-opt: error: ") and "law.H (line 6)" in done.stderr
    assert "Traceback" not in done.stderr and done.stderr.count("\n") == 1


# --- every raw traceback of the scenario and the CLI is a named error ---------------


def _springs_npz(tmp_path, kind):
    import numpy as np

    columns = {c: np.ones(4) for c in ("x", "y", "z", "nx", "ny", "area", "thickness")}
    columns["nz"] = np.ones(4)
    if kind == "object":
        columns["x"] = np.array([[0.0, 1.0], [2.0]], dtype=object)  # ragged lists become objects
    else:
        columns["y"] = np.ones(3)  # arrays of different lengths
    np.savez(tmp_path / "springs.npz", **columns)
    return PLATE.replace('kind = "plate"\nnx = 20\nny = 2', 'kind = "springs"\nfile = "springs.npz"')


@pytest.mark.parametrize(
    "name, expected",
    [
        ("non-UTF-8 TOML", "is not UTF-8 text (TOML files are UTF-8): byte 0xe9 at line 2"),
        ("TOML nested past Python's recursion limit", "nests tables or arrays too deeply"),
        ("TOML nested deeper than a scenario", "nests tables or arrays more than 16 levels deep"),
        ("law.H = 1e308", "law.H (line 6): must be <= 1e+30, got 1e+308"),
        ("NPZ springs with object arrays", "array 'x' holds Python objects"),
        ("NPZ springs with ragged arrays", "array 'y' has 3 values, but 'x' has 4"),
        ("a generator parameter of the wrong type", "geometry.parameters.step of hip_meshes must be a number"),
        ("a mesh path with a NUL byte", "geometry.mesh1 (line 3): a path cannot contain a NUL byte"),
        ("an output folder with a NUL byte", "output.directory (line 12): a path cannot contain a NUL byte"),
    ],
)
def test_raw_tracebacks_of_issue_10_are_named_errors(tmp_path, name, expected):
    scenario = tmp_path / "case.toml"
    if name == "non-UTF-8 TOML":
        scenario.write_bytes(PLATE.encode().replace(b"kind", b"# caf\xe9 (Latin-1)\nkind", 1))
    elif name.startswith("TOML nested"):
        depth = 100_000 if "recursion" in name else 40
        scenario.write_text(PLATE + "[solve]\nsolvers = " + "[" * depth + "]" * depth + "\n")
    elif name == "law.H = 1e308":
        scenario.write_text(PLATE.replace("H = 10.0", "H = 1e308"))
    elif name.startswith("NPZ"):
        scenario.write_text(_springs_npz(tmp_path, "object" if "object" in name else "ragged"))
    elif name.startswith("a generator"):
        scenario.write_text(
            PLATE.replace(
                'kind = "plate"\nnx = 20\nny = 2',
                'kind = "generator"\nfunction = "hip_meshes"\nparameters = {step = "3"}',
            )
        )
    elif name.startswith("a mesh path"):
        scenario.write_text(
            PLATE.replace('kind = "plate"\nnx = 20\nny = 2', 'kind = "meshes"\nmesh1 = "a\\u0000.stl"\nmesh2 = "b.stl"')
        )
    else:
        scenario.write_text(PLATE + '[output]\ndirectory = "out\\u0000put"\n')
    text = one_paragraph_error(
        invoke("run", scenario) if "output folder" in name else invoke("run", scenario, "-o", tmp_path / "out")
    )
    assert expected in text


def test_the_api_refuses_a_scenario_path_with_a_nul_byte():
    from dea_opt.scenario import ScenarioError, load_scenario

    with pytest.raises(ScenarioError, match="NUL byte"):
        load_scenario("case\0.toml")


def test_run_refuses_a_folder_of_someone_elses_and_force_overrides(tmp_path):
    folder = tmp_path / "home"
    folder.mkdir()
    (folder / "contact.csv").write_text("mine")
    text = one_paragraph_error(invoke("run", EXAMPLES / "plate_springs.toml", "-o", folder))
    assert f"the output folder {folder} holds files dea-opt did not write (contact.csv)" in text and "--force" in text
    assert (folder / "contact.csv").read_text() == "mine"
    result = invoke("run", EXAMPLES / "plate_springs.toml", "-o", folder, "--force", "-q")
    assert result.exit_code == 0 and (folder / "manifest.json").is_file()
    # now the folder holds a dea-opt run: a rerun needs no --force
    assert invoke("run", EXAMPLES / "plate_springs.toml", "-o", folder, "-q").exit_code == 0
