"""Pictures drawn in a second process (``dea_opt.run.pictures``): the same files as drawn in the
run's own process, the same errors, and nothing left behind however the worker or the run ends."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
import warnings

import numpy as np
import pytest

import dea_opt as d
from dea_opt.geometry import plate_layer
from dea_opt.loadpath import solve_path
from dea_opt.run.pictures import PictureWorker

#: The runs here draw in a PictureWorker, as outside the tests (tests/conftest.py).
pytestmark = pytest.mark.picture_worker

LOADS = np.array([[0.0, 0.0, -400.0, 0.0, m, 0.0] for m in (-1500.0, 0.0, 1500.0)])


@pytest.fixture(scope="module")
def path():
    problem = d.ContactProblem(plate_layer(40.0, 10.0, 40, 10, thickness=2.0), d.LinearLaw(10.0), free=("uz", "ry"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return solve_path(problem, LOADS, times=[0.0, 0.1, 0.2], method="newton")


@pytest.fixture(scope="module")
def worker():
    """One worker for the tests that neither end it nor look at what it leaves behind (each
    worker takes a second of CPU to warm up)."""
    with PictureWorker() as shared:
        yield shared


def _alive(pid: int) -> bool:
    """Whether ``pid`` still runs (a zombie, exited but not yet reaped, does not)."""
    import psutil

    try:
        return psutil.Process(pid).status() != psutil.STATUS_ZOMBIE
    except psutil.NoSuchProcess:
        return False


def test_the_worker_draws_the_same_files_as_the_run(path, tmp_path):
    here = path.write(tmp_path / "here", formats=("png",))
    with PictureWorker() as pictures:
        there = path.write(tmp_path / "there", formats=("png",), pictures=pictures)
        pids = [pictures._drawer.process.pid] if pictures._drawer.process is not None else []
        folder = pictures._folder
    assert pids, "the worker did not start"
    assert set(here) == set(there) == {"cycle_plot", "exposure_map"}
    for name in here:
        assert there[name].parent == tmp_path / "there"
        assert there[name].read_bytes() == here[name].read_bytes(), name
    assert folder is not None and not os.path.exists(folder), "the job files were left behind"


def test_a_job_the_worker_cannot_do_raises_the_error_the_run_would(path, tmp_path, worker):
    broken = path.table.drop(columns=["time_s"])
    from dea_opt.io.cycle import plot_cycle

    with pytest.raises(Exception) as here:
        plot_cycle(broken, tmp_path / "a.png")
    number = worker.submit("dea_opt.io.cycle", "plot_cycle", (broken, tmp_path / "b.png"))
    with pytest.raises(type(here.value)):
        worker.result(number)
    assert not (tmp_path / "b.png").exists()


def test_a_dead_worker_leaves_the_pictures_to_the_run(path, tmp_path):
    with PictureWorker() as pictures:
        process = pictures._drawer.process
        assert process is not None
        process.kill()
        process.wait()
        files = path.write(tmp_path, formats=("png",), pictures=pictures)
    assert files["cycle_plot"].stat().st_size > 1000
    assert files["exposure_map"].stat().st_size > 1000


def test_a_worker_killed_mid_job_leaves_the_picture_to_the_run(path, tmp_path):
    with PictureWorker() as pictures:
        number = pictures.submit("dea_opt.io.cycle", "plot_cycle", (path.table, tmp_path / "c.png"))
        pictures._drawer.process.send_signal(signal.SIGKILL)
        assert pictures.result(number) == tmp_path / "c.png"
    assert (tmp_path / "c.png").stat().st_size > 1000


def test_only_picture_functions_run_in_the_worker(tmp_path, worker):
    with pytest.raises(ValueError, match="picture worker runs functions of"):
        worker.result(worker.submit("os", "remove", (str(tmp_path / "x"),)))


def test_the_worker_ends_when_its_run_is_killed(tmp_path):
    script = (
        "import sys, time\n"
        "from dea_opt.run.pictures import PictureWorker\n"
        "w = PictureWorker()\n"
        "print(w._drawer.process.pid, flush=True)\n"
        "time.sleep(60)\n"
    )
    run = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    try:
        worker = int(run.stdout.readline())
        assert _alive(worker)
        run.kill()
        run.wait()
        deadline = time.monotonic() + 30
        while _alive(worker) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not _alive(worker), "the picture worker outlived the run that was killed"
    finally:
        run.kill()


def test_pictures_that_are_no_worker_are_a_named_error(path, tmp_path):
    with pytest.raises(d.InputError, match="pictures must be a dea_opt.run.pictures.PictureWorker"):
        path.write(tmp_path, formats=("png",), pictures="yes please")
    assert not any(tmp_path.iterdir())


def test_a_run_of_a_load_path_draws_in_a_worker_and_a_static_run_does_not(tmp_path, monkeypatch):
    from dea_opt.run.runner import picture_worker
    from dea_opt.scenario import load_scenario

    text = (
        'title = "t"\n[geometry]\nkind = "plate"\nnx = 10\nny = 4\n[law]\nkind = "linear"\nH = 10.0\n'
        '[body2]\nfree = ["uz"]\n'
    )
    static = tmp_path / "static.toml"
    static.write_text(text + "[load]\nforce = [0.0, 0.0, -10.0]\n")
    gait = tmp_path / "gait.toml"
    gait.write_text(text + '[load_path]\nbuiltin = "hip_gait"\nframes = 3\n')
    with picture_worker(load_scenario(static)) as none:
        assert none is None
    with picture_worker(load_scenario(gait)) as worker:
        assert isinstance(worker, PictureWorker)
    with picture_worker(load_scenario(gait), background=False) as none:
        assert none is None


def test_a_job_goes_to_the_worker_without_the_meshes_its_springs_were_cast_from(tmp_path, worker):
    """A load path on springs cast from meshes: the worker's pictures are the run's, byte for
    byte, and its jobs carry no SpringCast (the meshes and their ray tracer) and need no trimesh
    to be read, while the solutions they carry keep the validity assessed with the meshes."""
    import io
    import pickle

    from dea_opt.geometry import knee_meshes
    from dea_opt.mesh import springs_from_meshes
    from dea_opt.run.pictures import _JobPickler

    pair = knee_meshes(n_plateau=12, step=4.0)
    layer = springs_from_meshes(pair.mesh1, pair.mesh2, **pair.options)
    assert layer.cast is not None
    problem = d.ContactProblem(layer, d.LinearLaw(10.0), free=("uz", "ry"), reference=pair.reference2)
    loads = np.array([[0.0, 0.0, -300.0 * f, 0.0, 400.0 * f, 0.0] for f in (1.0, 2.0, 1.5)])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = solve_path(
            problem, loads, times=[0.0, 0.1, 0.2], method="newton", outputs=d.PathOutputs(keep_frames=("peak",))
        )
        here = result.write(tmp_path / "here", formats=("png",))
        there = result.write(tmp_path / "there", formats=("png",), pictures=worker)
    assert set(here) == set(there) and "peak_map" in here
    for name in here:
        assert there[name].read_bytes() == here[name].read_bytes(), name
    job = result._exposure_job(tmp_path / "e.png")
    peak = result.frame_solution(int(np.argmax(result.table["peak_pressure_MPa"].to_numpy())))
    buffer = io.BytesIO()
    _JobPickler(buffer, protocol=pickle.HIGHEST_PROTOCOL).dump((job, peak))
    (tmp_path / "job.pickle").write_bytes(buffer.getvalue())
    code = (
        "import pickle, sys; (m, f, args, kw), peak = pickle.load(open(sys.argv[1], 'rb')); "
        "assert args[0].cast is None and peak.problem.layer.cast is None; "
        "assert 'validity' in vars(peak); "
        "assert len(args[0]) == int(sys.argv[2]); "
        "print('trimesh' in sys.modules)"
    )
    out = subprocess.run(
        [sys.executable, "-c", code, str(tmp_path / "job.pickle"), str(len(layer))],
        capture_output=True,
        text=True,
        check=True,
    )
    assert out.stdout.strip() == "False", out.stdout + out.stderr
    np.testing.assert_array_equal(pickle.loads(buffer.getvalue())[0][2][0].points, layer.points)


def test_pictures_handed_over_together_are_each_answered_with_their_own_file(path, tmp_path, worker):
    """The worker draws jobs side by side in children of its own: a long job and a short one
    handed over at once come back each with its own answer, the one the run would draw."""
    from dea_opt.io.cycle import plot_cycle

    short = path.table.iloc[:2]
    numbers = [
        worker.submit("dea_opt.io.cycle", "plot_cycle", (path.table, tmp_path / "long.png")),
        worker.submit("dea_opt.io.cycle", "plot_cycle", (short, tmp_path / "short.png")),
        worker.submit("dea_opt.io.cycle", "plot_cycle", (path.table, tmp_path / "again.png")),
    ]
    answers = [worker.result(n) for n in reversed(numbers)][::-1]
    assert worker._drawer.process is not None, "the worker failed: the run drew the pictures"
    assert answers == [tmp_path / "long.png", tmp_path / "short.png", tmp_path / "again.png"]
    plot_cycle(short, tmp_path / "short_here.png")
    assert (tmp_path / "short.png").read_bytes() == (tmp_path / "short_here.png").read_bytes()
    assert (tmp_path / "long.png").read_bytes() == (tmp_path / "again.png").read_bytes()
    assert (tmp_path / "long.png").read_bytes() != (tmp_path / "short.png").read_bytes()


def test_a_drawing_child_killed_mid_job_leaves_its_picture_to_the_run(path, tmp_path, worker):
    """The child drawing a job is killed: the job's answer is an error naming how the child
    ended, the run draws the picture itself, and the worker (the module's, which other tests
    share) goes on."""
    import psutil

    from dea_opt.run.pictures import _parallel_jobs

    if not _parallel_jobs():
        pytest.skip("this platform draws in the worker itself (no fork): tested by the next test")
    process = psutil.Process(worker._drawer.process.pid)
    # A child killed once it has answered (a busy machine can be that slow to look) is
    # tried again with another job.
    for attempt in range(5):
        before = set(process.children())  # none once earlier jobs are answered: each child is reaped first
        number = worker.submit("dea_opt.io.cycle", "plot_cycle", (path.table, tmp_path / f"c{attempt}.png"))
        deadline = time.monotonic() + 60
        children: list = []
        while not children and time.monotonic() < deadline:
            children = [child for child in process.children() if child not in before]
            time.sleep(0.002)
        assert children, "the worker forked no child for the job"
        with contextlib.suppress(psutil.NoSuchProcess):
            children[0].kill()
        answer = worker._drawer.answer(number)
        if answer is not None and answer[0] == "error":
            break
    assert answer is not None and answer[0] == "error" and "ended with status" in answer[1], answer
    assert worker.result(number) == tmp_path / f"c{attempt}.png"
    assert (tmp_path / f"c{attempt}.png").stat().st_size > 1000
    assert worker._drawer.process is not None and worker._drawer.process.poll() is None, "the worker ended"


def test_without_fork_the_worker_draws_its_jobs_itself_in_order(path, tmp_path, monkeypatch):
    """Where ``fork`` is missing or unsafe (Windows, macOS) the worker draws each job itself, one
    after the other: the same answers, in the order the jobs came, a refused job answered too."""
    import gc
    import io
    import pickle

    from dea_opt.run import pictures as module

    monkeypatch.setattr(module, "_parallel_jobs", lambda: 0)
    jobs = [
        ("dea_opt.io.cycle", "plot_cycle", (path.table, tmp_path / "a.png"), {}),
        ("os", "remove", (str(tmp_path / "x"),), {}),
        ("dea_opt.io.cycle", "plot_cycle", (path.table.iloc[:2], tmp_path / "b.png"), {}),
    ]
    source, feed = os.pipe()
    for k, job in enumerate(jobs):
        (tmp_path / f"job{k}").write_bytes(pickle.dumps(job))
        os.write(feed, f"{tmp_path / f'job{k}'}\n".encode())
    os.close(feed)
    sink = io.BytesIO()
    try:
        module._serve(source, sink)
    finally:
        gc.unfreeze()
        os.close(source)
    sink.seek(0)
    answers = [pickle.load(sink) for _ in jobs]
    assert sink.read() == b""
    assert answers[0] == ("ok", tmp_path / "a.png") and answers[2] == ("ok", tmp_path / "b.png")
    assert answers[1][0] == "error" and "picture worker runs functions of" in answers[1][1]
    assert (tmp_path / "a.png").stat().st_size > 1000 and (tmp_path / "b.png").stat().st_size > 1000
