"""Shared pieces of the benchmarks: problems at a given size, timing, memory, tables.

Not collected by pytest (the folder has no tests); run the entry points with Python.
"""

from __future__ import annotations

import csv
import datetime as _dt
import io
import os
import platform
import resource
import time
import warnings
from contextlib import redirect_stdout
from pathlib import Path

import numpy as np

import dea_opt as dea
from dea_opt.geometry import plate_layer, sphere_on_bed_layer
from dea_opt.layer import SpringLayer


def plate_problem(n: int) -> dea.ContactProblem:
    """A 40 x 10 mm plate on about ``n`` springs, 500 N with lift-off (3 free dofs)."""
    nx = max(int(round(np.sqrt(4 * n))), 4)
    ny = max(n // nx, 1)
    layer = plate_layer(40.0, 10.0, nx, ny, thickness=2.0)
    return dea.ContactProblem(
        layer, dea.LinearLaw(10.0), load=dea.Load((0, 0, -500.0), point=(8.0, 2.0, 0)), free=("uz", "rx", "ry")
    )


def sphere_problem(n: int, law=None) -> dea.ContactProblem:
    """A sphere R = 25 mm on a bed of about ``n`` springs (1 free dof)."""
    sectors = max(int(np.sqrt(n / 2)), 4)
    rings = max(n // sectors, 2)
    layer = sphere_on_bed_layer(radius=25.0, thickness=2.0, extent=7.0, n_rings=rings, n_sectors=sectors)
    return dea.ContactProblem(
        layer, law or dea.LinearLaw(0.6), force=(0, 0, -10.0), reference=(0, 0, 25.0), free=("uz",)
    )


def box_layer(n: int, half=(10.0, 8.0, 6.0), gap: float = 0.02) -> SpringLayer:
    """Springs on all six faces of a box (about ``n`` in all), normals inward, a small gap.

    Body 1 is the box-shaped socket, body 2 a box inside it: every dof is resisted.
    """
    half = np.asarray(half)
    areas = np.array([half[1] * half[2], half[0] * half[2], half[0] * half[1]]) * 4
    share = areas / areas.sum() / 2
    points, normals, cell = [], [], []
    for axis in range(3):
        others = [a for a in range(3) if a != axis]
        count = max(int(n * share[axis]), 4)
        ratio = half[others[0]] / half[others[1]]
        k0 = max(int(round(np.sqrt(count * ratio))), 2)
        k1 = max(count // k0, 2)
        u = -half[others[0]] + (np.arange(k0) + 0.5) * 2 * half[others[0]] / k0
        v = -half[others[1]] + (np.arange(k1) + 0.5) * 2 * half[others[1]] / k1
        U, V = np.meshgrid(u, v, indexing="ij")
        for sign in (-1.0, 1.0):
            p = np.zeros((U.size, 3))
            p[:, axis] = sign * half[axis]
            p[:, others[0]] = U.ravel()
            p[:, others[1]] = V.ravel()
            nrm = np.zeros((U.size, 3))
            nrm[:, axis] = -sign  # from the outer box (body 1) inward to body 2
            points.append(p)
            normals.append(nrm)
            cell.append(np.full(U.size, 4 * half[others[0]] * half[others[1]] / U.size))
    return SpringLayer(np.vstack(points), np.vstack(normals), np.concatenate(cell), 2.0, gap)


def box_problem(n: int, law=None) -> dea.ContactProblem:
    """A box in a box-shaped socket, 6 free dofs, a load with all six components."""
    layer = box_layer(n)
    return dea.ContactProblem(
        layer, law or dea.LinearLaw(10.0), force=(300.0, -200.0, -500.0), moment=(400.0, 300.0, -250.0), free=dea.DOFS
    )


PROBLEMS = {"plate": plate_problem, "sphere": sphere_problem, "box": box_problem}


def peak_rss_mb() -> float:
    """Peak resident memory of this process so far (MB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def rss_now_mb() -> float:
    """Current resident memory of this process (MB)."""
    try:
        pages = int(Path("/proc/self/statm").read_text().split()[1])
        return pages * os.sysconf("SC_PAGE_SIZE") / 1024**2
    except (OSError, ValueError, IndexError):
        return float("nan")


def timed(fn, *args, **kwargs):
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dea.ValidityWarning)
        out = fn(*args, **kwargs)
    return out, time.perf_counter() - start


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _memory_gb() -> float:
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemTotal"):
                return int(line.split()[1]) / 1024**2
    except OSError:
        pass
    return float("nan")


def _git_state() -> str:
    """The commit benchmarked and whether dea_opt/ has uncommitted changes (read-only git calls)."""
    import subprocess

    root = Path(__file__).resolve().parent.parent
    try:
        head = subprocess.run(
            ["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True, text=True, timeout=10
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--", "dea_opt"], cwd=root, capture_output=True, text=True, timeout=10
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    if not head:
        return "unknown"
    return head + (f" + uncommitted changes in {len(dirty.splitlines())} file(s) of dea_opt/" if dirty else "")


def blas_info() -> list[str]:
    """One line per BLAS/OpenMP pool numpy and scipy load (threadpoolctl), or numpy's build info."""
    import numpy
    import scipy.linalg  # noqa: F401  (loads scipy's own OpenBLAS)

    try:
        from threadpoolctl import threadpool_info
    except ImportError:
        blas = numpy.show_config(mode="dicts").get("Build Dependencies", {}).get("blas", {})
        return [
            f"threadpoolctl not installed (pip install threadpoolctl); numpy built with "
            f"{blas.get('name', '?')} {blas.get('version', '')}"
        ]
    return [
        f"{i.get('user_api')}: {i.get('internal_api')} {i.get('version', '')} kernel={i.get('architecture', '?')} "
        f"threads={i.get('num_threads')} ({Path(i.get('filepath', '')).name})"
        for i in threadpool_info()
    ]


def header(title: str) -> str:
    """The machine, the software and the load the numbers were measured under, as ``# `` lines."""
    import numpy
    import scipy

    versions = [f"numpy {numpy.__version__}", f"scipy {scipy.__version__}"]
    for name in ("cvxpy", "clarabel", "casadi", "trimesh", "embreex"):
        try:
            from importlib.metadata import version

            versions.append(f"{name} {version(name)}")
        except Exception:  # noqa: BLE001 - a missing package is just not listed
            pass
    env = {
        k: os.environ[k]
        for k in ("OPENBLAS_CORETYPE", "OPENBLAS_L2_SIZE", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
        if k in os.environ
    }
    lines = [
        f"# {title}",
        f"# date: {_dt.datetime.now().isoformat(timespec='seconds')}",
        f"# machine: {_cpu_model()} ({platform.machine()}), cores={os.cpu_count()}, memory={_memory_gb():.1f} GB, "
        f"{platform.system()} {platform.release()}",
        f"# python {platform.python_version()}, dea-opt {dea.__version__} (git {_git_state()}), " + ", ".join(versions),
        *(f"# {line}" for line in blas_info()),
        f"# BLAS environment: {env if env else 'none of OPENBLAS_CORETYPE, OPENBLAS_L2_SIZE, *_NUM_THREADS set'}",
        f"# load average (1, 5, 15 min): {' '.join(f'{x:.2f}' for x in os.getloadavg())}",
    ]
    return "\n".join(lines) + "\n"


def print_table(rows: list[dict], columns: list[str]) -> str:
    def fmt(v):
        if isinstance(v, bool):
            return str(v)
        if isinstance(v, float):
            return "" if v != v else f"{v:.4g}"
        return "" if v is None else str(v)

    widths = {c: max(len(c), *(len(fmt(r.get(c, ""))) for r in rows)) for c in columns}
    lines = ["  ".join(c.ljust(widths[c]) for c in columns)]
    lines += ["  ".join(fmt(r.get(c, "")).ljust(widths[c]) for c in columns) for r in rows]
    text = "\n".join(lines)
    print(text, flush=True)
    return text


def write_csv(path: Path, rows: list[dict], columns: list[str], preamble: str = "") -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    with open(tmp, "w", newline="") as handle:
        handle.write(preamble)
        writer = csv.DictWriter(handle, fieldnames=columns, extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)
    os.replace(tmp, path)


def best_of(fn, *, repeats: int = 5, budget: float = 3.0, first=None):
    """Call ``fn()`` until ``repeats`` calls or ``budget`` seconds; return ``(results, times)``.

    For sub-second timings on a machine other jobs may load: the best of a few repeats is
    the machine's speed, the first call what a cold caller sees (both are reported).
    ``first`` is an already made ``(result, seconds)`` to count as the first call.
    """
    results, times = [], []
    if first is not None:
        results.append(first[0])
        times.append(first[1])
    spent = sum(times)
    while len(times) < repeats and (not times or spent + min(times) <= budget):
        out, t = timed(fn)
        results.append(out)
        times.append(t)
        spent += t
    return results, times


def loglog_slope(sizes, times) -> float:
    """Least-squares slope of ``log t`` against ``log N`` (nan for fewer than two points)."""
    pairs = [(n, t) for n, t in zip(sizes, times) if n and t and t > 0 and np.isfinite(t)]
    if len(pairs) < 2:
        return float("nan")
    x, y = np.log([p[0] for p in pairs]), np.log([p[1] for p in pairs])
    return float(np.polyfit(x, y, 1)[0])


def run_isolated(module: str, func: str, kwargs: dict, timeout: float) -> dict:
    """``module.func(**kwargs)`` in a fresh Python process (its peak RSS is its own).

    The function returns a JSON-able dict (or list of dicts). A time-out or a crash gives a
    row with ``status`` saying so and ``success`` False.
    """
    import json
    import subprocess
    import sys

    here = str(Path(__file__).resolve().parent)
    code = (
        f"import json, sys; sys.path.insert(0, {here!r}); from {module} import {func}; "
        f"print('ROW', json.dumps({func}(**json.loads(sys.argv[1]))), flush=True)"
    )
    start = time.perf_counter()
    try:
        out = subprocess.run(
            [sys.executable, "-c", code, json.dumps(kwargs)], capture_output=True, text=True, timeout=timeout
        )
    except subprocess.TimeoutExpired:
        return {"status": f"timeout>{timeout:g}s", "success": False, "wall_s": time.perf_counter() - start}
    for line in out.stdout.splitlines():
        if line.startswith("ROW "):
            return json.loads(line[4:])
    err = (out.stderr.strip() or out.stdout.strip() or f"exit code {out.returncode}").splitlines()
    return {"status": "error: " + " | ".join(err[-3:])[-300:], "success": False, "wall_s": time.perf_counter() - start}


def blas_limit(threads: int | None):
    """A context that caps the BLAS/OpenMP thread pools at ``threads`` (threadpoolctl), or does
    nothing for ``None`` (the machine's default, what a user gets)."""
    import contextlib

    if threads is None:
        return contextlib.nullcontext()
    from threadpoolctl import threadpool_limits

    return threadpool_limits(int(threads))


class Report:
    """Prints to the terminal and keeps a copy for ``run.txt``."""

    def __init__(self):
        self.text = io.StringIO()
        self.start = time.perf_counter()

    def __call__(self, line: str = "") -> None:
        print(line, flush=True)
        self.text.write(line + "\n")

    def table(self, rows, columns) -> None:
        buffer = io.StringIO()
        with redirect_stdout(buffer):
            print_table(rows, columns) if rows else print("(no rows)")
        self(buffer.getvalue().rstrip("\n"))

    def progress(self, what: str, row: dict, key: str) -> None:
        value = row.get(key)
        shown = f"{key}={value:.4g}" if isinstance(value, float) else f"status={row.get('status')}"
        self(f"  [{time.perf_counter() - self.start:6.0f} s] {what}: {shown}")


def _fmt_s(value) -> str:
    return f"{value:.3g} s" if isinstance(value, (int, float)) and value == value else "not run"
