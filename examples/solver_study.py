"""Which formulation when: every solver on the same hip, from a thousand to thirty thousand springs.
=================================================================================================

One problem, grown in resolution: a femoral head (R = 25 mm) in a socket covering 80 degrees
around its pole with 0.1 mm radial clearance and 3 mm of cartilage (the hip of
``dea-opt demo``), pushed by the gait-peak load of ``dea-opt demo``: 2400 N tilted 20 degrees
from the socket axis. The contact reaches the socket's rim, so the active set is a genuine
unknown. It is solved

* with the linear law ``LinearLaw(H = 10 MPa)`` by ``newton``, by ``qp`` with every QP solver
  cvxpy has here among CLARABEL, OSQP, SCS and PIQP, and by ``nlp`` in both forms
  (``form="constrained"``: one variable per spring; ``form="reduced"``: the free dofs only);
* with Ateshian's law, Eq. (2), ``AteshianLaw(H = 10 MPa, beta = 0.3)`` by ``newton`` and
  ``nlp`` (both forms); ``qp`` needs a linear law.

Every run is :func:`dea_opt.solve` with ``strict=False`` at the default accuracy: a row is a
**success** when the solver says so, dea_opt's certificate passes at 1e-6, and the pressures
and displacements agree with a Newton solution of the same problem to 1e-6 (relative to the
peak pressure and to the largest displacement), as in :func:`dea_opt.study.run_study`. That
function has no ``form`` option, so this script runs the same checks itself and summarises
with :func:`dea_opt.study.summarize`.

Run it with::

    python examples/solver_study.py --out figures/

(``--coarse`` for the few-second setting the tests use: 300 and 1000 springs, one run each;
``--sizes 1000 3000`` and ``--repeat 3`` to choose). Default: 1e3, 3e3, 1e4 and 3e4 springs;
each method runs once per size, and again (up to 20 times) while its runs stay under 0.5 s
in all, so the fast ones are timed over many runs; about a minute on two cores. It writes
``solver_study.csv`` (one row per run), ``solver_study_summary.csv`` (per law, method and
size: success rate, best and shifted-geometric-mean time), ``solver_study.png`` (wall time
against N, log-log, per method, and the disagreement with Newton) and ``solver_study.md``
into ``--out`` (default ``examples/output/solver_study/``), and prints the summary.

Times are wall-clock seconds of the whole :func:`dea_opt.solve` call (model building, the
load-support check the constrained methods run first, the solve and the certificate), the
best of the repeats; ``build_time_s`` and ``solve_time_s`` are what the formulation reports.
Every method is run once on a small problem first (not with ``--coarse``), so that imports and
first-call set-up do not land in the smallest size. With Eq. (2), IPOPT's trial steps in the
reduced form may crush a spring; CasADi then prints "NaN detected for output f" and IPOPT
shortens the step: harmless, the certificate judges the answer. Units: mm, N, MPa, s.
"""

from __future__ import annotations

import argparse
import io
import os
import time
import warnings
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only: the example must run without a display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

import dea_opt  # noqa: E402
from dea_opt.files import write_atomic  # noqa: E402
from dea_opt.geometry import socket_layer  # noqa: E402
from dea_opt.study import DEFAULT_SOLVERS, installed_qp_solvers, summarize  # noqa: E402

NAME = "solver_study"
DEFAULT_OUT = Path(__file__).resolve().parent / "output" / NAME

#: The socket of ``dea-opt demo`` (mm): only the resolution changes with N.
HIP = {"radius": 25.0, "thickness": 3.0, "coverage": 80.0, "gap": 0.1}
H = 10.0  # MPa, as in the demo: peak strain near 20 % at the gait peak
BETA = 0.3  # Ateshian's stiffening exponent, the middle of the paper's 0.05-0.6
PEAK_LOAD = 2400.0  # N, the gait-peak frame of ``dea-opt demo``
TILT_DEG = 20.0  # degrees from the socket axis, toward +x
#: Target spring counts: (default, coarse).
SIZES = ((1_000, 3_000, 10_000, 30_000), (300, 1_000))
#: Runs per method and size: at least 1, up to MAX_REPEAT while they take under BUDGET seconds.
MAX_REPEAT = (20, 1)
BUDGET = 0.5  # s
CHECK_TOL = 1e-6  # the certificate bound and the agreement with Newton, as the study's "default"
LAWS = ("linear", "ateshian")


# --- the problem ------------------------------------------------------------------------
def socket_grid(n_springs: int, coverage: float = HIP["coverage"]) -> tuple[int, int]:
    """``(n_rings, n_sectors)`` with about ``n_springs`` cells that are roughly square.

    A cell at mid-cap spans ``coverage / n_rings`` degrees of latitude and
    ``360 sin(coverage / 2) / n_sectors`` of longitude; equal spans give
    ``n_sectors / n_rings = 360 sin(coverage / 2) / coverage``.
    """
    ratio = 360.0 * np.sin(np.radians(coverage / 2.0)) / coverage
    n_rings = max(int(round(np.sqrt(n_springs / ratio))), 2)
    n_sectors = max(int(round(n_springs / n_rings)), 4)
    return n_rings, n_sectors


def peak_force(load: float = PEAK_LOAD, tilt_deg: float = TILT_DEG) -> np.ndarray:
    """The load on the head (N): ``load`` pushing into the socket, tilted toward +x."""
    t = np.radians(tilt_deg)
    return load * np.array([np.sin(t), 0.0, -np.cos(t)])


def make_law(name: str, H: float = H, beta: float = BETA) -> dea_opt.Law:
    """``"linear"`` -> ``LinearLaw(H)``; ``"ateshian"`` -> ``AteshianLaw(H, beta)`` (MPa)."""
    if name == "linear":
        return dea_opt.LinearLaw(H)
    if name == "ateshian":
        return dea_opt.AteshianLaw(H, beta)
    raise ValueError(f"law must be 'linear' or 'ateshian', got {name!r}")


def study_problem(n_springs: int, law: dea_opt.Law, force=None) -> dea_opt.ContactProblem:
    """The hip with about ``n_springs`` springs; the head (body 2) free to translate."""
    n_rings, n_sectors = socket_grid(n_springs)
    layer = socket_layer(n_rings=n_rings, n_sectors=n_sectors, **HIP)
    return dea_opt.ContactProblem(
        layer,
        law,
        force=tuple(peak_force() if force is None else force),
        reference=(0.0, 0.0, 0.0),
        free=("ux", "uy", "uz"),
    )


# --- the methods ------------------------------------------------------------------------
def qp_solvers() -> list[str]:
    """The QP solvers compared: :data:`dea_opt.study.DEFAULT_SOLVERS` that cvxpy has here."""
    installed = installed_qp_solvers()
    return [s for s in DEFAULT_SOLVERS if s in installed]


def method_cases(law: dea_opt.Law, solvers=None) -> list[dict]:
    """The runs for one law: ``{"label", "method", "solver", "options"}`` each.

    ``label`` names the curve (``newton``, ``qp-CLARABEL``, ``nlp-constrained``,
    ``nlp-reduced``); ``solver`` is the study's solver column (``-`` for Newton, the QP
    solver, ``IPOPT`` or ``IPOPT-reduced``).
    """
    cases = [{"label": "newton", "method": "newton", "solver": "-", "options": {}}]
    if law.is_linear:  # the QP is the linear law's energy; any other law needs nlp
        for solver in qp_solvers() if solvers is None else solvers:
            cases.append({"label": f"qp-{solver}", "method": "qp", "solver": solver, "options": {"solver": solver}})
    for form, solver in (("constrained", "IPOPT"), ("reduced", "IPOPT-reduced")):
        cases.append({"label": f"nlp-{form}", "method": "nlp", "solver": solver, "options": {"form": form}})
    return cases


def _difference(solution, reference) -> tuple[float, float]:
    """Largest pressure and displacement differences, relative to the peak and to max |u|."""
    if not np.isfinite(solution.u).all():
        return float("nan"), float("nan")
    dp = float(np.abs(solution.pressure - reference.pressure).max() / reference.peak_pressure)
    du = float(np.abs(solution.u - reference.u).max() / np.abs(reference.u).max())
    return dp, du


def run_case(problem: dea_opt.ContactProblem, case: dict, reference, repeat: int = 0) -> dict:
    """Solve ``problem`` once as ``case`` says; one row of the study table.

    The checks are those of :func:`dea_opt.study.run_study` at its ``default`` accuracy.
    """
    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dea_opt.ValidityWarning)  # the problem's business, not the solver's
        try:
            s = dea_opt.solve(problem, case["method"], certificate_tol=CHECK_TOL, strict=False, **case["options"])
        except dea_opt.DeaError as exc:  # a solver that breaks is a failed row, not a crash
            wall = time.perf_counter() - start
            return {
                "label": case["label"],
                "method": case["method"],
                "solver": case["solver"],
                "repeat": repeat,
                "success": False,
                "status": "error",
                "message": str(exc)[:200],
                "wall_time": wall,
                "total_time_s": wall,
            }
    wall = time.perf_counter() - start
    dp, du = _difference(s, reference)
    agrees = bool(max(dp, du) <= CHECK_TOL)
    solver_success = bool(s.info.get("solver_success", s.success))
    name, worst = s.certificate.worst()
    if not solver_success:
        message = f"solver reports {s.status}"
    elif not s.certificate.passed:
        message = f"inaccurate: {name} {worst:.1e} > {CHECK_TOL:g}"
    elif not agrees:
        message = f"differs from Newton by {max(dp, du):.1e}"
    else:
        message = "ok"
    return {
        "label": case["label"],
        "method": case["method"],
        "solver": case["solver"],
        "repeat": repeat,
        "success": bool(solver_success and s.certificate.passed and agrees),
        "solver_success": solver_success,
        "certified": s.certificate.passed,
        "agrees": agrees,
        "status": s.status,
        "message": message,
        "wall_time": wall,
        "build_time_s": s.build_time,
        "solve_time_s": s.solve_time,
        "total_time_s": s.build_time + s.solve_time,
        "iterations": s.iterations,
        "worst_residual": worst,
        "worst_name": name,
        "peak_pressure_MPa": s.peak_pressure,
        "contact_area_mm2": s.contact_area,
        "d_pressure": dp,
        "d_displacement": du,
    }


def warm_up(laws=LAWS, solvers=None) -> None:
    """Run every method once on a 200-spring problem: imports and first calls off the clock."""
    for name in laws:
        law = make_law(name)
        problem = study_problem(200, law)
        reference = dea_opt.solve(problem, "newton")
        for case in method_cases(law, solvers):
            run_case(problem, case, reference)


def run_study(
    sizes=SIZES[0],
    laws=LAWS,
    repeat: int = 1,
    solvers=None,
    *,
    max_repeat: int = MAX_REPEAT[0],
    budget: float = BUDGET,
    verbose: bool = False,
) -> pd.DataFrame:
    """Every law x size x method, at least ``repeat`` times; one row per run.

    A method is run again, up to ``max_repeat`` times in all, while its runs at this size
    have taken less than ``budget`` seconds, so fast methods are timed over several runs and
    slow ones once.

    Returns
    -------
    pandas.DataFrame
        ``law, n_target, n_springs, n_rings, n_sectors, label, method, solver, repeat,
        success, solver_success, certified, agrees, status, message, wall_time,
        build_time_s, solve_time_s, total_time_s``, ``iterations, worst_residual, worst_name,
        peak_pressure`` (MPa), ``contact_area`` (mm^2), ``d_pressure, d_displacement``
        (relative differences from the Newton reference), plus ``accuracy`` ("default") and
        ``check_tol`` for :func:`dea_opt.study.summarize`.
    """
    rows = []
    for name in laws:
        law = make_law(name)
        for n in sizes:
            problem = study_problem(n, law)
            n_rings, n_sectors = socket_grid(n)
            problem.system()  # the geometry is built once per problem and shared by every method
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", dea_opt.ValidityWarning)
                reference = dea_opt.solve(problem, "newton")
            for case in method_cases(law, solvers):
                spent, r = 0.0, 0
                # Fast solves are repeated until they fill the budget: a single run of a few
                # milliseconds says more about the machine's mood than about the method.
                while r < max(repeat, max_repeat) and (r < repeat or spent < budget):
                    row = run_case(problem, case, reference, r)
                    spent += row["wall_time"]
                    r += 1
                    rows.append(
                        {
                            "law": name,
                            "n_target": n,
                            "n_springs": len(problem.layer),
                            "n_rings": n_rings,
                            "n_sectors": n_sectors,
                            **row,
                        }
                    )
                if verbose:
                    print(
                        f"  {name:8s} N={len(problem.layer):6d} {case['label']:16s} {r} run(s), best "
                        f"{min(x['wall_time'] for x in rows[-r:]):8.4f} s  "
                        f"{'ok' if all(x['success'] for x in rows[-r:]) else rows[-1]['message']}"
                    )
    table = pd.DataFrame(rows)
    table["accuracy"] = "default"
    table["check_tol"] = CHECK_TOL
    return table


def summary_table(table: pd.DataFrame) -> pd.DataFrame:
    """Per law, size and method: runs, success rate, best and mean wall time, accuracy.

    ``best_time`` is the smallest wall time of the successful repeats (NaN if none);
    ``sgm_time`` the shifted geometric mean over every repeat with failures counted as the
    study's time limit (:func:`dea_opt.study.summarize`); ``relative`` is ``best_time``
    over Newton's at the same law and size.
    """
    rows = []
    for (law, n), group in table.groupby(["law", "n_springs"], sort=False):
        sgm = summarize(group).set_index(["method", "solver"])
        for label, runs in group.groupby("label", sort=False):
            ok = runs[runs["success"].astype(bool)]
            key = (runs["method"].iloc[0], runs["solver"].iloc[0])
            rows.append(
                {
                    "law": law,
                    "n_springs": n,
                    "label": label,
                    "method": key[0],
                    "solver": key[1],
                    "runs": len(runs),
                    "success_rate_percent": float(sgm.loc[key, "success_rate_percent"]),
                    "best_time": float(ok["wall_time"].min()) if len(ok) else float("nan"),
                    "sgm_time": float(sgm.loc[key, "shifted_gm_time_s"]),
                    "formulation_time": float(ok["total_time_s"].min()) if len(ok) else float("nan"),
                    "iterations": int(runs["iterations"].max()) if "iterations" in runs else -1,
                    "d_pressure": float(runs["d_pressure"].max()),
                    "worst_residual": float(runs["worst_residual"].max()),
                }
            )
    summary = pd.DataFrame(rows)
    newton = summary[summary["label"] == "newton"].set_index(["law", "n_springs"])["best_time"]
    summary["relative"] = [
        row.best_time / newton.loc[(row.law, row.n_springs)] for row in summary.itertuples(index=False)
    ]
    return summary


def fit_exponents(summary: pd.DataFrame) -> pd.DataFrame:
    """Per law and method, ``k`` in time ~ N^k between the two largest sizes.

    Only the largest sizes: at a thousand springs every method still pays mostly fixed
    costs (building a model, calling a solver), which would flatten a fit over all sizes.
    """
    rows = []
    for (law, label), g in summary.groupby(["law", "label"], sort=False):
        g = g[np.isfinite(g["best_time"])].sort_values("n_springs").tail(2)
        if len(g) == 2:
            n, t = g["n_springs"].to_numpy(dtype=float), g["best_time"].to_numpy(dtype=float)
            rows.append({"law": law, "label": label, "exponent": float(np.log(t[1] / t[0]) / np.log(n[1] / n[0]))})
    return pd.DataFrame(rows, columns=["law", "label", "exponent"])


# --- the picture ------------------------------------------------------------------------
_STYLE = {
    "newton": ("k", "o", "-"),
    "nlp-constrained": ("tab:red", "s", "-"),
    "nlp-reduced": ("tab:orange", "D", "-"),
    "qp-CLARABEL": ("tab:blue", "^", "--"),
    "qp-OSQP": ("tab:green", "v", "--"),
    "qp-SCS": ("tab:purple", "<", "--"),
    "qp-PIQP": ("tab:cyan", ">", "--"),
}
_LAW_TITLE = {"linear": f"linear law, H = {H:g} MPa", "ateshian": f"Eq. (2), H = {H:g} MPa, beta = {BETA:g}"}


def plot_study(summary: pd.DataFrame):
    """Top: best wall time against N (log-log) per method, one panel per law.
    Bottom: the largest pressure difference from Newton, relative to the peak."""
    laws = list(dict.fromkeys(summary["law"]))
    fig, axes = plt.subplots(
        2,
        len(laws),
        figsize=(5.2 * len(laws), 6.6),
        squeeze=False,
        gridspec_kw={"height_ratios": (2.2, 1)},
        sharex=True,
    )
    for j, law in enumerate(laws):
        ax, bx = axes[0, j], axes[1, j]
        rows = summary[summary["law"] == law]
        for label, g in rows.groupby("label", sort=False):
            colour, marker, ls = _STYLE.get(label, ("0.4", ".", ":"))
            ax.plot(g["n_springs"], g["best_time"], ls=ls, marker=marker, color=colour, label=label, ms=5)
            failed = g[g["success_rate_percent"] < 100]
            if len(failed):
                ax.plot(failed["n_springs"], failed["sgm_time"], "x", color=colour, ms=9)
            if label != "newton":  # Newton is the reference: its difference is zero by definition
                bx.plot(g["n_springs"], np.maximum(g["d_pressure"], 1e-16), ls=ls, marker=marker, color=colour, ms=4)
        n = np.array(sorted(set(rows["n_springs"])), dtype=float)
        ax.plot(
            n,
            rows[rows["label"] == "newton"]["best_time"].iloc[0] * n / n[0],
            ":",
            color="0.6",
            lw=1,
            label="~ N (guide)",
        )
        ax.set(xscale="log", yscale="log", ylabel="wall time per solve [s]", title=_LAW_TITLE.get(law, law))
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=7, loc="upper left")
        bx.axhline(CHECK_TOL, color="0.5", lw=0.8, ls="--")
        bx.set(xscale="log", yscale="log", xlabel="springs N", ylabel="max |p - p_newton| / peak", ylim=(1e-17, 1e-4))
        bx.grid(alpha=0.3, which="both")
    fig.suptitle(
        f"Hip at the gait peak ({PEAK_LOAD:g} N, {TILT_DEG:g} deg): best of the repeats, x = a failed run", fontsize=10
    )
    fig.tight_layout()
    return fig


def figure_bytes(fig, dpi: int = 100) -> bytes:
    """The figure as PNG bytes (closed afterwards)."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi)
    plt.close(fig)
    return buffer.getvalue()


def _write(path: Path, data) -> Path:
    """Write str or bytes atomically (:func:`dea_opt.files.write_atomic`)."""
    if isinstance(data, bytes):
        return write_atomic(path, lambda tmp: tmp.write_bytes(data))
    return write_atomic(path, lambda tmp: tmp.write_text(data, encoding="utf-8"))


def blas_threads() -> str:
    """How many threads the BLAS libraries use here (``threadpoolctl`` when installed).

    It matters: Newton's dense algebra is a few 3 x 3 solves, and on a small busy machine a
    multithreaded BLAS can spend far longer waking its threads than computing
    (``OPENBLAS_NUM_THREADS=1`` avoids that).
    """
    try:
        from threadpoolctl import threadpool_info
    except ImportError:
        return os.environ.get("OPENBLAS_NUM_THREADS", "default")
    counts = sorted({f"{i['internal_api']} {i['num_threads']}" for i in threadpool_info() if i["user_api"] == "blas"})
    return ", ".join(counts) or "unknown"


def summary_markdown(
    summary: pd.DataFrame, exponents: pd.DataFrame, *, coarse: bool, repeat: int, load_average: float | None = None
) -> str:
    """Best wall time per method and size as a Markdown table (numbers from ``summary``).

    ``repeat`` is the least number of runs per method and size; ``load_average`` the
    machine's 1-minute load average when the study started (timings from a busy machine are
    slower and noisier).
    """
    sizes = sorted(set(summary["n_springs"]))
    lines = [
        f"# Solver study: the hip at the gait peak ({PEAK_LOAD:g} N tilted {TILT_DEG:g} deg)",
        "",
        f"Computed by `examples/solver_study.py`{' --coarse' if coarse else ''}: best wall time of "
        f"at least {repeat} run(s) per solve, s; {os.cpu_count()} cores"
        + (f" (load average {load_average:.1f} at the start)" if load_average is not None else "")
        + f"; BLAS threads: {blas_threads()}"
        + f"; dea-opt {dea_opt.__version__}. "
        "`d_pressure` is the largest pressure difference from Newton relative to the peak.",
        "",
    ]
    for law, rows in summary.groupby("law", sort=False):
        lines += [
            f"## {_LAW_TITLE.get(law, law)}",
            "",
            "| method | "
            + " | ".join(f"N = {n}" for n in sizes)
            + " | k in time ~ N^k (two largest N) | worst d_pressure | success |",
            "|---|" + "---|" * (len(sizes) + 3),
        ]
        for label, g in rows.groupby("label", sort=False):
            g = g.set_index("n_springs")
            times = " | ".join(
                f"{g.loc[n, 'best_time']:.3g}" if n in g.index and np.isfinite(g.loc[n, "best_time"]) else "failed"
                for n in sizes
            )
            k = exponents[(exponents["law"] == law) & (exponents["label"] == label)]["exponent"]
            lines.append(
                f"| {label} | {times} | {k.iloc[0]:.2f} | {g['d_pressure'].max():.1e} | "
                f"{g['success_rate_percent'].mean():.0f} % |"
                if len(k)
                else f"| {label} | {times} | - | {g['d_pressure'].max():.1e} | {g['success_rate_percent'].mean():.0f} % |"
            )
        lines.append("")
    return "\n".join(lines)


# --- the script -------------------------------------------------------------------------
def run(
    out=DEFAULT_OUT,
    coarse: bool = False,
    sizes=None,
    repeat: int | None = None,
    laws=LAWS,
    solvers=None,
    verbose: bool = True,
) -> dict:
    """Run the study and write its table, summary, picture and Markdown into ``out``.

    Returns
    -------
    dict
        ``table`` (:func:`run_study`), ``summary`` (:func:`summary_table`), ``exponents``
        (:func:`fit_exponents`), ``markdown`` and ``files`` (name -> path).
    """
    out = Path(out)
    sizes = SIZES[1 if coarse else 0] if sizes is None else tuple(int(n) for n in sizes)
    repeat = 1 if repeat is None else int(repeat)
    load_average = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    if not coarse:  # the coarse run checks answers, not times: no need to pay for a warm-up
        warm_up(laws, solvers)
    table = run_study(sizes, laws, repeat, solvers, max_repeat=MAX_REPEAT[1 if coarse else 0], verbose=verbose)
    summary = summary_table(table)
    exponents = fit_exponents(summary)
    markdown = summary_markdown(summary, exponents, coarse=coarse, repeat=repeat, load_average=load_average)
    files = {
        "table": _write(out / "solver_study.csv", table.to_csv(index=False)),
        "summary": _write(out / "solver_study_summary.csv", summary.to_csv(index=False)),
        "markdown": _write(out / "solver_study.md", markdown),
        "png": _write(out / "solver_study.png", figure_bytes(plot_study(summary))),
    }
    return {"table": table, "summary": summary, "exponents": exponents, "markdown": markdown, "files": files}


def parse_args(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"output directory (default {DEFAULT_OUT})")
    parser.add_argument("--coarse", action="store_true", help="300 and 1000 springs, one repeat (the tests use it)")
    parser.add_argument("--sizes", type=int, nargs="+", help="target spring counts (default 1000 3000 10000 30000)")
    parser.add_argument(
        "--repeat",
        type=int,
        help="least runs per method and size (default 1; fast methods "
        f"are rerun up to {MAX_REPEAT[0]} times within {BUDGET:g} s)",
    )
    parser.add_argument("--laws", nargs="+", choices=LAWS, default=list(LAWS), help="laws to study")
    parser.add_argument("--solvers", nargs="+", help="QP solvers (default: CLARABEL, OSQP, SCS, PIQP as installed)")
    parser.add_argument("--quiet", action="store_true", help="no line per run")
    return parser.parse_args(argv)


def main(argv=None) -> dict:
    """Command-line entry point; returns what :func:`run` returns."""
    args = parse_args(argv)
    if args.repeat is not None and args.repeat < 1:
        raise SystemExit("--repeat must be at least 1")
    solvers = None if args.solvers is None else [s.upper() for s in args.solvers]
    if solvers is not None:
        missing = sorted(set(solvers) - set(installed_qp_solvers()))
        if missing:
            raise SystemExit(
                f"QP solver(s) {', '.join(missing)} not installed here; cvxpy has {', '.join(installed_qp_solvers())}"
            )
    start = time.perf_counter()
    result = run(
        args.out,
        coarse=args.coarse,
        sizes=args.sizes,
        repeat=args.repeat,
        laws=args.laws,
        solvers=solvers,
        verbose=not args.quiet,
    )
    print(result["markdown"])
    for path in result["files"].values():
        print(f"wrote {path}")
    print(f"{time.perf_counter() - start:.1f} s in all")
    return result


if __name__ == "__main__":
    main()
