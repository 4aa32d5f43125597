"""dea-opt speed benchmark: every row of the speed targets' table, in one run.

Run from the repository's top::

    python benchmarks/run.py                  # the whole suite (5 to 15 min on 2 cores)
    python benchmarks/run.py --quick          # small sizes only, in-process: a smoke check
    python benchmarks/run.py --only core gait # some sections
    python benchmarks/run.py --full           # also qp and nlp constrained at 1e6 springs

Sections (``--only``):

* ``core``: plate, sphere on a bed and a box with springs on all six faces (6 free dofs) at
  N = 1e3, 1e4, 1e5, 1e6 springs, linear law; per method (``newton``, ``qp`` = cvxpy + Clarabel,
  ``nlp-c`` = IPOPT constrained, ``nlp-r`` = IPOPT reduced) build time, solve time (best of a
  few repeats for sub-second solves, and the first), the whole ``dea.solve`` call, iterations,
  peak RSS. By default ``qp`` and ``nlp-c`` stop at 1e5, but for ``qp`` on the box, which runs at
  1e6 for the growth target (``--full`` adds the rest at 1e6).
* ``cubic``: sphere and box under the cubic law at 1e4 and 1e5 (newton, nlp-c, nlp-r).
* ``qp``: the ``qp`` model's first solve and re-solves with new loads against a direct Clarabel
  call on the minimal QP, same settings (``bench_qp.py``).
* ``mesh``: springs from two meshes of 1e4 and 1e5 faces, Embree and the grid caster.
* ``gait``: the 101-frame hip gait cycle at 2e4 springs per method, warm-started.
* ``study``: the comparison study's QP solvers at 1e4 and 1e5 springs.
* ``threads``: Newton at 1e6 springs and the Newton gait again with the BLAS pools capped at
  one thread, to show how much the machine's load costs through OpenBLAS's threads.
* ``finite``: the real knee with finite kinematics, one solve against the small kinematics and a
  101-frame gait (``bench_finite.py``; skipped without ``../shared/data/knee``).
* ``run``: ``dea-opt run`` of the real knee under a 51-frame load path with every default
  output, against the same work in-process (``bench_run.py``).
* ``sweep``: 200 cases of that knee (csv/json outputs) on 2 local Dask workers, against one
  case's in-process solve (``bench_sweep.py``).
* ``bandwidth``: Newton at 1e6 springs, the bytes its kernels read per second against the
  machine's copy bandwidth (``bench_bandwidth.py``).

Every heavy case runs in a fresh subprocess (its peak RSS is its own). The output starts with
the machine, the software, the BLAS pools (threadpoolctl) and the load average, then a table
per section and a final TARGETS table (what, target, measured, met). CSVs and the printed
report go to ``benchmarks/results/`` (or ``--out``).
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import bench_bandwidth  # noqa: E402
import bench_core  # noqa: E402
import bench_finite  # noqa: E402
import bench_mesh  # noqa: E402
import bench_qp  # noqa: E402
import bench_run  # noqa: E402
import bench_study  # noqa: E402
import bench_sweep  # noqa: E402
import speed_sections  # noqa: E402
from common import Report, header, loglog_slope, write_csv  # noqa: E402
from sections import (  # noqa: E402
    section_core,
    section_gait,
    section_mesh,
    section_qp,
    section_sensitivity,
    section_study,
    section_threads,
)
from speed_sections import target  # noqa: E402

SECTIONS = (
    "core",
    "cubic",
    "qp",
    "mesh",
    "gait",
    "study",
    "threads",
    "sensitivity",
    "finite",
    "run",
    "sweep",
    "bandwidth",
    "nlpqp",
)

FULL = {
    "core": {
        "problems": ["plate", "sphere", "box"],
        "sizes": [1e3, 1e4, 1e5, 1e6],
        "methods": ["newton", "qp", "nlp-c", "nlp-r"],
    },
    # Largest size per method in the default run; --full lifts the caps. qp on the box (the
    # 6-dof case of the targets) runs at 1e6 all the same, for the growth target (~1.5 min, ~4 GB).
    "caps": {"qp": 1e5, "nlp-c": 1e5},
    "uncapped": [("box", "qp", 1e6)],
    "cubic": {"problems": ["sphere", "box"], "sizes": [1e4, 1e5], "methods": ["newton", "nlp-c", "nlp-r"]},
    "qp": {"problems": ["sphere", "plate", "box"], "sizes": [1e4, 1e5]},
    "mesh": {"pairs": ["hip", "sphere_on_bed"], "faces": [1e4, 1e5], "engines": ["embree", "grid"]},
    "gait": {"springs": 2e4, "frames": None, "methods": ["newton", "nlp-r", "qp"], "full_methods": ["nlp-c"]},
    "study": {"problem": "sphere", "sizes": [1e4, 1e5]},
    "threads": {"core": [("box", "newton", 1e4), ("box", "newton", 1e5), ("box", "newton", 1e6)], "gait": ["newton"]},
    "sensitivity": {"springs": 1e5, "calibration": True},
    "finite": {"frames": 101, "repeats": 20},
    "run": {"repeats": 3, "frames": 51},
    "sweep": {"cases": 200, "workers": 2},
    "bandwidth": {"problem": "box", "springs": 1e6},
    "nlpqp": {"problems": ["sphere", "box"], "sizes": [1e5]},
}

QUICK = {
    "core": {"problems": ["plate", "sphere", "box"], "sizes": [1e3], "methods": ["newton", "qp", "nlp-c", "nlp-r"]},
    "caps": {},
    "cubic": {"problems": ["sphere"], "sizes": [1e3], "methods": ["newton", "nlp-c", "nlp-r"]},
    "qp": {"problems": ["sphere"], "sizes": [1e3]},
    "mesh": {"pairs": ["hip"], "faces": [2e3], "engines": ["embree", "grid"]},
    "gait": {"springs": 2e3, "frames": 21, "methods": ["newton"], "full_methods": []},
    "study": {"problem": "sphere", "sizes": [1e3]},
    "threads": {"core": [], "gait": []},
    "sensitivity": {"springs": 1e3, "calibration": False},
    "finite": {"frames": 11, "repeats": 2},
    "run": {"repeats": 1, "frames": 11},
    "sweep": {"cases": 6, "workers": 2},
    "bandwidth": {"problem": "box", "springs": 1e5},
    "nlpqp": {"problems": ["sphere"], "sizes": [1e3]},
}

CORE_COLUMNS = [
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
    "peak_rss_mb",
    "success",
    "certificate",
    "status",
    "load_1m",
]
GAIT_COLUMNS = [
    "method",
    "n_springs",
    "frames",
    "wall_s",
    "wall_first_s",
    "repeats",
    "solve_s",
    "first_frame_s",
    "later_frame_mean_s",
    "iterations",
    "overhead_ratio",
    "peak_rss_mb",
    "success",
    "blas_threads",
    "load_1m",
    "status",
]
TARGET_COLUMNS = ["what", "target", "measured", "met", "detail"]


# --- targets -------------------------------------------------------------------------------


def _find(rows, **match):
    for r in rows or []:
        if all(r.get(k) == v for k, v in match.items()):
            return r
    return None


def _near(rows, n, **match):
    """The row matching ``match`` whose n_springs is within 10 % of ``n``."""
    for r in rows or []:
        if all(r.get(k) == v for k, v in match.items()) and abs(r.get("n_springs", 0) - n) <= 0.1 * n:
            return r
    return None


def _ratio_one_thread(threads, rq, problem) -> str:
    t = _near(threads, 1e5, problem=problem, method="newton")
    if not t or "total_s" not in t:
        return ""
    return f"; with Newton's BLAS at 1 thread: {rq['total_s'] / t['total_s']:.0f}x"


def _gait_one_thread(rows) -> str:
    t = _find(rows, method="newton")
    if not t or "wall_s" not in t:
        return ""
    return f"; BLAS at 1 thread: {t['wall_s']:.3g} s (first {t['wall_first_s']:.3g} s)"


def targets(results) -> list[dict]:
    core, cubic = results.get("core"), results.get("cubic")
    out = []
    # 1. Newton at 1e6, 6 free dofs.
    threads, threads_gait = results.get("threads"), results.get("threads_gait")

    def one_thread(n, problem="box"):
        t = _near(threads, n, problem=problem, method="newton")
        return (
            f"; BLAS at 1 thread: solve {t['solve_s']:.3g} s, whole dea.solve {t['total_s']:.3g} s"
            if t and "solve_s" in t
            else ""
        )

    r = _near(core, 1e6, problem="box", method="newton")
    if r and "solve_s" in r:
        out.append(
            target(
                "Newton, 1e6 springs, 6 free dofs (box): solve",
                "<= 0.5 s",
                r["solve_s"],
                lambda v: v <= 0.5,
                f"first call {r['solve_first_s']:.3g} s; whole dea.solve "
                f"{r['total_s']:.3g} s (first {r['total_first_s']:.3g} s); {r['iterations']} iterations"
                + one_thread(1e6),
            )
        )
        out.append(
            target(
                "Newton, 1e6 springs, 6 free dofs (box): peak RSS",
                "<= 1.5 GB",
                r["peak_rss_mb"] / 1024,
                lambda v: v <= 1.5,
                f"RSS before building {r['base_rss_mb']:.0f} MB",
                fmt=lambda v: f"{v:.2f} GB",
            )
        )
    else:
        out.append(
            target(
                "Newton, 1e6 springs, 6 free dofs (box)", "<= 0.5 s, <= 1.5 GB", None, None, (r or {}).get("status", "")
            )
        )
    # 2. Newton vs qp at 1e5.
    for problem in ("plate", "sphere", "box"):
        rn, rq = _near(core, 1e5, problem=problem, method="newton"), _near(core, 1e5, problem=problem, method="qp")
        if rn and rq and "total_s" in rn and "total_s" in rq:
            out.append(
                target(
                    f"Newton vs qp, 1e5 springs ({problem}): qp time / Newton time",
                    ">= 50x",
                    rq["total_s"] / rn["total_s"],
                    lambda v: v >= 50,
                    f"whole dea.solve: qp {rq['total_s']:.3g} s, Newton {rn['total_s']:.3g} s; "
                    f"solve only: {rq['solve_s'] / rn['solve_s']:.0f}x" + _ratio_one_thread(threads, rq, problem),
                    fmt=lambda v: f"{v:.1f}x",
                )
            )
        elif core is not None:
            out.append(target(f"Newton vs qp, 1e5 springs ({problem})", ">= 50x", None, None))
    # 3. qp against a direct Clarabel call (and the other speed rows): speed_sections.py.
    # 4-5. NLP at 1e5 with the cubic law.
    for method, label, limit in (("nlp-c", "nlp constrained", 10.0), ("nlp-r", "nlp reduced", 1.0)):
        for problem in ("sphere", "box"):
            r = _near(cubic, 1e5, problem=problem, method=method)
            if r is None and cubic is None:
                continue
            ok = r is not None and "total_s" in r
            out.append(
                target(
                    f"{label}, 1e5 springs, cubic law ({problem})",
                    f"<= {limit:g} s",
                    r["total_s"] if ok else None,
                    lambda v, lim=limit: v <= lim,
                    (
                        f"build {r['build_s']:.3g} s, IPOPT {r['solve_s']:.3g} s, {r['iterations']} "
                        f"iterations, {r['status']}"
                    )
                    if ok
                    else (r or {}).get("status", ""),
                )
            )
    # 6. Springs from meshes.
    mesh = results.get("mesh")
    for r in mesh or []:
        if r.get("target_faces") == 100000:
            ok = "cold_s" in r
            # The target is with Embree; the grid caster (the fallback without
            # embreex) is reported for information.
            embree = r["engine"] == "embree"
            out.append(
                target(
                    f"springs from two 1e5-face meshes ({r['pair']}, {r['engine']})",
                    "<= 2 s" if embree else "(fallback: reported)",
                    r["cold_s"] if ok else None,
                    (lambda v: v <= 2.0) if embree else (lambda v: True),
                    (
                        f"{r['faces1']} + {r['faces2']} faces -> {r['n_springs']} springs; first "
                        f"{r['cold_first_s']:.3g} s; warm (cached meshes) {r['warm_s']:.3g} s"
                    )
                    if ok
                    else r.get("status", ""),
                )
            )
    if mesh is not None and not any(r.get("target_faces") == 100000 for r in mesh):
        out.append(target("springs from two 1e5-face meshes", "<= 2 s", None, None, "sizes below 1e5 (quick)"))
    # 7. Gait.
    gait = results.get("gait")
    if gait is not None:
        r = _find(gait, method="newton")
        full = r is not None and r.get("frames") == 101 and abs(r.get("n_springs", 0) - 2e4) <= 2e3
        ok = r is not None and "wall_s" in r and full
        out.append(
            target(
                "101-frame gait, 2e4 springs, Newton warm-started (whole path)",
                "<= 2 s",
                r["wall_s"] if ok else None,
                lambda v: v <= 2.0,
                (
                    f"first run {r['wall_first_s']:.3g} s; Newton's own solve time {r['solve_s']:.3g} s; "
                    f"{r['iterations']} iterations" + _gait_one_thread(threads_gait)
                )
                if ok
                else "not the full gait (quick)",
            )
        )
    # 8. Growth.
    for method in ("newton", "qp"):
        for problem in ("plate", "sphere", "box"):
            if core is None:
                continue
            pts = sorted(
                (r["n_springs"], r["solve_s"], r["total_s"])
                for r in core
                if r.get("problem") == problem
                and r.get("method") == method
                and "solve_s" in r
                and 0.9e4 <= r["n_springs"] <= 1.1e6
            )
            if len(pts) < 2:
                out.append(
                    target(
                        f"growth: {method} ({problem}), log-log slope of time vs N",
                        "0.9 - 1.2",
                        None,
                        None,
                        "fewer than two sizes in [1e4, 1e6]",
                    )
                )
                continue
            slope = loglog_slope([p[0] for p in pts], [p[1] for p in pts])
            total = loglog_slope([p[0] for p in pts], [p[2] for p in pts])
            out.append(
                target(
                    f"growth: {method} ({problem}), log-log slope of solve time vs N",
                    "0.9 - 1.2",
                    slope,
                    lambda v: 0.9 <= v <= 1.2,
                    f"N = {', '.join(f'{p[0]:.0e}' for p in pts)}: solve "
                    + ", ".join(f"{p[1]:.3g}" for p in pts)
                    + f" s; whole dea.solve slope {total:.2f}",
                    fmt=lambda v: f"{v:.2f}",
                )
            )
    # 9. Sensitivities and calibration.
    sens = results.get("sensitivity")
    if sens is not None:
        r = _near(sens, 1e5, case="box, Ateshian")
        out.append(
            target(
                "sensitivities of all outputs to 10 parameters, 1e5 springs (box): time / Newton solve",
                "< 3",
                r["ratio"] if r and "ratio" in r else None,
                lambda v: v < 3,
                (
                    f"sensitivities {r['sensitivities_s']:.3g} s; whole dea.solve {r['newton_s']:.3g} s "
                    f"(Newton's own {r['newton_formulation_s']:.3g} s)"
                )
                if r and "ratio" in r
                else "sizes below 1e5 (quick)",
                fmt=lambda v: f"{v:.2f}x",
            )
        )
        r = _find(sens, case="knee calibration")
        ok = r is not None and "calibration_s" in r
        out.append(
            target(
                "calibration of H and beta on the real knee (film, start 2x off)",
                "< 2 s",
                r["calibration_s"] if ok else None,
                lambda v: v < 2.0,
                (f"{r['solves']} solves; H {r['H']:.4g} MPa (true 5), beta {r['beta']:.4g} (true 0.6)")
                if ok
                else (r or {}).get("status", "not run (quick)"),
            )
        )
    # 10. Finite kinematics on the real knee.
    finite = results.get("finite")
    if finite is not None:

        def finite_ratio(case, what, detail):
            """The TARGETS row of a knee case's finite / small ratio (``detail(r)``: what it adds)."""
            r = _find(finite, case=case)
            ok = r is not None and "ratio" in r
            said = (
                f"finite {r['finite_s']:.3g} s ({r['updates']} spring updates, {r['rotation_deg']:.2f} deg), "
                f"small {r['small_s']:.3g} s; {detail(r)}"
                if ok
                else (r or {}).get("status", "not run")
            )
            return target(
                what, "<= 5x", r["ratio"] if ok else None, lambda v: v <= 5.0, said, fmt=lambda v: f"{v:.1f}x"
            )

        out.append(
            finite_ratio(
                "knee 1000 N, uz rx ry",
                "knee, 1000 N, uz rx ry free: finite / small kinematics, whole dea.solve (re-casts included)",
                lambda r: (
                    f"small + its validation re-cast {r['small_recast_s']:.3g} s "
                    f"({r['finite_s'] / r['small_recast_s']:.2f}x)"
                ),
            )
        )
        out.append(
            finite_ratio(
                "knee flexed 15 deg, 1000 N + 2000 N mm, H 40",
                "knee flexed 15 deg about its condyles' axis, 1000 N + a flexion moment of 2000 N mm, H 40, "
                "uz rx ry free: finite / small kinematics",
                lambda r: f"pairs' median {r['pair_ratio_median']:.1f}x; valid: {r['valid']}",
            )
        )
        r = next((row for row in finite if str(row.get("case", "")).startswith("knee gait")), None)
        ok = r is not None and "wall_ratio" in r
        out.append(
            target(
                "knee gait, finite kinematics: wall time of solve_path / the frames' solving time",
                "<= 2x",
                r["wall_ratio"] if ok else None,
                lambda v: v <= 2.0,
                (
                    f"{r['frames']} frames, {r['wall_s']:.3g} s wall, {r['solve_sum_s']:.3g} s solving; "
                    f"frames inside the model {r['valid']}"
                )
                if ok
                else (r or {}).get("status", "not run"),
                fmt=lambda v: f"{v:.2f}x",
            )
        )
        ok = r is not None and "wall_s" in r and r.get("frames") == 101
        out.append(
            target(
                "101-frame knee gait, finite kinematics (flexion prescribed, uz ry found)",
                "< 10 s",
                r["wall_s"] if ok else None,
                lambda v: v < 10.0,
                (
                    f"{r['per_frame_s'] * 1e3:.0f} ms a frame; the small kinematics' path without poses "
                    f"{r['small_path_s']:.3g} s"
                )
                if ok
                else (r or {}).get("status", "not run (quick)"),
            )
        )
    # The same growth with Newton's BLAS at one thread (information: no target of its own).
    pts = sorted(
        (r["n_springs"], r["solve_s"])
        for r in threads or []
        if r.get("method") == "newton"
        and r.get("problem") == "box"
        and "solve_s" in r
        and 0.9e4 <= r["n_springs"] <= 1.1e6
    )
    if len(pts) >= 2:
        slope = loglog_slope([p[0] for p in pts], [p[1] for p in pts])
        out.append(
            target(
                "growth: newton (box), BLAS at 1 thread (information)",
                "0.9 - 1.2",
                slope,
                lambda v: 0.9 <= v <= 1.2,
                f"N = {', '.join(f'{p[0]:.0e}' for p in pts)}: solve " + ", ".join(f"{p[1]:.3g}" for p in pts) + " s",
                fmt=lambda v: f"{v:.2f}",
            )
        )
    out += speed_sections.targets_issue15(results)
    return out


def markdown(rows, preamble: str = "") -> str:
    """The TARGETS table as Markdown (for the documentation's Performance page), under the run's header lines."""
    lines = [line.lstrip("# ") for line in preamble.splitlines()[1:]]
    text = "".join(f"{line}  \n" for line in lines) + "\n" if lines else ""
    text += "| what | target | measured | met |\n|---|---|---|---|\n"
    text += "".join(f"| {r['what']} | {r['target']} | {r['measured']} | {r['met']} |\n" for r in rows)
    return text


# --- main ----------------------------------------------------------------------------------


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="small sizes only, in this process (seconds)")
    parser.add_argument(
        "--only", nargs="+", choices=SECTIONS, metavar="NAME", help=f"run only these sections: {', '.join(SECTIONS)}"
    )
    parser.add_argument("--out", type=Path, default=HERE / "results", help="folder for the CSVs and run.txt")
    parser.add_argument("--full", action="store_true", help="lift the size caps (qp and nlp-c at 1e6, nlp-c gait)")
    parser.add_argument("--timeout", type=float, default=900.0, help="seconds per case (default 900)")
    parser.add_argument(
        "--blas-threads",
        type=int,
        default=None,
        help="cap the BLAS thread pools in every case (default: the machine's default)",
    )
    args = parser.parse_args(argv)
    cfg = QUICK if args.quick else FULL
    sections = [s for s in SECTIONS if s in (args.only or SECTIONS)]
    if args.quick and not args.only:
        sections = [s for s in sections if s != "threads"]
    say = Report()
    preamble = header("dea-opt speed benchmark" + (" (--quick: small sizes, in-process)" if args.quick else ""))
    for line in preamble.rstrip("\n").splitlines():
        say(line)
    say(
        f"# sections: {', '.join(sections)}; every heavy case in a fresh subprocess: {not args.quick}; "
        f"BLAS threads: {args.blas_threads or 'default'}"
    )
    notes, results = [], {}
    out = args.out

    def save(name, rows, columns):
        write_csv(out / f"{name}.csv", rows, columns, preamble)

    if "core" in sections:
        say("\n## core: build and solve per method and size (linear law)")
        rows = section_core(cfg, args, say, notes)
        results["core"] = rows
        say.table(rows, CORE_COLUMNS)
        save("core", rows, bench_core.COLUMNS)
    if "cubic" in sections:
        say("\n## cubic: the cubic law (CubicLaw(H, beta=0.3))")
        rows = section_core(cfg, args, say, notes, law="cubic", name="cubic")
        results["cubic"] = rows
        say.table(rows, CORE_COLUMNS)
        save("cubic", rows, bench_core.COLUMNS)
    if "qp" in sections:
        say("\n## qp: total time against Clarabel's own solve time (first solve, then re-solves with new loads)")
        rows = section_qp(cfg, args, say)
        results["qp"] = rows
        say.table(rows, bench_qp.COLUMNS)
        save("qp_overhead", rows, bench_qp.COLUMNS)
    if "mesh" in sections:
        say("\n## mesh: springs from two meshes")
        rows = section_mesh(cfg, args, say)
        results["mesh"] = rows
        say.table(rows, bench_mesh.COLUMNS)
        save("mesh", rows, bench_mesh.COLUMNS)
    if "gait" in sections:
        say(
            f"\n## gait: {cfg['gait']['frames'] or 101}-frame hip gait at {cfg['gait']['springs']:.0e} springs, "
            f"warm-started"
        )
        rows = section_gait(cfg, args, say, notes)
        results["gait"] = rows
        say.table(rows, GAIT_COLUMNS)
        save("gait", rows, GAIT_COLUMNS)
    if "study" in sections:
        say("\n## study: the comparison study's QP solvers (default accuracy)")
        rows = section_study(cfg, args, say)
        results["study"] = rows
        say.table(rows, bench_study.COLUMNS)
        save("study", rows, bench_study.COLUMNS)
    if "threads" in sections:
        say("\n## threads: BLAS pools capped at 1 thread (compare with the default rows above)")
        rows, gait = section_threads(cfg, args, say, notes)
        results["threads"], results["threads_gait"] = rows, gait
        say.table(rows, CORE_COLUMNS + ["blas_threads"])
        say.table(gait, GAIT_COLUMNS)
        save("threads", rows + gait, list(dict.fromkeys(CORE_COLUMNS + ["blas_threads"] + GAIT_COLUMNS)))

    if "sensitivity" in sections:
        say("\n## sensitivity: derivatives of every output to 10 parameters, and a calibration on the knee")
        import bench_sensitivity

        rows = section_sensitivity(cfg, args, say)
        results["sensitivity"] = rows
        say.table(rows, bench_sensitivity.COLUMNS)
        save("sensitivity", rows, bench_sensitivity.COLUMNS)

    if "finite" in sections:
        say(
            f"\n## finite: the real knee with finite kinematics (one solve against the small kinematics, and a "
            f"{cfg['finite']['frames']}-frame gait)"
        )
        rows = bench_finite.run(
            cfg["finite"]["frames"], args.timeout, isolate=not args.quick, repeats=cfg["finite"]["repeats"]
        )
        results["finite"] = rows
        say.table(rows, bench_finite.COLUMNS)
        save("finite", rows, bench_finite.COLUMNS)

    if "run" in sections:
        say(
            f"\n## run: dea-opt run of the real knee, {cfg['run']['frames']} frames, every default output, against "
            f"the same work in-process"
        )
        rows = speed_sections.section_run(cfg, args, say)
        results["run"] = rows
        say.table(rows, bench_run.COLUMNS)
        save("run", rows, bench_run.COLUMNS)
    if "sweep" in sections:
        say(
            f"\n## sweep: {cfg['sweep']['cases']} knee cases on {cfg['sweep']['workers']} local Dask workers, "
            f"against one case's in-process solve"
        )
        rows = speed_sections.section_sweep(cfg, args, say)
        results["sweep"] = rows
        say.table(rows, bench_sweep.COLUMNS)
        save("sweep", rows, bench_sweep.COLUMNS)
    if "bandwidth" in sections:
        say("\n## bandwidth: Newton's kernels against the machine's copy bandwidth")
        rows = speed_sections.section_bandwidth(cfg, args, say)
        results["bandwidth"] = rows
        say.table(rows, bench_bandwidth.COLUMNS)
        save("bandwidth", rows, bench_bandwidth.COLUMNS)

    if "nlpqp" in sections:
        import bench_nlp

        say("\n## nlpqp: nlp under the cubic law against qp under the linear law on the same springs")
        rows = speed_sections.section_nlpqp(cfg, args, say)
        results["nlpqp"] = rows
        say.table(rows, bench_nlp.COLUMNS)
        save("nlp_vs_qp", rows, bench_nlp.COLUMNS)

    rows = targets(results)
    say("\n## TARGETS" + (" (--quick: sizes below the targets' are 'not run')" if args.quick else ""))
    say.table(rows, TARGET_COLUMNS)
    missed = [r for r in rows if r["met"] == "NO"]
    say(
        f"\n{sum(r['met'] == 'yes' for r in rows)} met, {len(missed)} missed, "
        f"{sum(r['met'] == '-' for r in rows)} not run"
    )
    for note in dict.fromkeys(notes):
        say(f"note: {note}")
    say(
        f"# load average at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}; "
        f"wall time {time.perf_counter() - say.start:.0f} s"
    )
    save("targets", rows, TARGET_COLUMNS)
    out.mkdir(parents=True, exist_ok=True)
    (out / "targets.md").write_text(markdown(rows, preamble))
    (out / "run.txt").write_text(say.text.getvalue())
    say(f"written {out}/ (CSVs and run.txt)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
