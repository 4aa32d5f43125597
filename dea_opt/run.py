"""Running scenarios: one static solve or a load path, with every output published together.

The command line (:mod:`dea_opt.cli`) and the sweep workers (:mod:`dea_opt.sweep`) call
:func:`run_scenario`; ``dea-opt demo`` calls :func:`dea_opt.demo.run_demo`.

Outputs of a static load (in the output folder): ``contact.vtu`` (the contact surface with
pressure, strain, gap, thickness, ...), ``contact.csv`` (one row per spring),
``contact.json`` (summary, regions, certificate, validity) and ``contact.png`` (pressure map).
Outputs of a load path: ``frames.csv`` (one row per frame), ``series.pvd`` with
``series_frames/frame_NNNN.vtu`` (ParaView time series), ``exposure.vtu`` (exposure
fields), ``cycle.png`` (force, pressure and contact area over time), ``exposure.png``
(exposure maps) and ``summary.json``. Every run also writes ``manifest.json`` (last: the
run id, dea-opt version, scenario hash and every file with its size and SHA-256) and, when
a library had something to say, ``dea-opt.log`` (:mod:`dea_opt.io.publish`,
:mod:`dea_opt.runlog`).

Exit status of a run (:attr:`RunOutcome.exit_code`): 0 every answer certified and inside
validity; 1 an answer failed its certificate; 3 certified but outside the model's validity
(0 with ``[solve] allow_outside_validity = true``). Bad input raises a ``DeaError`` (exit 2
at the command line).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import InputError
from .runlog import LOG_NAME, captured, one_line

__all__ = ["EXIT_CODES", "RunOutcome", "check_method", "frame_validity", "publish_run", "run_info", "run_path_outputs",
           "run_scenario", "solve_options", "status_of"]

#: Exit status of a run, by its status.
EXIT_CODES = {"ok": 0, "certificate failed": 1, "bad input": 2, "outside validity": 3}


@dataclass(eq=False)
class RunOutcome:
    """What :func:`run_scenario` did.

    Attributes
    ----------
    kind : {"static", "path"}
    success : bool
        Every answer passed its certificate.
    message : str
        One line for the user.
    files : dict {name: Path}
    headline : dict
        The numbers a sweep puts in its table (with ``valid`` and ``validity_failed``).
    result : Solution or PathResult
    warnings : list of str
        dea-opt's own warnings of the run (validity, dropped springs, ...), one line each.
    valid : bool or None
        Every answer lies inside its model's validity (None: not assessed).
    validity : list of str
        Lines describing the validity (each check of a static answer; the frames outside
        validity of a load path).
    reasons : list of str
        Why the answer is outside validity (each failed check with its value, limit and
        advice; for a load path, the frames); empty when valid.
    allow_outside_validity : bool
        ``[solve] allow_outside_validity``: an answer outside validity exits 0.
    folder : Path or None
        The output folder; ``manifest`` its manifest once published.
    """

    kind: str
    success: bool
    message: str
    files: dict
    headline: dict
    result: object = None
    warnings: list = field(default_factory=list)
    valid: bool | None = True
    validity: list = field(default_factory=list)
    reasons: list = field(default_factory=list)
    allow_outside_validity: bool = False
    folder: Path | None = None
    manifest: dict | None = None

    @property
    def status(self) -> str:
        """``"ok"``, ``"certificate failed"`` or ``"outside validity"``."""
        return status_of(self.success, self.valid)

    @property
    def exit_code(self) -> int:
        """0, 1 or 3 (see the module's docstring)."""
        if self.status == "outside validity" and self.allow_outside_validity:
            return 0
        return EXIT_CODES[self.status]


def status_of(success: bool, valid: bool | None) -> str:
    """The status of a run: a failed certificate outranks an answer outside validity."""
    if not success:
        return "certificate failed"
    return "outside validity" if valid is False else "ok"


def solve_options(section, method: str, law) -> dict:
    """Formulation options from ``[solve]`` for ``method`` (only those it accepts).

    The formulation is ``method``, or under ``auto`` the one the registry falls back to for
    ``law`` (:func:`dea_opt.formulations.fallback_for`). ``[solve].tol`` sets the options one
    accuracy setting sets (:func:`~dea_opt.formulations.tolerance_options`), and each other
    key of ``[solve]`` that names one of its options (``solver``, ``form``) is passed as is.
    """
    from . import formulations

    if getattr(section, "kinematics", "small") == "finite":
        # finite kinematics: newton and nlp stand for the finite formulations, auto tries both
        from .formulations.finite import ALIASES

        chain = ["finite", "finite_nlp"] if method == "auto" else [ALIASES.get(method, method)]
        out: dict = {}
        for name in chain:
            if name in formulations.names() and formulations.takes(name, law, "finite"):
                out.update({o.name: getattr(section, o.name) for o in formulations.options(name)
                            if not o.tolerance and o.name in ("form",)})
                out.update(formulations.tolerance_options(name, section.tol))
        return out
    effective = method if method != "auto" else formulations.fallback_for(law)
    if effective is None:
        return {}
    options = {option.name: getattr(section, option.name) for option in formulations.options(effective)
               if not option.tolerance and getattr(section, option.name, None) is not None}
    return options | formulations.tolerance_options(effective, section.tol)


def check_method(method: str | None, default: str) -> str:
    """``method`` (or the scenario's ``default``), checked against the scenario's method names."""
    from .scenario import METHOD_NAMES

    method = default if method is None else method.strip().lower()
    if method not in METHOD_NAMES:
        raise InputError(f"method (--method or [solve].method) must be one of {', '.join(METHOD_NAMES)}, "
                         f"got {method!r}")
    return method


def run_info(scenario, command: str, method: str | None = None) -> dict:
    """What a manifest records about the run of ``scenario``."""
    return {"command": command, "title": scenario.title, "scenario": scenario.source,
            "scenario_sha256": scenario.text_sha256, "overrides": scenario.overrides,
            **({"method": method} if method else {})}


def run_scenario(scenario, output_dir=None, *, method: str | None = None, progress: bool = False,
                 force: bool = False, stop_on_error: bool = False) -> RunOutcome:
    """Solve a scenario and publish its outputs into one folder.

    Parameters
    ----------
    scenario : Scenario
    output_dir : str or Path, optional
        Default ``[output].directory`` (relative to the scenario file). It must be new,
        empty or hold an earlier dea-opt run (:func:`dea_opt.io.publish.check_output_folder`).
    method : str, optional
        Overrides ``[solve].method``.
    progress : bool
        Progress bar over the frames of a load path (on a terminal).
    force : bool
        Write into a folder that holds other files.
    stop_on_error : bool
        A load path stops at its first frame without a certified answer (a DeaError, and
        nothing published) instead of recording it and going on.

    Returns
    -------
    RunOutcome
        Its ``exit_code`` is the command line's.

    Raises
    ------
    DeaError
        Bad input (:class:`~dea_opt.errors.OutputFolderError` for a folder of someone
        else's), a load no spring can carry, a solver that fails outright. Nothing is
        published then, and the folder keeps what it held.
    dea_opt.io.publish.RunInterrupted
        Ctrl-C; its ``report`` says what the folder holds.
    """
    from .io.publish import check_output_folder
    from .scenario import build_problem

    method = check_method(method, scenario.solve.method)
    out = check_output_folder(scenario.output_dir(output_dir), force)
    with captured() as messages:
        problem = build_problem(scenario)
        options = solve_options(scenario.solve, method, problem.law)

        def solve_and_write(folder):
            if scenario.load_path is None:
                return _run_static(scenario, problem, method, options, folder)
            return run_path_outputs(scenario, problem, method, options, folder, progress, stop=stop_on_error)

        outcome = publish_run(scenario, out, solve_and_write, messages, force=force,
                              info=run_info(scenario, "run", method))
    return outcome


def publish_run(scenario, out: Path, solve_and_write, messages, *, force: bool, info: dict) -> RunOutcome:
    """Run ``solve_and_write(folder) -> RunOutcome`` in the staged folder ``out`` and publish it."""
    from .io.publish import output_run

    with output_run(out, force=force, info=info) as publication:
        outcome = solve_and_write(publication.folder)
        outcome.allow_outside_validity = scenario.solve.allow_outside_validity
        messages.collect()
        _drop_repeats(outcome, messages, scenario.notes)
        log = messages.log_text(f"dea-opt {info.get('command', 'run')} of {scenario.source or scenario.title}")
        if log:
            from .io.atomic import write_data

            outcome.files["log"] = write_data(publication.folder / LOG_NAME, log)
        outcome.manifest = publication.publish(
            status=outcome.status, exit_code=outcome.exit_code, success=outcome.success, valid=outcome.valid)
        outcome.folder = publication.folder
    return outcome


def _drop_repeats(outcome: RunOutcome, messages, notes=()) -> None:
    """The scenario's notes and the run's own warnings, but for the validity warnings: the
    validity lines of the outcome state them, with every check."""
    assessed = outcome.valid is not None
    outcome.warnings = [*notes, *(w for w in messages.own
                                  if not (assessed and messages.categories.get(w) == "ValidityWarning"))]


# --- one load ---------------------------------------------------------------------------

def _run_static(scenario, problem, method, options, out) -> RunOutcome:
    from . import io
    from .solver import solve

    solution = solve(problem, method, certificate_tol=scenario.solve.certificate_tol, strict=False, **options)
    formats = scenario.output.formats
    files = {}
    if "vtk" in formats:
        files["vtk"] = io.to_vtk(solution, out / "contact.vtu")
    if "csv" in formats:
        files["csv"] = io.to_csv(solution, out / "contact.csv")
    if "json" in formats:
        files["json"] = io.to_json(solution, out / "contact.json")
    if "png" in formats:
        files["png"] = io.plot_pressure(solution, out / "contact.png")
    name, value = solution.certificate.worst()
    validity = solution.validity
    headline = {
        "method": solution.method, "success": solution.success, "n_springs": len(solution.pressure),
        "peak_pressure": solution.peak_pressure, "mean_pressure": solution.mean_pressure,
        "contact_area": solution.contact_area, "max_compressive_strain": solution.max_compressive_strain,
        "iterations": solution.iterations, "solve_time": solution.solve_time, "worst_residual": value,
        **validity.columns(),
    }
    if solution.success:
        message = (f"{solution.method}: peak pressure {solution.peak_pressure:.4g} MPa, contact area "
                   f"{solution.contact_area:.4g} mm^2, {solution.iterations} iterations, certificate passed")
    else:
        message = (f"{solution.method} returned no certified answer (status {solution.status!r}; {name} = "
                   f"{value:.3g} > {scenario.solve.certificate_tol:g}); the outputs hold the uncertified answer")
    lines = [f"validity: {validity.summary()}"]
    lines += [f"  {check.describe()}" for check in validity.checks]
    return RunOutcome("static", solution.success, message, files, headline, solution, valid=validity.valid,
                      validity=lines, reasons=[c.describe() for c in validity.failed])


# --- a load path ------------------------------------------------------------------------

def frame_validity(result) -> np.ndarray | None:
    """Per frame, whether its answer is inside validity: the table's ``valid`` column, else
    the kept solutions' :attr:`~dea_opt.solution.Solution.validity`; None when neither exists."""
    table = result.table
    if "valid" in table.columns:
        return table["valid"].to_numpy(dtype=bool)
    if result.solutions:
        return np.array([s.validity.valid for s in result.solutions], dtype=bool)
    return None


def _failed_checks(result, valid: np.ndarray) -> list[str]:
    """The names of the validity checks failed by any frame, in order of first appearance."""
    table = result.table
    names: list[str] = []
    if "validity_failed" in table.columns:
        texts = table["validity_failed"].fillna("").astype(str)
    elif result.solutions:
        texts = [";".join(c.name for c in s.validity.failed) for s in result.solutions]
    else:
        texts = []
    for text in texts:
        for name in filter(None, text.split(";")):
            if name not in names:
                names.append(name)
    return names


def _frames_text(frames) -> str:
    shown = ", ".join(map(str, frames[:10]))
    return shown + (", ..." if len(frames) > 10 else "")


def run_path_outputs(scenario, problem, method, options, out, progress, extra_summary=None,
                     stop: bool = False) -> RunOutcome:
    """Solve the load path of ``scenario`` and write its outputs into ``out`` (staged by the caller)."""
    from .loadpath import solve_path
    from .scenario import read_load_path

    data = read_load_path(scenario.load_path)
    layer_for_pose = None
    if data.poses is not None:
        from .scenario import pose_builder

        layer_for_pose = pose_builder(scenario)

    formats = scenario.output.formats
    result = solve_path(problem, data.load_objects(), data.poses, method=method, times=data.times, body=data.body,
                        certificate_tol=scenario.solve.certificate_tol, keep_solutions="vtk" in formats,
                        layer_for_pose=layer_for_pose, threshold=scenario.output.exposure_threshold,
                        progress=progress, strict=stop, **options)
    valid = frame_validity(result)
    # Outside validity: certified frames only (a failed frame has its own status).
    certified = result.table["success"].to_numpy(dtype=bool)
    outside = [] if valid is None else result.table.loc[certified & ~valid, "frame"].astype(int).tolist()
    checks = [] if valid is None else _failed_checks(result, valid)
    run_valid = None if valid is None else not outside
    run_validity = {
        "valid": run_valid,
        "frames_outside_validity": outside,
        "failed_checks": checks,
    }
    extra = {"title": scenario.title, **(extra_summary or {})}
    if "validity" not in result.summary():
        extra["validity"] = run_validity
    files = result.write(out, formats, extra_summary=extra)
    summary = result.summary()
    headline = {
        "method": method, "success": result.success, "frames": summary["frames"], "n_springs": summary["n_springs"],
        "failed_frames": len(summary["failed_frames"]), "peak_pressure": summary["peak_pressure"],
        "peak_time": summary["peak_time"], "contact_area": summary["max_contact_area"],
        "max_compressive_strain": summary["max_compressive_strain"],
        "iterations": summary["iterations_total"], "solve_time": summary["solve_time_total"],
        "worst_residual": summary["worst_certificate_residual"],
        "max_pressure_time_integral": summary["exposure"]["max_pressure_time_integral"],
        "valid": run_valid, "frames_outside_validity": len(outside),
        "validity_failed": ";".join(checks),
    }
    message = (f"{summary['frames']} frames by {method}: peak pressure {summary['peak_pressure']:.4g} MPa at "
               f"{summary['peak_time']:.3g} s, largest contact area {summary['max_contact_area']:.4g} mm^2, "
               f"{summary['solve_time_total']:.2f} s solving")
    if not result.success:
        failed = summary["failed_frames"]
        message += (f"; {len(failed)} frame(s) failed their certificate ({_frames_text(failed)}) and are flagged "
                    f"in frames.csv")
    reasons = []
    if valid is None:
        lines = [("validity: not assessed (the frames' validity needs their solutions: add \"vtk\" to "
                  "[output].formats)")]
    elif outside:
        reasons = [f"{len(outside)} of {len(valid)} frame(s) outside validity ({_frames_text(outside)}), failed "
                   f"checks: {', '.join(checks)}"]
        if result.solutions:
            reasons.append(f"frame {outside[0]}: {one_line(result.solutions[outside[0]].validity.message())}")
        lines = [f"validity: NOT VALID: {reasons[0]}", *(f"  {r}" for r in reasons[1:])]
    else:
        lines = [f"validity: valid (every one of {len(valid)} frames)"]
    return RunOutcome("path", result.success, message, files, headline, result, valid=run_valid, validity=lines,
                      reasons=reasons)
