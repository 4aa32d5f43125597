"""dea-opt run: validity in every report and in the exit status (0 ok, 1 certificate failed, 2 bad
input, 3 outside validity), the reported reproducers end to end on the real knee, laws from the
registry (a toy law of the test's own through solve, a scenario and the CLI, law kinds in sweeps),
and no raw warning on the terminal."""

from __future__ import annotations

import json
import logging
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import COARSE_SOCKET, KNEE
from typer.testing import CliRunner

import dea_opt as d
from dea_opt.cli import app
from dea_opt.geometry import plate_layer
from dea_opt.laws import LAWS, Law, register_law
from dea_opt.laws.registry import Range
from dea_opt.run.publish import read_manifest
from dea_opt.scenario import parse_scenario, schema_text
from dea_opt.status import RunStatus

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
runner = CliRunner()


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def stderr_lines(result) -> list[str]:
    return [line for line in result.stderr.splitlines() if line.strip()]


# --- exit status and what the outputs say ---------------------------------------------------------


def test_version_option_and_command():
    for args in (["--version"], ["version"]):
        result = invoke(*args)
        assert result.exit_code == 0 and result.stdout.startswith(f"dea-opt {d.__version__}")


def test_a_valid_answer_exits_0_and_reports_every_check(tmp_path):
    result = invoke("run", EXAMPLES / "plate_springs.toml", "-o", tmp_path / "out")
    assert result.exit_code == 0, result.stderr
    summary = json.loads((tmp_path / "out" / "contact.json").read_text())
    checks = summary["validity"]["checks"]
    assert summary["validity"]["valid"] and {"strain", "rotation", "peak_pressure"} <= set(checks)
    # the plate's closed form: peak strain = peak pressure / H, well inside the linear law's 30 %
    assert checks["strain"]["value"] == pytest.approx(summary["peak_pressure_MPa"] / 10.0, rel=1e-9)
    assert checks["strain"]["limit"] == 0.3 and checks["strain"]["status"] == "passed"
    assert "validity: valid" in result.stdout and "strain 0.2" in result.stdout
    manifest = read_manifest(tmp_path / "out")
    assert manifest["status"] == "ok" and manifest["exit_code"] == 0 and manifest["valid"]


def test_outside_validity_exits_3_with_the_reason_unless_allowed(tmp_path):
    # H = 5 MPa: the plate's peak strain is about 2.19 / 5 = 0.44, beyond the linear law's 30 %
    result = invoke("run", EXAMPLES / "plate_springs.toml", "-o", tmp_path / "a", "--set", "law.H=5")
    assert result.exit_code == 3
    summary = json.loads((tmp_path / "a" / "contact.json").read_text())
    assert summary["validity"]["valid"] is False and summary["validity"]["failed"] == ["strain"]
    strain = summary["peak_pressure_MPa"] / 5.0
    assert summary["validity"]["checks"]["strain"]["value"] == pytest.approx(strain, rel=1e-9)
    last = stderr_lines(result)[-1]
    assert last.startswith(f"dea-opt: solved outside validity: strain {strain:.4g} > 0.3")
    assert "use AteshianLaw" in last and len(stderr_lines(result)) == 1  # said once, not twice
    assert read_manifest(tmp_path / "a")["status"] == RunStatus.OUTSIDE_VALIDITY
    result = invoke(
        "run",
        EXAMPLES / "plate_springs.toml",
        "-o",
        tmp_path / "b",
        "--set",
        "law.H=5",
        "--set",
        "solve.allow_outside_validity=true",
    )
    assert result.exit_code == 0
    assert "solved outside validity (allowed by [solve] allow_outside_validity)" in result.stderr
    assert json.loads((tmp_path / "b" / "contact.json").read_text())["validity"]["valid"] is False
    assert read_manifest(tmp_path / "b")["status"] == RunStatus.OUTSIDE_VALIDITY


def test_a_failed_certificate_outranks_validity(tmp_path):
    result = invoke(
        "run",
        EXAMPLES / "plate_springs.toml",
        "-o",
        tmp_path,
        "--set",
        "law.H=5",
        "-m",
        "newton",
        "--set",
        "solve.certificate_tol=1e-30",
    )
    assert result.exit_code == 1 and "no certified answer" in result.stderr
    assert read_manifest(tmp_path)["status"] == RunStatus.CERTIFICATE_FAILED


HIP_PATH = (
    COARSE_SOCKET.replace("H = 10.0", "H = {H}")
    + """\
[load_path]
builtin = "hip_gait"
frames = 11
"""
)


@pytest.mark.parametrize("H, code", [(10.0, 0), (4.0, 3)])
def test_a_load_path_with_any_frame_outside_validity_exits_3(tmp_path, H, code):
    scenario = tmp_path / "hip.toml"
    scenario.write_text(HIP_PATH.format(H=H))
    result = invoke("run", scenario, "-o", tmp_path / "out")
    assert result.exit_code == code, result.stderr
    frames = pd.read_csv(tmp_path / "out" / "frames.csv")
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    # independently of the validity code: the linear law is valid to 30 % compressive strain
    outside = frames.loc[frames["max_compressive_strain"] > 0.3, "frame"].tolist()
    assert summary["validity"]["frames_outside_validity"] == outside
    assert bool(outside) == (code == 3)
    if outside:
        assert f"{len(outside)} of 11 frame(s) outside validity" in stderr_lines(result)[-1]
    # the motion each frame found, per free dof: a column of frames.csv, its range in summary.json
    # and on the terminal; the head sinks along the load, further under the stiffer frames' load
    motion = summary["motion"]
    assert list(motion) == ["body2_ux_mm", "body2_uy_mm", "body2_uz_mm"]
    peak = frames["peak_pressure_MPa"].idxmax()
    for column, m in motion.items():
        assert m["unit"] == "mm"
        assert (m["min"], m["max"], m["at_peak"]) == (
            frames[column].min(),
            frames[column].max(),
            frames[column].iloc[peak],
        )
    assert frames.loc[frames["Fz_N"].abs().idxmax(), "body2_uz_mm"] == frames["body2_uz_mm"].min() < 0
    assert f"body2_uz {motion['body2_uz_mm']['min']:.4g} to {motion['body2_uz_mm']['max']:.4g} mm" in result.stdout


def test_a_load_path_with_a_failed_frame_exits_1(tmp_path):
    scenario = tmp_path / "hip.toml"
    scenario.write_text(HIP_PATH.format(H=4.0))
    result = invoke("run", scenario, "-o", tmp_path / "out", "-m", "newton", "--set", "solve.certificate_tol=1e-30")
    # one complete line for the eleven frames that fail alike, not one cut-off message per frame
    assert result.exit_code == 1 and "11 of 11 frames without a certified answer: every frame (11 of 11)" in (
        " ".join(result.stderr.split())
    )
    assert read_manifest(tmp_path / "out")["status"] == RunStatus.CERTIFICATE_FAILED
    failures = read_manifest(tmp_path / "out")["failures"]  # the frames' own statuses, counted
    assert sum(failures.values()) == 11 and "load_not_supported" not in failures
    # --stop-on-error: the first failed frame ends the run, a named error, nothing published
    result = invoke(
        "run",
        scenario,
        "-o",
        tmp_path / "stopped",
        "-m",
        "newton",
        "--stop-on-error",
        "--set",
        "solve.certificate_tol=1e-30",
    )
    assert result.exit_code == 2 and stderr_lines(result)[-1].startswith("dea-opt: error: frame 0")
    assert read_manifest(tmp_path / "stopped") is None


# --- the reported reproducers on the real knee, through dea-opt run ------------------------------

KNEE_FILES = ("femoral_cartilage.stl", "medial_tibial_cartilage.stl", "lateral_tibial_cartilage.stl")
needs_knee = pytest.mark.skipif(not all((KNEE / f).is_file() for f in KNEE_FILES), reason="no knee meshes")


def knee_scenario(tmp_path, scale=1.0, free='["uz", "ry"]', force=1000.0, H=10.0, check_inputs=True) -> Path:
    """The knee of tests/core/test_knee.py as a scenario: tibial cartilage (a table of medial and lateral
    meshes) under the femur, loaded along -z at the midpoint of the two tibial centroids."""
    import trimesh

    centres = [
        (m.area_faces @ m.triangles_center) / m.area
        for m in (trimesh.load(KNEE / KNEE_FILES[1]), trimesh.load(KNEE / KNEE_FILES[2]))
    ]
    reference = (0.5 * (centres[0] + centres[1]) * scale).tolist()
    path = tmp_path / "knee.toml"
    path.write_text(f"""\
[geometry]
kind = "meshes"
mesh1 = {{medial = "{KNEE / KNEE_FILES[1]}", lateral = "{KNEE / KNEE_FILES[2]}"}}
mesh2 = "{KNEE / KNEE_FILES[0]}"
scale = {scale}
max_gap = {2.0 * scale}
[law]
kind = "linear"
H = {H}
[body2]
reference = {reference}
free = {free}
[load]
force = [0.0, 0.0, {-force}]
[solve]
check_inputs = {str(check_inputs).lower()}
[output]
formats = ["json"]
""")
    return path


@needs_knee
@pytest.mark.parametrize(
    "case, options, failed, words",
    [
        # solved as it is: the check before solving, which stops meshes in metres, turned off
        ("metres", {"scale": 1e-3, "check_inputs": False}, {"extent", "layer_area", "thickness"}, "looks like metres"),
        ("a million newtons", {"force": 1e6}, {"peak_pressure"}, "load's units"),
        ("six free dofs", {"free": '"all"'}, {"rotation", "gap_error"}, "small-rotation kinematics"),
        ("crushed by a linear H = 5", {"H": 5.0, "force": 5000.0}, {"strain"}, "crushed through its whole thickness"),
    ],
)
def test_knee_reproducers_exit_3_with_the_reason(tmp_path, case, options, failed, words):
    result = invoke("run", knee_scenario(tmp_path, **options), "-o", tmp_path / "out", "-q")
    assert result.exit_code == 3, result.stderr
    reason = stderr_lines(result)[-1]
    assert reason.startswith("dea-opt: solved outside validity:") and words in reason
    summary = json.loads((tmp_path / "out" / "contact.json").read_text())
    assert summary["success"] and failed <= set(summary["validity"]["failed"])
    assert set(summary["regions"]) == {"medial", "lateral"}
    if case == "six free dofs":  # the femur rotated about 21 degrees
        assert summary["validity"]["checks"]["rotation"]["value"] > 10.0


@needs_knee
def test_the_physiological_knee_exits_0(tmp_path):
    result = invoke("run", knee_scenario(tmp_path), "-o", tmp_path / "out")
    assert result.exit_code == 0, result.stderr
    summary = json.loads((tmp_path / "out" / "contact.json").read_text())
    assert summary["validity"]["valid"] and 1.0 < summary["peak_pressure_MPa"] < 20.0
    regions = summary["regions"]
    force = np.array(summary["contact_force_N"])
    size = float(np.linalg.norm(force))
    vectors = {n: np.array(regions[n]["force_vector_N"]) for n in ("medial", "lateral")}
    np.testing.assert_allclose(vectors["medial"] + vectors["lateral"], force, rtol=0, atol=1e-9 * size)
    assert regions["medial"]["share"] + regions["lateral"]["share"] == pytest.approx(1.0, rel=1e-9)
    assert all(regions[n]["share"] > 0.0 for n in ("medial", "lateral"))
    for n in ("medial", "lateral"):  # the share is the region's resultant along the contact force
        assert regions[n]["share"] == pytest.approx(vectors[n] @ force / size**2, rel=1e-9)
        assert regions[n]["resultant_N"] == pytest.approx(np.linalg.norm(vectors[n]), rel=1e-12)
    # the springs' force magnitudes add up to more than the contact force: kept, named for what they are
    magnitudes = regions["medial"]["force_magnitude_sum_N"] + regions["lateral"]["force_magnitude_sum_N"]
    assert magnitudes == pytest.approx(summary["force_magnitude_sum_N"], rel=1e-9) and magnitudes > size
    # the terminal: each region's part of the contact force, in N, and the parts add up to it
    parts = {}
    for line in result.stdout.splitlines():
        match = re.match(
            r"region (\w+): ([\d.]+)% of the contact force \(([\d.]+) N of ([\d.]+) N along it;", line.strip()
        )
        if match:
            parts[match[1]] = float(match[3])
            assert float(match[4]) == pytest.approx(size, rel=1e-3)
    assert set(parts) == {"medial", "lateral"}
    assert parts["medial"] + parts["lateral"] == pytest.approx(size, rel=2e-3)


# --- laws from the registry ---------------------------------------------------------------------


@dataclass(frozen=True)
class ToyLaw(Law):
    """A stiffening toy: ``sigma = k eps + c eps^3``, energy ``k eps^2 / 2 + c eps^4 / 4``."""

    k: float
    c: float = 0.0
    ranges = {
        "k": Range(0.0, None, "MPa", "linear stiffness", low_open=True),
        "c": Range(0.0, None, "MPa", "cubic stiffness"),
    }

    def stress_expr(self, eps, xp):
        return self.k * eps + self.c * eps**3

    def tangent_expr(self, eps, xp):
        return self.k + 3.0 * self.c * eps**2

    def energy_expr(self, eps, xp):
        return 0.5 * self.k * eps**2 + 0.25 * self.c * eps**4


@pytest.fixture()
def toy():
    register_law(ToyLaw, name="toy")
    yield LAWS["toy"]
    LAWS.unregister("toy")


def test_the_registry_reads_each_law_from_its_class():
    assert list(LAWS) == ["linear", "ateshian", "cubic", "polynomial", "blankevoort"]
    assert LAWS["ateshian"].cls is d.AteshianLaw
    assert [p.name for p in LAWS["polynomial"].parameters] == ["H", "beta", "order"]
    order = LAWS["polynomial"].parameter("order")
    assert order.type is int and order.default == 5 and not order.required
    assert LAWS.kind_of(d.CubicLaw(1.0, 0.1)) == "cubic"


def test_describe_works_for_a_law_without_H(toy):
    law = ToyLaw(3.0, 0.5)
    assert law.describe() == "toylaw(k=3, c=0.5)"
    assert [(p.name, p.required) for p in toy.parameters] == [("k", True), ("c", False)]


PLATE_TOY = """\
[geometry]
kind = "plate"
nx = 40
ny = 4
[law]
kind = "toy"
k = 10.0
c = 50.0
[body2]
free = ["uz"]
[load]
force = [0.0, 0.0, -2000.0]
"""


def toy_strain(pressure, k, c):
    """The compressive strain of the toy law at ``pressure``: the real root of k e + c e^3 = p."""
    roots = np.roots([c, 0.0, k, -pressure])
    return float(roots[np.abs(roots.imag) < 1e-12].real[0])


@pytest.mark.parametrize("method", ["newton", "nlp"])
def test_a_toy_law_through_solve(toy, method):
    problem = d.ContactProblem(
        plate_layer(40.0, 10.0, 40, 4, 2.0), ToyLaw(10.0, 50.0), force=(0.0, 0.0, -2000.0), free=("uz",)
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        solution = d.solve(problem, method)
    assert solution.success
    # uniform contact: p = F / A and the strain is the toy law's own root at that pressure
    assert np.allclose(solution.pressure, 5.0, rtol=1e-8)
    assert np.allclose(solution.strain, -toy_strain(5.0, 10.0, 50.0), rtol=1e-8)
    assert -solution.spring_force.sum() == pytest.approx(2000.0, rel=1e-9)  # the test's own sum


def test_a_toy_law_through_a_scenario_the_schema_and_the_cli(toy, tmp_path):
    scenario = parse_scenario(PLATE_TOY)
    assert scenario.law.kind == "toy" and scenario.law.parameters == {"k": 10.0, "c": 50.0}
    assert 'kind = "toy"' in schema_text() and "k = ...  # required; linear stiffness (MPa)" in schema_text()
    (tmp_path / "toy.toml").write_text(PLATE_TOY)
    result = invoke("run", tmp_path / "toy.toml", "-o", tmp_path / "out", "--set", "law.c=0.0")
    assert result.exit_code in (0, 3), result.stderr
    summary = json.loads((tmp_path / "out" / "contact.json").read_text())
    assert summary["law"] == "toylaw(k=10, c=0)" and summary["peak_pressure_MPa"] == pytest.approx(5.0, rel=1e-9)
    assert summary["validity"]["checks"]["strain"]["value"] == pytest.approx(0.5, rel=1e-9)  # 5 MPa / 10 MPa
    bad = invoke("run", tmp_path / "toy.toml", "-o", tmp_path / "bad", "--set", "law.k=-1")
    assert bad.exit_code == 2 and "law.k" in bad.stderr and "must be > 0" in bad.stderr


def test_unregistered_kinds_and_bad_parameters_name_the_key():
    with pytest.raises(d.ScenarioError, match="law.kind.*'linear', 'ateshian'"):
        parse_scenario(PLATE_TOY)
    text = PLATE_TOY.replace(
        'kind = "toy"\nk = 10.0\nc = 50.0', 'kind = "polynomial"\nH = 1.0\nbeta = 0.1\norder = 2.5'
    )
    with pytest.raises(d.ScenarioError, match="law.order"):
        parse_scenario(text)
    with pytest.raises(d.ScenarioError, match=r"law.H \(line 7\): must be <= 1e\+30, got 1e\+308"):
        parse_scenario(text.replace("H = 1.0", "H = 1e308").replace("order = 2.5", "order = 3"))


def test_law_kinds_in_a_sweep_drop_what_a_kind_does_not_take(tmp_path):
    (tmp_path / "plate.toml").write_text(
        PLATE_TOY.replace('kind = "toy"\nk = 10.0\nc = 50.0', 'kind = "ateshian"\nH = 10.0\nbeta = 0.3')
    )
    result = invoke(
        "sweep",
        tmp_path / "plate.toml",
        "--set",
        "law.kind=linear,ateshian",
        "--set",
        "law.beta=0.2,0.4",
        "--scheduler",
        "synchronous",
        "-o",
        tmp_path / "sweep",
    )
    # the linear cases carry 5 MPa on H = 10 MPa: strain 0.5, past the linear law's 30 %
    assert result.exit_code == 3, result.stderr
    table = pd.read_csv(tmp_path / "sweep" / "sweep.csv")
    linear = table[table["law.kind"] == "linear"]
    assert len(table) == 4 and (table.loc[table["law.kind"] == "ateshian", "status"] == "ok").all()
    assert (linear["status"] == "outside_validity").all() and (linear["validity_failed"] == "strain").all()
    assert linear["warnings"].str.contains("law kind 'linear' takes no beta: dropped law.beta").all()
    assert np.allclose(linear["peak_pressure_MPa"], 5.0, rtol=1e-9)  # 2000 N over 400 mm^2
    assert table[table["law.kind"] == "ateshian"]["warnings"].isna().all()
    # a key no law takes is a misspelling, not a parameter to drop
    with pytest.raises(d.ScenarioError, match="law.betta"):
        parse_scenario(
            PLATE_TOY.replace('kind = "toy"\nk = 10.0\nc = 50.0', "H = 1.0"),
            overrides={"law.kind": "linear", "law.betta": 0.3},
        )
    # --set law=linear is law.kind=linear
    ateshian = parse_scenario(
        PLATE_TOY.replace('kind = "toy"\nk = 10.0\nc = 50.0', 'kind = "ateshian"\nH = 1.0\nbeta = 0.3'),
        overrides={"law": "linear"},
    )
    assert ateshian.law.kind == "linear" and ateshian.law.parameters == {"H": 1.0}
    assert ateshian.notes == ["law kind 'linear' takes no beta: dropped law.beta for this case"]


# --- nothing raw reaches the terminal -------------------------------------------------------------


def test_library_warnings_go_to_the_log_and_dea_opts_own_to_one_line(tmp_path, monkeypatch):
    import dea_opt.scenario as scenario_package
    from dea_opt.mesh.springs import _warn_dropped

    original = scenario_package.build_problem_cast

    def noisy(scenario, *args, **kwargs):
        warnings.warn("a library's deprecation", DeprecationWarning, stacklevel=2)  # raised here: not dea-opt's
        logging.getLogger("cvxpy").warning("a solver's chatter")
        _warn_dropped(np.array([1.0, np.nan]), np.ones(2), np.array([True, False]), None, 1.0)  # dea-opt's own
        return original(scenario, *args, **kwargs)

    monkeypatch.setattr(scenario_package, "build_problem_cast", noisy)
    result = invoke("run", EXAMPLES / "plate_springs.toml", "-o", tmp_path / "out", "-q")
    assert result.exit_code == 0, result.stderr
    lines = stderr_lines(result)
    assert len(lines) == 1 and lines[0].startswith("dea-opt: warning: thickness1 could not be measured at 1 springs")
    assert "Deprecation" not in result.stderr and "chatter" not in result.stderr and "Traceback" not in result.stderr
    log = (tmp_path / "out" / "dea-opt.log").read_text()
    assert "DeprecationWarning" in log and "a library's deprecation" in log and "a solver's chatter" in log
    assert "dea-opt.log" in read_manifest(tmp_path / "out")["files"]


def test_an_unexpected_failure_is_one_paragraph_with_the_traceback_in_a_file(tmp_path, monkeypatch):
    import dea_opt.scenario as scenario_package

    def broken(*args, **kwargs):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(scenario_package, "build_problem_cast", broken)
    result = invoke("run", EXAMPLES / "plate_springs.toml", "-o", tmp_path / "out")
    assert result.exit_code == 2 and "Traceback" not in result.stderr
    text = stderr_lines(result)
    assert len(text) == 1 and "unexpected internal error (ZeroDivisionError: a bug)" in text[0]
    crash = Path(text[0].rsplit("the traceback is in ", 1)[1])
    assert "ZeroDivisionError" in crash.read_text() and "Traceback" in crash.read_text()
    crash.unlink()


def test_the_guide_law_example_registers_a_law_a_scenario_can_use():
    import re

    page = (Path(__file__).resolve().parents[2] / "docs" / "guide" / "laws.md").read_text()
    section = page.split("`dea_opt.laws.LAWS` is the registry of law kinds", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    try:
        namespace: dict = {}
        exec(compile(code, "laws.md", "exec"), namespace)
        assert LAWS["stiffening"].cls is namespace["StiffeningLaw"]
        scenario = parse_scenario(PLATE_TOY.replace('kind = "toy"', 'kind = "stiffening"'))
        from dea_opt.scenario import build_law

        law = build_law(scenario.law)
        assert law.describe() == "stiffening(k=10, c=50)"
        assert law.stress(np.array([-0.5]))[0] == pytest.approx(-10.0 * 0.5 - 50.0 * 0.125)
    finally:
        LAWS.unregister("stiffening")


def test_a_library_warning_outside_a_run_is_one_line(tmp_path, monkeypatch):
    import dea_opt.scenario as scenario_package

    original = scenario_package.load_scenario

    def noisy(*args, **kwargs):  # before the run starts: no output folder to log into yet
        warnings.warn("a library's future change", FutureWarning, stacklevel=1)
        return original(*args, **kwargs)

    monkeypatch.setattr(scenario_package, "load_scenario", noisy)
    result = invoke("run", EXAMPLES / "plate_springs.toml", "-o", tmp_path / "out", "-q")
    assert result.exit_code == 0
    import re

    lines = stderr_lines(result)
    assert len(lines) == 1
    expected = r"dea-opt: warning: from a library: FutureWarning \(test_run.py:\d+\): a library's future change"
    assert re.fullmatch(expected, lines[0])
