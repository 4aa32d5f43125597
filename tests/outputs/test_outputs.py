"""One run, one consistent output folder: staged outputs published together under a manifest written
last, folders of someone else's refused, stale temporary files removed, Ctrl-C told truthfully.

The kill tests run ``dea-opt run`` in a subprocess and stop it with SIGKILL or SIGINT at seeded
random moments; whatever the moment, the folder holds either a manifest whose files all exist
and agree with it (and with each other: summary.json's peak is frames.csv's largest), or no
manifest at all.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import COARSE_SOCKET

from dea_opt.errors import OutputFolderError
from dea_opt.files.atomic import TEMPORARY_NAME, write_data
from dea_opt.run.publish import (
    INCOMPLETE_NAME,
    MANIFEST_NAME,
    RunInterrupted,
    check_output_folder,
    check_outputs,
    output_run,
    read_manifest,
)

ROOT = Path(__file__).resolve().parents[2]

PATH_SCENARIO = (
    'title = "coarse hip, short gait"\n'
    + COARSE_SOCKET
    + """\
[load_path]
builtin = "hip_gait"
frames = 24
[output]
directory = "out"
"""
)


def temporary_files(folder: Path) -> list[Path]:
    return [p for p in folder.rglob("*") if TEMPORARY_NAME.match(p.name)]


def consistent(folder: Path) -> bool:
    """True with a manifest whose files agree with it and with each other; False without a manifest."""
    manifest = read_manifest(folder)
    if manifest is None:
        return False
    assert check_outputs(folder) == [], check_outputs(folder)
    summary = json.loads((folder / "summary.json").read_text())
    frames = pd.read_csv(folder / "frames.csv")
    assert summary["peak_pressure_MPa"] == frames["peak_pressure_MPa"].max()
    assert summary["frames"] == len(frames)
    assert set(manifest["files"]) >= {"summary.json", "frames.csv", "series.pvd"}
    return True


# --- the publication, in process ------------------------------------------------------------


def test_staged_files_appear_together_with_the_manifest_last(tmp_path):
    folder = tmp_path / "out"
    with output_run(folder, info={"command": "test"}) as run:
        write_data(run.folder / "a.txt", "new a")
        write_data(run.folder / "sub" / "b.txt", "new b")
        # staged: complete temporary files beside the targets, the targets not there yet
        assert not (folder / "a.txt").exists() and not (folder / MANIFEST_NAME).exists()
        assert len(temporary_files(folder)) == 2
        manifest = run.publish(status="ok")
    assert (folder / "a.txt").read_text() == "new a" and (folder / "sub" / "b.txt").read_text() == "new b"
    assert set(manifest["files"]) == {"a.txt", "sub/b.txt"} and manifest["status"] == "ok"
    assert manifest["files"]["a.txt"]["size_bytes"] == 5
    assert read_manifest(folder)["run_id"] == manifest["run_id"] == run.run_id
    assert check_outputs(folder) == [] and temporary_files(folder) == [] and not (folder / INCOMPLETE_NAME).exists()


def test_a_rerun_replaces_the_old_set_and_removes_what_it_no_longer_writes(tmp_path):
    folder = tmp_path / "out"
    with output_run(folder) as run:
        write_data(run.folder / "old.txt", "old")
        write_data(run.folder / "frames" / "f0.txt", "0")
        write_data(run.folder / "kept.txt", "first")
        first = run.publish()
    (folder / "notes.txt").write_text("a file of the user's, written after the run")
    with output_run(folder) as run:
        assert run.previous["run_id"] == first["run_id"]
        write_data(run.folder / "kept.txt", "second")
        second = run.publish()
    assert set(second["files"]) == {"kept.txt"} and (folder / "kept.txt").read_text() == "second"
    assert not (folder / "old.txt").exists() and not (folder / "frames").exists()
    assert (folder / "notes.txt").read_text().startswith("a file of the user's")  # not in the old manifest
    assert check_outputs(folder) == []


def test_an_error_before_publishing_leaves_the_previous_run_untouched(tmp_path):
    folder = tmp_path / "out"
    with output_run(folder) as run:
        write_data(run.folder / "a.txt", "old")
        first = run.publish()
    with pytest.raises(ZeroDivisionError), output_run(folder) as run:
        write_data(run.folder / "a.txt", "new")
        raise ZeroDivisionError
    assert (folder / "a.txt").read_text() == "old" and read_manifest(folder)["run_id"] == first["run_id"]
    assert temporary_files(folder) == []


@pytest.mark.parametrize("published_before", [False, True])
def test_ctrl_c_reports_what_the_folder_holds(tmp_path, published_before):
    folder = tmp_path / "out"
    if published_before:
        with output_run(folder) as run:
            write_data(run.folder / "a.txt", "old")
            first = run.publish()
    with pytest.raises(RunInterrupted) as info, output_run(folder) as run:
        write_data(run.folder / "a.txt", "new")
        raise KeyboardInterrupt
    report = info.value.report
    assert isinstance(info.value, KeyboardInterrupt) and "no output of this run was published" in report
    if published_before:
        assert first["run_id"] in report and "complete outputs of the previous run" in report
        assert (folder / "a.txt").read_text() == "old" and check_outputs(folder) == []
    else:
        assert "holds no complete outputs" in report and read_manifest(folder) is None
    assert temporary_files(folder) == []


@pytest.mark.parametrize("moment", ["casting", "printing"])
def test_ctrl_c_outside_the_publication_still_says_what_the_folder_holds(tmp_path, monkeypatch, capsys, moment):
    """Before the run's folder is staged (casting) or after it published (printing the summary)."""
    import dea_opt.cli
    import dea_opt.scenario
    from dea_opt.cli import EXIT_INTERRUPTED, main

    scenario = tmp_path / "hip.toml"
    scenario.write_text(PATH_SCENARIO.replace("frames = 24", "frames = 3"))
    monkeypatch.chdir(tmp_path)
    assert main(["run", str(scenario), "-q"]) == 0
    first = read_manifest(tmp_path / "out")

    def interrupt(*args, **kwargs):
        raise KeyboardInterrupt

    if moment == "casting":
        monkeypatch.setattr(dea_opt.scenario, "build_problem_cast", interrupt)
    else:
        monkeypatch.setattr(dea_opt.cli, "_report_outcome", interrupt)
    capsys.readouterr()
    assert main(["run", str(scenario), "-q", "--set", "law.H=7"]) == EXIT_INTERRUPTED
    stderr = capsys.readouterr().err
    now = read_manifest(tmp_path / "out")
    assert stderr.startswith("dea-opt: interrupted; ") and "Traceback" not in stderr
    if moment == "casting":
        assert "no output of this run was published" in stderr and first["run_id"] in stderr
        assert now["run_id"] == first["run_id"]
    else:
        assert "published before the interrupt" in stderr and now["run_id"] != first["run_id"]
        assert now["overrides"] == {"law.H": 7}
    assert check_outputs(tmp_path / "out") == []


def test_ctrl_c_inside_a_string_exec_still_exits_130_under_python_m(tmp_path):
    """CPython 3.11 flags a KeyboardInterrupt that escaped ``exec("...")`` and ``python -m`` then
    kills itself with SIGINT at exit (return code -2, not the 130 we print)."""
    (tmp_path / "interrupted_cli.py").write_text(
        "import dea_opt.scenario\n"
        "def load(*args, **kwargs):\n"
        "    exec('raise KeyboardInterrupt')\n"
        "dea_opt.scenario.load_scenario = load\n"
        "from dea_opt.cli import entry\n"
        "entry()\n"
    )
    done = subprocess.run(
        [sys.executable, "-m", "interrupted_cli", "run", "any.toml"], cwd=tmp_path, capture_output=True, text=True
    )
    assert done.returncode == 130 and done.stderr.startswith("dea-opt: interrupted; "), done.stderr


def test_the_report_of_a_folder_after_its_run_published_says_so_however_it_is_named(tmp_path, monkeypatch):
    from dea_opt.run.publish import forget_published, interrupted_report

    monkeypatch.chdir(tmp_path)
    forget_published()
    assert "holds no complete outputs" in interrupted_report("out")
    with output_run("out") as run:
        write_data(run.folder / "a.txt", "new")
        run.publish()
    for name in ("out", tmp_path / "out", f"{tmp_path}/out/"):
        assert "were published before the interrupt" in interrupted_report(name)
    forget_published()  # another command: the folder holds a previous run
    assert f"complete outputs of the previous run {run.run_id}" in interrupted_report("out")


def test_ctrl_c_while_dea_opt_starts_exits_130_with_one_line(tmp_path):
    """The console script imports the package under a handler (``_dea_opt_cli``)."""
    code = (
        "import sys\n"
        "class Interrupting:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name == 'dea_opt.cli':\n"
        "            raise KeyboardInterrupt\n"
        "sys.meta_path.insert(0, Interrupting())\n"
        "import _dea_opt_cli\n"
        "_dea_opt_cli.entry()\n"
    )
    done = subprocess.run([sys.executable, "-c", code, "run", "any.toml"], capture_output=True, text=True, cwd=ROOT)
    assert done.returncode == 130, done.stderr
    assert done.stderr == "dea-opt: interrupted while starting; no output of this command was published\n"


def test_ctrl_c_while_the_command_line_is_parsed_says_so(monkeypatch, capsys):
    """typer turns a KeyboardInterrupt outside a command into a silent exit 130."""
    import typer

    from dea_opt.cli import EXIT_INTERRUPTED, app, main

    def interrupt(*args, **kwargs):
        raise KeyboardInterrupt

    # click's Command, as typer uses it (a typer release may carry its own copy of click)
    command = next(c for c in type(typer.main.get_command(app)).__mro__ if c.__name__ == "Command")
    monkeypatch.setattr(command, "parse_args", interrupt)
    assert main(["version"]) == EXIT_INTERRUPTED
    assert capsys.readouterr().err == "dea-opt: interrupted; no output of this command was published\n"


def test_ctrl_c_during_publication_waits_for_it_and_says_so(tmp_path):
    folder = tmp_path / "out"
    with pytest.raises(RunInterrupted) as info, output_run(folder) as run:
        write_data(run.folder / "a.txt", "new")
        original = os.replace

        def replace_then_interrupt(src, dst):  # Ctrl-C arrives in the middle of the renames
            original(src, dst)
            os.kill(os.getpid(), signal.SIGINT)

        os.replace = replace_then_interrupt
        try:
            run.publish()
        finally:
            os.replace = original
    assert "were published before the interrupt" in info.value.report
    assert check_outputs(folder) == [] and read_manifest(folder)["run_id"] == run.run_id


@pytest.mark.parametrize("renamed", [0, 1, 2, 3])
def test_a_crash_in_the_middle_of_the_renames_leaves_no_manifest_and_says_so(tmp_path, renamed):
    """Rename 0 is INCOMPLETE.json's: failing there leaves the old set; any later leaves no manifest."""
    folder = tmp_path / "out"
    with output_run(folder) as run:
        for name in ("a.txt", "b.txt", "c.txt"):
            write_data(run.folder / name, "old " + name)
        run.publish()
    original, count = os.replace, []

    def failing_replace(src, dst):  # the disk fills up (or the power fails) after `renamed` renames
        if len(count) == renamed:
            raise OSError(28, "No space left on device")
        count.append(dst)
        original(src, dst)

    with pytest.raises(OSError), output_run(folder) as run:
        for name in ("a.txt", "b.txt", "c.txt"):
            write_data(run.folder / name, "new " + name)
        os.replace = failing_replace
        try:
            run.publish()
        finally:
            os.replace = original
    texts = {(folder / n).read_text() for n in ("a.txt", "b.txt", "c.txt")}
    assert any(t.startswith("new") for t in texts) == (renamed > 1)  # the files may now mix two runs ...
    if renamed == 0:
        assert check_outputs(folder) == [] and texts == {"old a.txt", "old b.txt", "old c.txt"}
    else:
        assert not (folder / MANIFEST_NAME).exists()  # ... so there is no manifest, and the folder says why
        assert "did not finish" in json.loads((folder / INCOMPLETE_NAME).read_text())["message"]
    assert temporary_files(folder) == []
    check_output_folder(folder)  # still a dea-opt folder: the next run may complete it
    with output_run(folder) as run:
        write_data(run.folder / "a.txt", "third")
        run.publish()
    assert check_outputs(folder) == [] and not (folder / INCOMPLETE_NAME).exists()


# --- which folders a run may write into ------------------------------------------------------


def test_a_folder_of_someone_elses_is_refused_by_name(tmp_path):
    folder = tmp_path / "home"
    folder.mkdir()
    (folder / "contact.csv").write_text("a user's table that must survive")
    with pytest.raises(OutputFolderError) as info:
        check_output_folder(folder)
    assert str(folder) in str(info.value) and "contact.csv" in str(info.value) and "--force" in str(info.value)
    with pytest.raises(OutputFolderError), output_run(folder):
        pass
    assert (folder / "contact.csv").read_text() == "a user's table that must survive"
    with output_run(folder, force=True) as run:  # --force: allowed, the outputs replace their names only
        write_data(run.folder / "contact.csv", "dea-opt's")
        run.publish()
    assert read_manifest(folder) is not None


def test_new_empty_and_dea_opt_folders_are_accepted(tmp_path):
    assert check_output_folder(tmp_path / "new" / "deeper") == tmp_path / "new" / "deeper"
    (tmp_path / "empty").mkdir()
    check_output_folder(tmp_path / "empty")
    leftovers = tmp_path / "leftovers"  # only a lock, a stale temporary file and a sweep's folder
    (leftovers / "sweep").mkdir(parents=True)
    (leftovers / "sweep" / "sweep.jsonl").write_text("")
    (leftovers / ".dea-opt.lock").write_text("")
    (leftovers / ".contact.csv.0123abcd.tmp.csv").write_text("half")
    check_output_folder(leftovers)
    (tmp_path / "file").write_text("x")
    with pytest.raises(OutputFolderError, match="is a file"):
        check_output_folder(tmp_path / "file")


def test_a_nul_byte_in_the_folder_is_a_named_error(tmp_path):
    from dea_opt.errors import InputError

    with pytest.raises(InputError, match="NUL byte"):
        check_output_folder(str(tmp_path / "a\0b"))


def test_two_runs_into_one_folder_at_once_are_refused(tmp_path):
    folder = tmp_path / "out"
    with output_run(folder):
        with pytest.raises(OutputFolderError, match="another dea-opt run"), output_run(folder):
            pass


def test_stale_temporary_files_are_removed_at_the_start_of_the_next_run(tmp_path):
    folder = tmp_path / "out"
    (folder / "series_frames").mkdir(parents=True)
    stale = [folder / ".frames.csv.1234abcd.tmp.csv", folder / "series_frames" / ".frame_0001.vtu.deadbeef.tmp.vtu"]
    for path in stale:
        path.write_text("left by kill -9")
    (folder / "series_frames" / "frame_0001.vtu").write_text("")
    (folder / INCOMPLETE_NAME).write_text(json.dumps({"format": "dea-opt incomplete run"}))
    with output_run(folder) as run:
        assert not any(p.exists() for p in stale)
        write_data(run.folder / "frames.csv", "x\n")
        run.publish()
    assert temporary_files(folder) == [] and check_outputs(folder) == []


# --- kill -9 and Ctrl-C of dea-opt run, at random moments ------------------------------------


def _dea_opt(*args) -> list[str]:
    return [sys.executable, "-m", "dea_opt.cli", *map(str, args)]


def _run(args, cwd) -> subprocess.CompletedProcess:
    return subprocess.run(
        _dea_opt(*args), cwd=cwd, capture_output=True, text=True, timeout=300, env={**os.environ, "MPLBACKEND": "Agg"}
    )


@pytest.mark.slow
def test_kill_and_ctrl_c_at_random_moments_never_leave_two_runs_in_one_folder(tmp_path):
    scenario = tmp_path / "hip.toml"
    scenario.write_text(PATH_SCENARIO)
    folder = tmp_path / "out"
    start = time.perf_counter()
    done = _run(["run", scenario, "-q"], tmp_path)
    whole = time.perf_counter() - start
    assert done.returncode == 0, done.stderr
    assert consistent(folder)
    rng = np.random.default_rng(20261123)
    outcomes = []
    for trial in range(12):
        previous = read_manifest(folder)
        how = signal.SIGKILL if trial % 2 == 0 else signal.SIGINT
        modulus = 5.0 + trial  # every run's peak differs, so a mixed folder would show
        process = subprocess.Popen(
            _dea_opt("run", scenario, "-q", "--set", f"law.H={modulus}"),
            cwd=tmp_path,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env={**os.environ, "MPLBACKEND": "Agg"},
        )
        time.sleep(rng.uniform(0.3, 1.05) * whole)
        process.send_signal(how)
        _, stderr = process.communicate(timeout=300)
        has_manifest = consistent(folder)
        outcomes.append((how.name, process.returncode, has_manifest))
        if not has_manifest:
            assert not (folder / MANIFEST_NAME).exists()
        if how == signal.SIGINT and "dea-opt: interrupted" in stderr:  # the message tells the truth
            manifest = read_manifest(folder)
            if "published before the interrupt" in stderr:
                assert manifest is not None and manifest["run_id"] != (previous or {}).get("run_id")
            elif "complete outputs of the previous run" in stderr:
                assert manifest is not None and manifest["run_id"] == previous["run_id"]
                assert previous["run_id"] in stderr
            elif "no output of this command was published" in stderr:  # before the scenario named the folder
                assert (manifest or {}).get("run_id") == (previous or {}).get("run_id")
            else:
                assert "holds no complete outputs" in stderr or "incomplete earlier run" in stderr, stderr
                assert manifest is None
    print("\n(signal, exit code, manifest after):", outcomes)
    done = _run(["run", scenario, "-q"], tmp_path)  # the next run cleans up and publishes
    assert done.returncode == 0, done.stderr
    assert consistent(folder) and temporary_files(folder) == [] and not (folder / INCOMPLETE_NAME).exists()


def test_a_run_leaves_the_temporary_files_of_a_comparison_or_sweep_below_it_alone(tmp_path):
    folder = tmp_path / "out"
    (folder / "sweep").mkdir(parents=True)
    (folder / "sweep" / "sweep.jsonl").write_text("")
    busy = folder / "sweep" / ".sweep.csv.0123abcd.tmp.csv"  # a live sweep is writing sweep.csv
    busy.write_text("being written")
    (folder / "series_frames").mkdir()
    stale = folder / "series_frames" / ".frame_0000.vtu.0123abcd.tmp.vtu"
    stale.write_text("left by kill -9")
    (folder / INCOMPLETE_NAME).write_text(json.dumps({"format": "dea-opt incomplete run"}))  # killed mid-swap
    with output_run(folder) as run:
        run.publish()
    assert busy.exists() and not stale.exists()


def test_a_process_that_publishes_run_after_run_keeps_only_the_last_ones_for_its_report(tmp_path):
    from dea_opt.run import publish

    publish.forget_published()
    for k in range(publish._PUBLISHED_KEPT + 5):  # a sweep's worker: case after case
        with output_run(tmp_path / f"case{k}") as run:
            write_data(run.folder / "a.txt", str(k))
            run.publish()
    report = publish.published_report()
    assert len(publish._published) == publish._PUBLISHED_KEPT
    assert str(tmp_path / f"case{publish._PUBLISHED_KEPT + 4}") in report and f"{tmp_path / 'case0'} " not in report
    publish.forget_published()
