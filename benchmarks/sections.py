"""The sections of ``run.py`` that measure the core targets: each runs its cases (in fresh
processes unless ``--quick``) and returns their rows."""

from __future__ import annotations

import bench_core
import bench_mesh
import bench_qp
import bench_study

__all__ = [
    "section_core",
    "section_gait",
    "section_mesh",
    "section_qp",
    "section_sensitivity",
    "section_study",
    "section_threads",
]


def section_core(cfg, args, say, notes, law="linear", name="core"):
    rows = []
    for problem in cfg[name]["problems"]:
        for n in cfg[name]["sizes"]:
            for method in cfg[name]["methods"]:
                cap = cfg["caps"].get(method)
                if (
                    cap is not None
                    and n > cap
                    and not args.full
                    and (problem, method, n) not in cfg.get("uncapped", [])
                ):
                    notes.append(
                        f"{name}: {method} at N={n:.0e} skipped by default for {problem} (size cap "
                        f"{cap:.0e}); run with --full to include it"
                    )
                    continue
                row = bench_core.run_case(
                    problem,
                    method,
                    int(n),
                    {},
                    args.timeout,
                    law=law,
                    isolate=not args.quick,
                    blas_threads=args.blas_threads,
                )
                rows.append(row)
                say.progress(f"{name} {problem} {method} N={int(n)}", row, "total_s")
    return rows


def section_qp(cfg, args, say):
    rows = []
    for problem in cfg["qp"]["problems"]:
        for n in cfg["qp"]["sizes"]:
            out = bench_qp.run(problem, n, args.timeout, isolate=not args.quick, blas_threads=args.blas_threads)
            rows += out
            say.progress(f"qp overhead {problem} N={int(n)}", out[0], "ratio")
    return rows


def section_mesh(cfg, args, say):
    rows = []
    for faces in cfg["mesh"]["faces"]:
        for pair in cfg["mesh"]["pairs"]:
            for engine in cfg["mesh"]["engines"]:
                row = bench_mesh.run(
                    pair, faces, engine, args.timeout, isolate=not args.quick, blas_threads=args.blas_threads
                )
                rows.append(row)
                say.progress(f"mesh {pair} {faces:.0e} faces {engine}", row, "cold_s")
    return rows


def _gait_case(label, springs, frames, args, blas_threads):
    from common import run_isolated

    kwargs = {"label": label, "n_springs": int(springs), "frames": frames, "blas_threads": blas_threads}
    if args.quick:
        import bench_path

        try:
            row = bench_path.one(**kwargs)
        except Exception as exc:  # noqa: BLE001
            row = {"status": f"error: {type(exc).__name__}: {exc}"[:300], "success": False}
    else:
        row = run_isolated("bench_path", "one", kwargs, args.timeout)
    return {"method": label, "n_springs": int(springs), **row}


def section_gait(cfg, args, say, notes):
    g = cfg["gait"]
    methods = list(g["methods"]) + (list(g["full_methods"]) if args.full else [])
    for m in g["full_methods"]:
        if not args.full:
            notes.append(f"gait: {m} skipped by default (about 2 s a frame at 2e4 springs); run with --full")
    rows = []
    for label in methods:
        row = _gait_case(label, g["springs"], g["frames"], args, args.blas_threads)
        rows.append(row)
        say.progress(f"gait {label} {int(g['springs'])} springs", row, "wall_s")
    return rows


def section_study(cfg, args, say):
    rows = []
    for n in cfg["study"]["sizes"]:
        out = bench_study.run(
            cfg["study"]["problem"], n, args.timeout, isolate=not args.quick, blas_threads=args.blas_threads
        )
        rows += out
        say.progress(f"study {cfg['study']['problem']} N={int(n)}", out[0], "study_wall_s")
    return rows


def section_threads(cfg, args, say, notes):
    rows = []
    try:
        import threadpoolctl  # noqa: F401
    except ImportError:
        notes.append("threads: skipped, it needs threadpoolctl (pip install threadpoolctl)")
        return [], []
    for problem, method, n in cfg["threads"]["core"]:
        row = bench_core.run_case(problem, method, int(n), {}, args.timeout, isolate=not args.quick, blas_threads=1)
        rows.append(row)
        say.progress(f"threads=1 {problem} {method} N={int(n)}", row, "solve_s")
    gait = []
    for label in cfg["threads"]["gait"]:
        row = _gait_case(label, cfg["gait"]["springs"], cfg["gait"]["frames"], args, 1)
        gait.append(row)
        say.progress(f"threads=1 gait {label}", row, "wall_s")
    return rows, gait


def section_sensitivity(cfg, args, say):
    """Sensitivities to 10 parameters against Newton solves, and the knee's calibration
    (benchmarks/bench_sensitivity.py), each in a fresh process."""
    import bench_sensitivity
    from common import run_isolated

    cases = [("sensitivity_case", {"n_springs": cfg["sensitivity"]["springs"]})]
    if cfg["sensitivity"]["calibration"]:
        cases.append(("calibration_case", {}))
    rows = []
    for func, kwargs in cases:
        if args.quick:
            row = getattr(bench_sensitivity, func)(**kwargs)
        else:
            row = run_isolated("bench_sensitivity", func, kwargs, args.timeout)
        rows.append(row)
        say.progress(
            f"sensitivity {row.get('case', func)}",
            row,
            "sensitivities_s" if "sensitivities_s" in row else "calibration_s",
        )
    return rows
