"""Sweeps keyed on content: a row is reused only if it was computed from the same scenario text,
input files, overrides, --method and dea-opt version; unreadable results tables stop a sweep
before any case runs."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import scenario_text
from typer.testing import CliRunner

from dea_opt.cli import app
from dea_opt.errors import InputError
from dea_opt.geometry import plate_layer
from dea_opt.scenario import keys, load_scenario, write_springs
from dea_opt.sweep import (
    JOURNAL_NAME,
    RESULTS_NAME,
    make_cases,
    read_results,
    run_sweep,
)

PLATE = scenario_text(title="plate", size=(40.0, 10.0), point=(5.0, 0.0, 0.0), formats=("json",))

SPRINGS = """\
title = "springs table under a load path"
[geometry]
kind = "springs"
file = "a.csv"
[law]
kind = "linear"
H = 10.0
[body2]
free = ["uz", "rx", "ry"]
[load_path]
file = "path.csv"
point = [5.0, 0.0, 0.0]
[output]
formats = ["json"]
"""

LOAD_PATH = "time,Fx,Fy,Fz\n0,0,0,-100\n1,0,0,-500\n"


def sweep(scenario, sets, out, **options):
    return run_sweep(scenario, sets, out, scheduler="synchronous", log=False, **options)


def rigid_plate_peak(force: float, eccentricity: float, nx: int, ny: int, length: float, width: float) -> float:
    """Peak pressure under a rigid plate on equal linear springs in full contact (statics only).

    The plate sinks and tilts about y: p(x) = a + b x with sum p A = F and sum p A x = F e.
    """
    x = (np.arange(nx) + 0.5) * length / nx - length / 2
    x = np.repeat(x, ny)
    area = length * width / (nx * ny)
    a = force / (len(x) * area)
    b = force * eccentricity / (area * np.sum(x**2))
    return float(np.max(a + b * x))


@pytest.fixture()
def plate(tmp_path):
    path = tmp_path / "plate.toml"
    path.write_text(PLATE)
    return path


@pytest.fixture()
def springs(tmp_path):
    write_springs(plate_layer(40.0, 10.0, 40, 4, thickness=2.0), tmp_path / "a.csv")
    write_springs(plate_layer(40.0, 10.0, 40, 4, thickness=3.0), tmp_path / "b.csv")
    (tmp_path / "path.csv").write_text(LOAD_PATH)
    path = tmp_path / "springs.toml"
    path.write_text(SPRINGS)
    return path


def test_an_edited_scenario_is_recomputed_and_says_why(plate, tmp_path):
    out = tmp_path / "sweep"
    first = sweep(plate, ["law.H=5,10"], out)
    linear = first.table.set_index("law.H_MPa")
    exact = rigid_plate_peak(500.0, 5.0, 40, 4, 40.0, 10.0)
    np.testing.assert_allclose(linear["peak_pressure_MPa"], exact, rtol=1e-6)  # linear, full contact: H drops out

    plate.write_text(PLATE.replace('kind = "linear"', 'kind = "ateshian"\nbeta = 0.3'))
    lines = []
    second = sweep(plate, ["law.H=5,10"], out, on_report=lines.append)
    assert sorted(second.ran) == sorted(first.ran) and second.skipped == []
    assert set(second.recomputed.values()) == {"the scenario changed since its row was computed"}
    for case in first.ran:
        assert f"case {case}: the scenario changed since its row was computed; recomputing" in lines
    ateshian = second.table.set_index("law.H_MPa")
    assert len(second.table) == 2 and second.table["case_id"].is_unique
    assert (ateshian["key"] != linear["key"]).all()
    # Under a nonlinear law pressure is no longer linear in x: the rows hold its numbers, not the old ones.
    assert (np.abs(ateshian["peak_pressure_MPa"] - exact) > 1e-3 * exact).all()
    # Unchanged since: a third run reuses every row.
    third = sweep(plate, ["law.H=5,10"], out)
    assert third.ran == [] and sorted(third.skipped) == sorted(first.ran)


def test_the_cli_prints_the_stale_summary(plate, tmp_path):
    out = tmp_path / "sweep"
    args = ["sweep", str(plate), "--set", "law.H=8,10", "--scheduler", "synchronous", "-o", str(out)]
    assert CliRunner().invoke(app, args).exit_code == 0
    plate.write_text(PLATE.replace("point = [5.0", "point = [4.0"))
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.stderr
    assert result.stdout.splitlines() == [
        f"2 case(s) run, 0 already finished; results: {out / RESULTS_NAME}, report: {out / 'report.html'}",
        "  recomputed 2 case(s): the scenario changed since its row was computed",
    ]


def test_a_changed_input_file_recomputes_only_the_cases_that_read_it(springs, tmp_path):
    out = tmp_path / "sweep"
    sets = ["geometry.file=a.csv,b.csv"]
    first = sweep(springs, sets, out)
    ids = {row["geometry.file"]: row["case_id"] for row in first.table.to_dict("records")}
    assert len(first.ran) == 2

    # Same bytes written again (a new modification time): nothing to recompute.
    (tmp_path / "a.csv").write_bytes((tmp_path / "a.csv").read_bytes())
    assert sweep(springs, sets, out).ran == []

    write_springs(plate_layer(40.0, 10.0, 40, 4, thickness=2.5), tmp_path / "b.csv")
    second = sweep(springs, sets, out)
    assert second.ran == [ids["b.csv"]] and second.skipped == [ids["a.csv"]]
    assert second.recomputed == {
        ids["b.csv"]: "the input file geometry.file (b.csv) changed since its row was computed"
    }

    (tmp_path / "path.csv").write_text(LOAD_PATH.replace("-500", "-600"))
    third = sweep(springs, sets, out)
    assert sorted(third.ran) == sorted(ids.values())
    assert set(third.recomputed.values()) == {
        "the input file load_path.file (path.csv) changed since its row was computed"
    }
    # The rows keep what they were computed from; the journal names the files' hashes.
    record = [json.loads(line) for line in (out / JOURNAL_NAME).read_text().splitlines()][-1]
    assert set(record["inputs"]) == {"geometry.file", "load_path.file"}
    assert record["inputs"]["load_path.file"] == ["path.csv", keys.sha256_file(tmp_path / "path.csv")]


def test_files_are_found_after_the_overrides(springs, tmp_path):
    scenario = load_scenario(springs, {"geometry.file": "b.csv"})
    assert keys.input_files(scenario) == {
        "geometry.file": (tmp_path / "b.csv").resolve(),
        "load_path.file": (tmp_path / "path.csv").resolve(),
    }


def test_mesh_files_are_inputs():
    scenario = load_scenario(Path(__file__).parents[2] / "examples" / "scenarios" / "hip_meshes.toml")
    found = keys.input_files(scenario)
    assert {k: v.name for k, v in found.items()} == {
        "geometry.mesh1": "hip_socket.stl",
        "geometry.mesh2": "hip_head.stl",
    }


def test_a_new_version_or_method_recomputes(plate, tmp_path, monkeypatch):
    out = tmp_path / "sweep"
    sweep(plate, ["law.H=5"], out)
    again = sweep(plate, ["law.H=5"], out, method="newton")
    assert list(again.recomputed.values()) == ["it was solved with --method (the scenario default), now newton"]
    monkeypatch.setattr(keys, "__version__", "9.9.9")
    later = sweep(plate, ["law.H=5"], out, method="newton")
    assert list(later.recomputed.values()) == ["it was computed by dea-opt 0.1.0, this is 9.9.9"]
    assert later.table["dea_opt_version"].tolist() == ["9.9.9"]


def test_a_results_table_from_before_content_keys_is_kept_and_its_cases_recomputed(plate, tmp_path):
    out = tmp_path / "sweep"
    out.mkdir()
    old = make_cases(["law.H=5,7"])
    pd.DataFrame(
        [
            {"case_id": old[0].id, "law.H": 5, "status": "ok", "peak_pressure": 1.0},
            {"case_id": old[1].id, "law.H": 7, "status": "ok", "peak_pressure": 2.0},
        ]
    ).to_csv(out / RESULTS_NAME, index=False)
    result = sweep(plate, ["law.H=5"], out)
    assert result.ran == [old[0].id]
    assert result.recomputed == {old[0].id: "its row has no content key (it was computed by an older dea-opt)"}
    table = read_results(out).set_index("case_id")
    assert list(table.index) == [old[0].id, old[1].id]  # the other case's row is kept
    assert table.loc[old[1].id, "peak_pressure"] == 2.0 and table.loc[old[0].id, "peak_pressure_MPa"] != 1.0


@pytest.mark.parametrize(
    "content",
    [b"case_id,status\n\x00\xff\xfe\x80garbage\n", b"a,b\n1,2\n", b"case_id,status\n,ok\n"],
    ids=["binary", "no case_id", "empty case_id"],
)
def test_an_unreadable_results_table_stops_the_sweep_before_any_case(plate, tmp_path, content):
    out = tmp_path / "sweep"
    out.mkdir()
    (out / RESULTS_NAME).write_bytes(content)
    with pytest.raises(InputError, match="the results table .*sweep.csv"):
        sweep(plate, ["law.H=5"], out)
    assert sorted(p.name for p in out.iterdir()) == [RESULTS_NAME]  # nothing ran, nothing written
    result = CliRunner().invoke(
        app, ["sweep", str(plate), "--set", "law.H=5", "--scheduler", "synchronous", "-o", str(out)]
    )
    assert result.exit_code == 2 and result.stderr.startswith("dea-opt: error: the results table")
    assert str(out / RESULTS_NAME) in result.stderr and "Traceback" not in result.stderr
    assert (out / RESULTS_NAME).read_bytes() == content


def test_a_damaged_journal_is_named_with_its_line(plate, tmp_path):
    out = tmp_path / "sweep"
    sweep(plate, ["law.H=5"], out)
    with open(out / JOURNAL_NAME, "ab") as handle:
        handle.write(b"\x00\x01 not a record\n")
    with pytest.raises(InputError, match=r"sweep.jsonl cannot be read: line 2"):
        sweep(plate, ["law.H=5,6"], out)
    assert not (out / "cases" / make_cases(["law.H=6"])[0].id).exists()
