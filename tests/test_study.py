"""Comparison studies: every row has a status and residuals; success means certified and agreeing."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

import dea_opt as d
from dea_opt.cli import app
from dea_opt.errors import InputError
from dea_opt.geometry import socket_layer
from dea_opt.study import ACCURACY, installed_qp_solvers, run_study, shifted_geometric_mean, summarize

RESIDUALS = ["equilibrium", "tension", "complementarity", "consistency", "energy", "worst_residual"]
SOLVERS = [s for s in ("CLARABEL", "OSQP", "SCS", "PIQP") if s in installed_qp_solvers()]

HIP_TOML = """\
title = "coarse hip, gait peak"
[geometry]
kind = "socket"
radius = 25.0
thickness = 3.0
coverage = 80.0
gap = 0.1
n_rings = 12
n_sectors = 36
[law]
kind = "linear"
H = 10.0
[body2]
free = ["ux", "uy", "uz"]
[load]
force = [820.85, 0.0, -2255.26]
"""


@pytest.fixture(scope="module")
def hip():
    layer = socket_layer(radius=25.0, thickness=3.0, coverage=80.0, n_rings=12, n_sectors=36, gap=0.1)
    tilt = np.radians(20.0)
    force = 2400.0 * np.array([np.sin(tilt), 0.0, -np.cos(tilt)])
    return d.ContactProblem(layer, d.LinearLaw(10.0), force=force, free=("ux", "uy", "uz"))


@pytest.fixture(scope="module")
def study(hip):
    return run_study(hip, solvers=SOLVERS, accuracy=("low", "default"))


def test_every_row_has_a_status_and_residuals(study):
    table = study.table
    assert len(table) == 2 * (2 + len(SOLVERS))
    assert table["status"].notna().all() and (table["status"] != "").all()
    assert table[RESIDUALS].notna().all().all()
    assert set(table["solver"]) == {"-", "IPOPT", *SOLVERS}


def test_success_rows_agree_with_newton_to_the_accuracy_asked(study):
    table = study.table
    success = table[table["success"]]
    assert len(success) >= 4
    assert (success[["d_pressure", "d_displacement"]].max(axis=1) <= success["check_tol"]).all()
    assert (success["worst_residual"] <= success["check_tol"]).all()
    assert table.loc[table["method"] == "newton", "success"].all()


@pytest.mark.parametrize("solver", [s for s in ("SCS",) if s in SOLVERS])
def test_an_inaccurate_answer_is_not_a_success(hip, monkeypatch, solver):
    # A loose solver tolerance checked against a tight certificate: SCS stops early, claims
    # success, and the row must say it is inaccurate.
    from dea_opt.study import Accuracy

    monkeypatch.setitem(ACCURACY, "sloppy", Accuracy("sloppy", 1e-1, 1e-6))
    table = run_study(hip, methods=("newton", "qp"), solvers=[solver], accuracy=("sloppy",)).table
    inaccurate = table[(table["method"] == "qp") & ~table["success"]]
    assert len(inaccurate) == 1
    assert inaccurate["message"].str.startswith("inaccurate").all()
    assert (inaccurate["status"] == d.Status.INACCURATE).all()
    assert (inaccurate["solver_success"]).all()  # the solver itself claimed success


def test_summary_in_the_manner_of_qpbenchmark(study):
    summary = study.summary
    assert {"success_rate_percent", "shifted_gm_time_s", "relative_time"} <= set(summary.columns)
    for _, group in summary.groupby("accuracy"):
        assert group["relative_time"].min() == pytest.approx(1.0)
    failing = summary[summary["success_rate_percent"] == 0]
    assert np.allclose(failing["shifted_gm_time_s"], 10.0)


def test_shifted_geometric_mean():
    assert shifted_geometric_mean([0.0, 0.0]) == pytest.approx(0.0)
    assert shifted_geometric_mean([0.09, 0.09]) == pytest.approx(0.09)
    assert shifted_geometric_mean([0.0, 0.03], shift=0.01) == pytest.approx(np.sqrt(0.01 * 0.04) - 0.01)


def test_summary_counts_failures_at_the_time_limit():
    table = pd.DataFrame(
        {
            "accuracy": ["low"] * 2,
            "method": ["qp"] * 2,
            "solver": ["X"] * 2,
            "success": [True, False],
            "total_time_s": [0.01, 0.02],
        }
    )
    row = summarize(table, time_limit=1.0).iloc[0]
    assert row["success_rate_percent"] == 50.0
    assert row["shifted_gm_time_s"] == pytest.approx(np.sqrt(0.02 * 1.01) - 0.01)


def test_repeats_and_nonlinear_law(hip):
    result = run_study(hip.with_law(d.AteshianLaw(10.0, 0.3)), methods=("newton", "qp"), repeat=2)
    assert len(result.table) == 2 and result.table["repeat"].tolist() == [0, 1]
    assert result.skipped == ["qp needs a linear law"]


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"methods": ("newton", "simplex")}, "methods must be taken from"),
        ({"methods": ("qp",), "solvers": ("NOSUCH",)}, "NOSUCH is not available"),
        ({"accuracy": ("medium",)}, "accuracy must be taken from"),
        ({"repeat": 0}, "repeat must be a positive integer"),
    ],
)
def test_bad_study_input(hip, kwargs, match):
    with pytest.raises(InputError, match=match):
        run_study(hip, **kwargs)


def test_accuracy_settings_are_ordered():
    assert ACCURACY["low"].check_tol > ACCURACY["default"].check_tol > ACCURACY["high"].check_tol


def test_compare_command_on_the_hip(tmp_path):
    scenario = tmp_path / "hip.toml"
    scenario.write_text(HIP_TOML)
    result = CliRunner().invoke(
        app,
        ["compare", str(scenario), "--solvers", ",".join(SOLVERS), "--accuracy", "low", "-o", str(tmp_path / "out")],
    )
    assert result.exit_code == 0, result.stderr
    assert "Summary" in result.stdout and "inaccurate" in result.stdout
    table = pd.read_csv(tmp_path / "out" / "compare.csv")
    assert len(table) == 2 + len(SOLVERS)
    assert table["status"].notna().all() and table[RESIDUALS].notna().all().all()
    success = table[table["success"]]
    assert (success[["d_pressure", "d_displacement"]].max(axis=1) <= 1e-3).all()
    assert (tmp_path / "out" / "compare_summary.csv").is_file()


def test_compare_on_a_load_path_uses_the_peak_frame(tmp_path):
    scenario = tmp_path / "hip.toml"
    scenario.write_text(
        HIP_TOML.replace("[load]\nforce = [820.85, 0.0, -2255.26]\n", '[load_path]\nbuiltin = "hip_gait"\n')
    )
    result = CliRunner().invoke(app, ["compare", str(scenario), "--methods", "newton", "-o", str(tmp_path / "out")])
    assert result.exit_code == 0, result.stderr
    table = pd.read_csv(tmp_path / "out" / "compare.csv")
    assert table["success"].all()
    bad = CliRunner().invoke(app, ["compare", str(scenario), "--methods", "newton", "--frame", "500"])
    assert bad.exit_code == 2 and "--frame must be in 0..100" in bad.stderr


def test_both_nlp_forms_are_rows(hip):
    table = run_study(hip, methods=("newton", "nlp"), nlp_forms=("constrained", "reduced")).table
    nlp = table[table["method"] == "nlp"]
    assert sorted(nlp["solver"]) == ["IPOPT", "IPOPT-reduced"]
    assert nlp["success"].all()
    with pytest.raises(InputError, match="nlp_forms must be taken from constrained, reduced, got exact"):
        run_study(hip, methods=("nlp",), nlp_forms=("exact",))
