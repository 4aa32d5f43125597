"""Outputs within memory: ``dea-opt run`` of 1e7 springs, and a load path of 1e4 frames.

Run from the repository's top (each case in a fresh subprocess, its peak RSS its own)::

    python benchmarks/bench_outputs.py                    # both targets (about 10 min on 2 cores)
    python benchmarks/bench_outputs.py --springs 1e6      # smaller sizes, a quick look
    python benchmarks/bench_outputs.py --only run         # or: path

Targets:

* ``run``: ``dea-opt run`` of a scenario with 1e7 springs (a plate, ``[geometry] kind =
  "plate"``, 3 free dofs) and the default outputs (``contact.vtu``, ``.csv``, ``.json``,
  ``.png``) peaks under 4 GB RSS and takes at most 3 x (the solve + writing the VTK file),
  both measured on their own in another process: build the problem, ``dea_opt.solve``,
  ``to_vtk``.
* ``path``: a load path of 1e4 frames on the demo's hip (5400 springs) with the exposure
  peaks under 1 GB RSS, run as ``dea-opt run`` should run it: the frames' ``.vtu`` written as
  they are solved (``PathOutputs(series=...)``), nothing per frame kept (``keep_solutions=False,
  keep_pressures=False``), then ``PathResult.write`` (frames.csv, series.pvd, exposure.vtu,
  plots, summary.json). The same path keeping every solution is measured too, for scale.

Each row: what, size, wall time (s), peak RSS (MB). The final TARGETS table says met or not.
Results go to ``benchmarks/results/outputs.csv`` (or ``--out``).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

from common import header, print_table, write_csv

SCENARIO = """\
title = "Plate on {n} springs (bench_outputs)"
[geometry]
kind = "plate"
length = 40.0
width = 10.0
nx = {nx}
ny = {ny}
thickness = 2.0
[law]
kind = "linear"
H = 10.0
[body2]
free = ["uz", "rx", "ry"]
[load]
force = [0.0, 0.0, -500.0]
point = [8.0, 2.0, 0.0]
[solve]
method = "newton"
[output]
directory = "out"
"""

# The solve and the VTK file alone, as the 3x reference: the same problem as the scenario's.
REFERENCE = """
import json, sys, time
from dea_opt.scenario import load_scenario, build_problem
import dea_opt as dea
scenario = load_scenario(sys.argv[1])
start = time.perf_counter()
problem = build_problem(scenario)
build = time.perf_counter() - start
start = time.perf_counter()
solution = dea.solve(problem, "newton")
solve = time.perf_counter() - start
start = time.perf_counter()
solution.to_vtk(sys.argv[2])
vtk = time.perf_counter() - start
print(json.dumps({"build": build, "solve": solve, "vtk": vtk, "n": len(problem.layer)}))
"""

PATH = """
import json, sys, time, warnings
import dea_opt as dea
from dea_opt.gait import hip_gait_load
from dea_opt.geometry import socket_layer
frames, keep, out = int(sys.argv[1]), sys.argv[2] == "keep", sys.argv[3]
layer = socket_layer(radius=25.0, thickness=3.0, coverage=80.0, n_rings=45, n_sectors=120, gap=0.1)
problem = dea.ContactProblem(layer, dea.LinearLaw(10.0), free=("ux", "uy", "uz"))
loads = hip_gait_load(n_frames=frames)
start = time.perf_counter()
with warnings.catch_warnings():
    warnings.simplefilter("ignore")
    if keep:
        result = dea.solve_path(problem, loads, method="auto")
    else:
        result = dea.solve_path(problem, loads, method="auto", outputs=dea.PathOutputs(keep_solutions=False, keep_pressures=False,
                                series=out + "/series_frames"))
solve = time.perf_counter() - start
start = time.perf_counter()
files = result.write(out, formats=("csv", "json", "vtk", "png") if not keep else ("csv", "json", "png"))
write = time.perf_counter() - start
print(json.dumps({"solve": solve, "write": write, "frames": len(result), "n": len(layer),
                  "failed": len(result.failed_frames), "files": len(files)}))
"""


def child(command, cwd=None) -> tuple[dict | None, float, float, str]:
    """Run ``command``; return (its JSON line or None, wall time s, peak RSS MB, stderr tail)."""
    start = time.perf_counter()
    process = subprocess.Popen(
        command,
        cwd=cwd,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, "MPLBACKEND": "Agg"},
    )
    # wait4 gives this child's own peak RSS (ru_maxrss of RUSAGE_CHILDREN is the largest of all)
    _, status, usage = os.wait4(process.pid, 0)
    wall = time.perf_counter() - start
    out, err = process.stdout.read(), process.stderr.read()
    process.stdout.close()
    process.stderr.close()
    peak = usage.ru_maxrss / 1024.0  # kB on Linux
    lines = [line for line in out.splitlines() if line.startswith("{")]
    if os.waitstatus_to_exitcode(status) not in (0, 1, 3):
        return None, wall, peak, err[-2000:]
    return (json.loads(lines[-1]) if lines else None), wall, peak, err[-2000:]


def bench_run(n: float, work: Path) -> list[dict]:
    n = int(n)
    ny = max(round((n / 4) ** 0.5), 1)
    nx = max(n // ny, 1)
    scenario = work / "plate.toml"
    scenario.write_text(SCENARIO.format(n=nx * ny, nx=nx, ny=ny))
    ref, ref_wall, ref_peak, err = child([sys.executable, "-c", REFERENCE, str(scenario), str(work / "ref.vtu")])
    if ref is None:
        raise RuntimeError(f"the reference run failed:\n{err}")
    cli = Path(sys.executable).with_name("dea-opt")
    command = [str(cli)] if cli.is_file() else [sys.executable, "-m", "dea_opt.cli"]
    _, wall, peak, err = child([*command, "run", str(scenario), "-o", str(work / "run")])
    sizes = {p.name: p.stat().st_size for p in (work / "run").glob("contact.*")}
    if len(sizes) < 4:
        raise RuntimeError(f"dea-opt run wrote {sorted(sizes)}:\n{err}")
    return [
        {"what": "solve alone (newton)", "size": nx * ny, "time_s": ref["solve"], "peak_rss_mb": None},
        {"what": "to_vtk alone", "size": nx * ny, "time_s": ref["vtk"], "peak_rss_mb": None},
        {"what": "build + solve + to_vtk (one process)", "size": nx * ny, "time_s": ref_wall, "peak_rss_mb": ref_peak},
        {
            "what": "dea-opt run, default outputs",
            "size": nx * ny,
            "time_s": wall,
            "peak_rss_mb": peak,
            "files_mb": sum(sizes.values()) / 1e6,
            "reference_s": ref["solve"] + ref["vtk"],
        },
    ]


def bench_path(frames: float, work: Path, keep_too: bool) -> list[dict]:
    frames = int(frames)
    rows = []
    for mode in ("stream", "keep") if keep_too else ("stream",):
        out = work / f"path_{mode}"
        result, wall, peak, err = child([sys.executable, "-c", PATH, str(frames), mode, str(out)])
        if result is None:
            raise RuntimeError(f"the path ({mode}) failed:\n{err}")
        what = (
            "solve_path streamed (series=, nothing kept) + write"
            if mode == "stream"
            else "solve_path keeping every solution + write (no series)"
        )
        rows.append(
            {
                "what": what,
                "size": result["frames"],
                "time_s": wall,
                "peak_rss_mb": peak,
                "solve_s": result["solve"],
                "write_s": result["write"],
                "failed": result["failed"],
            }
        )
    return rows


def targets(run_rows, path_rows) -> list[dict]:
    out = []
    for row in run_rows:
        if row["what"].startswith("dea-opt run"):
            out.append(
                {
                    "what": f"dea-opt run, {row['size']:.0e} springs: peak RSS",
                    "target": "< 4 GB",
                    "measured": f"{row['peak_rss_mb'] / 1024:.2f} GB",
                    "met": row["peak_rss_mb"] < 4096,
                }
            )
            ratio = row["time_s"] / row["reference_s"]
            out.append(
                {
                    "what": f"dea-opt run, {row['size']:.0e} springs: time / (solve + VTK)",
                    "target": "<= 3",
                    "measured": f"{ratio:.2f} ({row['time_s']:.1f} s / {row['reference_s']:.1f} s)",
                    "met": ratio <= 3.0,
                }
            )
    for row in path_rows:
        if row["what"].startswith("solve_path streamed"):
            out.append(
                {
                    "what": f"load path, {row['size']} frames with exposure: peak RSS",
                    "target": "< 1 GB",
                    "measured": f"{row['peak_rss_mb'] / 1024:.2f} GB",
                    "met": row["peak_rss_mb"] < 1024,
                }
            )
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--springs", type=float, default=1e7, help="springs of the dea-opt run (default 1e7)")
    parser.add_argument("--frames", type=float, default=1e4, help="frames of the load path (default 1e4)")
    parser.add_argument("--only", nargs="+", choices=("run", "path"), default=("run", "path"))
    parser.add_argument("--no-keep", action="store_true", help="skip the path that keeps every solution")
    parser.add_argument("--out", type=Path, default=HERE / "results")
    args = parser.parse_args(argv)
    head = header("dea-opt outputs benchmark")
    print(head, flush=True)
    run_rows, path_rows = [], []
    with tempfile.TemporaryDirectory(prefix="dea-bench-outputs-") as tmp:
        work = Path(tmp)
        if "run" in args.only:
            run_rows = bench_run(args.springs, work)
        if "path" in args.only:
            path_rows = bench_path(args.frames, work, not args.no_keep)
    rows = run_rows + path_rows
    columns = ["what", "size", "time_s", "peak_rss_mb", "files_mb", "reference_s", "solve_s", "write_s", "failed"]
    print_table(rows, ["what", "size", "time_s", "peak_rss_mb"])
    goals = targets(run_rows, path_rows)
    print("\nTARGETS")
    print_table(goals, ["what", "target", "measured", "met"])
    write_csv(args.out / "outputs.csv", rows, columns, preamble=head)
    return 0 if all(g["met"] for g in goals) else 1


if __name__ == "__main__":
    sys.exit(main())
