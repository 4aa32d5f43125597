"""Core benchmark: build and solve time, iterations and memory per method and size.

Run::

    python benchmarks/bench_core.py                      # N = 1e3 .. 1e6, every method
    python benchmarks/bench_core.py --sizes 1e3 1e4 --methods newton qp

Each (problem, method, N) runs in a fresh subprocess so that its peak RSS is its own. The
table is printed and written to ``benchmarks/results/core.csv``; the Newton-versus-QP ratio
at 1e5 springs is measured in the same run.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

COLUMNS = ["problem", "method", "n_springs", "build_s", "solve_s", "total_s", "iterations", "peak_rss_mb",
           "success", "certificate", "status"]


def one(problem: str, method: str, n: int, options: dict) -> dict:
    """Build and solve one case in this process; return its row."""
    import dea_opt as dea
    from common import PROBLEMS, peak_rss_mb, timed

    # Import the solver libraries first: their import time is not the method's cost.
    dea.formulations.get(method)
    if method == "qp":
        import clarabel  # noqa: F401
        import cvxpy  # noqa: F401
    elif method == "nlp":
        import casadi

        x = casadi.MX.sym("x")  # loads the IPOPT plugin once
        casadi.nlpsol("warm", "ipopt", {"x": x, "f": x**2}, {"print_time": 0, "ipopt": {"print_level": 0, "sb": "yes"}})
    p, build = timed(PROBLEMS[problem], n)
    system, sys_time = timed(p.system)
    s, total = timed(dea.solve, p, method, strict=False, **options)
    name, worst = s.certificate.worst()
    return {
        "problem": problem, "method": method, "n_springs": len(p.layer), "build_s": build + sys_time + s.build_time,
        "solve_s": s.solve_time, "total_s": total, "iterations": s.iterations,
        "peak_rss_mb": peak_rss_mb(), "success": s.success, "certificate": f"{name}={worst:.1e}",
        "status": s.status,
    }


def run_case(problem: str, method: str, n: int, options: dict, timeout: float) -> dict:
    code = (f"import json,sys; sys.path.insert(0, {str(HERE)!r}); from bench_core import one; "
            f"print('ROW', json.dumps(one({problem!r}, {method!r}, {n}, {options!r})))")
    try:
        out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"problem": problem, "method": method, "n_springs": n, "status": f"timeout>{timeout:g}s", "success": False}
    for line in out.stdout.splitlines():
        if line.startswith("ROW "):
            return json.loads(line[4:])
    return {"problem": problem, "method": method, "n_springs": n, "status": "error: " + out.stderr.strip()[-200:],
            "success": False}


def main(argv=None):
    from common import header, print_table, write_csv

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", nargs="+", type=float, default=[1e3, 1e4, 1e5, 1e6])
    parser.add_argument("--methods", nargs="+", default=["newton", "qp", "nlp"])
    parser.add_argument("--problems", nargs="+", default=["plate"])
    parser.add_argument("--timeout", type=float, default=600.0, help="seconds per case")
    parser.add_argument("--out", type=Path, default=HERE / "results" / "core.csv")
    args = parser.parse_args(argv)
    preamble = header("dea-opt core benchmark")
    print(preamble, end="")
    rows = []
    for problem in args.problems:
        for n in (int(s) for s in args.sizes):
            for method in args.methods:
                rows.append(run_case(problem, method, n, {}, args.timeout))
                print(f"  {problem} {method} N={n}: {rows[-1].get('total_s', rows[-1]['status'])}", flush=True)
    print()
    print_table(rows, COLUMNS)
    for problem in args.problems:
        by = {(r["method"], r["n_springs"]): r for r in rows if r["problem"] == problem and "total_s" in r}
        sizes = sorted({n for _, n in by})
        for n in sizes:
            if ("newton", n) in by and ("qp", n) in by:
                ratio = by[("qp", n)]["total_s"] / by[("newton", n)]["total_s"]
                print(f"{problem} N={n}: qp / newton total time = {ratio:.1f}x")
    write_csv(args.out, rows, COLUMNS, preamble)
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
