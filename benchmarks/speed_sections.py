"""The sections of ``run.py`` for speed where users wait, and their TARGETS rows.

* ``qp``: ``method="qp"`` against a direct Clarabel call on the minimal QP (``bench_qp.py``);
* ``run``: ``dea-opt run`` of the real knee, 51 frames, every default output, against the same
  work in-process (``bench_run.py``);
* ``sweep``: 200 knee cases on 2 local Dask workers against one case's in-process solve
  (``bench_sweep.py``);
* ``bandwidth``: Newton at 1e6 springs, the bytes its kernels read per second against the
  machine's copy bandwidth (``bench_bandwidth.py``);
* ``nlpqp``: the NLP under the cubic law against the QP under the linear law on the same springs
  (``bench_nlp.py``).
"""

from __future__ import annotations

import math

__all__ = ["section_bandwidth", "section_nlpqp", "section_run", "section_sweep", "target", "targets_issue15"]


def fmt_s(value) -> str:
    return f"{value:.3g} s" if isinstance(value, (int, float)) and value == value else "not run"


def target(what, goal, value, ok, detail="", fmt=fmt_s) -> dict:
    """A TARGETS row: ``met`` is ``yes`` / ``NO`` by ``ok(value)``, ``-`` when not measured."""
    if value is None or (isinstance(value, float) and value != value):
        return {"what": what, "target": goal, "measured": "not run", "met": "-", "detail": detail}
    return {"what": what, "target": goal, "measured": fmt(value), "met": "yes" if ok(value) else "NO", "detail": detail}


def _decade(n) -> int:
    return int(10 ** round(math.log10(max(n, 1))))


def _quick_or_isolated(module, function, kwargs, args):
    """``module.function(**kwargs)`` here with ``--quick``, else in a fresh process."""
    from common import run_isolated

    if args.quick:
        import importlib

        try:
            return getattr(importlib.import_module(module), function)(**kwargs)
        except Exception as exc:  # noqa: BLE001 - a benchmark row records the failure
            return {"status": f"error: {type(exc).__name__}: {exc}"[:300], "success": False}
    return run_isolated(module, function, kwargs, args.timeout)


def section_run(cfg, args, say) -> list[dict]:
    """``dea-opt run`` of the knee against the same work in-process (bench_run.run_case runs its
    own subprocesses, so it runs here either way)."""
    import bench_run

    row = bench_run.run_case(cfg["run"]["repeats"], cfg["run"]["frames"], args.timeout)
    say.progress("run knee", row, "cli_s")
    return [row]


def section_sweep(cfg, args, say) -> list[dict]:
    import bench_sweep

    row = bench_sweep.run_case(cfg["sweep"]["cases"], cfg["sweep"]["workers"], max(args.timeout, 1800.0))
    say.progress(f"sweep {cfg['sweep']['cases']} knee cases", row, "sweep_s")
    return [row]


def section_bandwidth(cfg, args, say) -> list[dict]:
    row = _quick_or_isolated(
        "bench_bandwidth",
        "measure",
        {"problem": cfg["bandwidth"]["problem"], "n": int(cfg["bandwidth"]["springs"])},
        args,
    )
    row = {"problem": cfg["bandwidth"]["problem"], **row}
    say.progress(f"bandwidth {row['problem']} N={cfg['bandwidth']['springs']:.0e}", row, "fraction")
    return [row]


def section_nlpqp(cfg, args, say) -> list[dict]:
    rows = []
    for problem in cfg["nlpqp"]["problems"]:
        for n in cfg["nlpqp"]["sizes"]:
            row = _quick_or_isolated("bench_nlp", "compare", {"problem": problem, "n": int(n)}, args)
            row = {"problem": problem, "n_springs": int(n), **row}
            say.progress(f"nlp/qp {problem} N={n:.0e}", row, "nlp_s")
            rows.append(row)
    return rows


def _qp_rows(qp) -> list[dict]:
    import numpy as np

    rows = [dict(r, n_springs=_decade(r["n_springs"])) for r in qp if "n_springs" in r and "ratio" in r]
    out = []
    for first, label in ((True, "first solve"), (False, "re-solve with a new load")):
        sizes = sorted({r["n_springs"] for r in rows if r["n_springs"] >= 9e3}) or [None]
        for n in sizes:
            what = (
                f"qp / a direct Clarabel call on the minimal QP, {label}, N = {n:.0e}"
                if n
                else f"qp / a direct Clarabel call, {label}, N >= 1e4"
            )
            per = {}
            for r in rows:
                if r["n_springs"] == n and (r["call"] == "first") == first:
                    per.setdefault(r["problem"], []).append(r["ratio"])
            if not per:
                out.append(target(what, "<= 1.1x", None, None, "sizes below 1e4 (quick)" if n is None else ""))
                continue
            worst = {p: float(np.median(v)) for p, v in per.items()}
            detail = ", ".join(f"{p} {v:.3f}" for p, v in worst.items())
            if first:
                whole = [r for r in rows if r["n_springs"] == n and r["call"] == "first" and "dea_solve_ratio" in r]
                detail += "; whole dea.solve (system, cone test, certificate) / direct: " + ", ".join(
                    f"{r['problem']} {r['dea_solve_ratio']:.2f}" for r in whole
                )
                detail += "; Clarabel saw " + ", ".join(f"{r['problem']} {r['rows']} x {r['variables']}" for r in whole)
            else:
                detail = "median of the re-solves: " + detail
            out.append(
                target(what, "<= 1.1x", max(worst.values()), lambda v: v <= 1.1, detail, fmt=lambda v: f"{v:.3f}x")
            )
    return out


def targets_issue15(results) -> list[dict]:
    """The TARGETS rows of the sections of this module (those that ran)."""
    out = []
    if results.get("qp") is not None:
        out += _qp_rows(results["qp"])
    for r in results.get("nlpqp") or []:
        ok = "ratio" in r and _decade(r.get("n_springs", 0)) == 100_000
        out.append(
            target(
                f"nlp (cubic law) / qp (linear) on the same springs, 1e5 springs ({r['problem']})",
                "<= 4x",
                r["ratio"] if ok else None,
                lambda v: v <= 4.0,
                f"nlp {r['nlp_s']:.3g} s ({r['nlp_iterations']} IPOPT iterations from {r['nlp_start']}), "
                f"qp {r['qp_s']:.3g} s"
                if ok
                else r.get("status", "not 1e5 springs (quick)"),
                fmt=lambda v: f"{v:.2f}x",
            )
        )
    for r in results.get("run") or []:
        ok = "cli_s" in r and r.get("frames") == 51
        if "cli_s" in r and not ok:
            r = {**r, "status": f"{r.get('frames')} frames, not 51 (quick)"}
        out.append(
            target(
                "dea-opt run, real knee, 51 frames, every default output: wall time",
                "<= 1.5 x in-process + 1 s",
                r["cli_s"] if ok else None,
                lambda v, r=r: v <= r["limit_s"],
                (
                    f"in-process {r['inproc_s']:.3g} s (import {r['import_s']:.2f}, meshes and springs "
                    f"{r['build_s']:.2f}, solve_path {r['path_s']:.2f}), limit {r['limit_s']:.3g} s, "
                    f"(wall - 1 s) / in-process = {r['ratio']:.2f}; outputs alone: png {r['outputs_png_s']:.2f} "
                    f"s, vtk {r['outputs_vtk_s']:.2f} s, csv {r['outputs_csv_s']:.3f} s, json "
                    f"{r['outputs_json_s']:.3f} s; imports: {r['imports']}; not imported: {r['not_imported']}"
                )
                if ok
                else r.get("status", ""),
            )
        )
    for r in results.get("sweep") or []:
        ok = "sweep_s" in r and r.get("cases", 0) >= 200
        if "sweep_s" in r and not ok:
            r = {**r, "status": f"{r.get('cases')} cases, not 200 (quick)"}
        what = (
            f"sweep of {r.get('cases')} knee cases (51 frames, csv/json) on {r.get('workers')} local workers: wall time"
        )
        out.append(
            target(
                what,
                "<= 1.5 x cases x case solve / workers",
                r["sweep_s"] if ok else None,
                lambda v, r=r: v <= r["limit_s"],
                (
                    f"one case's in-process solve {r['case_solve_s']:.3g} s (solve_path {r['case_path_s']:.3g} "
                    f"s), limit {r['limit_s']:.3g} s, ratio {r['ratio']:.2f}; {r['workers']} cases side by side "
                    f"here took {r['parallel_case_s']:.3g} s each (against that: {r['ratio_machine']:.2f}); "
                    f"Dask's overhead per case {r['dask_overhead_per_case_s']:.3f} s; a case's own wall time "
                    f"{r['case_wall_mean_s']:.3g} s; {r['cast_entries']} spring cast(s) for {r['cases']} cases"
                )
                if ok
                else r.get("status", ""),
            )
        )
    for r in results.get("bandwidth") or []:
        ok = "fraction" in r and r.get("n_springs", 0) >= 9e5
        if "fraction" in r and not ok:
            r = {**r, "status": "below 1e6 springs (quick)"}
        out.append(
            target(
                f"Newton at {r.get('n_springs', 0):.0e} springs ({r.get('problem')}): bytes its kernels read "
                f"per second / copy bandwidth",
                ">= 50 %",
                r["fraction"] if ok else None,
                lambda v: v >= 0.5,
                (
                    f"{r['newton_GBs']:.3g} GB/s read ({r['newton_bytes'] / 1e9:.3g} GB in {r['newton_s']:.3g} s, "
                    f"{r['iterations']} iterations, {r['slopes']} line evaluations); copy reads {r['copy_GBs']:.3g}"
                    f" GB/s; in STREAM's units (read + written) {r['moved_GBs']:.3g} of {r['stream_copy_GBs']:.3g} "
                    f"GB/s = {r['fraction_moved']:.0%}; a pure read (sum) {r['read_GBs']:.3g} GB/s"
                )
                if ok
                else r.get("status", ""),
                fmt=lambda v: f"{v:.0%}",
            )
        )
    return out
