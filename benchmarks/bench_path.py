"""Load-path benchmark: the 101-frame hip gait cycle at about 2e4 springs.

Run::

    python benchmarks/bench_path.py                  # Newton and QP (Clarabel)
    python benchmarks/bench_path.py --springs 5000 --methods newton qp nlp

Targets of the scripted-analysis issue: Newton at most 2 s for the whole path; the QP
path's per-frame time after the first at most 1.1 x Clarabel's own solve time (the cvxpy
problem is compiled once and re-solved with the load as a Parameter). Prints a table and
writes ``benchmarks/results/path.csv``.
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import numpy as np

import dea_opt as dea
from dea_opt.gait import load_hip_gait
from dea_opt.geometry import socket_layer

HERE = Path(__file__).resolve().parent


def hip(n_springs: int) -> dea.ContactProblem:
    """The demo's hip (socket R = 25 mm, 80 degrees, 0.1 mm clearance) at about ``n_springs``."""
    rings = max(int(round(np.sqrt(n_springs / 3))), 4)
    sectors = max(n_springs // rings, 8)
    layer = socket_layer(radius=25.0, thickness=3.0, coverage=80.0, n_rings=rings, n_sectors=sectors, gap=0.1)
    return dea.ContactProblem(layer, dea.LinearLaw(10.0), free=("ux", "uy", "uz"))


def run(method: str, problem, loads, options: dict | None = None, label: str | None = None, repeats: int = 1) -> dict:
    """The whole path with ``method`` (``options`` for the formulation); ``wall_s`` is the best
    of ``repeats`` runs, ``wall_first_s`` the first."""
    options = ({"tol": 1e-12} if method == "qp" else {}) if options is None else options
    walls = []
    for _ in range(max(int(repeats), 1)):
        start = time.perf_counter()
        result = dea.solve_path(problem, loads, method=method, outputs=dea.PathOutputs(keep_solutions=False), **options)
        walls.append(time.perf_counter() - start)
        if walls[-1] > 5.0:
            break  # repeats are for short paths only
    wall = min(walls)
    table = result.table
    first = table["solve_time_s"].iloc[0] + table["build_time_s"].iloc[0]
    row = {
        "method": label or method,
        "n_springs": len(problem.layer),
        "frames": len(table),
        "wall_s": wall,
        "wall_first_s": walls[0],
        "repeats": len(walls),
        "solve_s": table["solve_time_s"].sum(),
        "first_frame_s": first,
        "later_frame_mean_s": table["solve_time_s"].iloc[1:].mean(),
        "iterations": int(table["iterations"].sum()),
        "success": result.success,
    }
    if method == "qp":
        # Clarabel's own time per frame, from a fresh path with the solutions kept.
        kept = dea.solve_path(problem, loads.iloc[:11], method="qp", **options)
        own = np.array([s.info.get("solver_time", np.nan) for s in kept.solutions[1:]])
        per_frame = kept.table["solve_time_s"].iloc[1:].to_numpy()
        row["overhead_ratio"] = float(np.mean(per_frame / own))
    return row


#: Method labels -> (dea_opt method, options) for the path benchmark.
PATH_METHODS = {
    "newton": ("newton", {}),
    "qp": ("qp", {"tol": 1e-12}),
    "nlp-c": ("nlp", {"form": "constrained"}),
    "nlp-r": ("nlp", {"form": "reduced"}),
}


def one(
    label: str, n_springs: int, frames: int | None = None, repeats: int = 3, blas_threads: int | None = None
) -> dict:
    """One method's gait path at about ``n_springs`` (the first ``frames`` frames, default all),
    for a fresh subprocess (``benchmarks/run.py``). Imports are warmed on a 3-frame path first.
    ``blas_threads`` caps the BLAS thread pools (default: as the machine has them)."""
    import os

    from common import blas_limit, peak_rss_mb

    method, options = PATH_METHODS[label]
    loads = load_hip_gait()
    if frames:
        loads = loads.iloc[:frames]
    with blas_limit(blas_threads):
        dea.solve_path(
            hip(500), loads.iloc[:3], method=method, outputs=dea.PathOutputs(keep_solutions=False), **options
        )
        row = run(method, hip(int(n_springs)), loads, options, label, repeats=repeats)
    row = {k: (v.item() if hasattr(v, "item") else v) for k, v in row.items()}
    row["peak_rss_mb"] = peak_rss_mb()
    row["blas_threads"] = "default" if blas_threads is None else blas_threads
    row["load_1m"] = os.getloadavg()[0]
    return row


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--springs", type=float, default=2e4)
    parser.add_argument("--methods", nargs="+", default=["newton", "qp"], choices=list(PATH_METHODS) + ["nlp"])
    args = parser.parse_args()
    problem = hip(int(args.springs))
    loads = load_hip_gait()
    rows = [
        run(PATH_METHODS[m][0], problem, loads, PATH_METHODS[m][1], m) if m in PATH_METHODS else run(m, problem, loads)
        for m in args.methods
    ]
    columns = list(dict.fromkeys(k for row in rows for k in row))
    (HERE / "results").mkdir(exist_ok=True)
    with open(HERE / "results" / "path.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, columns)
        writer.writeheader()
        writer.writerows(rows)
    for row in rows:
        print("  ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in row.items()))


if __name__ == "__main__":
    main()
