"""Sweeps: the Cartesian product of --set values on Dask, one row per case, resumable."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import distributed  # noqa: E402, F401 - a dev dependency: the sweeps need it
import pandas as pd
import pytest
from conftest import COARSE_SOCKET
from typer.testing import CliRunner

from dea_opt.cli import app
from dea_opt.errors import InputError, MissingDependencyError
from dea_opt.status import RunStatus
from dea_opt.sweep import (
    JOURNAL_NAME,
    RESULTS_NAME,
    case_id,
    make_cases,
    read_results,
    run_sweep,
)

# A small hip under a 5-frame gait: about a second per case with its outputs.
SCENARIO = (
    'title = "sweep test"\n'
    + COARSE_SOCKET
    + """\
[load_path]
builtin = "hip_gait"
frames = 5
[output]
formats = ["csv", "json", "vtk", "png"]
"""
)
TWELVE = ["law.H=5,10,20", "load_path.scale=0.5,1", "geometry.gap=0.05,0.1"]
FOUR = ["law.H=5,10", "load_path.scale=0.5,1", "geometry.gap=0.05"]


@pytest.fixture()
def scenario(tmp_path):
    path = tmp_path / "hip.toml"
    path.write_text(SCENARIO)
    return path


@pytest.fixture()
def tables_only(tmp_path):
    """The hip writing its tables only: for the tests of a sweep's bookkeeping, which read no
    picture and no VTK file (the cases' full outputs are those of ``scenario``)."""
    path = tmp_path / "hip_tables.toml"
    path.write_text(SCENARIO.replace('formats = ["csv", "json", "vtk", "png"]', 'formats = ["csv", "json"]'))
    return path


def runs(out: Path) -> dict:
    """How many times each case was computed (from its record in .sweep/records/)."""
    return {p.stem: json.loads(p.read_text())["runs"] for p in (out / ".sweep" / "records").glob("[!.]*.json")}


def journal_lines(out: Path) -> list[dict]:
    """Every record of the journal, in order (read here with plain json, not dea-opt's reader)."""
    return [json.loads(line) for line in (out / JOURNAL_NAME).read_text().splitlines() if line.strip()]


def test_cases_are_the_cartesian_product_with_stable_ids():
    cases = make_cases(TWELVE)
    assert len(cases) == 12 and len({c.id for c in cases}) == 12
    assert cases[0].overrides == {"law.H": 5, "load_path.scale": 0.5, "geometry.gap": 0.05}
    assert case_id({"a": 1, "b": 2}) == case_id({"b": 2, "a": 1}) != case_id({"a": 1, "b": 3})
    subset = {c.id for c in make_cases(FOUR)}
    assert subset < {c.id for c in cases}
    with pytest.raises(InputError, match="more than once"):
        make_cases(["law.H=1", "law.H=2"])


@pytest.mark.slow
def test_resume_runs_only_the_missing_cases(scenario, tmp_path):
    out = tmp_path / "sweep"
    first = run_sweep(scenario, FOUR, out, scheduler="synchronous")
    assert len(first.ran) == 4 and len(read_results(out / RESULTS_NAME)) == 4
    second = run_sweep(scenario, TWELVE, out, scheduler="synchronous")
    assert sorted(second.skipped) == sorted(first.ran) and len(second.ran) == 8
    table = second.table
    assert len(table) == 12 and table["case_id"].is_unique and (table["status"] == "ok").all()
    assert set(runs(out).values()) == {1}
    for row in table.itertuples():
        assert (Path(row.output_dir) / "frames.csv").is_file() and (Path(row.output_dir) / "series.pvd").is_file()
    again = run_sweep(scenario, TWELVE, out, scheduler="synchronous")
    assert again.ran == [] and len(again.skipped) == 12


def test_a_failing_case_is_recorded_and_its_retry_replaces_the_row(tables_only, tmp_path):
    scenario = tables_only
    out = tmp_path / "sweep"
    # the check before solving off: it would stop the negated path before its frames are solved
    sets = ["load_path.scale=1,-1", "solve.check_inputs=false"]
    result = run_sweep(scenario, sets, out, scheduler="synchronous")
    table = result.table.set_index("load_path.scale")
    assert table.loc[1.0, "status"] == "ok"
    # A load path goes on past frames the springs cannot carry: the case ran, its frames failed.
    assert table.loc[-1.0, "status"] == RunStatus.LOAD_NOT_SUPPORTED
    frames = pd.read_csv(Path(table.loc[-1.0, "output_dir"]) / "frames.csv", keep_default_na=False)
    assert (frames["status"] == "load_not_supported").all() and frames["message"].str.contains("cannot carry").all()
    assert len(result.failed) == 1
    first_row = table.loc[-1.0].to_dict()
    retry = run_sweep(scenario, sets, out, scheduler="synchronous", retry_failed=True)
    assert retry.ran == result.failed and retry.skipped == [table.loc[1.0, "case_id"]]
    assert retry.recomputed == {result.failed[0]: "its row says load_not_supported; retrying"}
    # The CSV a user opens: one row per case, the failed one replaced by its retry.
    csv = pd.read_csv(out / RESULTS_NAME, dtype={"case_id": str})
    assert len(csv) == 2 and csv["case_id"].is_unique
    assert runs(out) == {table.loc[1.0, "case_id"]: 1, result.failed[0]: 2}
    retried = csv.set_index("case_id").loc[result.failed[0]]
    assert retried["status"] == RunStatus.LOAD_NOT_SUPPORTED and retried["wall_time_s"] != first_row["wall_time_s"]
    # The journal keeps both computations of the failed case; the later one is the row.
    lines = journal_lines(out)
    assert [r["case_id"] for r in lines].count(result.failed[0]) == 2 and len(lines) == 3
    assert lines[-1]["wall_time_s"] == retried["wall_time_s"]
    # Through the CLI: --retry-failed replaces again and exits 1 (the case still fails).
    cli = CliRunner().invoke(
        app,
        [
            "sweep",
            str(scenario),
            "--set",
            "load_path.scale=1,-1",
            "--set",
            "solve.check_inputs=false",
            "--scheduler",
            "synchronous",
            "-o",
            str(out),
            "--retry-failed",
        ],
    )
    assert cli.exit_code == 1 and "1 case(s) run, 1 already finished" in cli.stdout
    assert len(pd.read_csv(out / RESULTS_NAME)) == 2 and runs(out)[result.failed[0]] == 3


def test_bad_overrides_stop_before_any_case_runs(scenario, tmp_path):
    with pytest.raises(InputError, match="law.HH"):
        run_sweep(scenario, ["law.HH=1,2"], tmp_path / "s", scheduler="synchronous")
    with pytest.raises(InputError, match="law.H"):
        run_sweep(scenario, ["law.H=1,abc"], tmp_path / "s", scheduler="synchronous")
    assert not (tmp_path / "s").exists()


def test_missing_dask_names_the_extra(scenario, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "dask.distributed", None)
    with pytest.raises(MissingDependencyError, match=r"pip install dea-opt\[distributed\]"):
        run_sweep(scenario, ["law.H=1"], tmp_path / "s")
    result = CliRunner().invoke(app, ["sweep", str(scenario), "--set", "law.H=1", "-o", str(tmp_path / "s")])
    assert result.exit_code == 2 and "dea-opt[distributed]" in result.stderr


def _command() -> list[str]:
    script = Path(sys.executable).with_name("dea-opt")
    return [str(script)] if script.exists() else [sys.executable, "-m", "dea_opt.cli"]


LIGHT = SCENARIO.replace('formats = ["csv", "json", "vtk", "png"]', 'formats = ["json"]')


@pytest.mark.slow
def test_twelve_cases_on_two_workers_survive_a_kill(tmp_path):
    """Kill a sweep after some cases, run it again: 12 rows, nothing finished is computed twice."""
    scenario = tmp_path / "hip.toml"
    scenario.write_text(LIGHT)
    out = tmp_path / "sweep"
    command = _command() + [
        "sweep",
        str(scenario),
        *[a for s in TWELVE for a in ("--set", s)],
        "--workers",
        "2",
        "-o",
        str(out),
    ]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True)
    deadline = time.monotonic() + 120
    try:
        while time.monotonic() < deadline and process.poll() is None:
            if (out / JOURNAL_NAME).is_file() and len(read_results(out)) >= 2:
                break
            time.sleep(0.05)
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)  # the sweep and its Dask workers, at once
        process.communicate(timeout=60)
    before = read_results(out)
    assert 2 <= len(before) < 12, "the sweep should have been killed part way"

    rerun = subprocess.run(command, capture_output=True, text=True, timeout=300, check=False)
    assert rerun.returncode == 0, rerun.stderr
    assert rerun.stderr == ""  # no Dask log line, traceback or warning on the terminal
    assert rerun.stdout.startswith(f"{12 - len(before)} case(s) run, {len(before)} already finished")
    after = pd.read_csv(out / RESULTS_NAME, dtype={"case_id": str})
    assert len(after) == 12 and after["case_id"].is_unique and (after["status"] == "ok").all()
    assert set(after["case_id"]) == {c.id for c in make_cases(TWELVE)}
    # Every case computed and journaled exactly once. (A kill between a case's journal line
    # and its record file leaves that case without a record file: it is not computed again.)
    assert sorted(r["case_id"] for r in journal_lines(out)) == sorted(after["case_id"])
    assert set(runs(out).values()) == {1}
    kept = after.set_index("case_id").loc[before["case_id"], "finished"].tolist()
    assert kept == before["finished"].tolist()
    assert len(set(after["pid"])) >= 2  # the cases ran in worker processes


def test_sweep_command(tables_only, tmp_path):
    scenario = tables_only
    result = CliRunner().invoke(
        app, ["sweep", str(scenario), "--set", "law.H=5,10", "--scheduler", "synchronous", "-o", str(tmp_path / "s")]
    )
    assert result.exit_code == 0, result.stderr
    assert "2 case(s) run, 0 already finished" in result.stdout
    table = pd.read_csv(tmp_path / "s" / RESULTS_NAME)
    assert list(table["law.H_MPa"]) == [5, 10] or sorted(table["law.H_MPa"]) == [5, 10]


def test_a_sweeps_cases_draw_their_pictures_in_their_own_process(scenario, tmp_path, monkeypatch):
    """A sweep keeps every core busy with cases: no second process per case for the PNGs."""
    import dea_opt.run.pictures as pictures

    def no_worker(*args, **kwargs):
        raise AssertionError("a sweep's case started a PictureWorker")

    monkeypatch.setattr(pictures, "PictureWorker", no_worker)
    result = run_sweep(scenario, ["law.H=5,10"], tmp_path / "sweep", scheduler="synchronous")
    assert (result.table["status"] == "ok").all()
    for row in result.table.itertuples():
        assert (Path(row.output_dir) / "cycle.png").stat().st_size > 1000
        assert (Path(row.output_dir) / "exposure.png").stat().st_size > 1000


def test_ctrl_c_in_a_sweep_says_how_many_cases_are_finished_and_a_rerun_completes_it(tmp_path, monkeypatch):
    import dea_opt.sweep as sweep_module
    from dea_opt.run.publish import RunInterrupted

    scenario = tmp_path / "hip.toml"
    scenario.write_text(LIGHT)
    out = tmp_path / "sweep"
    sets = ["law.H=5,10,20"]
    work, calls = sweep_module.work, []

    def interrupted_at_the_second(task):
        calls.append(task.case_id)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return work(task)

    monkeypatch.setattr(sweep_module, "work", interrupted_at_the_second)
    with pytest.raises(RunInterrupted) as info:
        run_sweep(scenario, sets, out, scheduler="synchronous")
    report = info.value.report
    assert "1 of the sweep's 3 cases are finished" in report and "compute the other 2" in report
    assert [line["case_id"] for line in journal_lines(out)] == calls[:1]
    assert list(read_results(out / RESULTS_NAME)["case_id"]) == calls[:1]  # the table agrees with the journal
    monkeypatch.setattr(sweep_module, "work", work)
    again = run_sweep(scenario, sets, out, scheduler="synchronous")
    assert again.skipped == calls[:1] and len(again.ran) == 2 and len(again.table) == 3
