"""The comparison study's QP solvers at a given size: :func:`dea_opt.study.run_study`.

Run::

    python benchmarks/bench_study.py                      # sphere on a bed, 1e4 and 1e5 springs
    python benchmarks/bench_study.py --sizes 1e4 --problem box

Every QP solver cvxpy has installed (Clarabel, OSQP, SCS, PIQP) and the Newton reference, at
the default accuracy, one run each, in a fresh subprocess per size. One row per solver: its
total time (model build, compile and solve), success (solver status, certificate, agreement
with Newton), iterations and worst certificate residual. Writes ``benchmarks/results/study.csv``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

COLUMNS = [
    "problem",
    "n_springs",
    "method",
    "solver",
    "success",
    "status",
    "iterations",
    "total_time_s",
    "solver_time_s",
    "relative_time",
    "worst_residual",
    "d_pressure",
    "study_wall_s",
    "peak_rss_mb",
]


def one(problem: str, n: int, methods=("newton", "qp"), blas_threads: int | None = None) -> list[dict]:
    """The study on ``problem`` at about ``n`` springs; one row per method and solver."""
    import time

    import numpy as np
    from bench_core import make_problem
    from common import blas_limit, peak_rss_mb

    from dea_opt.study import run_study

    with blas_limit(blas_threads):
        run_study(make_problem(problem, 200), methods=methods)  # warm every solver's code path
        p = make_problem(problem, n)
        start = time.perf_counter()
        result = run_study(p, methods=methods)
        wall = time.perf_counter() - start
    table, summary = result.table, result.summary
    relative = {(r["method"], r["solver"]): r["relative_time"] for _, r in summary.iterrows()}
    rows = []
    for _, r in table.iterrows():
        row = {
            "problem": problem,
            "n_springs": len(p.layer),
            "study_wall_s": wall,
            "peak_rss_mb": peak_rss_mb(),
            "relative_time": relative.get((r["method"], r["solver"]), np.nan),
        }
        for c in COLUMNS:
            if c in r.index:
                value = r[c]
                row[c] = value.item() if hasattr(value, "item") else value
        rows.append(row)
    return rows


def run(problem: str, n: int, timeout: float = 900.0, isolate: bool = True, blas_threads: int | None = None):
    from common import run_isolated

    kwargs = {"problem": problem, "n": int(n), "blas_threads": blas_threads}
    if isolate:
        out = run_isolated("bench_study", "one", kwargs, timeout)
    else:
        try:
            out = one(**kwargs)
        except Exception as exc:  # noqa: BLE001
            out = {"status": f"error: {type(exc).__name__}: {exc}"[:300], "success": False}
    if isinstance(out, dict):
        return [{"problem": problem, "n_springs": int(n), "method": "qp", "solver": "all", **out}]
    return out


def main(argv=None):
    from common import header, print_table, write_csv

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", nargs="+", type=float, default=[1e4, 1e5])
    parser.add_argument("--problem", default="sphere", choices=["plate", "sphere", "box"])
    parser.add_argument("--out", type=Path, default=HERE / "results" / "study.csv")
    args = parser.parse_args(argv)
    preamble = header("dea-opt comparison-study benchmark")
    print(preamble, end="")
    rows = [row for n in args.sizes for row in run(args.problem, n)]
    print_table(rows, COLUMNS)
    write_csv(args.out, rows, COLUMNS, preamble)
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
