"""The ``dea-opt`` command: run, compare, sweep, demo, calibrate, schema, version (and ``--version``).

Exit codes:

- 0: done; every answer certified and inside its model's validity;
- 1: outputs written, but an answer failed its certificate (a load path: any frame);
- 2: bad input or an error dea-opt reports: one paragraph ``dea-opt: error: ...`` on stderr,
  no traceback (an unexpected failure says so and leaves its traceback in a log file);
- 3: outputs written, every answer certified, but one lies outside its model's validity
  (0 with ``[solve] allow_outside_validity = true``); the reason is on stderr;
- 130: interrupted (Ctrl-C); the message says what the output folder holds.

dea-opt's own warnings print as ``dea-opt: warning: ...`` (one line each); the libraries'
warnings and log records go to ``dea-opt.log`` in the output folder.
"""

from __future__ import annotations

import functools
import json
import sys
import tempfile
import time
import traceback
from pathlib import Path
from typing import Annotated

import typer

from .errors import DeaError
from .run.log import captured, one_line
from .status import RunStatus

app = typer.Typer(
    name="dea-opt",
    help="Discrete element analysis of cartilage contact: scenario files in, certified results out.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    # Plain help text: "[solve]" and "dea-opt[distributed]" are TOML and pip, not markup.
    rich_markup_mode=None,
)

EXIT_OK = RunStatus.OK.exit_code  # 0
EXIT_UNCERTIFIED = RunStatus.CERTIFICATE_FAILED.exit_code  # 1
EXIT_ERROR = RunStatus.ERROR.exit_code  # 2
EXIT_OUTSIDE_VALIDITY = RunStatus.OUTSIDE_VALIDITY.exit_code  # 3
EXIT_INTERRUPTED = 130


def _fail(message: str, code: int = EXIT_ERROR):
    # One paragraph: dea-opt's messages may hold newlines from nested errors.
    typer.echo(f"dea-opt: error: {one_line(message)}", err=True)
    raise typer.Exit(code)


def _warn(messages) -> None:
    for message in messages:
        typer.echo(f"dea-opt: warning: {one_line(message)}", err=True)


def _crash_log(exc: BaseException) -> Path | None:
    """Write the traceback of an unexpected failure to a file of its own; its path, or None."""
    try:
        with tempfile.NamedTemporaryFile(
            "w",
            prefix=f"dea-opt-crash-{time.strftime('%Y%m%d-%H%M%S')}-",
            suffix=".log",
            delete=False,
            encoding="utf-8",
        ) as handle:
            handle.write(f"dea-opt {' '.join(sys.argv[1:])}\n")
            handle.write("".join(traceback.format_exception(exc)))
            return Path(handle.name)
    except OSError:
        return None


def _reported(command):
    """Turn every failure into a one-paragraph message on stderr: a DeaError (or an OSError, the
    user's to fix) exits 2, Ctrl-C 130 with what the output folder holds; dea-opt's own warnings
    print one line each, the libraries' never reach the terminal."""

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        try:
            with captured() as messages:
                try:
                    return command(*args, **kwargs)
                finally:
                    # A run logs the libraries' messages into its folder; any left here (before a run
                    # starts, or in a command without a folder) become one line each.
                    messages.collect()
                    _warn(messages.own + [f"from a library: {line}" for line in messages.log])
        except typer.Exit:
            raise
        except DeaError as exc:
            _fail(exc)
        except OSError as exc:  # a full disk, a folder we may not write: the user's to fix, not a bug
            where = f" ({exc.filename})" if exc.filename else ""
            _fail(f"{exc.strerror or exc}{where}")
        except KeyboardInterrupt as exc:
            report = getattr(exc, "report", None) or "no output of this command was published"
            typer.echo(f"dea-opt: interrupted; {report}", err=True)
            raise typer.Exit(EXIT_INTERRUPTED) from None
        except RecursionError:
            _fail("the input nests too deeply to be read (RecursionError); simplify it")
        except Exception as exc:  # noqa: BLE001 - a bug of dea-opt's: say so, keep the traceback off the terminal
            log = _crash_log(exc)
            where = f"; the traceback is in {log}" if log else ""
            _fail(
                f"unexpected internal error ({type(exc).__name__}: {exc}): this is a bug in dea-opt, please report "
                f"it with the scenario{where}"
            )

    return wrapper


def _split(text: str | None) -> list[str] | None:
    if text is None:
        return None
    return [item.strip() for item in text.split(",") if item.strip()]


def _overrides(sets: list[str] | None) -> dict:
    from .scenario import ScenarioError, parse_set

    overrides = {}
    for text in sets or []:
        key, values = parse_set(text)
        if len(values) != 1:
            raise ScenarioError(
                f"--set {key} takes one value here (several values are for dea-opt sweep), got {len(values)}"
            )
        overrides[key] = values[0]
    return overrides


def _report_outcome(outcome, quiet: bool = False) -> None:
    """Print a run's outcome and exit with its status (0, 1 or 3)."""
    _warn(outcome.warnings)
    if not quiet:
        typer.echo(outcome.message)
        for line in outcome.validity + outcome.regions:
            typer.echo(line)
        folder = outcome.folder
        typer.echo(f"outputs in {folder} (run {outcome.manifest['run_id']}, listed in manifest.json):")
        for name, path in outcome.files.items():
            shown = Path(path).relative_to(folder) if Path(path).is_relative_to(folder) else path
            typer.echo(f"  {name:13s} {shown}")
    if outcome.status.failed:
        typer.echo(f"dea-opt: {one_line(outcome.message)}", err=True)
    elif outcome.status is RunStatus.OUTSIDE_VALIDITY:
        allowed = " (allowed by [solve] allow_outside_validity)" if outcome.allow_outside_validity else ""
        typer.echo(f"dea-opt: solved outside validity{allowed}: {one_line('; '.join(outcome.reasons))}", err=True)
    if outcome.exit_code:
        raise typer.Exit(outcome.exit_code)


ScenarioArg = Annotated[Path, typer.Argument(help="The scenario TOML file (see: dea-opt schema).", show_default=False)]
OutputOpt = Annotated[
    Path | None,
    typer.Option(
        "--output", "-o", help="Output folder (default: the scenario's [output].directory).", show_default=False
    ),
]
MethodOpt = Annotated[
    str | None,
    typer.Option(
        "--method",
        "-m",
        help="auto, or a registered formulation (default: the scenario's [solve].method; dea-opt schema lists them).",
        show_default=False,
    ),
]
SetOpt = Annotated[
    list[str] | None,
    typer.Option("--set", help="Override a scenario value, e.g. --set law.H=0.45 (repeatable).", show_default=False),
]
ForceOpt = Annotated[
    bool,
    typer.Option(
        "--force",
        help="Write into the output folder even if it holds files dea-opt "
        "did not write (files named like the outputs are replaced).",
    ),
]


def _version_callback(value: bool) -> None:
    if value:
        from ._version import __version__

        typer.echo(f"dea-opt {__version__}")
        raise typer.Exit()


@app.callback()
def _main(
    version: Annotated[
        bool, typer.Option("--version", callback=_version_callback, is_eager=True, help="Print the version and exit.")
    ] = False,
) -> None:
    """Discrete element analysis of cartilage contact: scenario files in, certified results out.

    Exit codes: 0 ok; 1 an answer failed its certificate; 2 bad input (one paragraph on
    stderr); 3 certified but outside the model's validity (the reason on stderr); 130
    interrupted.
    """


@app.command()
@_reported
def run(
    scenario: ScenarioArg,
    output: OutputOpt = None,
    method: MethodOpt = None,
    set_: SetOpt = None,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Print nothing but errors and warnings.")] = False,
    force: ForceOpt = False,
    stop_on_error: Annotated[
        bool,
        typer.Option(
            "--stop-on-error",
            help="A load path stops at its first frame "
            "without a certified answer (exit 2, nothing published) instead "
            "of recording it and going on.",
        ),
    ] = False,
):
    """Solve a scenario (one load or a load path) and publish its outputs into one folder.

    A static load writes contact.vtu, contact.csv, contact.json and contact.png; a load
    path writes frames.csv, series.pvd (+ series_frames/), exposure.vtu, cycle.png,
    exposure.png and summary.json; then manifest.json, last. The folder must be new, empty
    or hold an earlier dea-opt run (--force: any folder). Exit 0 ok, 1 certificate failed,
    3 certified but outside validity ([solve] allow_outside_validity = true: 0).
    """
    from .run import run_scenario
    from .scenario import load_scenario

    loaded = load_scenario(scenario, _overrides(set_))
    outcome = run_scenario(loaded, output, method=method, progress=not quiet, force=force, stop_on_error=stop_on_error)
    _report_outcome(outcome, quiet)


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
):
    """Solve one problem by every method x solver x accuracy and tabulate the results.

    A row is a success only if the solver claims success, dea-opt's certificate passes at
    the accuracy's tolerance, and the answer agrees with Newton to that tolerance. Writes
    compare.csv and compare_summary.csv (and manifest.json) into <output>/compare.
    """
    from .io.publish import check_output_folder, output_run
    from .run import run_info
    from .scenario import load_scenario
    from .study import run_study

    loaded = load_scenario(scenario, _overrides(set_))
    folder = check_output_folder(output if output is not None else loaded.output_dir() / "compare", force)
    problem = _compare_problem(loaded, frame)
    section = loaded.solve
    with captured() as messages, output_run(folder, force=force, info=run_info(loaded, "compare")) as publication:
        # The default list is cut to the installed solvers by run_study; a list given is checked.
        result = run_study(
            problem,
            methods=_split(methods) or section.methods,
            solvers=_split(solvers) or section.solvers,
            accuracy=_split(accuracy) or section.accuracy,
            repeat=section.repeat if repeat is None else repeat,
            nlp_forms=_split(nlp_forms),
            progress=True,
        )
        files = result.to_csv(publication.folder)
        messages.collect()
        log = messages.log_text(f"dea-opt compare of {loaded.source or loaded.title}")
        if log:
            from .io.atomic import write_data
            from .run.log import LOG_NAME

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
    for note in result.skipped:
        typer.echo(f"(skipped: {note})")
    for name, path in files.items():
        typer.echo(f"  {name:8s} {path}")


def _compare_problem(loaded, frame):
    from .errors import InputError
    from .scenario import build_problem, read_load_path

    problem = build_problem(loaded)
    if loaded.load_path is None:
        if frame is not None:
            raise InputError("--frame applies to scenarios with a [load_path] only")
        return problem
    data = read_load_path(loaded.load_path)
    if data.poses is not None:
        raise InputError(
            "compare on a load path with poses is not supported; compare one pose as a static [load] scenario"
        )
    import numpy as np

    k = int(np.argmax(np.linalg.norm(data.loads[:, :3], axis=1))) if frame is None else frame
    if not 0 <= k < len(data):
        raise InputError(f"--frame must be in 0..{len(data) - 1}, got {frame}")
    return problem.with_load(data.load_objects()[k], body=data.body)


@app.command()
@_reported
def sweep(
    scenario: ScenarioArg,
    set_: Annotated[
        list[str],
        typer.Option(
            "--set",
            help="KEY=V1,V2,... e.g. --set law.H=0.3,0.45,0.6 (repeatable; the cases are the Cartesian product).",
            show_default=False,
        ),
    ],
    scheduler: Annotated[
        str | None,
        typer.Option(
            help="Dask scheduler address (default: a LocalCluster); 'synchronous' runs here, one case at a time.",
            show_default=False,
        ),
    ] = None,
    workers: Annotated[int, typer.Option(help="Worker processes of the LocalCluster.")] = 2,
    output: Annotated[
        Path | None,
        typer.Option(
            "--output",
            "-o",
            help="Folder of sweep.csv, sweep.jsonl, sweep.log and cases/ (default: <scenario output>/sweep).",
            show_default=False,
        ),
    ] = None,
    method: MethodOpt = None,
    retry_failed: Annotated[
        bool, typer.Option(help="Recompute the cases recorded as error or failed (their rows are replaced).")
    ] = False,
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="Print nothing but the final summary.")] = False,
    outputs: Annotated[
        str | None,
        typer.Option(
            help="The files each case writes, comma-separated: csv, json, "
            "vtk, png, or none (default: the scenario's [output].formats).",
            show_default=False,
        ),
    ] = None,
):
    """Run the Cartesian product of --set values, each case a Dask task.

    Each finished case is appended to the journal sweep.jsonl; sweep.csv (one row per case)
    is rewritten from it as the sweep goes and at the end; each case writes its outputs into
    cases/<case id>/. A rerun skips the cases whose row was computed from the same scenario,
    input files, overrides and dea-opt version, and recomputes the others, saying why.
    Sweeps may share a folder at once: no case is computed twice and no row is lost. On a
    terminal each finished case is printed with a progress bar; Dask's and Python's
    messages go to sweep.log. A case's status is ok, outside_validity, failed or error;
    exit 1 when a case failed or hit an error, else 3 when one is outside validity.
    Needs: pip install dea-opt[distributed].
    """
    from collections import Counter

    from tqdm.auto import tqdm

    from .sweep import run_sweep

    live = not quiet and sys.stdout.isatty()

    def report(line: str) -> None:
        tqdm.write(line, file=sys.stdout)

    result = run_sweep(
        scenario,
        set_,
        output,
        scheduler=scheduler,
        workers=workers,
        method=method,
        retry_failed=retry_failed,
        progress=live,
        on_report=report if live else None,
        outputs=outputs,
    )
    adopted = f", {len(result.adopted)} finished by another sweep meanwhile" if result.adopted else ""
    typer.echo(
        f"{len(result.ran)} case(s) run, {len(result.skipped)} already finished{adopted}; results: "
        f"{result.results_path}"
    )
    for reason, count in Counter(result.recomputed.values()).items():
        typer.echo(f"  recomputed {count} case(s): {reason}")
    if result.failed:
        typer.echo(
            f"dea-opt: {len(result.failed)} case(s) did not finish cleanly: {', '.join(result.failed)} "
            f"(see the status and message columns of {result.results_path})",
            err=True,
        )
    if result.outside_validity:
        typer.echo(
            f"dea-opt: {len(result.outside_validity)} case(s) solved outside validity: "
            f"{', '.join(result.outside_validity)} (see the validity_failed column of {result.results_path})",
            err=True,
        )
    if result.exit_code:
        raise typer.Exit(result.exit_code)


@app.command()
@_reported
def demo(
    output: Annotated[
        Path | None, typer.Option("--output", "-o", help="Output folder.", show_default="./dea-opt-demo")
    ] = None,
    frames: Annotated[
        int | None, typer.Option(help="Resample the 101-frame gait cycle to N frames.", show_default=False, min=2)
    ] = None,
    coarse: Annotated[bool, typer.Option(help="A coarse socket and 11 frames: a few seconds.")] = False,
    method: MethodOpt = None,
    compare_: Annotated[
        bool, typer.Option("--compare/--no-compare", help="Solve and print the gait-peak comparison table first.")
    ] = True,
    force: ForceOpt = False,
):
    """The embedded default: a hip under a synthetic 101-frame walking cycle.

    First one gait-peak frame (2.4 kN tilted 20 degrees) by Newton, QP and NLP with the
    linear and Ateshian laws, as a table; then the whole cycle, warm-started frame by
    frame, with the frames' validity and the share of each region of the socket (superior,
    anterior, posterior) on the terminal, written to ./dea-opt-demo/: frames.csv, series.pvd,
    cycle.png, exposure.png,
    exposure.vtu, summary.json, comparison.csv and, last, manifest.json. The folder must be
    new, empty or hold an earlier dea-opt run (--force: any folder).
    """
    from .run.demo import run_demo

    outcome = run_demo(
        output,
        frames=frames,
        coarse=coarse,
        method=method,
        compare=compare_,
        progress=True,
        echo=typer.echo,
        force=force,
    )
    _warn(outcome.warnings)
    if outcome.exit_code:
        raise typer.Exit(outcome.exit_code)


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
    noise: Annotated[float, typer.Option(help="Relative noise of a reading.")] = 0.05,
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
):
    """Fit law parameters to a measured pressure map (film or sensor) by least squares.

    The scenario's law values are the start. Writes calibration.json (fitted values, standard
    errors, correlation), residuals.csv (one row per matched point), calibration.png (measured
    vs predicted, residual map) and manifest.json into <output>/calibration. Exit code 1 when the
    fit did not converge.
    """
    from .errors import InputError
    from .io.publish import check_output_folder, output_run
    from .run import run_info
    from .scenario import load_scenario
    from .sensitivity.calibrate import calibrate_scenario

    loaded = load_scenario(scenario, _overrides(set_))
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
        )
        messages.collect()
        publication.publish(
            status=RunStatus.OK if fit.success else RunStatus.NOT_CONVERGED,
            exit_code=EXIT_OK if fit.success else RunStatus.NOT_CONVERGED.exit_code,
        )
    _warn(messages.own)
    typer.echo(f"{'parameter':>16s} {'start':>12s} {'fitted':>12s} {'std error':>12s}")
    for name in fit.parameters:
        typer.echo(f"{name:>16s} {fit.start[name]:12.6g} {fit.values[name]:12.6g} {fit.standard_errors[name]:12.3g}")
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


@app.command()
@_reported
def schema(json_: Annotated[bool, typer.Option("--json", help="Print the JSON Schema instead.")] = False):
    """Print the documented scenario schema (every table, key, default and unit)."""
    from .scenario import Scenario, schema_text

    if json_:
        typer.echo(json.dumps(Scenario.model_json_schema(), indent=2))
    else:
        typer.echo(schema_text(), nl=False)


@app.command()
def version():
    """Print the dea-opt version and those of its solvers."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as installed

    from ._version import __version__

    typer.echo(f"dea-opt {__version__}")
    for package in ("numpy", "scipy", "cvxpy", "clarabel", "casadi", "osqp", "scs", "piqp", "dask", "distributed"):
        try:
            typer.echo(f"  {package} {installed(package)}")
        except PackageNotFoundError:
            typer.echo(f"  {package} (not installed)")


def main(argv=None) -> int:
    """Console-script entry point (``dea-opt``)."""
    try:
        app(args=argv, prog_name="dea-opt", standalone_mode=True)
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else EXIT_ERROR)
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
