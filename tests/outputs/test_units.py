"""Every column of every CSV and every number of every JSON file dea-opt writes names its unit.

The convention (:mod:`dea_opt.units`): a name ends with its unit (``peak_pressure_MPa``,
``contact_area_mm2``, ``Fz_N``, ``Mx_Nmm``, ``time_s``); a name without one is listed among the
unitless ones (counts, indices, ratios, flags), or its number sits in an object that states its
``unit``. Each command's outputs are written here and every file of them read back: a CSV's
numeric columns, a JSON file's numbers at any depth.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from dea_opt.cli import app
from dea_opt.run.units import is_unitless, unnamed_units
from dea_opt.units import SUFFIXES, UNITLESS, dof_name, label, split_unit, with_unit

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "scenarios"
runner = CliRunner()


def invoke(*args):
    result = runner.invoke(app, [str(a) for a in args])
    assert result.exit_code in (0, 3), result.stdout + result.stderr
    return result


def columns_without_units(path: Path) -> list[str]:
    """The columns of numbers of a CSV whose name gives no unit and that are not unitless (a text
    column left empty reads as NaN: not a number); a sweep's swept scenario keys (``law.H_MPa``,
    ``load.scale``) carry the unit the scenario's schema gives them, if any."""
    table = pd.read_csv(path, comment="#")
    found = []
    for c in table.columns:
        column = table[c]
        if pd.api.types.is_bool_dtype(column) or not pd.api.types.is_numeric_dtype(column) or column.isna().all():
            continue
        if split_unit(c)[1] is None and not is_unitless(c):
            found.append(c)
    return found


def check_folder(folder: Path) -> dict:
    """``{file: what has no unit}`` over every CSV and JSON file under ``folder`` (empty: all named)."""
    found = {}
    files = [*folder.rglob("*.csv"), *folder.rglob("*.json"), *folder.rglob("*.jsonl")]
    assert files, f"no output in {folder}"
    for path in files:
        if any(part.startswith(".") for part in path.relative_to(folder).parts):
            continue  # a sweep's own bookkeeping (.sweep/), not an output
        if path.suffix == ".csv":
            bad = columns_without_units(path)
        elif path.suffix == ".jsonl":
            bad = [b for line in path.read_text().splitlines() if line for b in unnamed_units(json.loads(line))]
        else:
            bad = unnamed_units(json.loads(path.read_text()))
        if bad:
            found[str(path.relative_to(folder))] = sorted(set(bad))
    return found


PLATE = """
title = "A plate in two halves"
[geometry]
kind = "plate"
nx = 20
ny = 4
[law]
kind = "linear"
H = 10.0
[body2]
free = ["uz", "ry"]
[regions]
split = "x"
{load}
[output]
formats = ["csv", "json"]
anatomy = {{medial = [-1.0, 0.0, 0.0], proximal = [0.0, 0.0, 1.0], side = "right"}}
"""


@pytest.fixture()
def plate(tmp_path):
    static = tmp_path / "static.toml"
    static.write_text(PLATE.format(load="[load]\nforce = [0.0, 0.0, -400.0]\npoint = [3.0, 0.0, 0.0]"))
    (tmp_path / "path.csv").write_text(
        "time,Fx,Fy,Fz,Mx,My,Mz\n0,0,0,-300,0,0,0\n0.5,0,0,-600,0,800,0\n1,0,0,100,0,0,0\n"
    )
    path = tmp_path / "path.toml"
    path.write_text(PLATE.format(load='[load_path]\nfile = "path.csv"'))
    return static, path


def test_the_outputs_of_a_static_run_and_a_load_path_name_every_unit(plate, tmp_path):
    static, path = plate
    invoke("run", static, "-o", tmp_path / "static")
    runner.invoke(app, ["run", str(path), "-o", str(tmp_path / "path")])  # a frame pulls off: exit 1
    for folder in ("static", "path"):
        assert check_folder(tmp_path / folder) == {}, folder
    springs = pd.read_csv(tmp_path / "static" / "contact.csv")
    assert list(springs.columns[:3]) == ["x_mm", "y_mm", "z_mm"] and "pressure_MPa" in springs
    frames = pd.read_csv(tmp_path / "path" / "frames.csv")
    assert {"time_s", "Fz_N", "My_Nmm", "peak_pressure_MPa", "contact_area_mm2", "body2_uz_mm"} <= set(frames)
    assert {"body2_ry_rad", "medial_peak_pressure_MPa", "lateral_force_share", "cop_medial_mm"} <= set(frames)
    assert not frames["success"].iloc[2] and np.isnan(frames["peak_pressure_MPa"].iloc[2])
    summary = json.loads((tmp_path / "path" / "summary.json").read_text())
    assert summary["peak_pressure_MPa"] == frames["peak_pressure_MPa"].max()
    assert summary["motion"]["body2_uz_mm"]["unit"] == "mm"
    contact = json.loads((tmp_path / "static" / "contact.json").read_text())
    assert contact["contact_force_N"][2] == pytest.approx(400.0, rel=1e-9)
    assert set(contact["u"]) == {dof_name(f"body{b}.{k}") for b in (1, 2) for k in ("ux", "uy", "uz", "rx", "ry", "rz")}


def test_a_sweep_names_its_cases_by_their_values_and_gives_each_compartment_columns(plate, tmp_path):
    static, _ = plate
    invoke(
        "sweep",
        static,
        "--set",
        "law.H=8,10",
        "--set",
        "load.scale=1",
        "--scheduler",
        "synchronous",
        "-o",
        tmp_path / "s",
    )
    assert check_folder(tmp_path / "s") == {}
    table = pd.read_csv(tmp_path / "s" / "sweep.csv")
    assert list(table["case"]) == ["law.H=8", "law.H=10"]  # the swept values: load.scale is one value
    assert list(table.columns[:2]) == ["case", "case_id"] and "law.H_MPa" in table and "load.scale" in table
    for region in ("medial", "lateral"):
        assert {f"{region}_peak_pressure_MPa", f"{region}_contact_area_mm2", f"{region}_force_share"} <= set(table)
    shares = table["medial_force_share"] + table["lateral_force_share"]
    assert np.allclose(shares, 1.0, rtol=1e-9)  # the two halves carry the whole load


def test_the_demo_compare_and_calibrate_outputs_name_every_unit(plate, tmp_path):
    invoke("demo", "--coarse", "--frames", "3", "-o", tmp_path / "demo")
    assert check_folder(tmp_path / "demo") == {}
    comparison = pd.read_csv(tmp_path / "demo" / "comparison.csv")
    assert {"peak_pressure_MPa", "contact_area_mm2", "solve_time_s", "certificate_residual"} <= set(comparison)
    invoke("compare", EXAMPLES / "plate_springs.toml", "-o", tmp_path / "compare", "--methods", "newton,qp")
    assert check_folder(tmp_path / "compare") == {}
    static, _ = plate
    invoke("run", static, "-o", tmp_path / "truth")
    springs = pd.read_csv(tmp_path / "truth" / "contact.csv")
    film = springs[["x_mm", "y_mm", "z_mm", "pressure_MPa"]].set_axis(["x", "y", "z", "p"], axis=1)
    film.loc[film["p"] > 0].to_csv(tmp_path / "film.csv", index=False)  # a film reads where there is contact
    invoke("calibrate", static, "--data", tmp_path / "film.csv", "--parameters", "H", "-o", tmp_path / "fit")
    assert check_folder(tmp_path / "fit") == {}
    fit = json.loads((tmp_path / "fit" / "calibration.json").read_text())
    assert fit["values"]["H_MPa"] == pytest.approx(10.0, rel=1e-3)  # the film the plate itself left


def test_the_outputs_of_a_joint_name_every_unit(tmp_path):
    shutil.copytree(EXAMPLES / "joint", tmp_path / "joint")
    invoke("run", tmp_path / "joint" / "chain.toml", "-o", tmp_path / "static")
    invoke("run", tmp_path / "joint" / "chain_cycle.toml", "-o", tmp_path / "cycle")
    for folder in ("static", "cycle"):
        assert check_folder(tmp_path / folder) == {}, folder


def test_the_names_read_back_as_their_units():
    for unit, suffix in SUFFIXES.items():
        assert with_unit("peak", unit) == f"peak_{suffix}" and split_unit(f"peak_{suffix}") == ("peak", unit)
    assert with_unit("strain", "1") == "strain" and split_unit("strain") == ("strain", None)
    assert split_unit("max_pressure_time_integral_MPa_s") == ("max_pressure_time_integral", "MPa s")
    assert label("contact_area_mm2") == "contact area (mm^2)" and label("valid") == "valid"
    assert dof_name("body2.rx") == "body2_rx_rad" and dof_name("body1.uz", "force") == "body1_uz_N"
    assert dof_name("ry", "force") == "ry_Nmm"
    assert is_unitless("medial_force_share") and not is_unitless("peak_pressure")
    assert is_unitless("load.scale") and not is_unitless("law.H") and not is_unitless("ground.rx")
    assert all(split_unit(name)[1] is None for name in UNITLESS)  # no unitless name looks like one with a unit
    assert unnamed_units({"peak": 1.0, "area_mm2": 2.0, "check": {"value": 3.0, "unit": "deg"}}) == ["peak"]
    assert unnamed_units({"regions": {"medial": {"peak": [1.0, None]}}}) == ["regions.medial.peak"]
