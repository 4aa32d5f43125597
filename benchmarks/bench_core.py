"""Core benchmark: build and solve time, iterations and memory per method and size.

Run::

    python benchmarks/bench_core.py                      # N = 1e3 .. 1e6, every method
    python benchmarks/bench_core.py --sizes 1e3 1e4 --methods newton qp nlp-r --problems plate box

Methods: ``newton``, ``qp`` (cvxpy + Clarabel), ``nlp`` or ``nlp-c`` (IPOPT, constrained form),
``nlp-r`` (IPOPT, reduced form). Each (problem, method, N) runs in a fresh subprocess so that
its peak RSS is its own; sub-second solves are repeated and the best is reported beside the
first. The table is printed and written to ``benchmarks/results/core.csv``; the
Newton-versus-QP ratio per size is measured in the same run. ``benchmarks/run.py`` runs this
and every other target of the speed issue in one go.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

COLUMNS = [
    "problem",
    "law",
    "method",
    "n_springs",
    "n_dofs",
    "build_s",
    "solve_s",
    "solve_first_s",
    "total_s",
    "total_first_s",
    "repeats",
    "iterations",
    "solver_time_s",
    "base_rss_mb",
    "peak_rss_mb",
    "success",
    "certificate",
    "status",
    "blas_threads",
    "load_1m",
]

#: Method labels of the benchmark -> (dea_opt method, options).
METHODS = {
    "newton": ("newton", {}),
    "qp": ("qp", {}),
    "nlp": ("nlp", {"form": "constrained"}),
    "nlp-c": ("nlp", {"form": "constrained"}),
    "nlp-r": ("nlp", {"form": "reduced"}),
}


def _warm_imports(method: str) -> None:
    """Import the solver libraries first: their import time is not the method's cost."""
    import dea_opt as dea

    dea.formulations.get(method)
    if method == "qp":
        import clarabel  # noqa: F401
        import cvxpy  # noqa: F401
    elif method == "nlp":
        import casadi

        x = casadi.MX.sym("x")  # loads the IPOPT plugin once
        casadi.nlpsol("warm", "ipopt", {"x": x, "f": x**2}, {"print_time": 0, "ipopt": {"print_level": 0, "sb": "yes"}})


def make_problem(problem: str, n: int, law: str = "linear"):
    """The benchmark problem ``problem`` at about ``n`` springs under ``law`` ("linear" or
    "cubic": :class:`~dea_opt.CubicLaw` with the linear law's ``H`` and ``beta = 0.3``)."""
    from common import PROBLEMS

    import dea_opt as dea

    p = PROBLEMS[problem](n)
    if law == "cubic":
        p = p.with_law(dea.CubicLaw(p.law.H, 0.3))
    elif law != "linear":
        raise ValueError(f"law must be 'linear' or 'cubic', got {law!r}")
    return p


def one(
    problem: str,
    method: str,
    n: int,
    options: dict | None = None,
    law: str = "linear",
    repeats: int = 5,
    budget: float = 3.0,
    blas_threads: int | None = None,
) -> dict:
    """Build and solve one case in this process; return its row.

    ``build_s``: the problem, its spring system and the formulation's model; ``solve_s``:
    the formulation's own solve time (best of the repeats); ``total_s``: the whole
    :func:`dea_opt.solve` call (build of the model, load check, solve, certificate), best of
    the repeats; ``*_first_s`` the first call's. ``peak_rss_mb`` is taken after the first call.
    ``blas_threads`` caps the BLAS thread pools (default: as the machine has them).
    """
    from common import blas_limit

    with blas_limit(blas_threads):
        row = _one(problem, method, n, options, law, repeats, budget)
    row["blas_threads"] = "default" if blas_threads is None else blas_threads
    return row


def _one(problem, method, n, options, law, repeats, budget) -> dict:
    import os

    from common import best_of, peak_rss_mb, rss_now_mb, timed

    import dea_opt as dea

    label = method
    method, defaults = METHODS.get(method, (method, {}))
    options = {**defaults, **(options or {})}
    _warm_imports(method)
    # One tiny solve first: lazy imports and one-time set-up are not the size's cost.
    dea.solve(make_problem(problem, 200, law), method, strict=False, **options)
    base_rss = rss_now_mb()
    p, build = timed(make_problem, problem, n, law)
    system, sys_time = timed(p.system)
    first = timed(dea.solve, p, method, strict=False, **options)
    peak = peak_rss_mb()
    solutions, totals = best_of(
        lambda: dea.solve(p, method, strict=False, **options), repeats=repeats, budget=budget, first=first
    )
    s0 = solutions[0]
    best = min(range(len(totals)), key=totals.__getitem__)
    name, worst = s0.certificate.worst()
    return {
        "load_1m": os.getloadavg()[0],
        "problem": problem,
        "law": law,
        "method": label,
        "n_springs": len(p.layer),
        "n_dofs": system.n_dofs,
        "build_s": build + sys_time + s0.build_time,
        "solve_s": min(s.solve_time for s in solutions),
        "solve_first_s": s0.solve_time,
        "total_s": totals[best],
        "total_first_s": totals[0],
        "repeats": len(totals),
        "iterations": s0.iterations,
        "solver_time_s": s0.info.get("solver_time", float("nan")),
        "base_rss_mb": base_rss,
        "peak_rss_mb": peak,
        "success": all(s.success for s in solutions),
        "certificate": f"{name}={worst:.1e}",
        "status": s0.status,
    }


def run_case(
    problem: str,
    method: str,
    n: int,
    options: dict | None = None,
    timeout: float = 600.0,
    law: str = "linear",
    isolate: bool = True,
    blas_threads: int | None = None,
) -> dict:
    """:func:`one` in a fresh subprocess (``isolate``), or in this process."""
    from common import run_isolated

    kwargs = {
        "problem": problem,
        "method": method,
        "n": int(n),
        "options": options or {},
        "law": law,
        "blas_threads": blas_threads,
    }
    if not isolate:
        try:
            return one(**kwargs)
        except Exception as exc:  # noqa: BLE001 - a benchmark row records the failure
            row = {"status": f"error: {type(exc).__name__}: {exc}"[:300], "success": False}
    else:
        row = run_isolated("bench_core", "one", kwargs, timeout)
    if "total_s" not in row:
        row = {"problem": problem, "law": law, "method": method, "n_springs": int(n), **row}
    return row


def main(argv=None):
    from common import header, print_table, write_csv

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", nargs="+", type=float, default=[1e3, 1e4, 1e5, 1e6])
    parser.add_argument("--methods", nargs="+", default=["newton", "qp", "nlp-c", "nlp-r"], choices=list(METHODS))
    parser.add_argument("--problems", nargs="+", default=["plate"], choices=["plate", "sphere", "box"])
    parser.add_argument("--law", default="linear", choices=["linear", "cubic"])
    parser.add_argument("--timeout", type=float, default=600.0, help="seconds per case")
    parser.add_argument("--out", type=Path, default=HERE / "results" / "core.csv")
    args = parser.parse_args(argv)
    preamble = header("dea-opt core benchmark")
    print(preamble, end="")
    rows = []
    for problem in args.problems:
        for n in (int(s) for s in args.sizes):
            for method in args.methods:
                if method == "qp" and args.law != "linear":
                    continue
                rows.append(run_case(problem, method, n, {}, args.timeout, law=args.law))
                print(f"  {problem} {method} N={n}: {rows[-1].get('total_s', rows[-1]['status'])}", flush=True)
    print()
    print_table(rows, COLUMNS)
    for problem in args.problems:
        by = {(r["method"], r["n_springs"]): r for r in rows if r["problem"] == problem and "total_s" in r}
        for n in sorted({n for _, n in by}):
            if ("newton", n) in by and ("qp", n) in by:
                ratio = by[("qp", n)]["total_s"] / by[("newton", n)]["total_s"]
                print(f"{problem} N={n}: qp / newton total time = {ratio:.1f}x")
    write_csv(args.out, rows, COLUMNS, preamble)
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
