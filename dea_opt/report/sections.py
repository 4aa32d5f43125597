"""Sections every report has: the verdict, the validity checks, the certificate, the inputs and their
hashes, the timings, the software and the run's files."""

from __future__ import annotations

import functools
import platform
import sys
import time
from pathlib import Path

from .page import Page, Raw, escape, table

__all__ = [
    "SOFTWARE",
    "certificate_section",
    "checks_table",
    "files_section",
    "inputs_section",
    "software_section",
    "verdict_banner",
]

#: The packages whose versions a report lists (those that shape a result or its files).
SOFTWARE = (
    "dea-opt",
    "numpy",
    "scipy",
    "cvxpy",
    "clarabel",
    "casadi",
    "trimesh",
    "embreex",
    "meshio",
    "pandas",
    "matplotlib",
    "plotly",
    "dask",
)


def verdict_banner(page: Page, status, valid, message: str, reasons, warnings=()) -> None:
    """The verdict first: ``VALID``, ``OUTSIDE VALIDITY`` (with the reasons) or ``NO CERTIFIED
    ANSWER``; then the run's one-line message and dea-opt's warnings."""
    failed = getattr(status, "failed", False)
    if failed:
        css, head, text = "bad", "NO CERTIFIED ANSWER", message
    elif valid is False:
        css, head, text = "bad", "OUTSIDE VALIDITY", "; ".join(reasons) or message
    elif valid is None:
        css, head, text = "warn", "NOT JUDGED", message
    else:
        css, head, text = "ok", "VALID", "every answer certified and inside the model's validity"
    code = f" (exit code {status.exit_code})" if hasattr(status, "exit_code") else ""
    page.add(
        f'<div class="verdict {css}" id="verdict"><b>{head}</b>{escape(code)}: {escape(text)}'
        f"<br><span>{escape(message)}</span></div>"
    )
    if warnings:
        items = "".join(f"<li>{escape(w)}</li>" for w in warnings)
        page.add(f"<p><b>Warnings</b></p><ul>{items}</ul>")


def checks_table(page: Page, checks, values=None) -> None:
    """One row per validity check: value, limit, unit, status, advice (failed rows marked).
    ``values`` (``{name: value}``) replaces the checks' own values (a path's peak frame row)."""
    rows, classes = [], []
    for check in checks:
        value = check.value if values is None or check.name not in values else values[check.name]
        limit = f"{check.limit[0]:g} to {check.limit[1]:g}" if isinstance(check.limit, tuple) else check.limit
        rows.append([check.name, value, limit, check.unit or "1", check.status, check.advice])
        classes.append("failed" if check.passed is False else ("skipped" if check.passed is None else ""))
    page.add(table(["check", "value", "limit", "unit", "status", "advice"], rows, classes=classes))


def certificate_section(page: Page, certificate, note: str = "") -> None:
    """The certificate's residuals and the tolerance each must meet."""
    page.heading("Certificate", "certificate")
    page.paragraph(
        "Residuals dea-opt computed itself from the answer (never taken from a solver), each relative to the "
        "problem's scale; an answer is certified when every one is at most the tolerance."
        + (f" {note}" if note else "")
    )
    data = certificate.as_dict()
    tolerance = data.get("tolerance")
    parts = {"tolerance", "passed", "rounding"}  # the bound, the verdict, a part of equilibrium
    rows = [
        [name, value, tolerance, "yes" if value is not None and value <= tolerance else "no"]
        for name, value in data.items()
        if isinstance(value, float) and name not in parts
    ]
    page.add(table(["residual", "value", "tolerance", "within"], rows))
    if isinstance(data.get("rounding"), float):
        page.paragraph(f"Of equilibrium, the strains' rounding alone makes {data['rounding']:.3g}.", "note")
    page.paragraph(f"certificate {'passed' if data.get('passed') else 'FAILED'}", "note")


def inputs_section(page: Page, scenario, command: str) -> None:
    """The scenario (its file and SHA-256, the --set overrides), every input file it reads with its
    SHA-256, and the scenario's text."""
    from ..scenario.keys import FileHashes, input_files

    page.heading("Inputs", "inputs")
    source = scenario.source or "(a scenario made from text)"
    rows = [
        ["command", f"dea-opt {command}"],
        ["scenario", source],
        ["scenario SHA-256", scenario.text_sha256 or "–"],
        ["overrides (--set)", ", ".join(f"{k}={v}" for k, v in scenario.overrides.items()) or "none"],
    ]
    page.add(table(["", ""], rows))
    hashes = FileHashes()
    files = []
    for key, path in input_files(scenario).items():
        try:
            files.append([key, str(path), Path(path).stat().st_size, hashes(Path(path))])
        except OSError as exc:
            files.append([key, str(path), None, f"unreadable: {exc.strerror or exc}"])
    if files:
        page.add(table(["scenario key", "file", "bytes", "SHA-256"], files))
    text = _scenario_text(scenario)
    if text:
        page.add(f"<details><summary>The scenario file</summary><pre>{escape(text)}</pre></details>")


def _scenario_text(scenario) -> str:
    if not scenario.source:
        return ""
    try:
        return Path(scenario.source).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return ""


@functools.cache
def _versions() -> tuple:
    """``(name, version)`` of Python, the platform and :data:`SOFTWARE`, read once per process:
    each lookup scans the installed distributions (20 ms for the list, paid by every report of a
    sweep's cases or a test's runs otherwise)."""
    from importlib.metadata import PackageNotFoundError, version

    rows = [("python", sys.version.split()[0]), ("platform", platform.platform())]
    for package in SOFTWARE:
        try:
            rows.append((package, version(package)))
        except PackageNotFoundError:
            rows.append((package, "not installed"))
    return tuple(rows)


def software_section(page: Page, timings: list) -> None:
    """Timings (``[(what, seconds)]``) and the versions of Python, the platform and :data:`SOFTWARE`."""
    page.heading("Timings and software", "software")
    page.add(table(["step", "time (s)"], timings))
    rows = [list(row) for row in _versions()]
    rows.append(["report written", time.strftime("%Y-%m-%d %H:%M:%S %z")])
    page.add(table(["software", "version"], rows))


def files_section(page: Page, files: dict, folder: Path) -> None:
    """The run's files, linked relative to the report (``manifest.json`` lists their sizes and hashes)."""
    page.heading("Files of this run", "files")
    rows = []
    for name, path in files.items():
        path = Path(path)
        shown = path.relative_to(folder).as_posix() if path.is_relative_to(folder) else str(path)
        rows.append([name, Raw(f'<a href="{escape(shown)}">{escape(shown)}</a>')])
    rows.append(["manifest", Raw('<a href="manifest.json">manifest.json</a>')])
    page.add(table(["output", "file"], rows))
    page.paragraph("manifest.json, written last, lists every file with its size and SHA-256.", "note")
