"""Running scenarios: one static solve or a load path, with every output published together.

The command line (:mod:`dea_opt.cli`) and the sweep workers (:mod:`dea_opt.sweep`) call
:func:`run_scenario`; ``dea-opt demo`` calls :func:`dea_opt.demo.run_demo`.

Outputs of a static load (in the output folder): ``contact.vtu`` (the contact surface with
pressure, strain, gap, thickness, ...), ``contact.csv`` (one row per spring),
``contact.json`` (summary, regions, certificate, validity) and ``contact.png`` (pressure map).
Outputs of a load path: ``frames.csv`` (one row per frame), ``series.pvd`` with
``series_frames/frame_NNNN.vtu`` (ParaView time series, each frame written as it is solved:
nothing is kept per frame), ``exposure.vtu`` (exposure fields), ``cycle.png`` (force, moment,
pressure and contact area over time), ``exposure.png`` (exposure maps) and ``summary.json``.
``[output] anatomy`` draws the maps in the joint's anatomical frame. When the springs were cast
from meshes they are re-cast at the solved pose (a load path: its peak frame), which evaluates
the ``dropped_springs`` validity check and adds ``recast`` to ``contact.json``/``summary.json``. Every run also writes ``manifest.json`` (last: the
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

__all__ = ["EXIT_CODES", "RunOutcome", "check_method", "peak_recast", "publish_run", "recast_solution", "run_info",
           "run_path_outputs", "run_scenario", "solve_options", "status_of"]

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
    regions : list of str
        One line per labelled region (compartment): its share of the load, peak pressure and
        contact area (for a load path: over the frames); empty without labels.
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
    regions: list = field(default_factory=list)
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
    from .scenario import build_problem_cast

    method = check_method(method, scenario.solve.method)
    out = check_output_folder(scenario.output_dir(output_dir), force)
    with captured() as messages:
        problem, cast = build_problem_cast(scenario)
        options = solve_options(scenario.solve, method, problem.law)

        def solve_and_write(folder):
            if scenario.load_path is None:
                return _run_static(scenario, problem, method, options, folder, cast)
            return run_path_outputs(scenario, problem, method, options, folder, progress, stop=stop_on_error,
                                    cast=cast)

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
    """The scenario's notes, the outcome's own notes (a re-cast that failed) and the run's own
    warnings, but for the validity warnings: the validity lines of the outcome state them, with
    every check."""
    assessed = outcome.valid is not None
    outcome.warnings = [*notes, *outcome.warnings,
                        *(w for w in messages.own
                          if not (assessed and messages.categories.get(w) == "ValidityWarning"))]


# --- one load ---------------------------------------------------------------------------

def _run_static(scenario, problem, method, options, out, cast=None) -> RunOutcome:
    from . import io
    from .io.summary import summary_dict, write_json
    from .solver import solve

    solution = solve(problem, method, certificate_tol=scenario.solve.certificate_tol, strict=False, **options)
    notes = []
    recast = None
    if cast is not None:
        solution, recast = recast_solution(solution, cast)
        if "error" in recast:
            notes.append(recast["error"])
    formats, anatomy = scenario.output.formats, scenario.output.anatomy
    files = {}
    if "vtk" in formats:
        files["vtk"] = io.to_vtk(solution, out / "contact.vtu")
    if "csv" in formats:
        files["csv"] = io.to_csv(solution, out / "contact.csv")
    if "json" in formats:
        summary = summary_dict(solution, anatomy=anatomy)
        if recast is not None:
            summary["recast"] = recast
        files["json"] = write_json(summary, out / "contact.json")
    if "png" in formats:
        files["png"] = io.plot_pressure(solution, out / "contact.png", anatomy=anatomy)
    name, value = solution.certificate.worst()
    validity = solution.validity
    headline = {
        "method": solution.method, "success": solution.success, "n_springs": len(solution.pressure),
        "peak_pressure": solution.peak_pressure, "mean_pressure": solution.mean_pressure,
        "contact_area": solution.contact_area, "max_compressive_strain": solution.max_compressive_strain,
        "iterations": solution.iterations, "solve_time": solution.solve_time, "worst_residual": value,
        **validity.columns(),
        **({"recast_force_error": recast.get("force_error")} if recast is not None else {}),
    }
    if solution.success:
        message = (f"{solution.method}: peak pressure {solution.peak_pressure:.4g} MPa, contact area "
                   f"{solution.contact_area:.4g} mm^2, {solution.iterations} iterations, certificate passed")
    else:
        message = (f"{solution.method} returned no certified answer (status {solution.status!r}; {name} = "
                   f"{value:.3g} > {scenario.solve.certificate_tol:g}); the outputs hold the uncertified answer")
    lines = [f"validity: {validity.summary()}"]
    lines += [f"  {check.describe()}" for check in validity.checks]
    if recast is not None and "error" not in recast:
        lines.append(f"re-cast at the solved pose: {recast['describe']}")
    return RunOutcome("static", solution.success, message, files, headline, solution, warnings=notes,
                      valid=validity.valid, validity=lines, reasons=[c.describe() for c in validity.failed],
                      regions=_static_regions(solution))


def _static_regions(solution) -> list[str]:
    """One line per labelled region of a static answer."""
    if solution.problem.layer.labels is None or not np.isfinite(solution.pressure).all():
        return []
    from .regions import regional_statistics

    return [f"region {name}: force {r.force:.4g} N ({r.share:.1%} of the total), peak {r.peak_pressure:.4g} MPa, "
            f"contact area {r.contact_area:.4g} mm^2" for name, r in regional_statistics(solution).items()]


def recast_solution(solution, cast) -> tuple:
    """``(solution, recast)``: the springs of ``cast`` re-cast at the pose ``solution`` reached
    (:func:`dea_opt.mesh.recast_at_solution`) and the solution carrying the count the window
    dropped there (its ``dropped_springs`` validity check evaluated).

    ``recast`` is JSON-ready: the counts (``springs``, ``kept``, ``gained``, ``lost``,
    ``dropped``, ``rejected``), the force (N) and moment (N mm, about body 2's reference)
    the re-cast springs carry at that pose beside the solution's own (``solution_force``,
    ``solution_moment``), their relative difference ``force_error`` and a one-line
    ``describe``; or ``{"error": ...}`` when the answer is not certified or the re-cast failed
    (the solution is then returned as it is).
    """
    from .errors import DeaError
    from .mesh import recast_at_solution

    if not solution.success or not np.isfinite(solution.u).all():
        return solution, {"error": "springs not re-cast at the solved pose: the answer is not certified"}
    try:
        again = recast_at_solution(solution, cast)
    except DeaError as exc:
        return solution, {"error": f"springs not re-cast at the solved pose: {one_line(str(exc))}"}
    info = {
        "springs": len(again.cast.layer), "kept": again.kept, "gained": len(again.gained),
        "lost": {reason: len(faces) for reason, faces in again.lost.items()},
        "dropped": again.dropped, "rejected": again.rejected,
        **{name: np.asarray(getattr(again, name), dtype=float).tolist()
           for name in ("force", "moment", "solution_force", "solution_moment")},
        "force_error": again.force_error, "describe": again.describe(),
    }
    return solution.with_validity(dropped=again.dropped), info


# --- a load path ------------------------------------------------------------------------

def _frames_text(frames) -> str:
    shown = ", ".join(map(str, frames[:10]))
    return shown + (", ..." if len(frames) > 10 else "")


def run_path_outputs(scenario, problem, method, options, out, progress, extra_summary=None,
                     stop: bool = False, cast=None) -> RunOutcome:
    """Solve the load path of ``scenario`` and write its outputs into ``out`` (staged by the caller).

    The frames are streamed: each frame's ``.vtu`` is written as it is solved
    (``series_frames/``) and no solution or pressure is kept per frame, so memory does not
    grow with frames x springs. When the springs were cast from meshes (``cast``, or the
    meshes of a path with poses), the peak frame is solved once more and its springs re-cast
    at its solved pose (:func:`peak_recast`): its ``dropped_springs`` check is evaluated and
    the re-cast force goes into ``summary.json`` (``recast``).
    """
    from .loadpath import solve_path
    from .scenario import pose_caster, read_load_path

    data = read_load_path(scenario.load_path)
    caster = layer_for_pose = None
    poses = data.poses
    if poses is not None:
        caster = pose_caster(scenario)
        if caster is not None:
            def layer_for_pose(pose):
                return caster(pose).layer

    formats, anatomy = scenario.output.formats, scenario.output.anatomy
    loads = data.load_objects()
    result = solve_path(problem, loads, data.poses, method=method, times=data.times, body=data.body,
                        certificate_tol=scenario.solve.certificate_tol, stop_on_error=stop, keep_solutions=False,
                        keep_pressures=False, series=out / "series_frames" if "vtk" in formats else None,
                        layer_for_pose=layer_for_pose, threshold=scenario.output.exposure_threshold,
                        progress=progress, **options)
    notes = []
    recast = None
    if cast is not None or caster is not None:
        def frame_cast(k):
            return cast if caster is None or poses is None else caster(poses[k])

        recast = peak_recast(result, loads, data.body, frame_cast, method, options, scenario.solve.certificate_tol)
        if recast is not None and "error" in recast:
            notes.append(recast["error"])
    extra = {"title": scenario.title, **(extra_summary or {})}
    if recast is not None:
        extra["recast"] = recast
    files = result.write(out, formats, extra_summary=extra, anatomy=anatomy)
    summary = result.summary()
    validity = summary["validity"]
    outside = validity["frames_outside_validity"]
    checks = validity["failed_checks"]
    headline = {
        "method": method, "success": result.success, "frames": summary["frames"], "n_springs": summary["n_springs"],
        "failed_frames": len(summary["failed_frames"]), "peak_pressure": summary["peak_pressure"],
        "peak_time": summary["peak_time"], "contact_area": summary["max_contact_area"],
        "max_compressive_strain": summary["max_compressive_strain"],
        "iterations": summary["iterations_total"], "solve_time": summary["solve_time_total"],
        "worst_residual": summary["worst_certificate_residual"],
        "max_pressure_time_integral": summary["exposure"]["max_pressure_time_integral"],
        "valid": not outside, "frames_outside_validity": len(outside),
        "validity_failed": ";".join(checks),
        **({"recast_force_error": recast.get("force_error")} if recast is not None else {}),
    }
    if summary["peak_frame"] is None:
        message = f"{summary['frames']} frames by {method}: no frame has a certified answer"
    else:
        message = (f"{summary['frames']} frames by {method}: peak pressure {summary['peak_pressure']:.4g} MPa at "
                   f"{summary['peak_time']:.3g} s, largest contact area {summary['max_contact_area']:.4g} mm^2, "
                   f"{summary['solve_time_total']:.2f} s solving")
    if not result.success:
        message += f"; {result.failure_message()} (status and message of each in frames.csv)"
    reasons = []
    if outside:
        parts = [f"{name} in {len(c['frames'])} frame(s) (worst {c['worst']:.4g} at frame {c['worst_frame']})"
                 for name, c in validity["checks"].items()]
        first = (f"{len(outside)} of {summary['frames']} frame(s) outside validity ({_frames_text(outside)}), "
                 f"failed checks: {', '.join(checks)}")
        reasons = [first, *parts]
        lines = [f"validity: NOT VALID: {reasons[0]}", *(f"  {r}" for r in reasons[1:])]
    else:
        certified = summary["frames"] - len(summary["failed_frames"])
        lines = [f"validity: valid (every one of the {certified} certified frames)"]
    if recast is not None and "error" not in recast:
        lines.append(f"re-cast at the solved pose of the peak frame {recast['frame']}: {recast['describe']}")
    regions = [f"region {name}: force share {r['mean_force_share']:.1%} on average ({r['min_force_share']:.1%} to "
               f"{r['max_force_share']:.1%}), peak {r['peak_pressure']:.4g} MPa at {r['peak_time']:.3g} s, largest "
               f"contact area {r['max_contact_area']:.4g} mm^2" for name, r in summary["regions"].items()]
    return RunOutcome("path", result.success, message, files, headline, result, warnings=notes, valid=not outside,
                      validity=lines, reasons=reasons, regions=regions)


def peak_recast(result, loads, body: int, frame_cast, method: str, options: dict, certificate_tol: float):
    """Re-cast the springs at the solved pose of a load path's peak frame (the certified frame of
    the largest peak pressure), and evaluate that frame's ``dropped_springs`` check.

    The frames are not kept, so the peak frame is solved once more (the same answer: the
    problem has one) and :func:`recast_solution` re-casts it: one solve and one cast, not
    one per frame. The table's row of that frame gets ``validity_dropped_springs`` (and, when
    the window dropped springs, ``valid`` False and ``dropped_springs`` in
    ``validity_failed``); every other frame keeps it not evaluated (NaN).

    Parameters
    ----------
    result : PathResult
        Its ``table`` is updated.
    loads : list of Load
    body : int
    frame_cast : callable
        ``k -> SpringCast`` of frame ``k``.
    method, options, certificate_tol :
        As the path was solved.

    Returns
    -------
    dict or None
        ``recast_solution``'s report with ``frame`` and ``time``; None without a certified frame.
    """
    import warnings

    from .errors import DeaError, ValidityWarning
    from .solver import solve

    table = result.table
    certified = table.loc[table["success"]]
    if not len(certified) or not certified["peak_pressure"].notna().any():
        return None
    row = certified["peak_pressure"].idxmax()
    k = int(table.loc[row, "frame"])
    where = {"frame": k, "time": float(table.loc[row, "time"])}
    try:
        cast = frame_cast(k)
        problem = result.problem.with_layer(cast.layer) if result.moving else result.problem
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ValidityWarning)
            solution = solve(problem.with_load(loads[k], body=body), method, certificate_tol=certificate_tol,
                             strict=False, **options)
    except DeaError as exc:
        return {**where, "error": f"the peak frame {k} was not re-cast at its solved pose: {one_line(str(exc))}"}
    solution, recast = recast_solution(solution, cast)
    if "error" in recast:
        return {**where, "error": f"frame {k}: {recast['error']}"}
    check = solution.validity["dropped_springs"]
    table.loc[row, "validity_dropped_springs"] = check.value
    if check.passed is False:
        failed = [n for n in str(table.loc[row, "validity_failed"]).split(";") if n]
        table.loc[row, "validity_failed"] = ";".join([*failed, check.name])
        table.loc[row, "valid"] = False
    return {**where, **recast}
