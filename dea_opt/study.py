"""Comparison studies: one problem, every method x solver x accuracy setting, with repeats.

Each run is :func:`dea_opt.solve` with ``strict=False``, so an answer that fails its
certificate comes back as a row that says so instead of an exception. A row is a
**success** only when the solver claims success, the certificate computed by dea_opt
passes at the accuracy's tolerance, and the answer agrees with a reference Newton solution
to that same tolerance (largest pressure difference relative to the peak, largest
displacement difference relative to the largest displacement).

The summary follows qpbenchmark (Caron et al.): per method and solver, the success rate
and the shifted geometric mean of the run time (shift 10 ms; a failed run counts as the
time limit), normalised so that the fastest is 1.

Accuracy settings (:data:`ACCURACY`): the solver is asked for ``solver_tol`` and the answer
is checked against ``check_tol``:

=========  ====================  ==========
setting    solver_tol            check_tol
=========  ====================  ==========
low        1e-3                  1e-3
default    the formulation's     1e-6
high       1e-10                 1e-9
=========  ====================  ==========
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from . import formulations
from .agreement import pressure_difference
from .errors import DeaError, InputError
from .status import Status

if TYPE_CHECKING:
    import pandas as pd

    from .solution import Solution

__all__ = ["ACCURACY", "Accuracy", "StudyResult", "installed_qp_solvers", "run_study", "shifted_geometric_mean"]


@dataclass(frozen=True)
class Accuracy:
    """What a setting asks of the solver (``solver_tol``) and of its answer (``check_tol``)."""

    name: str
    solver_tol: float | None
    check_tol: float


ACCURACY = {
    "low": Accuracy("low", 1e-3, 1e-3),
    "default": Accuracy("default", None, 1e-6),
    "high": Accuracy("high", 1e-10, 1e-9),
}
#: The QP solvers compared by default (those cvxpy has installed are used).
DEFAULT_SOLVERS = ("CLARABEL", "OSQP", "SCS", "PIQP")
SHIFT = 0.010  # s, qpbenchmark's shift of the geometric mean
TIME_LIMIT = 10.0  # s, the time a failed run counts as


def installed_qp_solvers() -> list[str]:
    """The QP solvers cvxpy can call here."""
    import cvxpy as cp

    return sorted(cp.installed_solvers())


def _variant_option(method):
    """The :class:`~dea_opt.formulations.Option` a study varies for ``method``, or None."""
    variant = formulations.variant(method)
    if variant is None:
        return None
    return next(option for option in formulations.options(method) if option.name == variant.option)


def _check_names(methods, solvers, accuracy, what="methods"):
    names = formulations.names()
    methods = [m.strip().lower() if isinstance(m, str) else m for m in methods]
    bad = [m for m in methods if m not in names]
    if bad or not methods:
        raise InputError(f"{what} must be taken from {', '.join(names)}, got {', '.join(map(str, bad)) or 'none'}")
    bad = [a for a in accuracy if a not in ACCURACY]
    if bad or not accuracy:
        raise InputError(f"accuracy must be taken from {', '.join(ACCURACY)}, got {', '.join(bad) or 'none'}")
    solvers = [s.strip().upper() for s in solvers]
    by_solver = [m for m in methods if (option := _variant_option(m)) is not None and option.name == "solver"]
    if by_solver:
        installed = installed_qp_solvers()
        if tuple(solvers) == DEFAULT_SOLVERS:
            solvers = [s for s in DEFAULT_SOLVERS if s in installed]
        bad = [s for s in solvers if s not in installed]
        if bad:
            raise InputError(
                f"solver {', '.join(bad)} is not available to cvxpy here; installed QP solvers: "
                f"{', '.join(installed)} (pip install dea-opt[solvers] adds OSQP, SCS and PIQP)"
            )
        if not solvers:
            raise InputError(f"solvers is empty: name at least one QP solver for method {by_solver[0]}")
    return methods, solvers, list(accuracy)


def _check_forms(methods, nlp_forms) -> list:
    """``nlp_forms`` checked against the ``form`` option of the methods a study varies by it."""
    for method in methods:
        option = _variant_option(method)
        if option is not None and option.name == "form":
            bad = [f for f in nlp_forms if f not in option.accepted()]
            if bad or not nlp_forms:
                raise InputError(
                    f"nlp_forms must be taken from {', '.join(option.accepted())}, got "
                    f"{', '.join(map(str, bad)) or 'none'}"
                )
    return list(nlp_forms)


def _variants(method, solvers, forms) -> list[tuple[str, dict]]:
    """``(label, options)`` for each row of ``method``: one per value of the option a study
    varies for it (``solvers`` for a ``solver`` option, ``forms`` for a ``form`` option)."""
    option, variant = _variant_option(method), formulations.variant(method)
    if option is None or variant is None:
        return [("-", {})]
    values = {"solver": solvers, "form": forms}.get(option.name, [option.default])
    return [(variant.label(value), {option.name: value}) for value in values]


def _cases(methods, solvers, accuracy, repeat, forms=("constrained",)):
    return [
        (ACCURACY[acc], method, label, options, r)
        for acc in accuracy
        for method in methods
        for label, options in _variants(method, solvers, forms)
        for r in range(repeat)
    ]


def _options(method, variant_options: dict, accuracy: Accuracy) -> dict:
    return {**variant_options, **formulations.tolerance_options(method, accuracy.solver_tol)}


def _difference(solution, reference) -> tuple[float, float]:
    if reference is None or not np.isfinite(solution.u).all():
        return float("nan"), float("nan")
    dp = pressure_difference(solution, reference) / max(reference.peak_pressure, 1e-300)
    du = float(np.abs(solution.u - reference.u).max() / max(np.abs(reference.u).max(), 1e-300))
    return dp, du


def _run_one(problem, accuracy, method, solver, variant_options, repeat, reference) -> dict:
    from .solver import solve

    row = {
        "accuracy": accuracy.name,
        "method": method,
        "solver": solver,
        "repeat": repeat,
        "check_tol": accuracy.check_tol,
        "solver_tol": accuracy.solver_tol,
    }
    start = time.perf_counter()
    try:
        import warnings

        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # validity warnings belong to the problem, not to the solver
            solution = solve(
                problem,
                method,
                certificate_tol=accuracy.check_tol,
                strict=False,
                **_options(method, variant_options, accuracy),
            )
    except DeaError as exc:
        elapsed = time.perf_counter() - start
        return row | {
            "success": False,
            "solver_success": False,
            "certified": False,
            "agrees": False,
            "status": Status.of_error(exc),
            "message": str(exc).splitlines()[0][:200],
            "total_time_s": elapsed,
        }
    certificate = solution.certificate
    dp, du = _difference(solution, reference)
    agrees = bool(max(dp, du) <= accuracy.check_tol) if reference is not None else float("nan")
    solver_success = bool(solution.info.get("solver_success", solution.success))
    worst_name, worst = certificate.worst()
    success = bool(solver_success and certificate.passed and (reference is None or agrees))
    return row | {
        "success": success,
        "solver_success": solver_success,
        "certified": certificate.passed,
        "agrees": agrees,
        "status": solution.status,
        "message": _verdict(solution, agrees, accuracy, dp, du),
        "build_time_s": solution.build_time,
        "solve_time_s": solution.solve_time,
        "total_time_s": solution.build_time + solution.solve_time,
        "solver_time_s": solution.info.get("solver_time_s", float("nan")),
        "iterations": solution.iterations,
        "equilibrium": certificate.equilibrium,
        "tension": certificate.tension,
        "complementarity": certificate.complementarity,
        "consistency": certificate.consistency,
        "energy": certificate.energy,
        "worst_residual": worst,
        "worst_name": worst_name,
        "peak_pressure_MPa": solution.peak_pressure,
        "contact_area_mm2": solution.contact_area,
        "d_pressure": dp,
        "d_displacement": du,
    }


def _verdict(solution, agrees, accuracy, dp, du) -> str:
    if not solution.info.get("solver_success", True):
        return f"solver reports {solution.info.get('native_status') or solution.status}"
    if not solution.certificate.passed:
        name, value = solution.certificate.worst()
        return f"inaccurate: {name} {value:.1e} > {accuracy.check_tol:g}"
    if agrees is False:
        reference = formulations.resolve(formulations.DEFAULT, None, solution.problem.kinematics).name
        return f"disagrees with the reference ({reference}): {max(dp, du):.1e} > {accuracy.check_tol:g}"
    return "ok"


def shifted_geometric_mean(times, shift: float = SHIFT) -> float:
    """``exp(mean(log(t + shift))) - shift`` (s): qpbenchmark's runtime average."""
    times = np.asarray(times, dtype=float)
    if times.size == 0:
        return float("nan")
    return float(np.exp(np.mean(np.log(times + shift))) - shift)


@dataclass(eq=False)
class StudyResult:
    """The rows of a comparison study, the reference solution and the summary.

    Attributes
    ----------
    table : pandas.DataFrame
        One row per run (see :func:`run_study` for the columns).
    summary : pandas.DataFrame
        Per accuracy, method and solver: ``runs``, ``success_rate_percent``,
        ``shifted_gm_time_s``, ``relative_time`` (1 = fastest at that accuracy),
        ``worst_residual``, ``max_d_pressure``.
    reference : Solution or None
        The default formulation's (Newton's) solution differences are measured against.
    skipped : list of str
        Combinations that do not apply (qp with a nonlinear law or finite kinematics), and why.
    notes : list of str
        Names that stand for another formulation (``newton`` for ``finite`` with finite kinematics).
    """

    table: pd.DataFrame
    summary: pd.DataFrame
    reference: Solution | None = None
    skipped: list = field(default_factory=list)
    notes: list = field(default_factory=list)

    def to_csv(self, directory) -> dict:
        """``compare.csv`` and ``compare_summary.csv`` in ``directory``."""
        from pathlib import Path

        from .files import write_data

        directory = Path(directory)
        return {
            name: write_data(directory / file, frame.to_csv(index=False, lineterminator="\n"))
            for name, file, frame in (
                ("table", "compare.csv", self.table),
                ("summary", "compare_summary.csv", self.summary),
            )
        }

    def format_table(self) -> str:
        """The runs as aligned text (the columns a reader looks at first)."""
        columns = [
            "accuracy",
            "method",
            "solver",
            "repeat",
            "success",
            "status",
            "iterations",
            "total_time_s",
            "worst_residual",
            "d_pressure",
            "d_displacement",
            "message",
        ]
        table = self.table[[c for c in columns if c in self.table]]
        return table.to_string(index=False, float_format=lambda v: f"{v:.3g}")

    def format_summary(self) -> str:
        return self.summary.to_string(index=False, float_format=lambda v: f"{v:.3g}")


def summarize(table, time_limit: float = TIME_LIMIT, shift: float = SHIFT):
    """The qpbenchmark-style summary of a study table (see :class:`StudyResult`)."""
    import pandas as pd

    rows: list = []
    keys = ["accuracy", "method", "solver"]
    if not len(table) or not set(keys) <= set(table.columns):  # no run at all: an empty summary
        return pd.DataFrame(
            columns=[
                *keys,
                "runs",
                "success_rate_percent",
                "shifted_gm_time_s",
                "relative_time",
                "worst_residual",
                "max_d_pressure",
            ]
        )
    for (accuracy, method, solver), group in table.groupby(keys, sort=False):
        success = group["success"].astype(bool)
        times = np.where(success, group["total_time_s"].astype(float), time_limit)
        rows.append(
            {
                "accuracy": accuracy,
                "method": method,
                "solver": solver,
                "runs": len(group),
                "success_rate_percent": 100.0 * success.mean(),
                "shifted_gm_time_s": shifted_geometric_mean(times, shift),
                "worst_residual": float(group.get("worst_residual", pd.Series([math.nan])).max()),
                "max_d_pressure": float(group.get("d_pressure", pd.Series([math.nan])).max()),
            }
        )
    summary = pd.DataFrame(rows)
    if len(summary):
        fastest = summary.groupby("accuracy")["shifted_gm_time_s"].transform("min")
        summary.insert(6, "relative_time", summary["shifted_gm_time_s"] / fastest)
    return summary


def run_study(
    problem,
    methods=None,
    solvers=DEFAULT_SOLVERS,
    accuracy=("default",),
    repeat: int = 1,
    *,
    nlp_forms=("constrained",),
    time_limit: float = TIME_LIMIT,
    progress: bool = False,
    what: str = "methods",
) -> StudyResult:
    """Solve ``problem`` with every method x solver x accuracy setting, ``repeat`` times each.

    Parameters
    ----------
    problem : ContactProblem
    methods : sequence of str, optional
        Registered formulations (default: every one of :func:`dea_opt.formulations.names` that
        solves the problem; one named that does not is skipped, with a note). For finite
        kinematics ``newton`` and ``nlp`` stand for ``finite`` and ``finite_nlp`` (rows and
        ``notes`` say so).
    solvers : sequence of str
        QP solvers for the formulations a study varies by their ``solver`` option (``qp``;
        cvxpy names). The default list is cut to the installed ones; a solver named
        explicitly that is not installed is an :class:`InputError`.
    accuracy : sequence of {"low", "default", "high"}
        See :data:`ACCURACY`.
    repeat : int
        Runs per combination (for timing).
    nlp_forms : sequence of {"constrained", "reduced"}
        The forms to run of the formulations a study varies by their ``form`` option (``nlp``);
        each is a row labelled by the formulation's variant (``IPOPT`` or ``IPOPT-reduced``).
    time_limit : float
        Time (s) a failed run counts as in the summary.
    progress : bool
        Show a progress bar (on a terminal).
    what : str
        How error messages name ``methods`` (the command line: ``--methods`` or ``solve.methods``).

    Returns
    -------
    StudyResult
        ``table`` columns: accuracy, method, solver, repeat, check_tol, solver_tol,
        success, solver_success, certified, agrees, status, message, build_time_s,
        solve_time_s, total_time_s, solver_time_s, iterations, the certificate's
        equilibrium, tension, complementarity, consistency, energy, worst_residual and
        worst_name, peak_pressure_MPa, contact_area_mm2, d_pressure and
        d_displacement (relative differences from the Newton reference).

    Raises
    ------
    InputError
        Unknown method, solver or accuracy; ``repeat < 1``; no method named solves the problem.
    LoadNotSupportedError
        The load cannot be carried (no method could answer).
    """
    import pandas as pd

    from .progress import bar, showing
    from .solver import check_load_supported, solve

    if isinstance(repeat, bool) or int(repeat) != repeat or repeat < 1:
        raise InputError(f"repeat must be a positive integer, got {repeat!r}")
    if methods is None:
        methods = [name for name in formulations.names() if formulations.takes(name, problem.law, problem.kinematics)]
    methods, solvers, accuracy = _check_names(methods, solvers, accuracy, what)
    chosen = formulations.select(methods, problem.law, problem.kinematics, what=what)
    forms = _check_forms(chosen.run, nlp_forms)
    cases = _cases(chosen.run, solvers, accuracy, int(repeat), forms)
    check_load_supported(problem)
    import warnings

    with showing(progress) as shown:
        if shown is not None:
            shown.stage(f"solving the reference answer ({formulations.DEFAULT})")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            solved = solve(problem, formulations.DEFAULT, strict=False)
        reference = solved if solved.success else None
        rows = []
        with bar(len(cases), "compare", "run", progress) as counted:
            for acc, method, label, options, r in cases:
                rows.append(_run_one(problem, acc, method, label, options, r, reference))
                counted.update()
    table = pd.DataFrame(rows)
    return StudyResult(
        table=table,
        summary=summarize(table, time_limit),
        reference=reference,
        skipped=list(chosen.skipped.values()),
        notes=chosen.notes,
    )
