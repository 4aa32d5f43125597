"""A load path's pictures (``cycle.png``, ``exposure.png``) are outputs like the others: staged,
published with the rest, listed in ``manifest.json`` with their SHA-256, removed by a rerun that no
longer writes them, and checked by ``check_outputs`` -- also when a
:class:`~dea_opt.run.pictures.PictureWorker` draws them in its own process."""

from __future__ import annotations

import hashlib
import json
import os
import warnings
from pathlib import Path

import numpy as np
import pytest

import dea_opt as d
from dea_opt.files.atomic import TEMPORARY_NAME
from dea_opt.geometry import plate_layer
from dea_opt.loadpath import solve_path
from dea_opt.run import pictures as pictures_module
from dea_opt.run.pictures import DrawHere, PictureFiles, PictureWorker
from dea_opt.run.publish import INCOMPLETE_NAME, MANIFEST_NAME, check_outputs, output_run, read_manifest

#: The runs here draw in a PictureWorker, as outside the tests (tests/conftest.py).
pytestmark = pytest.mark.picture_worker

LOADS = np.array([[0.0, 0.0, -400.0, 0.0, m, 0.0] for m in (-1500.0, 0.0, 1500.0)])
PNGS = ("cycle.png", "exposure.png")

SCENARIO = """\
title = "plate, short gait"
[geometry]
kind = "plate"
nx = 10
ny = 4
[law]
kind = "linear"
H = 10.0
[body2]
free = ["uz"]
[load_path]
builtin = "hip_gait"
frames = 3
"""


def _solve(scale: float):
    problem = d.ContactProblem(plate_layer(40.0, 10.0, 40, 10, thickness=2.0), d.LinearLaw(10.0), free=("uz", "ry"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return solve_path(
            problem, LOADS * scale, times=[0.0, 0.1, 0.2], method="newton", outputs=d.PathOutputs(keep_solutions=True)
        )


@pytest.fixture(scope="module")
def paths():
    """A path and the same path under 1.5 times the load: other pictures."""
    return _solve(1.0), _solve(1.5)


@pytest.fixture(scope="module")
def worker():
    """One PictureWorker for the tests that hand it their pictures (each worker takes a second of
    CPU to warm up); ``dea-opt run``'s own workers are tested by the scenario's test."""
    with PictureWorker() as shared:
        yield shared


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _temporary(folder: Path) -> list[Path]:
    return [p for p in folder.rglob("*") if TEMPORARY_NAME.match(p.name)]


def _publish(path, folder: Path, formats=("csv", "json", "vtk", "png"), pictures=None) -> dict:
    with output_run(folder) as run:
        files = path.write(run.folder, formats, pictures=pictures)
        staged = {name: (folder / name).exists() for name in PNGS}
        manifest = run.publish(status="ok")
    return {"files": files, "staged": staged, "manifest": manifest}


def _worker_only(monkeypatch):
    """Drawing in this process fails: a picture must come from the worker."""

    def refuse(*job):
        raise AssertionError(f"drawn in the run's process, not the worker: {job[:2]}")

    monkeypatch.setattr(pictures_module, "_call", refuse)


@pytest.mark.parametrize("drawer", ["worker", "here"])
def test_the_manifest_lists_the_pictures_with_their_sha256(paths, tmp_path, monkeypatch, drawer, request):
    folder = tmp_path / "out"
    if drawer == "worker":
        worker = request.getfixturevalue("worker")
        assert worker._drawer.process is not None, "the worker did not start"
        _worker_only(monkeypatch)  # the worker still draws them, in parallel with the other files
        out = _publish(paths[0], folder, pictures=worker)
    else:
        out = _publish(paths[0], folder)
    assert out["staged"] == {"cycle.png": False, "exposure.png": False}, "a picture reached the folder unpublished"
    assert (
        out["files"]["cycle_plot"] == folder / "cycle.png" and out["files"]["exposure_map"] == folder / "exposure.png"
    )
    listed = read_manifest(folder)["files"]
    assert listed == out["manifest"]["files"]
    for name in PNGS:
        png = folder / name
        assert png.read_bytes().startswith(b"\x89PNG\r\n\x1a\n")
        assert listed[name] == {"size_bytes": png.stat().st_size, "sha256": _sha256(png)}, name
    summary = json.loads((folder / "summary.json").read_text())
    assert summary["files"]["cycle_plot"] == str(folder / "cycle.png")
    assert check_outputs(folder) == [] and _temporary(folder) == [] and not (folder / INCOMPLETE_NAME).exists()


def test_the_worker_and_the_run_draw_the_same_published_files(paths, tmp_path, worker, monkeypatch):
    here = _publish(paths[0], tmp_path / "here", formats=("png",))["manifest"]["files"]
    _worker_only(monkeypatch)
    there = _publish(paths[0], tmp_path / "there", formats=("png",), pictures=worker)["manifest"]["files"]
    assert set(here) == set(PNGS) and here == there


def test_a_rerun_without_pictures_removes_the_old_pictures(paths, tmp_path, worker):
    """As a shorter path's rerun removes the frames it no longer writes (``series_frames/``)."""
    folder = tmp_path / "out"
    _publish(paths[0], folder, pictures=worker)
    assert {"cycle.png", "exposure.png", "series_frames/frame_0002.vtu"} <= set(read_manifest(folder)["files"])
    second = _publish(paths[1], folder, formats=("csv", "json"), pictures=worker)["manifest"]
    assert set(second["files"]) == {"frames.csv", "summary.json"}
    assert sorted(p.name for p in folder.iterdir()) == [".dea-opt.lock", "frames.csv", MANIFEST_NAME, "summary.json"]
    assert check_outputs(folder) == []


def test_a_run_of_a_scenario_publishes_its_pictures_and_its_rerun_removes_them(tmp_path):
    """The command line's path: ``dea-opt run`` (a PictureWorker), then a rerun with other formats."""
    from dea_opt.run.runner import run_scenario
    from dea_opt.scenario import load_scenario

    scenario = tmp_path / "gait.toml"
    scenario.write_text(SCENARIO)
    folder = tmp_path / "out"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        first = run_scenario(load_scenario(scenario), folder)
        assert {"cycle_plot", "exposure_map"} <= set(first.files)
        for name in PNGS:
            assert first.manifest["files"][name]["sha256"] == _sha256(folder / name)
        second = run_scenario(load_scenario(scenario, {"law.H": 20.0, "output.formats": ["csv", "json"]}), folder)
    assert not any((folder / name).exists() for name in PNGS), "the H=10 pictures were left beside the H=20 run"
    assert not set(second.manifest["files"]) & set(PNGS)
    assert check_outputs(folder) == []


def test_the_previous_run_stays_whole_until_the_pictures_are_published(paths, tmp_path, worker):
    """A run killed before its publication leaves the previous run's pictures, which its manifest lists."""
    folder = tmp_path / "out"
    _publish(paths[0], folder)
    old = {name: _sha256(folder / name) for name in PNGS}
    with output_run(folder) as run:
        paths[1].write(run.folder, pictures=worker)  # drawn and staged, not published: then the kill
        assert {name: _sha256(folder / name) for name in PNGS} == old
        assert check_outputs(folder) == []
        new = {p.name.split(".tmp")[0][1:].rsplit(".", 1)[0]: _sha256(p) for p in _temporary(folder)}
        assert set(new) >= set(PNGS) and all(new[name] != old[name] for name in PNGS)
    assert check_outputs(folder) == [] and _temporary(folder) == []


@pytest.mark.parametrize("name", PNGS)
def test_a_crash_while_a_picture_is_renamed_leaves_no_manifest_and_says_so(paths, tmp_path, name, worker):
    folder = tmp_path / "out"
    _publish(paths[0], folder)
    original = os.replace

    def failing_replace(src, dst):  # the power fails when the new picture is renamed into place
        if Path(dst).name == name:
            raise OSError(28, "No space left on device")
        original(src, dst)

    with pytest.raises(OSError), output_run(folder) as run:
        paths[1].write(run.folder, pictures=worker)
        os.replace = failing_replace
        try:
            run.publish(status="ok")
        finally:
            os.replace = original
    assert not (folder / MANIFEST_NAME).exists()
    assert "did not finish" in json.loads((folder / INCOMPLETE_NAME).read_text())["message"]
    assert check_outputs(folder) != []


def test_check_outputs_finds_a_picture_that_differs_from_the_manifest(paths, tmp_path):
    folder = tmp_path / "out"
    _publish(paths[0], folder, formats=("json", "png"))
    cycle, exposure = folder / "cycle.png", folder / "exposure.png"
    data = bytearray(cycle.read_bytes())
    data[-20] ^= 0xFF  # the same size, other bytes
    cycle.write_bytes(bytes(data))
    assert check_outputs(folder) == ["cycle.png differs from the manifest's SHA-256"]
    exposure.write_bytes(cycle.read_bytes())  # another picture in its place
    problems = check_outputs(folder)
    assert problems[0] == "cycle.png differs from the manifest's SHA-256" and problems[1].startswith("exposure.png ")
    exposure.unlink()
    assert check_outputs(folder)[1] == "exposure.png is missing"


def test_a_picture_that_cannot_be_drawn_leaves_no_reserved_file(paths, tmp_path):
    broken = paths[0].table.drop(columns=["time_s"])
    with pytest.raises(KeyError), PictureFiles(DrawHere()) as drawn:
        drawn.submit(
            "cycle_plot", tmp_path / "cycle.png", lambda p: ("dea_opt.io.cycle", "plot_cycle", (broken, p), {})
        )
        drawn.results()
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(ZeroDivisionError), PictureFiles(DrawHere()) as drawn:  # an error before the drawing
        drawn.submit("cycle_plot", tmp_path / "cycle.png", paths[0]._cycle_job)
        raise ZeroDivisionError
    assert list(tmp_path.iterdir()) == []
