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
  instrumented run: each tangent with its number of springs, each line-search evaluation)
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
    """The bytes Newton's kernels read (``formulations/newton.py``, ``_solve``), for N = ``n``
    springs, ``m`` free dofs, ``k`` of them resisted, and the kernel ``counts`` of one solve.

    Per kernel, the arrays it reads (float64: 8 bytes a value; ``AT`` is k x N):

    * set-up: the scaling ``T^T A^T`` (8mN) and the first strains ``e0 + xi AT`` (8kN + 8N);
    * every iteration's residual: ``min(eps, 0)``, the stress, ``V * sigma`` and ``AT @ w``
      (40N + 8kN); all but the last also ``compressed = min(eps, 0)`` (8N), the direction
      ``d @ AT`` (8kN) and, after the line search, ``eps < 0`` and the comparison of active
      sets (9N + N);
    * the bilateral residual of the extended first iteration (32N + 8kN);
    * a tangent over ``n_t`` springs: ``AT_t * w`` and ``(AT_t w) @ AT_t^T`` (24k n_t + 8 n_t); over
      the compressed springs also ``eps < 0`` with ``flatnonzero`` (9N), the gather of their
      columns of ``AT`` (8k n_t) and of ``V``, the strains, the law's tangent and their product
      (40 n_t); over every spring, the law's tangent and ``V *`` it (24N);
    * a line-search slope: ``alpha Ad``, ``eps +``, ``min(, 0)``, the stress, ``V * sigma`` and
      ``@ Ad`` (72N); an energy: ``alpha Ad``, ``eps +``, ``min``, the energy density and ``V @ w``
      (56N);
    * the confirmation of a step below ``xtol`` (48N + 8kN) and the stress of the answer (16N).
    """
    iterations = counts["iterations"]
    total = 8 * m * n + 8 * k * n + 8 * n
    total += iterations * (40 * n + 8 * k * n) + (iterations - 1) * (8 * n + 8 * k * n + 10 * n)
    if counts["extended"]:
        total += 32 * n + 8 * k * n
    for springs in counts["tangent_springs"]:
        total += 24 * k * springs + 8 * springs
        total += 24 * n if springs == n else 9 * n + 8 * k * springs + 40 * springs
    total += 72 * n * counts["slopes"] + 56 * n * counts["energies"]
    total += (48 * n + 8 * k * n) * counts["confirmed"] + 16 * n
    return int(total)


def bytes_written(n: int, m: int, k: int, counts: dict) -> int:
    """The bytes Newton's kernels write (the arrays of N values or more they make), with the
    kernels of :func:`bytes_read`: the scaled ``AT`` (8kN) and the first strains (16N); per
    iteration the residual's three temporaries (24N), and but for the last ``compressed``, the
    direction ``Ad`` and the active mask (17N); the bilateral residual (16N); per tangent
    ``AT_t * w`` (8k n_t), over the compressed springs also their mask, indices, gathered
    columns and values (N + 8k n_t + 40 n_t), over every spring the law's tangent times ``V``
    (16N); 40N per slope, 32N per energy, 24N for the confirmation and 16N for the answer."""
    iterations = counts["iterations"]
    total = 8 * k * n + 16 * n + iterations * 24 * n + (iterations - 1) * 17 * n
    if counts["extended"]:
        total += 16 * n
    for springs in counts["tangent_springs"]:
        total += 8 * k * springs + (16 * n if springs == n else n + 8 * k * springs + 40 * springs)
    total += 40 * n * counts["slopes"] + 32 * n * counts["energies"] + 24 * n * counts["confirmed"] + 16 * n
    return int(total)


def count_kernels(system, law) -> dict:
    """Newton's kernels in one cold solve: its tangents (springs each), slopes and energies."""
    from dea_opt.formulations import newton

    counts = {"tangent_springs": [], "slopes": 0, "energies": 0}
    real_tangent, real_slope, real_phi = newton._tangent, newton._Line.slope, newton._Line.phi

    def tangent(AT, weight):
        counts["tangent_springs"].append(int(AT.shape[1]))
        return real_tangent(AT, weight)

    def slope(self, alpha):
        counts["slopes"] += 1
        return real_slope(self, alpha)

    def phi(self, alpha):
        counts["energies"] += 1
        return real_phi(self, alpha)

    newton._tangent, newton._Line.slope, newton._Line.phi = tangent, slope, phi
    try:
        result = newton.NewtonModel(system, law).solve()
    finally:
        newton._tangent, newton._Line.slope, newton._Line.phi = real_tangent, real_slope, real_phi
    n = system.n_springs
    counts["iterations"] = result.iterations
    # The extended first iteration's tangent is over every spring, and it is the first tangent.
    counts["extended"] = bool(counts["tangent_springs"]) and counts["tangent_springs"][0] == n
    counts["confirmed"] = int("xtol" in result.message)
    return counts


def measure(problem: str = "box", n: int = 1_000_000, repeats: int = 5) -> dict:
    """The row: Newton's time and bytes, and the copy bandwidth, in this process."""
    import warnings

    from bench_core import make_problem

    import dea_opt as dea
    from dea_opt.formulations.newton import NewtonModel
    from dea_opt.formulations.scaling import scaling

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
