"""dea-opt calibrate: a scenario and a film CSV in, the fitted law and its outputs out."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

import dea_opt as d
from dea_opt.cli import app
from dea_opt.scenario import build_problem, load_scenario

runner = CliRunner()

SCENARIO = """\
title = "sphere on a bed, Ateshian's law"

[geometry]
kind = "sphere_on_bed"
radius = 25.0
thickness = 2.0
extent = 7.0
n_rings = 60
n_sectors = 48

[law]
kind = "ateshian"
H = {H}
beta = {beta}

[body2]
reference = [0.0, 0.0, 25.0]
free = ["uz", "rx", "ry"]

[load]
force = [0.0, 0.0, -20.0]
point = [0.5, 0.3, 0.0]

[output]
directory = "out"
"""


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


@pytest.fixture()
def case(tmp_path):
    """A scenario whose law starts 2x off, and the film the true law (H = 0.6, beta = 0.3) leaves."""
    truth = tmp_path / "truth.toml"
    truth.write_text(SCENARIO.format(H=0.6, beta=0.3))
    solution = d.solve(build_problem(load_scenario(truth)))
    rng = np.random.default_rng(4)
    points = solution.problem.layer.points
    reading = solution.pressure * np.exp(0.05 * rng.standard_normal(len(points)))
    pd.DataFrame({"x": points[:, 0], "y": points[:, 1], "z": points[:, 2], "p": reading}).to_csv(
        tmp_path / "film.csv", index=False
    )
    scenario = tmp_path / "start.toml"
    scenario.write_text(SCENARIO.format(H=1.2, beta=0.6))
    return scenario, tmp_path / "film.csv", solution


def test_calibrate_writes_the_fit(case):
    scenario, film, truth = case
    result = invoke("calibrate", scenario, "--data", film, "--film", "0.05,0.4")
    assert result.exit_code == 0, (result.stdout, result.stderr)
    out = scenario.parent / "out" / "calibration"
    summary = json.loads((out / "calibration.json").read_text())
    assert summary["parameters"] == ["H", "beta"] and summary["film"]["upper_MPa"] == 0.4
    for name, true in (("H_MPa", 0.6), ("beta", 0.3)):
        assert abs(summary["values"][name] - true) < 3 * summary["standard_errors"][name]
        assert f"{summary['values'][name]:12.6g}" in result.stdout
    table = pd.read_csv(out / "residuals.csv")
    assert len(table) == len(truth.pressure) and {"below", "measured"} <= set(table.state)
    assert (out / "calibration.png").read_bytes()[:4] == b"\x89PNG"
    assert "correlation: H-beta" in result.stdout
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["command"] == "calibrate" and manifest["status"] == "ok"
    assert set(manifest["files"]) >= {"calibration.json", "residuals.csv", "calibration.png"}


def test_calibrate_one_parameter_into_a_folder(case, tmp_path):
    scenario, film, _ = case
    result = invoke(
        "calibrate", scenario, "--data", film, "--parameters", "H", "--set", "law.beta=0.3", "-o", tmp_path / "fit"
    )
    assert result.exit_code == 0, result.stderr
    summary = json.loads((tmp_path / "fit" / "calibration.json").read_text())
    assert summary["parameters"] == ["H"] and summary["values"]["H_MPa"] == pytest.approx(0.6, rel=0.01)


@pytest.mark.parametrize(
    "extra, expected",
    [
        (["--data", "nosuch.csv"], "no such file"),
        (["--data", "{film}", "--film", "XYZ"], "film must be one of"),
        (["--data", "{film}", "--film", "a,b"], "--film must be"),
        (["--data", "{film}", "--parameters", "E"], "parameters must name"),
        (["--data", "{film}", "--noise", "-1"], "noise must be"),
        (["--data", "{film}", "--correlation-length", "0"], "correlation_length: length must be a number > 0"),
    ],
)
def test_bad_input_exits_2_with_one_paragraph(case, extra, expected):
    scenario, film, _ = case
    result = invoke("calibrate", scenario, *[str(a).format(film=film) for a in extra])
    assert result.exit_code == 2, (result.stdout, result.stderr)
    text = result.stderr.strip()
    assert text.startswith("dea-opt: error: ") and "\n" not in text and "Traceback" not in text
    assert expected in text


def test_help():
    result = invoke("calibrate", "--help")
    assert result.exit_code == 0 and "--data" in result.stdout and "--film" in result.stdout


@pytest.mark.slow
def test_the_standard_errors_say_where_they_come_from(case, tmp_path):
    """The film read at one point for one parameter: with --noise the noise carried through the
    slope; without it, nothing to estimate it from, and the command says so (JSON null)."""
    scenario, film, truth = case
    table = pd.read_csv(film)
    one = tmp_path / "one.csv"
    table.iloc[[int(np.argmax(truth.pressure))]].to_csv(one, index=False)
    args = ("calibrate", scenario, "--data", one, "--parameters", "H", "--set", "law.beta=0.3")
    stated = invoke(*args, "--noise", "0.1", "-o", tmp_path / "stated")
    assert stated.exit_code == 0, stated.stderr
    summary = json.loads((tmp_path / "stated" / "calibration.json").read_text())
    assert summary["errors"] == "stated" and summary["noise"] == 0.1 and summary["standard_errors"]["H_MPa"] > 0
    assert "standard errors: from the stated noise" in stated.stdout
    doubled = invoke(*args, "--noise", "0.2", "-o", tmp_path / "doubled")
    assert doubled.exit_code == 0, doubled.stderr
    se = json.loads((tmp_path / "doubled" / "calibration.json").read_text())["standard_errors"]["H_MPa"]
    assert se == pytest.approx(2.0 * summary["standard_errors"]["H_MPa"], rel=1e-6)  # the noise through the slope
    unstated = invoke(*args, "-o", tmp_path / "unstated")
    assert unstated.exit_code == 0, unstated.stderr
    summary = json.loads((tmp_path / "unstated" / "calibration.json").read_text())
    assert summary["errors"] == "estimated" and summary["standard_errors"] == {"H_MPa": None}
    assert summary["noise"] is None and "undefined" in summary["notes"][0]
    assert "undefined" in unstated.stdout and "note: the standard errors are undefined" in unstated.stdout
    assert "nan" not in unstated.stdout.lower()
    correlated = invoke(
        *args[:3], film, *args[4:], "--noise", "0.05", "--correlation-length", "2", "-o", tmp_path / "c"
    )
    assert correlated.exit_code == 0, correlated.stderr
    with_length = json.loads((tmp_path / "c" / "calibration.json").read_text())
    assert with_length["correlation_length_mm"] == 2.0 and with_length["errors"] == "stated"
    independent = invoke(*args[:3], film, *args[4:], "--noise", "0.05", "-o", tmp_path / "i")
    assert independent.exit_code == 0, independent.stderr
    without = json.loads((tmp_path / "i" / "calibration.json").read_text())
    assert without["values"] == with_length["values"]  # the same fit: each reading weighted by its noise
    # the option is the API's spatial correlation of the map's points
    from dea_opt.sensitivity import spatial_correlation
    from dea_opt.sensitivity.calibrate import PressureMap, calibrate

    data = PressureMap.from_csv(film, noise=0.05)
    data = PressureMap(data.points, data.pressure, noise=0.05, correlation=spatial_correlation(data.points, 2.0))
    problem = build_problem(load_scenario(scenario, {"law.beta": 0.3}))
    fit = calibrate(problem, data, ("H",))
    assert with_length["standard_errors"]["H_MPa"] == pytest.approx(fit.standard_errors["H"], rel=1e-6)
    assert with_length["standard_errors"]["H_MPa"] != pytest.approx(without["standard_errors"]["H_MPa"], rel=1e-3)
