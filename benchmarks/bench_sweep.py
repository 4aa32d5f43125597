"""A sweep as a user meets it: 200 cases of the real knee's 51-frame stance on 2 local Dask workers.

Run::

    python benchmarks/bench_sweep.py                  # 200 cases, 2 workers
    python benchmarks/bench_sweep.py --cases 20

The scenario is the knee of ``bench_run.py`` (two labelled tibial plateaus against the femoral
cartilage, linear law, 51 frames); the cases vary ``law.H`` (200 values from 8 to 12 MPa) and
write ``frames.csv`` and ``summary.json`` each (``--outputs csv,json``). Measured in one run,
each in a fresh process:

* ``case_solve_s``: one case's in-process solve, the work a case cannot skip: ``solve_path``
  of the 51 frames and the re-cast of its peak frame at its solved pose (one more solve and
  one cast), on a problem already built; the median over eight cases of other ``H`` after the
  first (``case_path_s`` is ``solve_path`` alone);
* ``sweep_s``: ``run_sweep`` on a LocalCluster of ``workers`` processes, from the call to its
  return (the cluster's start and stop included), into a new folder.

Target (speed issue): ``sweep_s <= 1.5 cases case_solve_s / workers``. On a shared machine two
busy processes do not get a core each: ``parallel_case_s`` is :func:`case_solve` in ``workers``
processes at once, measured just before the sweep, and ``ratio_machine`` the sweep's time over
``cases parallel_case_s / workers`` (what the machine gave, not what the sweep machinery lost).
Reported with them:
Dask's overhead per case, ``(sweep_s workers - sum of the cases' own wall times) / cases`` (the
scheduler, the cluster's start, the transfer of tasks and rows, idle workers), the cases'
mean wall time inside the workers, and the spring casts the sweep made (entries of its cache:
one for one geometry and pose).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

COLUMNS = [
    "case",
    "cases",
    "workers",
    "frames",
    "n_springs",
    "sweep_s",
    "limit_s",
    "ratio",
    "case_solve_s",
    "case_path_s",
    "parallel_case_s",
    "ratio_machine",
    "case_wall_mean_s",
    "dask_overhead_per_case_s",
    "cast_entries",
    "statuses",
    "status",
    "success",
]


def _values(cases: int) -> str:
    return ",".join(f"{8.0 + 4.0 * k / max(cases - 1, 1):.6g}" for k in range(cases))


def case_solve(scenario: str, cases: int = 8) -> dict:
    """One case's in-process solve (solve_path and the peak frame's re-cast), on a built problem."""
    import warnings

    import numpy as np

    import dea_opt as dea
    from dea_opt.run import peak_recast, solve_options
    from dea_opt.scenario import build_problem_cast, load_scenario, read_load_path

    loaded = load_scenario(scenario)
    problem, cast = build_problem_cast(loaded)
    data = read_load_path(loaded.load_path)
    loads = data.load_objects()
    method = loaded.solve.method
    options = solve_options(loaded.solve, method, problem.law)
    whole, path = [], []
    for H in np.linspace(8.0, 12.0, cases + 1):
        case = problem.with_law(dea.LinearLaw(float(H)))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            start = time.perf_counter()
            result = dea.solve_path(
                case,
                loads,
                data.poses,
                method=method,
                times=data.times,
                body=data.body,
                outputs=dea.PathOutputs(keep_solutions=False, keep_pressures=False),
                **options,
            )
            solved = time.perf_counter()
            peak_recast(result, loads, data.body, lambda k: cast, method, options, loaded.solve.certificate_tol)
            done = time.perf_counter()
        whole.append(done - start)
        path.append(solved - start)
    return {
        "case_solve_s": float(np.median(whole[1:])),
        "case_path_s": float(np.median(path[1:])),
        "frames": len(result),
        "n_springs": len(problem.layer),
    }


def concurrent_case_solve(scenario: str, workers: int, timeout: float) -> float:
    """:func:`case_solve` in ``workers`` processes at once (started together): the mean case time
    when as many cases run side by side as the sweep runs, what this machine gives two busy
    processes (1 would be a core each)."""
    import json
    import subprocess

    with tempfile.TemporaryDirectory() as tmp:
        go = Path(tmp) / "go"
        code = (
            f"import json, sys, time; from pathlib import Path; sys.path.insert(0, {str(HERE)!r}); "
            f"from bench_sweep import case_solve; print('ready', flush=True)\n"
            f"while not Path({str(go)!r}).exists(): time.sleep(0.001)\n"
            f"print('ROW', json.dumps(case_solve({scenario!r})), flush=True)"
        )
        env = {**os.environ, "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
        processes = [
            subprocess.Popen(
                [sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
            )
            for _ in range(workers)
        ]
        for process in processes:
            process.stdout.readline()
        go.touch()
        times = []
        for process in processes:
            out, _ = process.communicate(timeout=timeout)
            rows = [json.loads(line[4:]) for line in out.splitlines() if line.startswith("ROW ")]
            times += [r["case_solve_s"] for r in rows]
    return sum(times) / len(times) if len(times) == workers else float("nan")


def sweep(scenario: str, out: str, cases: int, workers: int) -> dict:
    """``run_sweep`` of ``cases`` values of law.H on a LocalCluster of ``workers``, timed."""
    from dea_opt.sweep import run_sweep
    from dea_opt.sweep.cases import SPRING_CACHE

    start = time.perf_counter()
    result = run_sweep(scenario, [f"law.H={_values(cases)}"], out, workers=workers, outputs="csv,json")
    wall = time.perf_counter() - start
    table = result.table
    own = float(table["wall_time_s"].sum())
    return {
        "sweep_s": wall,
        "case_wall_mean_s": own / len(table),
        "rows": len(table),
        "dask_overhead_per_case_s": (wall * workers - own) / len(table),
        "statuses": ", ".join(f"{k} {v}" for k, v in table["status"].value_counts().items()),
        "cast_entries": len(list((Path(out) / SPRING_CACHE).glob("*.npz"))),
        "all_ok": bool((table["status"] == "ok").all()),
    }


def run_case(cases: int = 200, workers: int = 2, timeout: float = 1800.0) -> dict:
    """The whole measurement, each part in a fresh process; one row."""
    from bench_run import KNEE, write_scenario
    from common import run_isolated

    row = {"case": "knee", "cases": cases, "workers": workers}
    if not KNEE.is_dir():
        return {**row, "status": f"skipped: no knee data at {KNEE}", "success": False}
    with tempfile.TemporaryDirectory() as tmp:
        scenario = str(write_scenario(Path(tmp)))
        base = run_isolated("bench_sweep", "case_solve", {"scenario": scenario}, timeout)
        if "case_solve_s" not in base:
            return {**row, **base}
        base["parallel_case_s"] = concurrent_case_solve(scenario, workers, timeout)
        swept = run_isolated(
            "bench_sweep",
            "sweep",
            {"scenario": scenario, "out": str(Path(tmp) / "sweep"), "cases": cases, "workers": workers},
            timeout,
        )
    if "sweep_s" not in swept:
        return {**row, **base, **swept}
    row |= base | swept
    row["limit_s"] = 1.5 * cases * row["case_solve_s"] / workers
    row["ratio"] = row["sweep_s"] / (cases * row["case_solve_s"] / workers)
    row["ratio_machine"] = row["sweep_s"] / (cases * row["parallel_case_s"] / workers)
    row["success"] = swept["all_ok"] and swept["rows"] == cases
    row["status"] = "ok" if row["success"] else f"{swept['rows']} rows: {swept['statuses']}"
    return row


def main(argv=None):
    from common import header, print_table, write_csv

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cases", type=int, default=200)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=HERE / "results" / "sweep.csv")
    args = parser.parse_args(argv)
    preamble = header("dea-opt sweep benchmark")
    print(preamble, end="")
    row = run_case(args.cases, args.workers)
    print_table([row], COLUMNS)
    write_csv(args.out, [row], COLUMNS, preamble)
    print(f"written {args.out}")


if __name__ == "__main__":
    os.environ.setdefault("MPLBACKEND", "Agg")
    main()
