"""The sweep's spring cache: springs cast once per distinct geometry and pose, shared
on disk by the workers; and the cases' outputs chosen per sweep.

A cast taken from the cache must be the cast, bit for bit; its key must follow the content
(meshes, options, pose), not the objects; concurrent processes must cast a key once; a process
killed while casting must leave nothing half written; an unreadable entry is cast again.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time
import warnings

import numpy as np
import pandas as pd
import pytest

import dea_opt as d
from dea_opt import geometry
from dea_opt.mesh import cache as spring_cache
from dea_opt.mesh import cast_springs
from dea_opt.sweep import RESULTS_NAME, run_sweep
from dea_opt.sweep.cases import SPRING_CACHE

TILT = np.array(
    [
        [np.cos(0.02), 0.0, np.sin(0.02), 0.1],
        [0.0, 1.0, 0.0, -0.05],
        [-np.sin(0.02), 0.0, np.cos(0.02), -0.01],
        [0.0, 0.0, 0.0, 1.0],
    ]
)


@pytest.fixture(scope="module")
def pair():
    return geometry.sphere_on_bed_meshes(25.0, 2.0, extent=6.0, n_bed=14, step=3.0)


@pytest.fixture(autouse=True)
def empty_memory():
    """Every test starts without casts in this process's memory."""
    spring_cache._casts.clear()
    spring_cache._prepared.clear()
    spring_cache._meshes.clear()
    yield


def cast_fields(springs) -> dict:
    """Every array of a SpringCast and its layer, by name."""
    layer = springs.layer
    out = {
        name: getattr(layer, name)
        for name in (
            "points",
            "normals",
            "areas",
            "thickness",
            "gap",
            "source_face",
            "labels",
            "target_points",
            "target_normals",
            "target_faces",
        )
    }
    out |= {
        "surface_vertices": layer.surface[0],
        "surface_faces": layer.surface[1],
        "hit_face": springs.hit_face,
        "hit_point": springs.hit_point,
        "thickness1": springs.thickness1,
        "thickness2": springs.thickness2,
        "pose": springs.pose,
        "outcome": springs.outcome,
        **{f"dropped_{k}": v for k, v in springs.dropped.faces.items()},
    }
    return out


def assert_same_cast(a, b) -> None:
    fa, fb = cast_fields(a), cast_fields(b)
    assert fa.keys() == fb.keys()
    for name in fa:
        if fa[name] is None:
            assert fb[name] is None, name
            continue
        assert np.asarray(fa[name]).dtype == np.asarray(fb[name]).dtype, name
        np.testing.assert_array_equal(fa[name], fb[name], err_msg=name)


def options_of(pair, n_faces) -> dict:
    labels = np.where(np.arange(n_faces) % 3 == 0, "anterior", "posterior")
    return {"thickness2": 0.0, "max_gap": 1.5, "labels": labels}


@pytest.mark.parametrize("pose", [None, TILT])
def test_a_cast_from_the_cache_is_the_cast_bit_for_bit(pair, tmp_path, pose):
    options = options_of(pair, len(pair.mesh1.faces))
    fresh = cast_springs(pair.mesh1, pair.mesh2, pose=pose, **options)
    with spring_cache.active(tmp_path):
        before = spring_cache.stats()
        computed = spring_cache.cast(pair.mesh1, pair.mesh2, pose=pose, **options)
        spring_cache._casts.clear()  # the next one is read from disk
        spring_cache._prepared.clear()
        from_disk = spring_cache.cast(pair.mesh1, pair.mesh2, pose=pose, **options)
        from_memory = spring_cache.cast(pair.mesh1, pair.mesh2, pose=pose, **options)
        after = spring_cache.stats()
    assert (
        after["casts"] - before["casts"],
        after["hits_disk"] - before["hits_disk"],
        after["hits_memory"] - before["hits_memory"],
    ) == (1, 1, 1)
    assert from_memory is from_disk
    assert_same_cast(fresh, computed)
    assert_same_cast(fresh, from_disk)
    assert len(list(tmp_path.glob("*.npz"))) == 1


def test_without_an_active_cache_nothing_is_kept(pair, tmp_path):
    before = spring_cache.stats()
    first = spring_cache.cast(pair.mesh1, pair.mesh2, thickness2=0.0)
    second = spring_cache.cast(pair.mesh1, pair.mesh2, thickness2=0.0)
    assert first is not second and spring_cache.stats() == before
    assert_same_cast(first, second)


def test_the_key_follows_the_content_not_the_objects(pair):
    options = {"thickness2": 0.0, "max_gap": 1.5}
    key = spring_cache.cast_key(pair.mesh1, pair.mesh2, None, options)
    assert key == spring_cache.cast_key(pair.mesh1.copy(), pair.mesh2.copy(), np.eye(4), dict(options))
    moved = pair.mesh2.copy()
    moved.vertices[0, 0] += 1e-9
    others = [
        spring_cache.cast_key(pair.mesh1, moved, None, options),
        spring_cache.cast_key(pair.mesh1, pair.mesh2, TILT, options),
        spring_cache.cast_key(pair.mesh1, pair.mesh2, None, {**options, "max_gap": 1.4}),
        spring_cache.cast_key(pair.mesh1, pair.mesh2, None, {**options, "thickness1": 2.0}),
        spring_cache.cast_key(pair.mesh1, pair.mesh2, None, {**options, "flip": True}),
        spring_cache.cast_key(pair.mesh2, pair.mesh1, None, options),
    ]
    assert len({key, *others}) == 1 + len(others)


def test_an_unreadable_entry_is_cast_again_and_replaced(pair, tmp_path):
    options = {"thickness2": 0.0}
    with spring_cache.active(tmp_path):
        good = spring_cache.cast(pair.mesh1, pair.mesh2, **options)
        entry = next(tmp_path.glob("*.npz"))
        for damage in (b"not a zip file", entry.read_bytes()[:200]):
            entry.write_bytes(damage)
            spring_cache._casts.clear()
            before = spring_cache.stats()["casts"]
            again = spring_cache.cast(pair.mesh1, pair.mesh2, **options)
            assert spring_cache.stats()["casts"] == before + 1
            assert_same_cast(good, again)
        spring_cache._casts.clear()
        before = spring_cache.stats()["hits_disk"]
        spring_cache.cast(pair.mesh1, pair.mesh2, **options)
        assert spring_cache.stats()["hits_disk"] == before + 1  # the replaced entry is whole


def test_the_warnings_of_a_cast_are_given_again_from_the_cache(pair, tmp_path):
    """Faces given zero thickness make springs of zero total thickness, dropped with a warning:
    a case that takes the cast from the cache lists the same warning as the one that cast it."""
    thickness1 = np.full(len(pair.mesh1.faces), 2.0)
    thickness1[::5] = 0.0
    with spring_cache.active(tmp_path):
        for _ in range(2):
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                spring_cache.cast(pair.mesh1, pair.mesh2, thickness1=thickness1, thickness2=0.0)
            assert any("zero total thickness" in str(w.message) for w in caught)
            spring_cache._casts.clear()


CONCURRENT = textwrap.dedent("""
    import json, sys, time
    from pathlib import Path
    import numpy as np
    from dea_opt import geometry
    from dea_opt.mesh import cache as spring_cache
    folder, go = Path(sys.argv[1]), Path(sys.argv[2])
    pair = geometry.sphere_on_bed_meshes(25.0, 2.0, extent=6.0, n_bed=14, step=3.0)
    print("ready", flush=True)
    while not go.exists():
        time.sleep(0.002)
    with spring_cache.active(folder):
        springs = spring_cache.cast(pair.mesh1, pair.mesh2, thickness2=0.0, max_gap=1.5)
    layer = springs.layer
    digest = [float(layer.gap.sum()), float(layer.thickness.sum()), int(springs.hit_face.sum()), len(layer)]
    print(json.dumps({"stats": spring_cache.stats(), "digest": digest}), flush=True)
""")


def _start(code, *args):
    process = subprocess.Popen(
        [sys.executable, "-c", code, *map(str, args)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    assert process.stdout.readline().strip() == "ready", process.stderr.read()
    return process


def test_concurrent_processes_cast_a_key_once(tmp_path):
    go = tmp_path / "go"
    folder = tmp_path / "springs"
    processes = [_start(CONCURRENT, folder, go) for _ in range(4)]
    go.touch()
    outs = []
    for process in processes:
        out, err = process.communicate(timeout=120)
        assert process.returncode == 0, err
        outs.append(json.loads(out.strip().splitlines()[-1]))
    assert sum(o["stats"]["casts"] for o in outs) == 1
    assert sum(o["stats"]["hits_disk"] for o in outs) == 3
    assert len({json.dumps(o["digest"]) for o in outs}) == 1
    assert sorted(p.suffix for p in folder.iterdir()) == [".lock", ".npz"]


KILLED = textwrap.dedent("""
    import sys, time
    from pathlib import Path
    from dea_opt import geometry
    from dea_opt.mesh import springs
    from dea_opt.mesh import cache as spring_cache
    real = springs._cast
    def slow(*args, **kwargs):
        out = real(*args, **kwargs)
        print("cast", flush=True)
        time.sleep(60)
        return out
    springs._cast = slow
    pair = geometry.sphere_on_bed_meshes(25.0, 2.0, extent=6.0, n_bed=14, step=3.0)
    print("ready", flush=True)
    with spring_cache.active(Path(sys.argv[1])):
        spring_cache.cast(pair.mesh1, pair.mesh2, thickness2=0.0)
""")


def test_a_process_killed_while_casting_leaves_no_entry_and_no_held_lock(pair, tmp_path):
    process = _start(KILLED, tmp_path)
    assert process.stdout.readline().strip() == "cast"  # it holds the key's lock now
    os.kill(process.pid, signal.SIGKILL)
    process.communicate(timeout=30)
    assert [p.suffix for p in tmp_path.iterdir()] == [".lock"]  # nothing half written
    start = time.monotonic()
    with spring_cache.active(tmp_path):
        before = spring_cache.stats()["casts"]
        springs = spring_cache.cast(pair.mesh1, pair.mesh2, thickness2=0.0)
    assert time.monotonic() - start < 30  # the dead process's lock did not hold us
    assert spring_cache.stats()["casts"] == before + 1
    assert_same_cast(springs, cast_springs(pair.mesh1, pair.mesh2, thickness2=0.0))


# --- a sweep over mesh files -------------------------------------------------------------

SCENARIO = """\
title = "sphere on a bed, from STL files"
[geometry]
kind = "meshes"
mesh1 = "bed.stl"
mesh2 = "sphere.stl"
thickness2 = 1.0
max_gap = 1.5
[law]
kind = "linear"
H = 5.0
[body2]
reference = [0.0, 0.0, 25.0]
free = ["uz"]
[load]
force = [0.0, 0.0, -20.0]
[output]
formats = ["csv", "json", "vtk", "png"]
"""


@pytest.fixture()
def scenario(pair, tmp_path):
    pair.mesh1.export(tmp_path / "bed.stl")
    pair.mesh2.export(tmp_path / "sphere.stl")
    path = tmp_path / "sphere.toml"
    path.write_text(SCENARIO)
    return path


def test_a_sweep_casts_each_geometry_once_and_writes_the_outputs_asked(scenario, tmp_path):
    out = tmp_path / "sweep"
    sets = ["law.H=4,5,6", "geometry.max_gap=1.5,1.2"]
    result = run_sweep(scenario, sets, out, scheduler="synchronous", outputs="csv,json")
    table = pd.read_csv(out / RESULTS_NAME)
    assert len(table) == 6 and (table["status"] == "ok").all()
    assert len(list((out / SPRING_CACHE).glob("*.npz"))) == 2  # two proximity windows
    for case in result.cases:
        assert sorted(p.name for p in (out / "cases" / case).iterdir() if not p.name.startswith(".")) == [
            "contact.csv",
            "contact.json",
            "manifest.json",
        ]
    # Each row is what a solve of that case gives without any cache.
    from dea_opt.scenario import build_problem, load_scenario

    for row in table.to_dict("records"):  # the swept values' columns carry their units
        overrides = {"law.H": row["law.H_MPa"], "geometry.max_gap": row["geometry.max_gap_mm"]}
        assert row["case"] == f"law.H={row['law.H_MPa']:g}, geometry.max_gap={row['geometry.max_gap_mm']:g}"
        problem = build_problem(load_scenario(scenario, overrides))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            solution = d.solve(problem)
        assert row["peak_pressure_MPa"] == pytest.approx(solution.peak_pressure, rel=1e-12)
        assert row["n_springs"] == len(problem.layer)
    # Other outputs are another content: the cases run again, saying why.
    again = run_sweep(scenario, sets, out, scheduler="synchronous", outputs="json")
    assert len(again.ran) == 6
    assert set(again.recomputed.values()) == {"it wrote the outputs csv,json, now json"}
    assert sorted(p.name for p in (out / "cases" / result.cases[0]).iterdir() if not p.name.startswith(".")) == [
        "contact.json",
        "manifest.json",
    ]
    assert run_sweep(scenario, sets, out, scheduler="synchronous", outputs=["json"]).skipped == result.cases


@pytest.mark.parametrize("outputs, named", [("csv,xls", "'xls'"), (["vtk", 3], "3"), ("pdf", "'pdf'")])
def test_unknown_outputs_are_named_before_any_case_runs(scenario, tmp_path, outputs, named):
    with pytest.raises(d.InputError, match=rf"outputs .*{named}"):
        run_sweep(scenario, ["law.H=4,5"], tmp_path / "s", scheduler="synchronous", outputs=outputs)
    assert not (tmp_path / "s").exists()
