"""A refused run leaves no trace: ``dea-opt run`` / ``compare`` that reject their input after the
output folder was locked (exit 2) remove the lock file and the folders they made, when nothing else
is in them; a folder that was there before, or holds anything else, stays as it was. Two runs at
once: the second is refused by the first's lock and leaves the first's lock and folder alone.
"""

from __future__ import annotations

import os

import pytest
from conftest import KNEE_SCENARIO, scenario_text
from typer.testing import CliRunner

from dea_opt.cli import app
from dea_opt.errors import InputError, OutputFolderError
from dea_opt.files.atomic import write_data
from dea_opt.run import folderlock
from dea_opt.run.publish import LOCK_NAME, MANIFEST_NAME, check_outputs, output_run, read_manifest

runner = CliRunner()

#: A plate pulled away from its bed: bad input found by the solve, inside the output folder's lock
#: (the check before solving, which would stop it before the lock, is turned off).
PULLED = (
    scenario_text(nx=8, H=20.0, free=("uz",), force=500.0)
    + '[solve]\ncheck_inputs = false\n[output]\nformats = ["json"]\n'
)
PRESSED = PULLED.replace("force = [0.0, 0.0, 500.0]", "force = [0.0, 0.0, -500.0]")
#: The coarse generated knee with finite kinematics: ``compare --methods qp`` is refused.


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


def refused(result, *words):
    assert result.exit_code == 2, (result.stdout, result.stderr)
    text = " ".join(result.stderr.split())
    assert text.startswith("dea-opt: error: ") and "Traceback" not in text and "internal error" not in text
    for word in words:
        assert word in text, text


def listing(folder):
    return sorted(p.relative_to(folder).as_posix() for p in folder.rglob("*"))


@pytest.fixture
def pulled(tmp_path):
    path = tmp_path / "pulled.toml"
    path.write_text(PULLED)
    return path


def test_a_refused_run_into_a_new_folder_leaves_no_folder(pulled, tmp_path):
    out = tmp_path / "new" / "deeper" / "out"  # three folders the run makes
    refused(invoke("run", pulled, "-o", out), "cannot carry this load")
    assert not (tmp_path / "new").exists()


def test_a_refused_compare_into_a_new_folder_leaves_no_folder(finite, tmp_path):
    out = tmp_path / "cmp"
    refused(invoke("compare", finite, "--methods", "qp", "-o", out), "qp is a small-kinematics method")
    assert not out.exists()
    # its default folder, <[output].directory>/compare, and the output directory above it
    refused(invoke("compare", finite, "--methods", "qp"), "no method in --methods solves this problem")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["finite.toml"]


def test_a_refused_run_into_a_folder_with_a_file_leaves_both_as_they_were(pulled, tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("a file of the user's")
    before = os.stat(out)
    refused(invoke("run", pulled, "-o", out, "--force"), "cannot carry this load")
    assert listing(out) == ["notes.txt"]  # no lock left behind either: the run made it
    assert (out / "notes.txt").read_text() == "a file of the user's"
    assert (os.stat(out).st_ino, os.stat(out).st_dev) == (before.st_ino, before.st_dev)
    # an empty folder of the user's stays too
    empty = tmp_path / "empty"
    empty.mkdir()
    refused(invoke("run", pulled, "-o", empty), "cannot carry this load")
    assert empty.is_dir() and listing(empty) == []


def test_a_refused_run_into_the_folder_of_an_earlier_run_leaves_that_run_whole(pulled, tmp_path):
    pressed = tmp_path / "pressed.toml"
    pressed.write_text(PRESSED)
    out = tmp_path / "out"
    assert invoke("run", pressed, "-o", out).exit_code == 0
    first, files = read_manifest(out), listing(out)
    assert LOCK_NAME in files
    refused(invoke("run", pulled, "-o", out), "cannot carry this load")
    assert listing(out) == files and read_manifest(out)["run_id"] == first["run_id"] and check_outputs(out) == []


def test_a_second_run_at_once_is_refused_and_leaves_the_first_runs_lock_and_folder(pulled, tmp_path):
    out = tmp_path / "new" / "out"
    with output_run(out) as first:  # the first run made both folders and holds the lock
        lock = out / LOCK_NAME
        held = os.stat(lock)
        assert lock.read_text() == f"{os.getpid()}\n"
        with pytest.raises(OutputFolderError, match=f"another dea-opt run \\(pid {os.getpid()}\\) is writing"):
            with output_run(out):
                pass
        refused(invoke("run", pulled, "-o", out), "another dea-opt run", str(out))
        assert os.path.samestat(os.stat(lock), held) and lock.read_text() == f"{os.getpid()}\n"
        write_data(first.folder / "a.txt", "the first run's")
        first.publish()
    assert (out / "a.txt").read_text() == "the first run's" and check_outputs(out) == []


def test_a_lock_on_a_file_a_refused_run_removed_is_no_lock_and_the_next_run_looks_again(tmp_path, monkeypatch):
    out = tmp_path / "out"
    with pytest.raises(InputError, match="refused"), output_run(out):
        stale = os.open(out / LOCK_NAME, os.O_RDWR)  # a second run opened the lock file meanwhile
        raise InputError("refused")
    assert not out.exists()  # the first run left: its folder and lock file are gone
    opened = []

    def open_lock(path):  # the second run locks the file it opened before it was removed
        opened.append(path)
        return (stale, False) if len(opened) == 1 else real(path)

    real = folderlock._open_lock
    monkeypatch.setattr(folderlock, "_open_lock", open_lock)
    with output_run(out) as second:
        assert len(opened) == 2  # it looked again, made the folder and a lock file anew
        with pytest.raises(OutputFolderError, match="another dea-opt run"), output_run(out):
            pass  # and that lock is the one a third run meets
        write_data(second.folder / "a.txt", "second")
        second.publish()
    assert check_outputs(out) == [] and (out / MANIFEST_NAME).is_file()


def test_a_parent_removed_while_a_run_makes_its_folder_is_made_again(tmp_path, monkeypatch):
    """Two sweep cases share ``cases/``: one that refuses its input removes it when it made it and
    it is empty, while the other is making ``cases/<id>`` inside."""
    out = tmp_path / "cases" / "b"
    out.parent.mkdir()  # made by the other case, which refuses its input and removes it
    real = os.mkdir
    removed = []

    def mkdir(path, *args, **kwargs):
        if str(path) == str(out) and not removed:  # the other case removes cases/ just now
            removed.append(True)
            os.rmdir(out.parent)
        return real(path, *args, **kwargs)

    monkeypatch.setattr(folderlock.os, "mkdir", mkdir)
    with output_run(out) as run:  # cases/ seen, removed, then missing under cases/b: made again
        assert removed and out.is_dir()
        write_data(run.folder / "a.txt", "b's")
        run.publish()
    assert check_outputs(out) == []


def test_a_sweep_case_refused_before_it_wrote_anything_names_no_folder(tmp_path, monkeypatch):
    """The case's row says where its outputs are; a case that left none names no folder."""
    import dea_opt.run
    from dea_opt.sweep.cases import run_case

    scenario = tmp_path / "s.toml"
    scenario.write_text(KNEE_SCENARIO)

    def refused(scenario, output_dir, **kwargs):
        with output_run(output_dir):  # takes the folder's lock, then refuses its input
            raise InputError("law.H: expected a positive number, got -1")

    monkeypatch.setattr(dea_opt.run, "run_scenario", refused)
    case_dir = tmp_path / "sweep" / "cases" / "abc"
    row = run_case(scenario, {}, case_dir)
    assert row["status"] == "error" and "law.H" in row["message"]
    assert row["output_dir"] == "" and not (tmp_path / "sweep").exists()


def test_a_path_stopped_at_a_failed_frame_leaves_no_frames_folder(tmp_path):
    """``--stop-on-error``: the frames solved before the failed one were written into
    ``series_frames/`` as they came (staged); none is published, so neither is the folder."""
    loads = tmp_path / "loads.csv"
    loads.write_text("time,Fx,Fy,Fz,Mx,My,Mz\n0,0,0,-500,0,0,0\n0.1,0,0,-800,0,0,0\n0.2,0,0,500,0,0,0\n")
    scenario = tmp_path / "path.toml"
    scenario.write_text(
        PULLED.replace("[load]\nforce = [0.0, 0.0, 500.0]", '[load_path]\nfile = "loads.csv"').replace(
            'formats = ["json"]', 'formats = ["json", "vtk"]'
        )
    )
    out = tmp_path / "out"
    refused(invoke("run", scenario, "-o", out, "--stop-on-error"), "frame 2")
    assert not out.exists()
    # the same into an earlier run's folder: that run stays whole, no frames folder beside it
    assert invoke("run", scenario, "-o", out).exit_code == 1  # frame 2 recorded as failed
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    assert any(p.parent.name == "series_frames" for p in before)
    refused(invoke("run", scenario, "-o", out, "--stop-on-error"), "frame 2")
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before and check_outputs(out) == []
