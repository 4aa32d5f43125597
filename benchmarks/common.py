"""Shared pieces of the benchmarks: problems at a given size, timing, memory, tables.

Not collected by pytest (the folder has no tests); run the entry points with Python.
"""

from __future__ import annotations

import csv
import datetime as _dt
import os
import platform
import resource
import time
import warnings
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
    return dea.ContactProblem(layer, dea.LinearLaw(10.0), load=dea.Load((0, 0, -500.0), point=(8.0, 2.0, 0)),
                              free=("uz", "rx", "ry"))


def sphere_problem(n: int, law=None) -> dea.ContactProblem:
    """A sphere R = 25 mm on a bed of about ``n`` springs (1 free dof)."""
    sectors = max(int(np.sqrt(n / 2)), 4)
    rings = max(n // sectors, 2)
    layer = sphere_on_bed_layer(radius=25.0, thickness=2.0, extent=7.0, n_rings=rings, n_sectors=sectors)
    return dea.ContactProblem(layer, law or dea.LinearLaw(0.6), force=(0, 0, -10.0), reference=(0, 0, 25.0),
                              free=("uz",))


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
    return dea.ContactProblem(layer, law or dea.LinearLaw(10.0), force=(300.0, -200.0, -500.0),
                              moment=(400.0, 300.0, -250.0), free=dea.DOFS)


PROBLEMS = {"plate": plate_problem, "sphere": sphere_problem, "box": box_problem}


def peak_rss_mb() -> float:
    """Peak resident memory of this process so far (MB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def timed(fn, *args, **kwargs):
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dea.ValidityWarning)
        out = fn(*args, **kwargs)
    return out, time.perf_counter() - start


def header(title: str) -> str:
    import numpy
    import scipy

    blas = ""
    try:
        from threadpoolctl import threadpool_info

        blas = ", ".join(sorted({f"{i['internal_api']} {i.get('architecture', '')}".strip() for i in threadpool_info()}))
    except ImportError:
        pass
    return (
        f"# {title}\n"
        f"# date: {_dt.datetime.now().isoformat(timespec='seconds')}  machine: {platform.machine()} "
        f"{platform.processor() or ''} cores={os.cpu_count()}  python {platform.python_version()}  "
        f"numpy {numpy.__version__}  scipy {scipy.__version__}  dea-opt {dea.__version__}  {blas}\n"
        f"# load average: {' '.join(f'{x:.2f}' for x in os.getloadavg())}\n"
    )


def print_table(rows: list[dict], columns: list[str]) -> str:
    def fmt(v):
        if isinstance(v, float):
            return f"{v:.4g}"
        return str(v)

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
