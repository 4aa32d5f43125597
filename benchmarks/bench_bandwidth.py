"""How close Newton comes to the machine's memory bandwidth at 1e6 springs.

Run::

    python benchmarks/bench_bandwidth.py            # the box (6 free dofs) at 1e6 springs

Newton's passes over the springs are matrix-vector products and elementwise kernels on arrays
of N values: memory-bound. Measured in one process, one thread (Newton runs BLAS on one
thread, ``single_threaded_blas``; NumPy's kernels use one):

* ``copy_GBs``: the machine's copy bandwidth, ``numpy.copyto`` of a 512 MB array (best of
  five), as the bytes it reads per second, the unit of Newton's count (``stream_copy_GBs``
  counts the bytes written too, as STREAM does; ``read_GBs`` is ``numpy.sum`` of the array, a
  pure read);
* ``newton_s``: Newton's own solve time (``FormulationResult.solve_time``, best of five), cold
  start, the box at 1e6 springs;
* ``newton_bytes``: the bytes its kernels read, from the kernels it ran (counted in a separate,
  instrumented run: each fused sweep, with the springs of the tangents it sums, each line-search
  evaluation)
  and the arrays each kernel reads (:func:`bytes_read`); the temporaries kernels write, and
  read back, are not counted, so this is a lower bound of its memory traffic;
* ``newton_GBs = newton_bytes / newton_s`` and ``fraction = newton_GBs / copy_GBs``;
* in STREAM's units, the bytes read and written (:func:`bytes_written`) per second,
  ``moved_GBs``, and ``fraction_moved = moved_GBs / stream_copy_GBs``.

Target (speed issue): ``fraction >= 0.5``.
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
    "iterations",
    "tangents",
    "tangent_springs",
    "sweeps",
    "slopes",
    "energies",
    "newton_s",
    "newton_bytes",
    "newton_GBs",
    "copy_GBs",
    "stream_copy_GBs",
    "read_GBs",
    "fraction",
    "moved_GBs",
    "fraction_moved",
    "success",
    "status",
]


def copy_bandwidth(megabytes: int = 512, repeats: int = 5) -> tuple[float, float]:
    """``(copy, read)``: bytes read per second by ``numpy.copyto`` of a ``megabytes`` array, and
    by ``numpy.sum`` of it (a pure read), best of ``repeats`` each."""
    import numpy as np

    src = np.ones(megabytes * (1 << 20) // 8)
    dst = np.empty_like(src)
    np.copyto(dst, src)  # fault the pages in
    copy = read = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        np.copyto(dst, src)
        middle = time.perf_counter()
        src.sum()
        copy, read = min(copy, middle - start), min(read, time.perf_counter() - middle)
    return src.nbytes / copy, src.nbytes / read


def bytes_read(n: int, m: int, k: int, counts: dict) -> int:
    """The bytes Newton's kernels read (``formulations/newton.py``, ``_iterate``, and its fused
    sweeps ``formulations/_parts/sweeps.py``), for N = ``n`` springs, ``m`` free dofs, ``k`` of them
    resisted, and the kernel ``counts`` of one solve.

    Per kernel, the arrays it reads (float64: 8 bytes a value; ``AT`` is k x N):

    * set-up: the scaling ``T^T A^T`` (8mN) and the first strains ``e0 + xi AT`` (8kN + 8N);
    * every sweep (:func:`~dea_opt.formulations._parts.sweeps.state`: the residual with the
      tangent over the compressed springs, or the confirmation's residual alone): ``AT``, the
      strains and the volumes (8kN + 16N);
    * every iteration but the last: the direction ``d @ AT`` (8kN) and the active set's comparison
      (9N);
    * a line-search slope or energy: the strains, the direction and the volumes (24N);
    * the stress of the answer (8N).
    """
    iterations = counts["iterations"]
    total = 8 * m * n + 8 * k * n + 8 * n
    total += counts["sweeps"] * (8 * k * n + 16 * n)
    total += (iterations - 1) * (8 * k * n + 9 * n)
    total += 24 * n * (counts["slopes"] + counts["energies"])
    total += 8 * n
    return int(total)


def bytes_written(n: int, m: int, k: int, counts: dict) -> int:
    """The bytes Newton's kernels write (the arrays of N values or more they make), with the
    kernels of :func:`bytes_read`: the scaled ``AT`` (8kN) and the first strains (8N); per
    iteration but the last the direction ``Ad`` and the active mask (9N); 8N per slope (the trial
    strains; a sweep and an energy write nothing of N values) and 16N for the answer's stress."""
    iterations = counts["iterations"]
    total = 8 * k * n + 8 * n + (iterations - 1) * 9 * n + 8 * n * counts["slopes"] + 16 * n
    return int(total)


def count_kernels(system, law) -> dict:
    """Newton's kernels in one cold solve: its sweeps (each tangent's springs), slopes and energies."""
    import numpy as np

    from dea_opt.formulations import newton
    from dea_opt.formulations._parts import sweeps

    counts = {"tangent_springs": [], "sweeps": 0, "slopes": 0, "energies": 0}
    real_state, real_slope, real_phi = sweeps.state, newton._Line.slope, newton._Line.phi

    def state(AT, V, eps, law, *, tangent=True, extended=False):
        counts["sweeps"] += 1
        if extended:
            counts["tangent_springs"].append(int(eps.size))
        if tangent:
            counts["tangent_springs"].append(int(np.count_nonzero(eps < 0)))
        return real_state(AT, V, eps, law, tangent=tangent, extended=extended)

    def slope(self, alpha):
        counts["slopes"] += 1
        return real_slope(self, alpha)

    def phi(self, alpha):
        counts["energies"] += 1
        return real_phi(self, alpha)

    sweeps.state, newton._Line.slope, newton._Line.phi = state, slope, phi
    try:
        result = newton.NewtonModel(system, law).solve()
    finally:
        sweeps.state, newton._Line.slope, newton._Line.phi = real_state, real_slope, real_phi
    counts["iterations"] = result.iterations
    return counts


def measure(problem: str = "box", n: int = 1_000_000, repeats: int = 5) -> dict:
    """The row: Newton's time and bytes, and the copy bandwidth, in this process."""
    import warnings

    from bench_core import make_problem

    import dea_opt as dea
    from dea_opt.formulations import scaling
    from dea_opt.formulations.newton import NewtonModel

    warnings.simplefilter("ignore", dea.ValidityWarning)
    p = make_problem(problem, n)
    system = p.system()
    NewtonModel(make_problem(problem, 1000).system(), p.law).solve()  # warm the code paths
    copy, read = copy_bandwidth()
    times, result = [], None
    for _ in range(repeats):
        result = NewtonModel(system, p.law).solve()  # a new model: a cold start every time
        times.append(result.solve_time)
    counts = count_kernels(system, p.law)
    k = scaling(system, p.law.modulus).n_dofs
    total = bytes_read(system.n_springs, system.n_dofs, k, counts)
    written = bytes_written(system.n_springs, system.n_dofs, k, counts)
    best = min(times)
    return {
        "problem": problem,
        "n_springs": system.n_springs,
        "n_dofs": system.n_dofs,
        "iterations": counts["iterations"],
        "tangents": len(counts["tangent_springs"]),
        "tangent_springs": " ".join(map(str, counts["tangent_springs"])),
        "sweeps": counts["sweeps"],
        "slopes": counts["slopes"],
        "energies": counts["energies"],
        "newton_s": best,
        "newton_bytes": total,
        "newton_GBs": total / best / 1e9,
        "copy_GBs": copy / 1e9,
        "stream_copy_GBs": 2 * copy / 1e9,
        "read_GBs": read / 1e9,
        "fraction": total / best / copy,
        "moved_GBs": (total + written) / best / 1e9,
        "fraction_moved": (total + written) / best / (2 * copy),
        "success": bool(result.success),
        "status": str(result.status),
    }


def run(problem: str = "box", n: int = 1_000_000, timeout: float = 900.0, isolate: bool = True) -> dict:
    from common import run_isolated

    if isolate:
        row = run_isolated("bench_bandwidth", "measure", {"problem": problem, "n": int(n)}, timeout)
    else:
        try:
            row = measure(problem, int(n))
        except Exception as exc:  # noqa: BLE001 - a benchmark row records the failure
            row = {"status": f"error: {type(exc).__name__}: {exc}"[:300], "success": False}
    return {"problem": problem, **row}


def main(argv=None):
    from common import header, print_table, write_csv

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--springs", type=float, default=1e6)
    parser.add_argument("--problem", default="box", choices=["plate", "sphere", "box"])
    parser.add_argument("--out", type=Path, default=HERE / "results" / "bandwidth.csv")
    args = parser.parse_args(argv)
    preamble = header("dea-opt Newton bandwidth benchmark")
    print(preamble, end="")
    row = run(args.problem, args.springs)
    print_table([row], COLUMNS)
    write_csv(args.out, [row], COLUMNS, preamble)
    print(f"written {args.out}")


if __name__ == "__main__":
    main()
