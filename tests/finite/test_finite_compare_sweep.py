"""Finite kinematics in compare, sweeps, ``--set`` and calibrate: the names that stand for the
finite formulations, methods that do not solve the kinematics, errors that name the key and
where it came from, sweeps over the kinematics, and reports of a zero load.

Most tests use a coarse generated knee (``knee_meshes``: a second or two a solve, IPOPT's
included); the real knee of ``../shared/data/knee`` reproduces the reports and skips without it.
"""

from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest
from conftest import COARSE_KNEE_SCENARIO, KNEE, real_knee_scenario
from typer.testing import CliRunner

import dea_opt as d
from dea_opt import formulations
from dea_opt.cli import app
from dea_opt.scenario import build_problem, parse_scenario
from dea_opt.study import _difference, run_study, summarize

runner = CliRunner()

#: The generated knee, coarse, solved with finite kinematics (labelled medial and lateral).
FINITE = COARSE_KNEE_SCENARIO


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def one_line(result) -> str:
    return " ".join(result.output.split())


@pytest.fixture
def knee(tmp_path):
    """The real knee with finite kinematics and a varus-valgus tilt free (the defect reports' scenario)."""
    if not all((KNEE / n).is_file() for n in ("femoral_cartilage.stl", "medial_tibial_cartilage.stl")):
        pytest.skip(f"the knee meshes are not in {KNEE}")
    path = tmp_path / "knee.toml"
    path.write_text(real_knee_scenario(["uz", "rx", "ry"]))
    return path


# --- A. compare: newton and nlp stand for the finite formulations, qp is said to be small only ----------


def test_compare_runs_newton_and_nlp_as_the_finite_formulations(finite, tmp_path):
    for methods, run in (("newton", "finite"), ("nlp", "finite_nlp")):
        result = invoke("compare", finite, "--methods", methods, "-o", tmp_path / methods)
        assert result.exit_code == 0, result.output
        table = pd.read_csv(tmp_path / methods / "compare.csv")
        assert list(table["method"]) == [run] and table["success"].all(), table
        assert f"{methods} stands for {run} with finite kinematics" in result.output
    # from the scenario's [solve].methods, newton and finite named together are one row
    result = invoke("compare", finite, "--set", 'solve.methods=["newton", "finite"]', "-o", tmp_path / "set")
    assert result.exit_code == 0, result.output
    assert list(pd.read_csv(tmp_path / "set" / "compare.csv")["method"]) == ["finite"]


def test_compare_says_qp_is_a_small_kinematics_method(finite, tmp_path):
    result = invoke("compare", finite, "--methods", "qp,newton", "-o", tmp_path / "both")
    assert result.exit_code == 0, result.output
    assert list(pd.read_csv(tmp_path / "both" / "compare.csv")["method"]) == ["finite"]
    assert "(skipped: qp is a small-kinematics method and this problem has kinematics='finite'" in result.output
    # nothing left to run: exit 2, naming where the methods came from; never an internal error
    for args, named in ((("--methods", "qp"), "--methods"), (("--set", 'solve.methods=["qp"]'), "solve.methods")):
        result = invoke("compare", finite, *args, "-o", tmp_path / named.strip("-"))
        assert result.exit_code == 2, result.output
        text = one_line(result)
        assert f"no method in {named} solves this problem: qp is a small-kinematics method" in text
        assert "'newton' and 'nlp', which stand for 'finite' and 'finite_nlp'" in text
        assert "internal error" not in text and "Traceback" not in text


def test_the_study_names_what_it_ran_and_summarizes_failed_and_empty_tables(finite):
    problem = build_problem(parse_scenario(FINITE))
    with pytest.raises(d.InputError, match="no method in methods solves this problem"):
        run_study(problem, methods=["qp"])
    with pytest.raises(d.InputError, match="--methods must be taken from"):
        run_study(problem, methods=["simplex"], what="--methods")
    study = run_study(problem, methods=["newton"])
    assert list(study.table["method"]) == ["finite"] and study.notes == [
        "newton stands for finite with finite kinematics"
    ]
    assert study.summary["success_rate_percent"].tolist() == [100.0]
    # an empty table and a table of failures only (rows without residuals) summarize
    empty = summarize(pd.DataFrame())
    assert len(empty) == 0 and {"method", "success_rate_percent", "relative_time"} <= set(empty.columns)
    failed = pd.DataFrame(
        [
            {"accuracy": "default", "method": m, "solver": "-", "success": False, "total_time_s": 0.1}
            for m in ("finite", "finite_nlp")
        ]
    )
    summary = summarize(failed)
    assert summary["success_rate_percent"].tolist() == [0.0, 0.0] and summary["worst_residual"].isna().all()


def test_pressures_of_answers_on_different_springs_are_matched_by_face():
    """Finite answers re-cast at their own pose may hold different springs: matched by source face,
    a spring of one answer only counting with its whole pressure."""

    def answer(faces, pressure, u):
        layer = SimpleNamespace(source_face=np.array(faces))
        pressure = np.array(pressure, dtype=float)
        return SimpleNamespace(
            pressure=pressure, peak_pressure=pressure.max(), u=np.array(u, float), problem=SimpleNamespace(layer=layer)
        )

    reference = answer([1, 2, 3], [1.0, 2.0, 4.0], [0.0, 1.0])
    same = answer([1, 2, 3], [1.0, 2.0, 3.0], [0.0, 1.0])
    moved = answer([2, 3, 7], [2.0, 4.0, 0.5], [0.0, 1.0])
    assert _difference(same, reference) == (0.25, 0.0)
    assert _difference(moved, reference) == (0.25, 0.0)  # face 1 (1 MPa) lost, face 7 (0.5) gained: 1/4


def test_real_knee_compare_newton_and_qp(knee, tmp_path):
    result = invoke("compare", knee, "--methods", "newton", "-o", tmp_path / "newton")
    assert result.exit_code == 0, result.output
    table = pd.read_csv(tmp_path / "newton" / "compare.csv")
    assert list(table["method"]) == ["finite"] and table["success"].all()
    result = invoke("compare", knee, "--methods", "qp", "-o", tmp_path / "qp")
    assert result.exit_code == 2 and "qp is a small-kinematics method" in one_line(result)
    assert "internal error" not in result.output


# --- B. where a value came from, and sweeps over the kinematics ------------------------------------------


def error_of(text, **overrides) -> str:
    with pytest.raises(d.ScenarioError) as info:
        parse_scenario(text, name="s.toml", overrides=overrides)
    return " ".join(str(info.value).split())


def test_errors_say_whether_a_value_came_from_the_file_or_from_set():
    small = FINITE.replace('kinematics = "finite"', 'kinematics = "small"')
    said = error_of(FINITE, **{"solve.kinematics": "small", "solve.max_recasts": 3})
    assert "solve.max_recasts (from --set): max_recasts = 3" in said and "line" not in said
    assert 'solve.kinematics is "small" (from --set)' in said
    said = error_of(small, **{"solve.max_recasts": 3})
    assert "solve.max_recasts (from --set)" in said and 'solve.kinematics is "small" (line 15)' in said
    said = error_of(small.replace('kinematics = "small"', 'kinematics = "small"\nmax_recasts = 4'))
    assert "solve.max_recasts (line 16)" in said and 'solve.kinematics is "small" (line 15)' in said
    # an error of a whole table (two equal region names) says which of its keys came from --set
    regions = FINITE + '[regions]\nsplit = "x"\n'
    said = error_of(regions, **{"regions.names": ["a", "a"]})
    assert "regions (line 18, with --set regions.names): names must be two different" in said


def test_run_with_both_set_values_is_refused_naming_each_origin(finite, tmp_path):
    result = invoke(
        "run", finite, "--set", "solve.kinematics=small", "--set", "solve.max_recasts=3", "-o", tmp_path / "out"
    )
    assert result.exit_code == 2
    text = one_line(result)
    assert "solve.max_recasts (from --set)" in text and 'solve.kinematics is "small" (from --set)' in text
    assert "(line" not in text


def test_a_sweep_over_the_kinematics_drops_max_recasts_from_its_small_cases(finite, tmp_path):
    result = invoke(
        "sweep",
        finite,
        "--set",
        "solve.kinematics=small,finite",
        "--set",
        "solve.max_recasts=3,10",
        "--scheduler",
        "synchronous",
        "-o",
        tmp_path / "sweep",
    )
    assert result.exit_code == 0, result.output
    table = pd.read_csv(tmp_path / "sweep" / "sweep.csv")
    assert len(table) == 4 and (table["status"] == "ok").all(), table
    small = table[table["solve.kinematics"] == "small"]
    assert small["warnings"].str.contains("kinematics 'small' takes no max_recasts: dropped solve.max_recasts").all()
    assert table.loc[table["solve.kinematics"] == "finite", "warnings"].isna().all()


# --- C. messages that name the field ------------------------------------------------------------------------


def test_a_method_that_does_not_solve_the_kinematics_names_both_keys(finite, tmp_path):
    result = invoke("run", finite, "--set", "solve.method=qp", "-o", tmp_path / "qp")
    assert result.exit_code == 2
    text = one_line(result)
    assert "solve.method = 'qp' (from --set) is a small-kinematics method" in text
    assert 'solve.kinematics = "finite" (line 15)' in text
    assert "'newton' and 'nlp', which stand for 'finite' and 'finite_nlp'" in text
    assert "which it does not solve" not in text
    result = invoke("run", finite, "--method", "qp", "-o", tmp_path / "qp")
    assert result.exit_code == 2 and "--method 'qp' is a small-kinematics method" in one_line(result)
    small = FINITE.replace('kinematics = "finite"', 'kinematics = "small"')
    (tmp_path / "small.toml").write_text(small)
    result = invoke("run", tmp_path / "small.toml", "--set", "solve.method=finite", "-o", tmp_path / "f")
    assert result.exit_code == 2 and "solve.method = 'finite' (from --set) is a finite-kinematics method" in one_line(
        result
    )
    # the registry says it too, to Python callers
    with pytest.raises(d.InputError, match="it is a small-kinematics method; use method='finite'.*'newton' and 'nlp'"):
        formulations.resolve("qp", d.LinearLaw(1.0), "finite").check()
    # in a sweep, that case is an error row and the others run
    result = invoke(
        "sweep", finite, "--set", "solve.method=qp,newton", "--scheduler", "synchronous", "-o", tmp_path / "sweep"
    )
    assert result.exit_code == 1
    table = pd.read_csv(tmp_path / "sweep" / "sweep.csv").set_index("solve.method")
    assert table.loc["newton", "status"] == "ok" and table.loc["qp", "status"] == "error"
    assert "solve.method = 'qp' (from --set) is a small-kinematics method" in table.loc["qp", "message"]


def test_calibrate_asks_for_small_kinematics_by_its_key(finite, tmp_path):
    film = tmp_path / "film.csv"
    film.write_text("x,y,z,p\n0,0,0,1.0\n1,0,0,1.5\n")
    result = invoke("calibrate", finite, "--data", film, "--film", "LLW", "-o", tmp_path / "cal")
    assert result.exit_code == 2
    text = one_line(result)
    assert 'solve.kinematics = "finite" (line 15): set solve.kinematics = "small"' in text
    assert not (tmp_path / "cal").exists()  # refused before the output folder is taken
    from dea_opt.sensitivity.calibrate import PressureMap

    problem = build_problem(parse_scenario(FINITE))
    with pytest.raises(d.InputError, match="kinematics='finite': build it with kinematics='small'"):
        d.calibrate(problem, PressureMap(np.zeros((1, 3)), np.ones(1)))


def test_a_zero_load_reports_no_nan_percentages(finite, tmp_path):
    result = invoke("run", finite, "--set", "load.scale=0", "-o", tmp_path / "zero")
    assert result.exit_code == 0, result.output
    assert "nan" not in result.output.lower()
    assert "no share of the contact force (the springs carry none)" in result.output
    assert "(-: the solution carries no force)" in result.output


def test_a_study_of_a_finite_punch_runs_newton_and_nlp_as_the_finite_formulations():
    from dea_opt.geometry import plate_layer

    layer = plate_layer(6.0, 6.0, 6, 6, thickness=10.0)
    problem = d.ContactProblem(
        layer, d.LinearLaw(10.0), force=(0, 0, -50.0), reference=(0, 0, 0), free=("uz",), kinematics="finite"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        study = run_study(problem, methods=["newton", "qp", "nlp"])
    assert list(study.table["method"]) == ["finite", "finite_nlp"] and study.table["success"].all()
    assert len(study.skipped) == 1 and study.skipped[0].startswith("qp is a small-kinematics method")
