"""``dea-opt compare`` and ``dea-opt calibrate``: the commands that analyse a scenario rather than run it."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer

from .common import (
    EXIT_OK,
    EXIT_UNCERTIFIED,
    ForceOpt,
    QuietOpt,
    RunStatus,
    ScenarioArg,
    SetOpt,
    _overrides,
    _reported,
    _split,
    _warn,
    app,
    captured,
)


@app.command()
@_reported
def compare(
    scenario: ScenarioArg,
    methods: Annotated[
        str | None,
        typer.Option(
            help="Comma-separated registered formulations (default: "
            "[solve].methods, else every one that solves the problem).",
            show_default=False,
        ),
    ] = None,
    solvers: Annotated[
        str | None,
        typer.Option(
            help="QP solvers for qp, e.g. CLARABEL,OSQP,SCS,PIQP (default: [solve].solvers, cut to those installed).",
            show_default=False,
        ),
    ] = None,
    accuracy: Annotated[
        str | None,
        typer.Option(
            help="low | default | high, or several comma-separated (default: [solve].accuracy).", show_default=False
        ),
    ] = None,
    repeat: Annotated[
        int | None, typer.Option(help="Runs per combination (default: [solve].repeat).", show_default=False)
    ] = None,
    frame: Annotated[
        int | None,
        typer.Option(help="For a load path: the frame to compare on (default: the largest force).", show_default=False),
    ] = None,
    nlp_forms: Annotated[
        str, typer.Option(help="NLP forms for nlp, comma-separated: constrained,reduced.")
    ] = "constrained",
    output: Annotated[
        Path | None,
        typer.Option(
            "--output",
            "-o",
            help="Output folder (default: <the scenario's [output].directory>/compare).",
            show_default=False,
        ),
    ] = None,
    set_: SetOpt = None,
    force: ForceOpt = False,
    quiet: QuietOpt = False,
):
    """Solve one problem by every method x solver x accuracy and tabulate the results.

    A row is a success only if the solver claims success, dea-opt's certificate passes at
    the accuracy's tolerance, and the answer agrees with Newton to that tolerance. Writes
    compare.csv and compare_summary.csv (and manifest.json) into <output>/compare.
    """
    from ..progress import showing

    with showing(not quiet):
        _compare(scenario, methods, solvers, accuracy, repeat, frame, nlp_forms, output, set_, force, quiet)


def _compare(scenario, methods, solvers, accuracy, repeat, frame, nlp_forms, output, set_, force, quiet) -> None:
    """The body of :func:`compare`, inside its progress."""
    from ..run import run_info
    from ..run.publish import check_output_folder, output_run
    from ..scenario import load_scenario
    from ..study import run_study

    loaded = load_scenario(scenario, _overrides(set_))
    folder = check_output_folder(output if output is not None else loaded.output_dir() / "compare", force)
    from ..scenario.joint_schema import JointScenario

    if isinstance(loaded, JointScenario):  # a whole joint: dea_opt/run/joint_compare.py
        from ..run.joint_compare import compare_joint_scenario

        return compare_joint_scenario(loaded, folder, _split(methods), force)
    problem, suspicions = _compare_problem(loaded, frame)
    _warn(f"suspicious input: {line}" for line in suspicions)
    section = loaded.solve
    with captured() as messages, output_run(folder, force=force, info=run_info(loaded, "compare")) as publication:
        # The default list is cut to the installed solvers by run_study; a list given is checked.
        result = run_study(
            problem,
            methods=_split(methods) or section.methods,
            what="--methods" if _split(methods) else "solve.methods" if section.methods else "methods",
            solvers=_split(solvers) or section.solvers,
            accuracy=_split(accuracy) or section.accuracy,
            repeat=section.repeat if repeat is None else repeat,
            nlp_forms=_split(nlp_forms),
            progress=not quiet,
        )
        files = result.to_csv(publication.folder)
        messages.collect()
        log = messages.log_text(f"dea-opt compare of {loaded.source or loaded.title}")
        if log:
            from ..files.atomic import write_data
            from ..run.log import LOG_NAME

            files["log"] = write_data(publication.folder / LOG_NAME, log)
        publication.publish(status=RunStatus.OK)
    _warn(messages.own)
    typer.echo(result.format_table())
    typer.echo("")
    typer.echo(
        "Summary (success needs the certificate; time: shifted geometric mean, shift 10 ms, failures "
        "count as 10 s; relative to the fastest):"
    )
    typer.echo(result.format_summary())
    for note in result.notes:
        typer.echo(f"(note: {note})")
    for note in result.skipped:
        typer.echo(f"(skipped: {note})")
    for name, path in files.items():
        typer.echo(f"  {name:8s} {path}")


def _compare_problem(loaded, frame):
    """``(problem, suspicions)``: the problem compared (a load path's frame ``frame``, default the
    largest force), built and checked as a run's is (:func:`dea_opt.run.prepare_run`)."""
    from ..errors import InputError
    from ..run import prepare_run

    problem, _, data, suspicions = prepare_run(loaded)
    if loaded.load_path is None:
        if frame is not None:
            raise InputError("--frame applies to scenarios with a [load_path] only")
        return problem, suspicions
    if data.poses is not None:
        raise InputError(
            "compare on a load path with poses is not supported; compare one pose as a static [load] scenario"
        )
    import numpy as np

    k = int(np.argmax(np.linalg.norm(data.loads[:, :3], axis=1))) if frame is None else frame
    if not 0 <= k < len(data):
        raise InputError(f"--frame must be in 0..{len(data) - 1}, got {frame}")
    return problem.with_load(data.load_objects()[k], body=data.body), suspicions


@app.command()
@_reported
def calibrate(
    scenario: ScenarioArg,
    data: Annotated[
        Path,
        typer.Option(
            "--data",
            help="Pressure map CSV with columns x, y, z, p (mm, MPa), in the springs' frame.",
            show_default=False,
        ),
    ],
    parameters: Annotated[
        str | None,
        typer.Option(
            help="Parameters to fit, e.g. H,beta (default: the law's; also thickness_scale, Fx..Mz).",
            show_default=False,
        ),
    ] = None,
    film: Annotated[
        str | None,
        typer.Option(
            help="The film's range: LLLW, LLW, LW, MS, HS or LOWER,UPPER in MPa (readings at its limits are censored).",
            show_default=False,
        ),
    ] = None,
    noise: Annotated[
        float | None,
        typer.Option(
            help="Relative noise of a reading (0.05: 5 %); not given: the standard errors come from the residuals' scatter.",
            show_default=False,
        ),
    ] = None,
    correlation_length: Annotated[
        float | None,
        typer.Option(
            help="Readings' noise correlated over this distance (mm), e.g. a film's grain; not given: independent.",
            show_default=False,
        ),
    ] = None,
    max_distance: Annotated[
        float | None, typer.Option(help="Drop points farther than this from every spring (mm).", show_default=False)
    ] = None,
    output: Annotated[
        Path | None,
        typer.Option(
            "--output",
            "-o",
            help="Output folder (default: <the scenario's [output].directory>/calibration).",
            show_default=False,
        ),
    ] = None,
    set_: SetOpt = None,
    force: ForceOpt = False,
    quiet: QuietOpt = False,
):
    """Fit law parameters to a measured pressure map (film or sensor) by least squares.

    The scenario's law values are the start. Writes calibration.json (fitted values, standard
    errors, correlation), residuals.csv (one row per matched point), calibration.png (measured
    vs predicted, residual map) and manifest.json into <output>/calibration. Exit code 1 when the
    fit did not converge.
    """
    from ..errors import InputError
    from ..run import run_info
    from ..run.publish import check_output_folder, output_run
    from ..scenario import load_scenario
    from ..sensitivity.scenario_fit import calibrate_scenario, check_scenario

    loaded = load_scenario(scenario, _overrides(set_))
    check_scenario(loaded)  # before the output folder is taken
    bounds = _split(film)
    try:
        film_value = (float(bounds[0]), float(bounds[1])) if bounds and len(bounds) == 2 else film
    except ValueError:
        raise InputError(f"--film must be a film's name or LOWER,UPPER in MPa, got {film!r}") from None
    folder = check_output_folder(output if output is not None else loaded.output_dir() / "calibration", force)
    info = {**run_info(loaded, "calibrate"), "data": str(data)}
    with captured() as messages, output_run(folder, force=force, info=info) as publication:
        fit, files = calibrate_scenario(
            loaded,
            data,
            publication.folder,
            parameters=_split(parameters),
            film=film_value,
            noise=noise,
            max_distance=max_distance,
            correlation_length=correlation_length,
            progress=not quiet,
        )
        messages.collect()
        publication.publish(
            status=RunStatus.OK if fit.success else RunStatus.NOT_CONVERGED,
            exit_code=EXIT_OK if fit.success else RunStatus.NOT_CONVERGED.exit_code,
        )
    _warn(messages.own)
    typer.echo(f"{'parameter':>16s} {'start':>12s} {'fitted':>12s} {'std error':>12s}")
    for name in fit.parameters:
        se = fit.standard_errors[name]
        shown = f"{se:12.3g}" if math.isfinite(se) else f"{'undefined':>12s}"
        typer.echo(f"{name:>16s} {fit.start[name]:12.6g} {fit.values[name]:12.6g} {shown}")
    typer.echo(
        "standard errors: from the stated noise"
        if fit.errors == "stated"
        else f"standard errors: the noise estimated from the residuals' scatter ({fit.degrees_of_freedom:.4g} degrees of freedom)"
    )
    for note in fit.notes:
        typer.echo(f"note: {note}")
    if len(fit.parameters) > 1:
        typer.echo(
            "correlation: "
            + "; ".join(
                f"{a}-{b} {fit.correlation[i, j]:+.3f}"
                for i, a in enumerate(fit.parameters)
                for j, b in enumerate(fit.parameters)
                if j > i
            )
        )
    typer.echo(f"{int(fit.residuals.size)} points, cost {fit.cost:.6g}, {fit.nfev} solves: {fit.message}")
    for name, path in files.items():
        typer.echo(f"  {name:9s} {path}")
    if not fit.success:
        raise typer.Exit(EXIT_UNCERTIFIED)
