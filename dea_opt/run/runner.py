"""Running a scenario: its method and options, the solve, and the outputs published together."""

from __future__ import annotations

import time
from pathlib import Path

from .log import LOG_NAME, captured
from .outcome import RunOutcome
from .path import run_path_outputs
from .static import run_static

__all__ = [
    "check_method",
    "picture_worker",
    "prepare_run",
    "publish_run",
    "report_ahead",
    "run_info",
    "run_scenario",
    "solve_options",
]


def solve_options(section, method: str, law) -> dict:
    """Formulation options from ``[solve]`` for ``method`` (only those it accepts).

    The formulation is ``method``, or under ``auto`` the one the registry falls back to for
    ``law`` (:func:`dea_opt.formulations.fallback_for`). ``[solve].tol`` sets the options one
    accuracy setting sets (:func:`~dea_opt.formulations.tolerance_options`), and each other
    key of ``[solve]`` that names one of its options (``solver``, ``form``; ``max_recasts`` for
    finite kinematics) is passed as is.
    """
    from .. import formulations

    if getattr(section, "kinematics", "small") == "finite":
        # finite kinematics: newton and nlp stand for the finite formulations, auto tries both
        if method == "auto":
            chain = ["finite", "finite_nlp"]
        else:
            chain = [formulations.resolve(method, None, "finite").name] if method in formulations.names() else []
        out: dict = {}
        for name in chain:
            if name in formulations.names() and formulations.takes(name, law, "finite"):
                out.update(
                    {
                        o.name: getattr(section, o.name)
                        for o in formulations.options(name)
                        if not o.tolerance
                        and o.name in ("form", "max_recasts")
                        and getattr(section, o.name) is not None
                    }
                )
                out.update(formulations.tolerance_options(name, section.tol))
        return out
    effective = method if method != "auto" else formulations.fallback_for(law)
    if effective is None:
        return {}
    options = {
        option.name: getattr(section, option.name)
        for option in formulations.options(effective)
        if not option.tolerance and getattr(section, option.name, None) is not None
    }
    return options | formulations.tolerance_options(effective, section.tol)


def check_method(method: str | None, default: str) -> str:
    """``method`` (or the scenario's ``default``), checked against the scenario's method names."""
    from ..scenario import check_method_name

    method = default if method is None else method.strip().lower()
    return check_method_name(method, "method (--method or [solve].method)")


def run_info(scenario, command: str, method: str | None = None) -> dict:
    """What a manifest records about the run of ``scenario``."""
    return {
        "command": command,
        "title": scenario.title,
        "scenario": scenario.source,
        "scenario_sha256": scenario.text_sha256,
        "overrides": scenario.overrides,
        **({"method": method} if method else {}),
    }


def run_scenario(
    scenario,
    output_dir=None,
    *,
    method: str | None = None,
    progress: bool = False,
    force: bool = False,
    stop_on_error: bool = False,
    background_pictures: bool = True,
) -> RunOutcome:
    """Solve a scenario and publish its outputs into one folder.

    Parameters
    ----------
    scenario : Scenario
    output_dir : str or Path, optional
        Default ``[output].directory`` (relative to the scenario file). It must be new,
        empty or hold an earlier dea-opt run (:func:`dea_opt.run.publish.check_output_folder`).
    method : str, optional
        Overrides ``[solve].method``.
    progress : bool
        Show the run's stages (reading meshes, casting springs, checking the inputs, solving,
        writing outputs) and a bar over a load path's frames with the time left, on stderr when
        it is a terminal (:mod:`dea_opt.progress`); nothing when it is not, or with False.
    force : bool
        Write into a folder that holds other files.
    stop_on_error : bool
        A load path stops at its first frame without a certified answer (a DeaError, and
        nothing published) instead of recording it and going on.
    background_pictures : bool
        Draw a load path's PNGs in a second process while the run solves and writes
        (:class:`~dea_opt.run.pictures.PictureWorker`): for a single run, which leaves a core idle.
        A sweep's cases run one per core and draw in their own process (Matplotlib imported
        once per worker, not once per case).

    Returns
    -------
    RunOutcome
        Its ``exit_code`` is the command line's.

    Raises
    ------
    DeaError
        Bad input (:class:`~dea_opt.errors.OutputFolderError` for a folder of someone
        else's; :class:`~dea_opt.errors.ImplausibleInputError` from the check before solving,
        :func:`prepare_run`), a load no spring can carry, a solver that fails outright. Nothing is
        published then, and the folder keeps what it held.
    dea_opt.run.publish.RunInterrupted
        Ctrl-C; its ``report`` says what the folder holds.
    """
    from ..progress import showing
    from ..scenario.joint_schema import JointScenario
    from .publish import RunInterrupted, check_output_folder, interrupted_report

    started = time.perf_counter()
    if isinstance(scenario, JointScenario):
        from .joint import run_joint_scenario

        return _run_joint(scenario, output_dir, method, force, stop_on_error, run_joint_scenario, started)
    method = check_method(method, scenario.solve.method)
    out = check_output_folder(scenario.output_dir(output_dir), force)
    try:
        with (
            showing(progress) as shown,
            captured() as messages,
            picture_worker(scenario, background_pictures) as pictures,
        ):
            problem, cast, data, suspicions = prepare_run(scenario)
            report_ahead(scenario)
            for line in suspicions:
                if shown is not None:
                    shown.note(f"dea-opt: warning: suspicious input: {line}")
            options = solve_options(scenario.solve, method, problem.law)

            def solve_and_write(folder):
                if scenario.load_path is None:
                    outcome = run_static(scenario, problem, method, options, folder, cast, suspicions)
                else:
                    outcome = run_path_outputs(
                        scenario,
                        problem,
                        method,
                        options,
                        folder,
                        progress,
                        stop=stop_on_error,
                        cast=cast,
                        pictures=pictures,
                        data=data,
                        suspicions=suspicions,
                    )
                outcome.suspicions = list(suspicions)
                return outcome

            outcome = publish_run(
                scenario,
                out,
                solve_and_write,
                messages,
                force=force,
                info=run_info(scenario, "run", method),
                started=started,
            )
    except RunInterrupted:
        raise
    except KeyboardInterrupt:  # before the publication began (casting) or after it ended (closing)
        raise RunInterrupted(interrupted_report(out)) from None
    return outcome


def prepare_run(scenario) -> tuple:
    """``(problem, cast, data, suspicions)``: a scenario read, its springs cast, its load path
    read and the check before solving made (:mod:`dea_opt.run.preflight`): the meshes' units
    right after they are read (before a cast that would take long in the wrong units), the rest
    once the springs exist. ``data`` is the :class:`~dea_opt.scenario.LoadPathData` (None for
    ``[load]``); ``suspicions`` the lines of what is plausible but suspicious.

    Raises
    ------
    ImplausibleInputError, LoadNotSupportedError
        What the check stops (``[solve] check_inputs = false`` turns it off).
    """
    from ..progress import stage
    from ..scenario import build_problem_cast, load_meshes, read_load_path
    from ..scenario.schema import MeshGeometry
    from .preflight import check_inputs, check_meshes

    meshes = None
    if isinstance(scenario.geometry, MeshGeometry):
        meshes = load_meshes(scenario.geometry)
        check_meshes(scenario, meshes)
    else:
        stage("building the springs")
    problem, cast = build_problem_cast(scenario, meshes=meshes)
    data = None
    if scenario.load_path is not None:
        stage("reading the load path")
        data = read_load_path(scenario.load_path)
    stage("checking the inputs")
    return problem, cast, data, check_inputs(scenario, problem, data)


def _run_joint(scenario, output_dir, method, force, stop_on_error, run_joint_scenario, started) -> RunOutcome:
    """A joint scenario (``[[bodies]]``): its method checked, solved and published like a two-body run."""
    from ..errors import InputError
    from ..joint import JOINT_METHODS
    from .publish import RunInterrupted, check_output_folder, interrupted_report

    method = scenario.solve.method if method is None else method.strip().lower()
    if method not in JOINT_METHODS:
        raise InputError(
            f"method (--method or [solve].method) must be one of {', '.join(JOINT_METHODS)} for a joint, got {method!r}"
        )
    out = check_output_folder(scenario.output_dir(output_dir), force)
    try:
        with captured() as messages:
            return publish_run(
                scenario,
                out,
                lambda folder: run_joint_scenario(scenario, folder, method, stop_on_error=stop_on_error),
                messages,
                force=force,
                info=run_info(scenario, "run", method),
                started=started,
            )
    except RunInterrupted:
        raise
    except KeyboardInterrupt:
        raise RunInterrupted(interrupted_report(out)) from None


def report_ahead(scenario) -> None:
    """Start making what the run's ``report.html`` embeds of Plotly (its script, gzipped: 0.2-0.3 s,
    made once per process) in a thread while the run solves, when the run writes a report: the
    compression releases the GIL, so it runs on the core the picture worker leaves idle then, not
    after the run's pictures. Whatever goes wrong there, the report makes it again and says so."""
    if "html" not in scenario.output.formats:
        return
    import threading

    def make() -> None:
        try:
            from ..report.page import plotly_script

            plotly_script()
        except Exception:  # noqa: BLE001 - the report calls it again, and raises there
            pass

    threading.Thread(target=make, name="dea-opt-report-ahead", daemon=True).start()


def picture_worker(scenario, background: bool = True):
    """A :class:`~dea_opt.run.pictures.PictureWorker` when the run draws a load path's pictures
    (it imports matplotlib while the run casts and solves) and ``background``, else a context
    that gives None (the pictures are drawn in the run's process)."""
    from contextlib import nullcontext

    if not background or scenario.load_path is None or "png" not in scenario.output.formats:
        return nullcontext(None)
    from .pictures import PictureWorker

    return PictureWorker()


def publish_run(
    scenario,
    out: Path,
    solve_and_write,
    messages,
    *,
    force: bool,
    info: dict,
    started: float | None = None,
    report_extra: dict | None = None,
) -> RunOutcome:
    """Run ``solve_and_write(folder) -> RunOutcome`` in the staged folder ``out`` and publish it.

    With ``html`` among ``[output] formats`` the run's ``report.html`` (:mod:`dea_opt.report`) is
    written last before the publication, once the outcome's warnings are known; ``started``
    (``time.perf_counter()`` when the run began) times the run in it, ``report_extra`` gives it
    more sections (the demo's comparison)."""
    from .publish import output_run

    started = time.perf_counter() if started is None else started
    with output_run(out, force=force, info=info) as publication:
        outcome = solve_and_write(publication.folder)
        outcome.allow_outside_validity = scenario.solve.allow_outside_validity
        messages.collect()
        _drop_repeats(outcome, messages, scenario.notes)
        if "html" in scenario.output.formats:
            from ..report import write_run_report

            outcome.files["report"] = write_run_report(
                publication.folder,
                outcome,
                scenario,
                command=info.get("command", "run"),
                elapsed=time.perf_counter() - started,
                extra=report_extra,
            )
        log = messages.log_text(f"dea-opt {info.get('command', 'run')} of {scenario.source or scenario.title}")
        if log:
            from ..files.atomic import write_data

            outcome.files["log"] = write_data(publication.folder / LOG_NAME, log)
        failures = {"failures": {str(k): int(n) for k, n in outcome.failures.items()}} if outcome.failures else {}
        outcome.manifest = publication.publish(
            status=outcome.status, exit_code=outcome.exit_code, success=outcome.success, valid=outcome.valid, **failures
        )
        outcome.folder = publication.folder
    return outcome


def _drop_repeats(outcome: RunOutcome, messages, notes=()) -> None:
    """The scenario's notes, the outcome's own notes (a re-cast that failed) and the run's own
    warnings, but for the validity warnings: the validity lines of the outcome state them, with
    every check."""
    assessed = outcome.valid is not None
    outcome.warnings = [
        *(f"suspicious input: {line}" for line in outcome.suspicions),
        *notes,
        *outcome.warnings,
        *(w for w in messages.own if not (assessed and messages.categories.get(w) == "ValidityWarning")),
    ]
