"""QP overhead: ``method="qp"`` against a direct Clarabel call on the minimal QP, first solve and re-solves.

Run::

    python benchmarks/bench_qp.py                     # sphere, plate, box at 1e4 and 1e5 springs
    python benchmarks/bench_qp.py --sizes 1e4 --problems box

The denominator is Clarabel's Python API on the minimal QP of the speed issue,
``min 1/2 sum V_i H c_i^2 - r.x`` s.t. ``c >= 0``, ``c + e0 + A x >= 0`` (``P`` diagonal, ``2N``
rows of one nonnegative cone), in the scaled variables of ``formulations/qp.md`` and with the
same settings (``TOLERANCE_OPTIONS``). This file builds its matrices itself (scipy's
``block_array``, untimed) and times only ``clarabel.DefaultSolver(P, q, G, b, cones,
settings)`` plus ``solve()`` (first solve) and ``update(q=...)`` plus ``solve()`` (a re-solve
with a new load): the direct call is given its data for free.

The numerator drives :class:`dea_opt.formulations.qp.QPModel` as a load path does:
``QPModel(system, law)`` (the scaling, the matrices, the settings) plus its first
``solve()``, then ``solve(new_load)`` per re-solve. Both sides run alternately, the whole
sequence a few times; the best time of each call is kept (a busy 2-core machine delays
either side at random). ``ratio`` is qp over direct. For information: the whole
``dea.solve(problem, "qp")`` (the spring system, the cone test, the certificate) over the
direct first solve, Clarabel's own ``solve_time``, and what Clarabel saw (variables, rows,
nonzeros of ``G``).

On a machine other jobs load, the best of a few alternating repeats still moves by 10-20 % between
the two sides (both are Clarabel's time, one read by the other's delays). So each row also gives
``outside_s``: qp's own time outside Clarabel, the best over every other repeat of qp's time less the time
spent inside Clarabel's constructor and ``solve`` (timed by a thin proxy around
``clarabel.DefaultSolver`` in the same calls), and ``quiet_ratio = (direct_s + outside_s) /
direct_s``, the ratio the machine's load cannot move.

Targets (speed issue): at 1e4 and 1e5 springs, ratio <= 1.1 (``goal``) on the first solve and on a
re-solve; ``met`` says whether the row's ``ratio`` meets it. Writes
``benchmarks/results/qp_overhead.csv``.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

COLUMNS = [
    "problem",
    "n_springs",
    "n_dofs",
    "call",
    "qp_s",
    "qp_build_s",
    "direct_s",
    "ratio",
    "goal",
    "met",
    "outside_s",
    "quiet_ratio",
    "clarabel_s",
    "iterations",
    "direct_iterations",
    "dea_solve_s",
    "dea_solve_ratio",
    "variables",
    "rows",
    "nnz_G",
    "repeats",
    "success",
    "status",
    "peak_rss_mb",
]

#: New loads of the re-solves, as multiples of the problem's own load.
FACTORS = (1.25, 0.8, 1.1)


def minimal_qp(system, law, tol):
    """The reported QP in Clarabel's form, built here with scipy's blocks: ``(P, q, G, b, cones,
    settings, scaling)``."""
    import clarabel
    import numpy as np
    import scipy.sparse as sp

    from dea_opt.formulations import scaling
    from dea_opt.formulations.qp import TOLERANCE_OPTIONS

    sc = scaling(system, law.H)
    k, n, s0 = sc.n_dofs, system.n_springs, sc.strain_scale
    P = sp.csc_array(sp.triu(sp.diags_array(np.concatenate([np.zeros(k), sc.volume * law.H * s0**2]))))
    P.eliminate_zeros()
    G = sp.csc_array(sp.block_array([[None, -sp.eye_array(n)], [sp.csc_array(-sc.AT.T / s0), -sp.eye_array(n)]]))
    b = np.concatenate([np.zeros(n), system.e0 / s0])
    q = np.concatenate([-sc.load(system.load), np.zeros(n)])
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    for name, value in TOLERANCE_OPTIONS["CLARABEL"](tol).items():
        setattr(settings, name, value)
    return P, q, G, b, [clarabel.NonnegativeConeT(2 * n)], settings, sc


#: The goal of ``ratio`` (and of ``quiet_ratio``).
GOAL = 1.1


class _Inside:
    """A proxy of ``clarabel.DefaultSolver`` that adds the time of its constructor and ``solve``
    to :attr:`seconds`; every other attribute is the solver's own."""

    seconds = 0.0
    real = None

    def __init__(self, *args):
        start = time.perf_counter()
        self._solver = _Inside.real(*args)
        _Inside.seconds += time.perf_counter() - start

    def solve(self):
        start = time.perf_counter()
        out = self._solver.solve()
        _Inside.seconds += time.perf_counter() - start
        return out

    def __getattr__(self, name):
        return getattr(self._solver, name)


def overhead(
    problem: str,
    n: int,
    resolves: int = len(FACTORS),
    repeats: int = 5,
    budget: float = 90.0,
    blas_threads: int | None = None,
) -> list[dict]:
    """The first solve and ``resolves`` re-solves, qp against the direct call; one row per call."""
    from common import blas_limit

    with blas_limit(blas_threads):
        return _overhead(problem, n, resolves, repeats, budget)


def _overhead(problem: str, n: int, resolves: int, repeats: int, budget: float) -> list[dict]:
    import warnings

    import clarabel
    import numpy as np
    from bench_core import make_problem
    from common import peak_rss_mb

    import dea_opt as dea
    from dea_opt.formulations.qp import OPTIONS, QPModel

    tol = next(o.default for o in OPTIONS if o.name == "tol")
    _Inside.real = clarabel.DefaultSolver
    warnings.simplefilter("ignore", dea.ValidityWarning)
    # Warm both code paths on a tiny problem first.
    tiny = make_problem(problem, 200)
    QPModel(tiny.system(), tiny.law).solve()
    P, q, G, b, cones, settings, _ = minimal_qp(tiny.system(), tiny.law, tol)
    clarabel.DefaultSolver(P, q, G, b, cones, settings).solve()

    p = make_problem(problem, n)
    system = p.system()
    P, q, G, b, cones, settings, sc = minimal_qp(system, p.law, tol)
    k = sc.n_dofs
    loads = [system.load] + [system.load * f for f in FACTORS[:resolves]]
    qs = [np.concatenate([-sc.load(load), np.zeros(system.n_springs)]) for load in loads]
    best = {}
    started = time.perf_counter()
    done = 0
    while done < repeats and (done < 2 or time.perf_counter() - started < budget):
        # Direct: DefaultSolver + solve, then update(q) + solve per new load.
        for i, qi in enumerate(qs):
            start = time.perf_counter()
            if i == 0:
                solver = clarabel.DefaultSolver(P, qi, G, b, cones, settings)
            else:
                solver.update(q=qi)
            out = solver.solve()
            elapsed = time.perf_counter() - start
            row = best.setdefault(i, {"direct_s": np.inf, "qp_s": np.inf})
            row["direct_s"] = min(row["direct_s"], elapsed)
            row["direct_iterations"], row["direct_status"] = int(out.iterations), str(out.status)
        # qp: QPModel(...) + solve(), then solve(new load); every other repeat with the time
        # inside Clarabel taken out (the proxy's own cost is in outside_s, not in qp_s).
        timed = done % 2 == 1
        clarabel.DefaultSolver = _Inside if timed else _Inside.real
        try:
            for i, load in enumerate(loads):
                _Inside.seconds = 0.0
                start = time.perf_counter()
                if i == 0:
                    model = QPModel(system, p.law)
                    build = time.perf_counter() - start
                result = model.solve(load)
                elapsed = time.perf_counter() - start
                row = best[i]
                if timed:
                    row["outside_s"] = min(row.get("outside_s", np.inf), elapsed - _Inside.seconds)
                elif elapsed < row["qp_s"]:
                    row.update(qp_s=elapsed, qp_build_s=build if i == 0 else 0.0)
                row.update(
                    iterations=result.iterations,
                    clarabel_s=float(result.info.get("solver_time", np.nan)),
                    success=bool(result.success),
                    status=str(result.status),
                )
        finally:
            clarabel.DefaultSolver = _Inside.real
        done += 1
    whole_s = np.inf
    for _ in range(2 if best[0]["direct_s"] < budget / 8 else 1):
        start = time.perf_counter()
        whole = dea.solve(p, "qp")
        whole_s = min(whole_s, time.perf_counter() - start)
    rows = []
    for i, row in sorted(best.items()):
        rows.append(
            {
                "problem": problem,
                "n_springs": system.n_springs,
                "n_dofs": k,
                "call": "first" if i == 0 else f"re-solve {i}",
                **row,
                "ratio": row["qp_s"] / row["direct_s"],
                "goal": GOAL,
                "met": bool(row["qp_s"] / row["direct_s"] <= GOAL),
                "quiet_ratio": (row["direct_s"] + row.get("outside_s", np.nan)) / row["direct_s"],
                "dea_solve_s": whole_s if i == 0 else np.nan,
                "dea_solve_ratio": whole_s / row["direct_s"] if i == 0 else np.nan,
                "variables": G.shape[1],
                "rows": G.shape[0],
                "nnz_G": G.nnz,
                "repeats": done,
                "success": row["success"] and whole.success,
                "peak_rss_mb": peak_rss_mb(),
            }
        )
    return rows


def run(
    problem: str, n: int, timeout: float = 900.0, isolate: bool = True, blas_threads: int | None = None
) -> list[dict]:
    from common import run_isolated

    kwargs = {"problem": problem, "n": int(n), "blas_threads": blas_threads}
    if isolate:
        out = run_isolated("bench_qp", "overhead", kwargs, timeout)
    else:
        try:
            out = overhead(**kwargs)
        except Exception as exc:  # noqa: BLE001
            out = {"status": f"error: {type(exc).__name__}: {exc}"[:300], "success": False}
    if isinstance(out, dict):
        return [{"problem": problem, "n_springs": int(n), "call": "first", **out}]
    return out


def main(argv=None):
    from common import header, print_table, write_csv

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sizes", nargs="+", type=float, default=[1e4, 1e5])
    parser.add_argument("--problems", nargs="+", default=["sphere", "plate", "box"])
    parser.add_argument("--out", type=Path, default=HERE / "results" / "qp_overhead.csv")
    args = parser.parse_args(argv)
    preamble = header("dea-opt qp overhead benchmark")
    print(preamble, end="")
    rows = [row for problem in args.problems for n in args.sizes for row in run(problem, n)]
    print_table(rows, COLUMNS)
    write_csv(args.out, rows, COLUMNS, preamble)
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
