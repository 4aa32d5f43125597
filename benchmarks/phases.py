"""Where the time goes: cProfile and per-phase timers for one benchmark case.

Run from the repository's top::

    python benchmarks/phases.py newton --problem box --n 1e6
    python benchmarks/phases.py qp --problem box --n 1e5
    python benchmarks/phases.py nlp --problem sphere --n 1e5 --law cubic --form constrained
    python benchmarks/phases.py mesh --pair hip --faces 1e5 --engine embree
    python benchmarks/phases.py gait --springs 2e4

``newton``: one ``dea.solve`` under cProfile, with Newton's iterations and line-search
evaluations (each one pass over the spring data). ``qp``: the QPModel phases of
``bench_qp.py`` and cProfile of the first solve (cvxpy's canonicalization by function).
``nlp``: IPOPT's own timing statistics (``print_timing_statistics``), which split the solve
into function evaluations (CasADi) and IPOPT's linear algebra (MUMPS), and the model build.
``mesh`` and ``gait``: cProfile of the call. ``--blas-threads 1`` caps the BLAS pools.
"""

from __future__ import annotations

import argparse
import cProfile
import io
import os
import pstats
import sys
import time
import warnings
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))


def _profile(fn, top: int = 25):
    """``fn()`` under cProfile; print the top functions by cumulative and by own time."""
    profiler = cProfile.Profile()
    start = time.perf_counter()
    profiler.enable()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        out = fn()
    profiler.disable()
    wall = time.perf_counter() - start
    for key, title in (("cumulative", "cumulative time"), ("tottime", "own time")):
        buffer = io.StringIO()
        stats = pstats.Stats(profiler, stream=buffer)
        stats.sort_stats(key).print_stats(top)
        text = buffer.getvalue().replace(str(Path(sys.prefix)), "<venv>").replace(str(HERE.parent) + "/", "")
        body = text[text.find("   ncalls") :]
        print(f"--- top {top} by {title} (wall {wall:.3f} s under the profiler) ---")
        print(body.rstrip())
    return out, wall


def newton(args):
    from bench_core import make_problem

    import dea_opt as dea

    dea.solve(make_problem(args.problem, 200, args.law), "newton")  # warm imports
    p = make_problem(args.problem, int(args.n), args.law)
    start = time.perf_counter()
    system = p.system()
    print(
        f"problem {args.problem}, {len(p.layer)} springs, {system.n_dofs} free dofs; geometry and system "
        f"{time.perf_counter() - start:.3f} s"
    )
    for k in range(2):
        start = time.perf_counter()
        s = dea.solve(p, "newton", strict=False)
        print(
            f"dea.solve #{k + 1}: {time.perf_counter() - start:.3f} s (Newton's own solve_time {s.solve_time:.3f} s); "
            f"{s.iterations} iterations, {s.info.get('line_evaluations')} line-search evaluations"
        )
    s, _ = _profile(lambda: dea.solve(p, "newton", strict=False))
    nbytes = system.AT.nbytes + system.e0.nbytes + system.volume.nbytes
    print(
        f"spring data of the system: {nbytes / 1e6:.0f} MB (AT {system.AT.shape}, e0, volume); "
        f"iterations {s.iterations}, line-search evaluations {s.info.get('line_evaluations')}"
    )


def qp(args):
    import bench_qp

    rows = bench_qp.overhead(args.problem, int(args.n))
    from common import print_table

    print_table(rows, bench_qp.COLUMNS)
    from bench_core import make_problem

    from dea_opt.formulations.qp import QPModel

    p = make_problem(args.problem, int(args.n))
    system = p.system()

    def first():
        model = QPModel(system, p.law)
        return model.solve(system.load)

    print("\ncProfile of QPModel(...) + the first solve:")
    _profile(first, top=30)


def nlp(args):
    """IPOPT's timing statistics: run the solve in a child so that IPOPT's C output is caught."""
    import subprocess

    code = (
        f"import sys, time, warnings; sys.path.insert(0, {str(HERE)!r}); "
        "from bench_core import make_problem, _warm_imports; _warm_imports('nlp'); "
        "from dea_opt.formulations.nlp import NLPModel; "
        f"p = make_problem({args.problem!r}, {int(args.n)}, {args.law!r}); s = p.system(); "
        "t = time.perf_counter(); "
        f"m = NLPModel(s, p.law, form={args.form!r}, ipopt_options={{'print_timing_statistics': 'yes', "
        "'print_level': 3}); b = time.perf_counter() - t; "
        "t = time.perf_counter(); r = m.solve(); w = time.perf_counter() - t; "
        "print(f'NLPModel build {b:.3f} s; solve call {w:.3f} s; iterations {r.iterations}; {r.status}', "
        "flush=True)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=args.timeout)
    text = out.stdout + out.stderr
    keep = [line for line in text.splitlines() if line.strip() and not line.startswith("*")]
    print("\n".join(keep[-80:]))


def mesh(args):
    import bench_mesh

    from dea_opt.mesh import springs_from_meshes

    small = bench_mesh.make_pair(args.pair, 2000)
    springs_from_meshes(small.mesh1, small.mesh2, engine=args.engine, **small.options)
    pair = bench_mesh.make_pair(args.pair, args.faces)
    print(f"{args.pair}: {len(pair.mesh1.faces)} + {len(pair.mesh2.faces)} faces, engine {args.engine}")
    _profile(
        lambda: springs_from_meshes(pair.mesh1.copy(), pair.mesh2.copy(), engine=args.engine, **pair.options), top=30
    )


def gait(args):
    from bench_path import hip, load_hip_gait

    import dea_opt as dea

    loads = load_hip_gait()
    dea.solve_path(hip(500), loads.iloc[:3], method="newton", outputs=dea.PathOutputs(keep_solutions=False))
    problem = hip(int(args.springs))
    start = time.perf_counter()
    result = dea.solve_path(problem, loads, method="newton", outputs=dea.PathOutputs(keep_solutions=False))
    wall = time.perf_counter() - start
    table = result.table
    print(
        f"gait: {len(problem.layer)} springs, {len(table)} frames: {wall:.3f} s in all; Newton's own solve time "
        f"{table['solve_time_s'].sum():.3f} s, {int(table['iterations'].sum())} iterations"
    )
    _profile(
        lambda: dea.solve_path(problem, loads, method="newton", outputs=dea.PathOutputs(keep_solutions=False)), top=30
    )


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("case", choices=["newton", "qp", "nlp", "mesh", "gait"])
    parser.add_argument("--problem", default="box", choices=["plate", "sphere", "box"])
    parser.add_argument("--n", type=float, default=1e5, help="springs (newton, qp, nlp)")
    parser.add_argument("--law", default="linear", choices=["linear", "cubic"])
    parser.add_argument("--form", default="constrained", choices=["constrained", "reduced"])
    parser.add_argument("--pair", default="hip", choices=["hip", "sphere_on_bed"])
    parser.add_argument("--faces", type=float, default=1e5)
    parser.add_argument("--engine", default="embree", choices=["embree", "grid"])
    parser.add_argument("--springs", type=float, default=2e4, help="springs of the gait")
    parser.add_argument("--blas-threads", type=int, default=None)
    parser.add_argument("--timeout", type=float, default=900.0)
    args = parser.parse_args(argv)
    from common import blas_limit, header

    print(header(f"dea-opt phases: {args.case}"), end="")
    with blas_limit(args.blas_threads):
        globals()[args.case](args)
    print(f"# load average at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")


if __name__ == "__main__":
    main()
