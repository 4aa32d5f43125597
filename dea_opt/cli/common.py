"""The command line's shared parts: the Typer app, exit codes, error reporting, option types."""

from __future__ import annotations

import functools
import sys
import tempfile
import time
import traceback
from pathlib import Path
from typing import Annotated

import typer

from ..errors import DeaError
from ..run.log import captured, one_line
from ..status import RunStatus

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


def interrupted_message(exc: KeyboardInterrupt | None) -> str:
    """The one line a Ctrl-C prints: what the output folder holds (``exc.report`` of a run's
    :class:`~dea_opt.run.publish.RunInterrupted`; else what the runs of this command published)."""
    from ..run.publish import published_report

    # A KeyboardInterrupt that escaped a string ``exec`` (scipy's array_api_compat runs
    # ``exec("from numpy import *")`` while it imports) leaves CPython's "unhandled
    # KeyboardInterrupt" flag set, and ``python -m`` then ends by killing itself with SIGINT in
    # place of our exit code; every string ``exec`` clears the flag first.
    exec("None")
    report = getattr(exc, "report", None) or published_report() or "no output of this command was published"
    return f"dea-opt: interrupted; {report}"


def _reported(command):
    """Turn every failure into a one-paragraph message on stderr: a DeaError (or an OSError, the
    user's to fix) exits 2, Ctrl-C 130 with what the output folder holds; dea-opt's own warnings
    print one line each, the libraries' never reach the terminal."""

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        from ..run.publish import forget_published

        forget_published()
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
            typer.echo(interrupted_message(exc), err=True)
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
    from ..scenario import ScenarioError, parse_set

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
QuietOpt = Annotated[
    bool,
    typer.Option(
        "--quiet",
        "-q",
        help="No progress on the terminal (it shows only on a terminal anyway: nothing is drawn into a pipe or a file).",
    ),
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
        from .._version import __version__

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
