"""Sweeps under concurrency and kills: real processes share one sweep folder.

The cases are a small plate (100 x 10 springs, linear law, JSON output only): a few
milliseconds each, so the tests spend their time in process start-up, and the sweeps run
with the synchronous scheduler (the LocalCluster kill test is in test_sweep.py).
Evidence of "computed once" is read here with plain json from the journal (one line per
computation) and from the records' computation counts, not through dea-opt's reader.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import pandas as pd
import pytest
from conftest import scenario_text

from dea_opt.sweep import (
    JOURNAL_NAME,
    RESULTS_NAME,
    journal,
    make_cases,
    read_results,
    run_sweep,
)
from dea_opt.sweep.cases import CaseTask, read_text

PLATE = scenario_text(title="plate for sweeps", nx=100, ny=10, point=(5.0, 0.0, 0.0), formats=("json",))

# A sweep in its own process, started when the file `go` appears, so two start together.
DRIVER = """\
import json, sys, time
from pathlib import Path
from dea_opt.sweep import run_sweep
scenario, out, go, *sets = sys.argv[1:]
print("ready", flush=True)
while not Path(go).exists():
    time.sleep(0.002)
result = run_sweep(scenario, sets, out, scheduler="synchronous")
print(json.dumps({"ran": result.ran, "skipped": result.skipped, "adopted": result.adopted}))
"""

# Holds a case's claim like a sweep computing it; on "compute" computes it, as a sweep would.
HOLDER = """\
import json, sys
from dea_opt.sweep.cases import CaseTask, work_claimed
from dea_opt.sweep.journal import claim
task = CaseTask(**json.loads(sys.argv[1]))
with claim(task.out, task.case_id, wait=False) as held:
    print("held" if held else "taken", flush=True)
    if held and sys.stdin.readline().strip() == "compute":
        print(work_claimed(task)["outcome"], flush=True)
"""


@pytest.fixture()
def plate(tmp_path):
    path = tmp_path / "plate.toml"
    path.write_text(PLATE)
    return path


def journal_lines(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / JOURNAL_NAME).read_text().splitlines() if line.strip()]


def runs(out: Path) -> dict:
    return {p.stem: json.loads(p.read_text())["runs"] for p in (out / ".sweep" / "records").glob("[!.]*.json")}


def statuses_right(csv) -> bool:
    """Every case certified; outside validity exactly where the plate's peak strain (peak pressure
    over H, the linear law) passes the linear law's 30 %."""
    outside = csv["peak_pressure_MPa"] / csv["law.H_MPa"] > 0.3
    return bool((csv["status"] == outside.map({True: "outside_validity", False: "ok"})).all())


def values(first: int, last: int) -> str:
    return "law.H=" + ",".join(str(h) for h in range(first, last + 1))


def sweeps_at_once(tmp_path, scenario, out, jobs: list[list[str]]) -> list[dict]:
    """Run one sweep process per entry of ``jobs`` (its --set texts), started together."""
    driver = tmp_path / "driver.py"
    driver.write_text(DRIVER)
    go = tmp_path / "go"
    processes = [
        subprocess.Popen(
            [sys.executable, str(driver), str(scenario), str(out), str(go), *sets],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for sets in jobs
    ]
    for process in processes:
        assert process.stdout.readline().strip() == "ready"
    go.touch()
    reports = []
    for process in processes:
        stdout, stderr = process.communicate(timeout=180)
        assert process.returncode == 0, stderr
        reports.append(json.loads(stdout.splitlines()[-1]))
    return reports


def test_two_sweeps_with_disjoint_cases_into_one_folder_lose_nothing(plate, tmp_path):
    out = tmp_path / "sweep"
    jobs = [[values(1, 20), "load.scale=1"], [values(21, 40), "load.scale=1"]]
    reports = sweeps_at_once(tmp_path, plate, out, jobs)
    for sets, report in zip(jobs, reports):
        assert sorted(report["ran"]) == sorted(c.id for c in make_cases(sets))
    expected = sorted(c.id for sets in jobs for c in make_cases(sets))
    assert sorted(r["case_id"] for r in journal_lines(out)) == expected  # each computed and recorded once
    csv = pd.read_csv(out / RESULTS_NAME, dtype={"case_id": str})
    assert sorted(csv["case_id"]) == expected and statuses_right(csv)
    assert sorted(csv["law.H_MPa"]) == list(range(1, 41))
    assert set(runs(out).values()) == {1}


def test_the_same_sweep_twice_at_once_computes_each_case_once(plate, tmp_path):
    out = tmp_path / "sweep"
    sets = [values(1, 30), "load.scale=1,2"]
    expected = sorted(c.id for c in make_cases(sets))
    reports = sweeps_at_once(tmp_path, plate, out, [sets, sets])
    first, second = (set(r["ran"]) for r in reports)
    assert not first & second and sorted(first | second) == expected
    for report in reports:  # each process accounts for every case exactly once
        assert sorted(report["ran"] + report["skipped"] + report["adopted"]) == expected
    assert sorted(r["case_id"] for r in journal_lines(out)) == expected
    csv = pd.read_csv(out / RESULTS_NAME, dtype={"case_id": str})
    assert sorted(csv["case_id"]) == expected and statuses_right(csv)
    assert set(runs(out).values()) == {1} and sorted(runs(out)) == expected


def _task(scenario: Path, out: Path, overrides: dict) -> CaseTask:
    text, sha = read_text(scenario)
    case = make_cases([f"{k}={v}" for k, v in overrides.items()])[0]
    return CaseTask(str(out), str(scenario), text, sha, case.id, case.overrides)


def _hold(tmp_path, task: CaseTask) -> subprocess.Popen:
    holder = tmp_path / "holder.py"
    holder.write_text(HOLDER)
    process = subprocess.Popen(
        [sys.executable, str(holder), json.dumps(task.__dict__)],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        text=True,
    )
    assert process.stdout.readline().strip() == "held"
    return process


def _sweep_in_thread(scenario, sets, out):
    box = {}

    def target():
        try:
            box["result"] = run_sweep(scenario, sets, out, scheduler="synchronous", log=False)
        except BaseException as exc:  # noqa: BLE001 - handed to the test
            box["error"] = exc

    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    return thread, box


def _wait_for_rows(out: Path, n: int, thread) -> pd.DataFrame:
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and thread.is_alive():
        if (out / JOURNAL_NAME).is_file() and len(table := read_results(out)) >= n:
            return table
        time.sleep(0.02)
    raise AssertionError(f"the sweep did not reach {n} rows")


def test_a_case_another_live_process_computes_is_taken_from_its_record(plate, tmp_path):
    out = tmp_path / "sweep"
    sets = [values(1, 6)]
    held = _task(plate, out, {"law.H": 3})
    holder = _hold(tmp_path, held)
    try:
        thread, box = _sweep_in_thread(plate, sets, out)
        table = _wait_for_rows(out, 5, thread)
        # Every other case is done; the held one is not computed while its claim is held.
        assert held.case_id not in set(table["case_id"]) and thread.is_alive()
        holder.stdin.write("compute\n")
        holder.stdin.flush()
        assert holder.stdout.readline().strip() == "ran"
        thread.join(timeout=120)
    finally:
        holder.kill()
        holder.wait()
    assert "error" not in box, box.get("error")
    result = box["result"]
    assert result.adopted == [held.case_id] and held.case_id not in result.ran and len(result.ran) == 5
    lines = journal_lines(out)
    assert sorted(r["case_id"] for r in lines) == sorted(c.id for c in make_cases(sets))
    assert next(r["pid"] for r in lines if r["case_id"] == held.case_id) == holder.pid
    assert runs(out)[held.case_id] == 1
    assert len(pd.read_csv(out / RESULTS_NAME)) == 6


def test_a_claim_dies_with_its_process(plate, tmp_path):
    out = tmp_path / "sweep"
    sets = [values(1, 4)]
    held = _task(plate, out, {"law.H": 2})
    holder = _hold(tmp_path, held)
    thread, box = _sweep_in_thread(plate, sets, out)
    try:
        _wait_for_rows(out, 3, thread)
        assert thread.is_alive()
    finally:
        os.kill(holder.pid, signal.SIGKILL)  # it dies holding the claim
        holder.wait()
    thread.join(timeout=120)
    assert "error" not in box, box.get("error")
    result = box["result"]
    assert held.case_id in result.ran and not result.adopted and len(result.ran) == 4
    assert [r["pid"] for r in journal_lines(out) if r["case_id"] == held.case_id] == [os.getpid()]


def test_kill_9_mid_sweep_then_rerun_finishes_with_one_row_per_case(plate, tmp_path):
    out = tmp_path / "sweep"
    sets = [values(1, 60)]
    command = [
        sys.executable,
        "-m",
        "dea_opt.cli",
        "sweep",
        str(plate),
        "--set",
        sets[0],
        "--scheduler",
        "synchronous",
        "-o",
        str(out),
    ]
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 120
    try:
        while time.monotonic() < deadline and process.poll() is None:
            if (out / JOURNAL_NAME).is_file() and len(journal_lines(out)) >= 5:
                break
            time.sleep(0.005)
    finally:
        process.kill()
        process.communicate(timeout=60)
    before = {r["case_id"] for r in journal_lines(out)}
    assert 5 <= len(before) < 60, "the sweep should have been killed part way"
    result = run_sweep(plate, sets, out, scheduler="synchronous", log=False)
    assert set(result.skipped) == before and len(result.ran) == 60 - len(before)
    expected = sorted(c.id for c in make_cases(sets))
    assert sorted(r["case_id"] for r in journal_lines(out)) == expected
    csv = pd.read_csv(out / RESULTS_NAME, dtype={"case_id": str})
    assert sorted(csv["case_id"]) == expected and statuses_right(csv)


# --- the journal itself ---------------------------------------------------------------

APPENDER = """\
import sys
from dea_opt.sweep import journal
out, name, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
for i in range(n):
    journal.append(out, {"case_id": f"{name}-{i}", "status": "ok", "padding": "x" * (i % 7) * 1000})
"""


def test_appends_from_two_processes_lose_nothing(tmp_path):
    script = tmp_path / "appender.py"
    script.write_text(APPENDER)
    processes = [subprocess.Popen([sys.executable, str(script), str(tmp_path), name, "300"]) for name in "ab"]
    assert [p.wait(timeout=120) for p in processes] == [0, 0]
    ids = [r["case_id"] for r in journal_lines(tmp_path)]
    assert sorted(ids) == sorted(f"{name}-{i}" for name in "ab" for i in range(300))


def test_an_append_writes_one_line_and_never_reads_the_rest(tmp_path):
    # What is already there is not even JSON: an append that parsed or rewrote it would fail.
    before = b"not json\n" * 100_000
    (tmp_path / JOURNAL_NAME).write_bytes(before)
    offset, length = journal.append(tmp_path, {"case_id": "abc", "status": "ok"})
    data = (tmp_path / JOURNAL_NAME).read_bytes()
    assert data[: len(before)] == before and offset == len(before) and len(data) == len(before) + length
    assert json.loads(data[offset:]) == {"case_id": "abc", "status": "ok"}


def test_a_line_cut_short_by_a_kill_is_dropped_and_the_journal_goes_on(tmp_path):
    whole = b'{"case_id":"a","status":"ok"}\n'
    (tmp_path / JOURNAL_NAME).write_bytes(whole + b'{"case_id":"b","sta')
    assert list(journal.read_records(tmp_path)) == ["a"]  # the cut line is not a record
    journal.append(tmp_path, {"case_id": "c", "status": "ok"})
    assert (tmp_path / JOURNAL_NAME).read_bytes() == whole + b'{"case_id":"c","status":"ok"}\n'
    assert list(journal.read_records(tmp_path)) == ["a", "c"]


def test_a_later_record_replaces_the_row_in_place(tmp_path):
    for record in (
        {"case_id": "a", "status": "error"},
        {"case_id": "b", "status": "ok"},
        {"case_id": "a", "status": "ok"},
    ):
        journal.append(tmp_path, record)
    table = journal.publish_table(tmp_path)
    csv = pd.read_csv(tmp_path / RESULTS_NAME)
    assert list(csv["case_id"]) == ["a", "b"] and list(csv["status"]) == ["ok", "ok"]
    assert list(table["status"]) == ["ok", "ok"]


def test_a_claim_is_exclusive_between_processes(tmp_path, plate):
    task = _task(plate, tmp_path, {"law.H": 1})
    holder = _hold(tmp_path, task)
    try:
        with journal.claim(tmp_path, task.case_id) as held:
            assert held is False
        second = subprocess.run(
            [sys.executable, str(tmp_path / "holder.py"), json.dumps(task.__dict__)],
            input="",
            capture_output=True,
            text=True,
            timeout=60,
            check=False,
        )
        assert second.stdout.strip() == "taken"
    finally:
        holder.kill()
        holder.wait()
    with journal.claim(tmp_path, task.case_id) as held:
        assert held is True
