"""The ``dea-opt`` command: run, compare, sweep, demo, calibrate, import-osim, init, schema, version (and ``--version``).

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

import json
import sys
from pathlib import Path
from typing import Annotated

import typer

from .common import (
    EXIT_ERROR,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_OUTSIDE_VALIDITY,
    EXIT_UNCERTIFIED,
    ForceOpt,
    MethodOpt,
    OutputOpt,
    ScenarioArg,
    SetOpt,
    _overrides,
    _report_outcome,
    _reported,
    _warn,
    app,
)

__all__ = [
    "EXIT_ERROR",
    "EXIT_INTERRUPTED",
    "EXIT_OK",
    "EXIT_OUTSIDE_VALIDITY",
    "EXIT_UNCERTIFIED",
    "app",
    "entry",
    "main",
]


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
    exposure.png, peak.png and summary.json; either writes report.html (the run on one page,
    open it in a browser); then manifest.json, last. The folder must be new, empty
    or hold an earlier dea-opt run (--force: any folder). Exit 0 ok, 1 certificate failed,
    3 certified but outside validity ([solve] allow_outside_validity = true: 0).
    """
    from ..run import run_scenario
    from ..scenario import check_kinematics_method, load_scenario

    loaded = load_scenario(scenario, _overrides(set_))
    named = method.strip().lower() if method else None
    check_kinematics_method(loaded, named, "--method" if named else None)
    outcome = run_scenario(loaded, output, method=method, progress=not quiet, force=force, stop_on_error=stop_on_error)
    _report_outcome(outcome, quiet)


# compare and calibrate, then import-osim and init, registered on the app in the order the help lists them
from . import analyses, init, osim  # noqa: E402, F401


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
    cases/<case id>/; report.html, written at the end, plots any output against any swept
    value and sorts the cases by any column. A rerun skips the cases whose row was computed from the same scenario,
    input files, overrides and dea-opt version, and recomputes the others, saying why.
    Sweeps may share a folder at once: no case is computed twice and no row is lost. On a
    terminal each finished case is printed with a progress bar; Dask's and Python's
    messages go to sweep.log. A case's status is ok, outside_validity, failed or error;
    exit 1 when a case failed or hit an error, else 3 when one is outside validity; Ctrl-C
    exits 130 saying how many cases are finished. Needs: pip install dea-opt[distributed].
    """
    from collections import Counter

    from tqdm.auto import tqdm

    from ..sweep import run_sweep

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
        f"{result.results_path}" + (f", report: {result.report_path}" if result.report_path else "")
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
    cycle.png, exposure.png, peak.png, exposure.vtu, summary.json, comparison.csv,
    report.html (open it in a browser) and, last, manifest.json. The folder must be
    new, empty or hold an earlier dea-opt run (--force: any folder).
    """
    from ..run.demo import run_demo

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
def schema(json_: Annotated[bool, typer.Option("--json", help="Print the JSON Schema instead.")] = False):
    """Print the documented scenario schema (every table, key, default and unit)."""
    from ..scenario import Scenario, schema_text

    if json_:
        typer.echo(json.dumps(Scenario.model_json_schema(), indent=2))
    else:
        typer.echo(schema_text(), nl=False)


@app.command()
def version():
    """Print the dea-opt version and those of its solvers."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as installed

    from .._version import __version__

    typer.echo(f"dea-opt {__version__}")
    for package in ("numpy", "scipy", "cvxpy", "clarabel", "casadi", "osqp", "scs", "piqp", "dask", "distributed"):
        try:
            typer.echo(f"  {package} {installed(package)}")
        except PackageNotFoundError:
            typer.echo(f"  {package} (not installed)")


def main(argv=None) -> int:
    """Console-script entry point (``dea-opt``)."""
    from ..run.publish import forget_published

    forget_published()  # a new command: no run of it published yet (main may run again in one process)
    try:
        app(args=argv, prog_name="dea-opt", standalone_mode=True)
    except SystemExit as exc:
        if _interrupted_outside_a_command(exc):
            from .common import interrupted_message

            typer.echo(interrupted_message(None), err=True)
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else EXIT_ERROR)
    return 0


def _interrupted_outside_a_command(exc: SystemExit) -> bool:
    """Ctrl-C while typer parsed the command line or imported a command (typer turns it into a
    silent exit 130); inside a command, :func:`~dea_opt.cli.common._reported` said what happened."""
    exit_ = exc.__context__
    return exc.code == EXIT_INTERRUPTED and exit_ is not None and isinstance(exit_.__cause__, KeyboardInterrupt)


def entry() -> None:
    """The process's entry point (the ``dea-opt`` script, ``python -m dea_opt.cli``): exit with
    :func:`main`'s code. A Ctrl-C after the command ended (while the interpreter shuts down)
    is ignored: the command's outcome and its exit code stand, published outputs included.

    The command has written, fsynced and published everything by then, so the process leaves
    without the interpreter's teardown (:func:`_leave`): freeing every module and object of numpy,
    SciPy, pandas, trimesh and matplotlib took 0.4-0.9 s of a run on the knee, after its work."""
    import signal

    code = main()
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _leave(code)


def _leave(code: int) -> None:
    """Exit with ``code`` once what Python runs at exit has run, in its order (the threads that are
    not daemons joined and the executors' exit calls, then the ``atexit`` handlers: logging
    flushed, temporary folders removed) and the standard streams are flushed, without the teardown
    that follows them (``os._exit``); a stream that cannot be flushed exits as ``sys.exit`` would
    (its error said, the code kept)."""
    import atexit
    import os
    import threading

    shutdown = getattr(threading, "_shutdown", None)  # what the interpreter's own exit calls first
    if shutdown is not None:
        shutdown()
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            if stream is not None:
                stream.flush()
        except (OSError, ValueError):  # a closed pipe: the interpreter's own exit says so
            sys.exit(code)
    os._exit(code)


if __name__ == "__main__":  # pragma: no cover
    entry()
