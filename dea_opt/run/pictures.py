"""Pictures drawn in a second process while a run solves and writes its other outputs.

Matplotlib's import (0.3-0.5 s) and the drawing of a load path's pictures (0.8-0.9 s on the
knee of ``../shared/data/knee``: the cycle plot, the exposure maps, the peak frame's map) are
most of what ``dea-opt run`` spends outside its solve. :class:`PictureWorker` starts a Python
process when the run starts; it imports matplotlib (and what the pictures read: pandas, scipy's
spatial and image modules) and draws a small figure on the other core while the run casts and
solves. The pictures need every frame, so they are all handed over at once when the last frame is
solved: the worker then forks a child per picture, up to one per core, and they are drawn side by
side (0.5 s on the knee) while the run writes its tables and VTK files. The run waits for them
before it publishes.

Written here rather than with :class:`concurrent.futures.ProcessPoolExecutor` because the
worker must end with the run however the run ends: it reads its jobs from a pipe and returns
when the pipe closes (``kill -9`` of the run included), and it never re-imports the console
script that started the run. Whatever goes wrong in the worker (it could not start, it died, a
job raised) the picture is drawn in the run's own process instead, so the run's errors and
files are the same either way.

Jobs are ``(module, function, args, kwargs)`` of :mod:`dea_opt.io`'s picture functions,
pickled into files of a temporary folder whose names go through the pipe; the answers come
back pickled through the other pipe: ``("ok", value)`` or ``("error", text)``.

A run's outputs are staged in the run's process (:func:`dea_opt.files.atomic.staged`), which the
worker does not see: given the output's own name it would rename its picture straight into the
output folder, outside the manifest. :class:`PictureFiles` therefore hands the drawer a
temporary file reserved beside each output (:func:`~dea_opt.files.atomic.atomic_path`) and,
once the picture is drawn there, stages it (or renames it into place) in the run's process,
like every other output: published with the others and listed in ``manifest.json``.
"""

from __future__ import annotations

import contextlib
import gc
import importlib
import os
import pickle
import select
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from ..files.atomic import atomic_path

__all__ = ["DrawHere", "PictureFiles", "PictureWorker"]

#: The modules a worker may run functions of.
_MODULES = ("dea_opt.io.cycle", "dea_opt.io.plots")


#: What a job's pictures import on their way, imported while the run casts and solves rather than
#: on the first job while the run waits: pandas (a load path's table comes as a DataFrame),
#: scipy's spatial and image modules (the maps' site triangles and region outlines).
_READ_BY_PICTURES = ("pandas", "scipy.spatial", "scipy.ndimage")


def _call(module: str, function: str, args, kwargs):
    if module not in _MODULES:
        raise ValueError(f"a picture worker runs functions of {_MODULES}, not {module!r}")
    return getattr(importlib.import_module(module), function)(*args, **kwargs)


def _layer(cls, state: dict):
    """A :class:`~dea_opt.layer.SpringLayer` of ``state`` (its attributes), made without its
    ``__init__``'s checks: the worker's copy of a layer the run has already checked."""
    layer = object.__new__(cls)
    layer.__dict__.update(state)
    return layer


class _JobPickler(pickle.Pickler):
    """A job's pickler: a spring layer goes without the :class:`~dea_opt.mesh.SpringCast` its
    springs were cast from (the meshes, their caches and ray tracer: 33 MB on the knee, and
    trimesh's import in the worker, 1.6 s), which no picture reads; a solution goes with its
    validity assessed here first, where the meshes are (its ``gap_error`` check reads them), and
    where that assessment raises, the layers after it keep their casts."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        from ..layer import SpringLayer
        from ..solution import Solution

        self._types = SpringLayer, Solution
        self._keep_casts = False

    def reducer_override(self, obj):
        layer, solution = self._types
        if isinstance(obj, solution):
            try:
                obj.validity  # noqa: B018 - assessed (and kept in its __dict__) before it is pickled
            except Exception:  # noqa: BLE001 - the picture assesses it, and raises as the run would
                self._keep_casts = True  # with the meshes, as it would here
        elif isinstance(obj, layer) and obj.cast is not None and not self._keep_casts:
            return _layer, (type(obj), {k: v for k, v in vars(obj).items() if k != "_cast"})
        return NotImplemented


class DrawHere:
    """:class:`PictureWorker`'s interface, drawing in this process: each job when its result is
    asked for."""

    def __init__(self):
        self._jobs: list = []

    def submit(self, module: str, function: str, args=(), kwargs=None) -> int:
        self._jobs.append((module, function, tuple(args), dict(kwargs or {})))
        return len(self._jobs) - 1

    def result(self, number: int):
        return _call(*self._jobs[number])

    def draw(self, job: tuple):
        """Run ``job`` ``(module, function, args, kwargs)`` now; its value."""
        return self.result(self.submit(*job))

    def files(self) -> PictureFiles:
        """:class:`PictureFiles` drawn in this process (as :meth:`PictureWorker.files`)."""
        return PictureFiles(self)


class _Drawer:
    """One worker process: the jobs sent to it and the answers read back, in order."""

    def __init__(self, env):
        self.sent = 0
        self.answers: list = []
        try:
            self.process: subprocess.Popen | None = subprocess.Popen(
                [sys.executable, "-m", "dea_opt.run.pictures"],
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=subprocess.DEVNULL,
                env=env,
            )
        except OSError:
            self.process = None  # drawn in the run's process instead

    def send(self, path: str) -> int | None:
        """Hand the job file ``path`` over; its place among this worker's answers, or None."""
        process = self.process
        if process is None or process.stdin is None:
            return None
        try:
            process.stdin.write(path.encode() + b"\n")
            process.stdin.flush()
        except OSError:
            self.stop()
            return None
        self.sent += 1
        return self.sent - 1

    def answer(self, place: int):
        """The answer in ``place`` (answers come in order), or None if the worker failed."""
        try:
            while len(self.answers) <= place:
                assert self.process is not None and self.process.stdout is not None
                self.answers.append(pickle.load(self.process.stdout))
        except Exception:  # the worker died or wrote something else: drawn in the run instead
            self.stop()
            return None
        return self.answers[place]

    def stop(self) -> None:
        process, self.process = self.process, None
        if process is None:
            return
        # Its answers are no longer wanted: the worker is ended at once (it may still be warming
        # up, a second of CPU for nothing), and not waited for (its end is no part of the run).
        # A child drawing a job the run gave up on finishes it and ends, its pipe's reader gone.
        for stream in (process.stdin, process.stdout):
            try:
                if stream is not None:
                    stream.close()
            except OSError:
                pass
        with contextlib.suppress(OSError):
            process.kill()


class PictureWorker:
    """A second Python process that draws pictures; :meth:`submit` jobs, then :meth:`result`.

    Start it early (``PictureWorker()``): the process imports matplotlib while the caller
    works. Use it as a context manager, or call :meth:`close`.
    """

    def __init__(self):
        self._jobs: list = []
        self._folder: str | None = None
        package = str(Path(__file__).resolve().parents[2])
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(p for p in (package, env.get("PYTHONPATH")) if p)
        env.setdefault("MPLBACKEND", "Agg")
        # The worker draws on one core beside the run: a BLAS thread pool of its own would only
        # contend with the run's (its arrays are a few thousand rows: a thread's hand-over costs more)
        for name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
            env.setdefault(name, "1")
        self._drawer = _Drawer(env)

    def submit(self, module: str, function: str, args=(), kwargs=None) -> int:
        """Queue ``module.function(*args, **kwargs)``; returns the job's number for :meth:`result`.

        The job goes to the worker as a file (its name through the pipe), so that handing it
        over never waits for the worker to finish drawing the one before."""
        job = (module, function, tuple(args), dict(kwargs or {}))
        place = None
        if self._drawer.process is not None:
            try:
                if self._folder is None:
                    self._folder = tempfile.mkdtemp(prefix="dea-opt-pictures-")
                path = os.path.join(self._folder, f"job{len(self._jobs)}.pickle")
                with open(path, "wb") as handle:
                    _JobPickler(handle, protocol=pickle.HIGHEST_PROTOCOL).dump(job)
                place = self._drawer.send(path)
            except (OSError, pickle.PicklingError, TypeError, AttributeError):
                place = None
        self._jobs.append((job, place))
        return len(self._jobs) - 1

    def result(self, number: int):
        """The value of job ``number``: the worker's, or, if the worker failed, the job run here."""
        job, place = self._jobs[number]
        if place is not None:
            answer = self._drawer.answer(place)
            if answer is not None and answer[0] == "ok":
                return answer[1]
        return _call(*job)

    def files(self) -> PictureFiles:
        """The run's pictures drawn here, as outputs: :class:`PictureFiles` of this worker (what
        :meth:`dea_opt.loadpath.PathResult.write` draws its PNGs through)."""
        return PictureFiles(self)

    def close(self) -> None:
        """End the worker and remove the job files (a picture asked for and not yet drawn is
        drawn here when its result is asked for)."""
        self._drawer.stop()
        if self._folder is not None:
            shutil.rmtree(self._folder, ignore_errors=True)
            self._folder = None

    def __enter__(self) -> PictureWorker:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __del__(self):
        if hasattr(self, "_drawer"):
            self.close()


class PictureFiles:
    """Pictures that are outputs of a run, drawn by ``drawer`` (a :class:`PictureWorker` or
    :class:`DrawHere`) and written like every other output.

    :meth:`submit` reserves a temporary file beside the output (:func:`~dea_opt.files.atomic.atomic_path`)
    and hands the drawer the job that draws into it; :meth:`results` waits for the drawings
    and then stages each file in this process (inside :func:`~dea_opt.files.atomic.staged`; else
    renames it into place). Use it as a context manager: leaving the block with an error, or
    without :meth:`results`, removes the reserved files.
    """

    def __init__(self, drawer):
        self._drawer = drawer
        self._files = contextlib.ExitStack()
        self._jobs: dict = {}

    def submit(self, name: str, target, job) -> None:
        """Draw output ``name`` into ``target``: ``job(path)`` gives the drawer's job
        ``(module, function, args, kwargs)`` writing the picture to ``path``."""
        target = Path(target)
        reserved = self._files.enter_context(atomic_path(target))
        self._jobs[name] = (target, self._drawer.submit(*job(reserved)))

    def results(self) -> dict:
        """``{name: target}`` once every picture is drawn and staged (an error of a drawing is
        raised, and no picture is kept)."""
        with self._files:
            for _, number in self._jobs.values():
                self._drawer.result(number)
        files, self._jobs = {name: target for name, (target, _) in self._jobs.items()}, {}
        return files

    def __enter__(self) -> PictureFiles:
        return self

    def __exit__(self, *exc) -> None:
        self._files.__exit__(*exc)


def _warm_up() -> None:
    """Draw a small figure of what the pictures hold (text, a legend, mathtext, triangles coloured
    by face, a colour bar, axes placed by :mod:`dea_opt.io.layout`), so that the first real picture
    does not pay for matplotlib's first drawing (fonts, caches, the mathtext parser, the modules of
    triangles and colour bars) while the run waits: the worker draws it while the run casts and
    solves."""
    import io

    import numpy as np
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.cm import ScalarMappable
    from matplotlib.collections import LineCollection
    from matplotlib.colors import Normalize
    from matplotlib.figure import Figure
    from matplotlib.tri import Triangulation

    from ..io.layout import colorbar_axes, place_maps

    fig = Figure(figsize=(3, 2), layout=None)
    FigureCanvasAgg(fig)
    line, tri = fig.subplots(1, 2)
    line.plot([0, 1], [0, 1], label="warm")
    line.legend(fontsize="x-small", loc="upper left", bbox_to_anchor=(1.01, 1.0))
    line.set_ylabel("area (mm$^2$)")
    line.set_title("warm", fontweight="bold")
    triangles = Triangulation(np.array([0.0, 1.0, 0.0, 1.0]), np.array([0.0, 0.0, 1.0, 1.0]), [[0, 1, 2], [1, 3, 2]])
    norm = Normalize(0.0, 1.0)
    tri.tripcolor(triangles, facecolors=np.array([0.2, 0.8]), cmap="magma", norm=norm, edgecolors="none")
    tri.tripcolor(triangles, np.array([0.0, 0.5, 1.0, 0.5]), cmap="viridis", norm=norm, shading="gouraud")
    tri.add_collection(LineCollection([[(0.0, 0.0), (1.0, 1.0)]], colors="k", linewidths=0.8))
    tri.set_aspect("equal")
    bar = fig.colorbar(ScalarMappable(norm=norm, cmap="magma"), cax=colorbar_axes(fig), label="warm (MPa s)")
    place_maps(fig, [(tri, bar)], fig.suptitle("warm\nwarm", fontsize="medium"))
    fig.savefig(io.BytesIO(), format="png", dpi=40)


def _answer(path: str) -> bytes:
    """The pickled answer to the job in file ``path``: ``("ok", value)`` or ``("error", text)``."""
    try:
        with open(path, "rb") as handle:
            job = pickle.load(handle)
        answer = ("ok", _call(*job))
    except BaseException as error:  # answered, and the run draws it itself to raise the same
        answer = ("error", f"{type(error).__name__}: {error}")
    try:
        return pickle.dumps(answer, protocol=pickle.HIGHEST_PROTOCOL)
    except Exception as error:  # noqa: BLE001 - a value that does not pickle: the run draws it
        return pickle.dumps(("error", f"{type(error).__name__}: {error}"))


def _parallel_jobs() -> int:
    """How many jobs the worker draws at once, each in a child forked from it (0: one after the
    other in the worker itself, where ``fork`` is missing or unsafe: Windows, macOS)."""
    if not hasattr(os, "fork") or sys.platform == "darwin":
        return 0
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return max(1, cores or 1)


class _Child:
    """A job drawn in a child forked from the warmed-up worker; its answer read back through a pipe."""

    def __init__(self, path: str, pipes: tuple):
        read, write = os.pipe()
        self.pid = os.fork()
        if self.pid == 0:  # the child: draw, send the answer, leave without the parent's cleanup
            code = 1
            try:
                os.close(read)
                # Off the run's pipes: a child the worker outlives (the worker killed mid-job)
                # must not keep the run waiting for the end of the worker's answers.
                null = os.open(os.devnull, os.O_RDWR)
                for fd in pipes:
                    os.dup2(null, fd)
                data = memoryview(_answer(path))
                while data:
                    data = data[os.write(write, data) :]
                code = 0
            finally:
                os._exit(code)
        os.close(write)
        self.fd = read
        self.data = bytearray()

    def read(self) -> bool:
        """Read what the child sent; True once it has closed its end (its answer is complete)."""
        chunk = os.read(self.fd, 1 << 16)
        self.data += chunk
        if chunk:
            return False
        os.close(self.fd)
        _, status = os.waitpid(self.pid, 0)
        if status != 0 or not self.data:  # it died mid-job: the run draws the picture itself
            self.data = bytearray(pickle.dumps(("error", f"the drawing process ended with status {status}")))
        return True


def _serve(source: int, sink) -> None:
    """The worker's loop: read job files' names, one per line, from the file descriptor
    ``source`` until it closes; answer each job on ``sink``, in the order the jobs came.

    Once warmed up, the worker forks a child per job, up to one per core, so that a run's
    pictures (all handed over when its last frame is solved) are drawn at once rather than one
    after the other while the run waits; a fork of the warmed-up worker starts in milliseconds
    where a new process would import matplotlib again. When the run closes the pipe, jobs not
    yet started are dropped (nobody waits for them) and those drawing finish."""
    import matplotlib

    matplotlib.use("Agg")
    for module in _MODULES + _READ_BY_PICTURES:
        importlib.import_module(module)
    _warm_up()
    # What is loaded now (matplotlib, its fonts and caches) lives as long as the worker: kept out
    # of the garbage collector's full passes, which otherwise walk it again and again while a
    # picture of ten thousand polygons is made (a fifth of the exposure maps' time), and left
    # untouched in the children's copy-on-write memory.
    gc.freeze()
    parallel = _parallel_jobs()
    if not parallel:  # one job after the other, read as they come (select takes no pipe on Windows)
        with os.fdopen(source, "rb", closefd=False) as jobs:
            for line in jobs:
                try:
                    sink.write(_answer(line.decode().rstrip("\n")))
                    sink.flush()
                except OSError:
                    return
        return
    waiting: list = []  # (place, job file) not yet started, in order
    drawing: dict = {}  # file descriptor -> (place, _Child)
    answers: dict = {}  # place -> pickled answer not yet sent
    received = sent = 0
    pending = b""
    open_ = True
    while open_ or drawing:
        while waiting and len(drawing) < parallel:
            place, path = waiting.pop(0)
            child = _Child(path, (source, sink.fileno()))
            drawing[child.fd] = (place, child)
        while sent in answers:
            try:
                sink.write(answers.pop(sent))
                sink.flush()
            except OSError:
                return
            sent += 1
        if not open_ and not drawing:
            break
        ready, _, _ = select.select(([source] if open_ else []) + list(drawing), [], [])
        for fd in ready:
            if fd == source:
                chunk = os.read(source, 1 << 16)
                if not chunk:
                    open_, waiting = False, []
                    continue
                pending += chunk
                *lines, pending = pending.split(b"\n")
                for line in lines:
                    waiting.append((received, line.decode()))
                    received += 1
            else:
                place, child = drawing[fd]
                if child.read():
                    del drawing[fd]
                    answers[place] = bytes(child.data)


if __name__ == "__main__":
    try:
        _serve(sys.stdin.fileno(), sys.stdout.buffer)
    except KeyboardInterrupt:  # Ctrl-C reaches the run's whole process group: the run says what happened
        pass
