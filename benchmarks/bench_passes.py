"""Newton's whole certified and assessed solve at 1e6 springs, counted in passes over the springs.

Run::

    python benchmarks/bench_passes.py                # the box (6 free dofs) at 1e6 springs
    python benchmarks/bench_passes.py --phases       # and where a first call's passes go

One *pass* is the memory-bound floor of an iteration: reading every spring array once and
writing one strain array, timed here as ``eps = e0 + xi @ AT`` and a sum of each other array the
problem holds per spring (the system's ``volume``; the layer's points, normals, areas,
thicknesses and gaps; the normal operator, 12 values a spring), best of nine, in the same process. The
solve is the whole ``dea.solve(problem, "newton")`` (Newton, the certificate and the validity
report that ``solve`` assesses), on a problem whose spring system is built before the clock
starts: ``first`` is the first such call in a fresh process (what a user's one solve costs:
fresh memory, nothing cached), ``best`` the best of five more. Both are divided by the pass.

``--phases`` times a first call once more, in a fresh process of its own, by phase: Newton
(its sweeps over the springs apart), the certificate, the validity report, and the rest of
``solve`` (the strains and pressures at the answer, the load checks), each in passes.

Target (speed issue): the first call in at most 20 passes. The row also names the CPU and the load
average, since the absolute times move with the machine and with what else runs on it.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

GOAL = 20.0

COLUMNS = [
    "problem",
    "n_springs",
    "n_dofs",
    "iterations",
    "pass_ms",
    "first_s",
    "best_s",
    "first_passes",
    "best_passes",
    "goal",
    "met",
    "cpu",
    "load",
    "success",
]


def pass_time(problem, repeats: int = 9) -> float:
    """Seconds of one pass over ``problem``'s springs (best of ``repeats``)."""
    import numpy as np

    system, layer = problem.system(), problem.layer
    others = (
        system.volume,
        layer.points,
        layer.normals,
        layer.areas,
        layer.thickness,
        layer.gap,
        problem.normal_operator,
    )
    xi = np.linspace(0.1, 0.6, system.n_dofs)
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        eps = system.e0 + xi @ system.AT
        for arr in others:
            float(arr.sum())
        best = min(best, time.perf_counter() - start)
        del eps
    return best


def measure(problem: str = "box", n: int = 1_000_000, repeats: int = 5) -> dict:
    """The row, measured in this process (call it in a fresh one: :func:`run`)."""
    import os
    import warnings

    from bench_core import make_problem
    from common import _cpu_model

    import dea_opt as dea
    from dea_opt._checks.threads import single_threaded_blas

    warnings.simplefilter("ignore", dea.ValidityWarning)
    dea.solve(make_problem(problem, 2000), "newton")  # imports and code paths, not the big arrays
    p = make_problem(problem, n)
    system = p.system()
    with single_threaded_blas():
        unit = pass_time(p)
    start = time.perf_counter()
    solution = dea.solve(p, "newton")
    first = time.perf_counter() - start
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        solution = dea.solve(p, "newton")
        times.append(time.perf_counter() - start)
    assert solution.validity is not None
    best = min(times)
    return {
        "problem": problem,
        "n_springs": system.n_springs,
        "n_dofs": system.n_dofs,
        "iterations": solution.iterations,
        "pass_ms": unit * 1e3,
        "first_s": first,
        "best_s": best,
        "first_passes": first / unit,
        "best_passes": best / unit,
        "goal": GOAL,
        "met": bool(first / unit <= GOAL),
        "cpu": _cpu_model(),
        "load": " ".join(f"{x:.2f}" for x in os.getloadavg()),
        "success": bool(solution.success),
    }


#: The phases of a first call (module, function, phase), timed by wrapping the function where
#: ``solve`` looks it up.
PHASES = (
    ("dea_opt.formulations.newton", "_solve", "newton"),
    ("dea_opt.formulations._parts.sweeps", "state", "newton sweeps"),
    ("dea_opt.formulations._parts.sweeps", "slope", "newton sweeps"),
    ("dea_opt.formulations._parts.sweeps", "energy", "newton sweeps"),
    ("dea_opt.solver", "certify", "certificate"),
    ("dea_opt.solution", "assess", "validity"),
)


def phases(problem: str = "box", n: int = 1_000_000) -> dict:
    """Where the passes of a first call go (call it in a fresh process: :func:`run_phases`)."""
    import collections
    import importlib
    import warnings

    from bench_core import make_problem

    import dea_opt as dea
    from dea_opt._checks.threads import single_threaded_blas

    spent: dict = collections.defaultdict(float)

    def timed(function, phase):
        def wrapper(*args, **kwargs):
            start = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                spent[phase] += time.perf_counter() - start

        return wrapper

    for module, name, phase in PHASES:
        owner = importlib.import_module(module)
        setattr(owner, name, timed(getattr(owner, name), phase))
    warnings.simplefilter("ignore", dea.ValidityWarning)
    dea.solve(make_problem(problem, 2000), "newton")
    p = make_problem(problem, n)
    p.system()
    with single_threaded_blas():
        unit = pass_time(p)
    spent.clear()
    start = time.perf_counter()
    dea.solve(p, "newton")
    total = time.perf_counter() - start
    sweeps = spent.pop("newton sweeps", 0.0)
    row = {
        "total": total / unit,
        "newton (own)": (spent.pop("newton", 0.0) - sweeps) / unit,
        "newton sweeps": sweeps / unit,
    }
    row.update({phase: seconds / unit for phase, seconds in spent.items()})
    row["rest of solve"] = row["total"] - sum(v for k, v in row.items() if k != "total")
    return row


def run_phases(problem: str = "box", n: int = 1_000_000, timeout: float = 900.0) -> dict:
    from common import run_isolated

    return run_isolated("bench_passes", "phases", {"problem": problem, "n": int(n)}, timeout)


def run(problem: str = "box", n: int = 1_000_000, timeout: float = 900.0) -> dict:
    from common import run_isolated

    return {"problem": problem, **run_isolated("bench_passes", "measure", {"problem": problem, "n": int(n)}, timeout)}


def main(argv=None):
    from common import header, print_table, write_csv

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--springs", type=float, default=1e6)
    parser.add_argument("--problem", default="box", choices=["plate", "sphere", "box"])
    parser.add_argument("--runs", type=int, default=1, help="fresh processes to measure in (one row each)")
    parser.add_argument("--out", type=Path, default=HERE / "results" / "passes.csv")
    parser.add_argument("--phases", action="store_true", help="where a first call's passes go, by phase")
    args = parser.parse_args(argv)
    preamble = header("dea-opt Newton passes benchmark")
    print(preamble, end="")
    rows = [run(args.problem, args.springs) for _ in range(args.runs)]
    print_table(rows, COLUMNS)
    for row in rows:
        if "first_passes" in row:
            print(
                f"Newton, certified and assessed, {row['n_springs']} springs: {row['first_passes']:.1f} passes "
                f"(first call; best {row['best_passes']:.1f}) against the goal <= {GOAL:g} on {row['cpu']}, "
                f"load {row['load']}"
            )
    write_csv(args.out, rows, COLUMNS, preamble)
    print(f"written {args.out}")
    if args.phases:
        split = run_phases(args.problem, args.springs)
        if "status" in split:  # (the child failed: its error)
            print(f"phases: {split['status']}")
        else:
            print("A first call by phase, in passes: " + ", ".join(f"{k} {v:.1f}" for k, v in split.items()))


if __name__ == "__main__":
    main()
