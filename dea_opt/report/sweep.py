"""The report of a sweep (``report.html`` in the sweep's folder): every case on one page.

The cases' statuses first, then a plot of any output against any swept value (two menus; each
case a point, coloured by its status, named on hover), a table of the cases sortable by any
column (each case linked to its own report), the scenario and its SHA-256, and the software.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..files.atomic import write_data
from .page import Page, Raw, escape
from .page import table as html_table
from .sections import software_section

__all__ = ["sweep_report", "write_sweep_report"]

#: Columns of sweep.csv that are bookkeeping, not results: left out of the report's table and plot.
_BOOKKEEPING = (
    "case_id",
    "key",
    "scenario_sha256",
    "dea_opt_version",
    "method_option",
    "outputs_option",
    "output_dir",
    "finished",
    "pid",
    "warnings",
    "exit_code",
)
_STATUS_COLOURS = {"ok": "#1a7f37", "outside_validity": "#e37400"}


def write_sweep_report(folder, cases, swept, scenario_path, sets) -> Path:
    """Write ``report.html`` into the sweep's ``folder`` (atomically) and return its path."""
    path = Path(folder) / "report.html"
    return write_data(path, sweep_report(cases, swept, scenario_path, sets, Path(folder)))


def _swept_columns(cases, swept) -> list:
    """The columns of the swept keys (with their units: ``law.H_MPa``)."""
    found = []
    for key in swept:
        found += [c for c in cases.columns if c == key or (c.startswith(f"{key}_") and "." in c)]
    return list(dict.fromkeys(found))


def _numeric(cases, columns) -> list:
    import pandas as pd

    return [c for c in columns if pd.api.types.is_numeric_dtype(cases[c]) and not pd.api.types.is_bool_dtype(cases[c])]


def sweep_report(cases, swept, scenario_path, sets, folder: Path) -> str:
    """The HTML of a sweep's report (see the module's docstring)."""
    from ..scenario import load_scenario
    from ..scenario.keys import sha256_file

    try:
        title = load_scenario(scenario_path).title
    except Exception:  # noqa: BLE001 - a report of the cases must not fail on the scenario's title
        title = ""
    page = Page(f"Sweep: {title or Path(scenario_path).stem}", f"dea-opt sweep · {len(cases)} cases · {folder}")
    statuses = cases["status"].value_counts().to_dict() if "status" in cases else {}
    clean = set(statuses) <= {"ok"}
    counts = ", ".join(f"{n} {s}" for s, n in statuses.items())
    css = "ok" if clean else "bad"
    head = "EVERY CASE VALID" if clean else "NOT EVERY CASE IS A CLEAN SUCCESS"
    page.add(f'<div class="verdict {css}" id="verdict"><b>{head}</b>: {escape(counts)}</div>')
    swept_columns = _swept_columns(cases, swept)
    outputs = [c for c in cases.columns if c not in _BOOKKEEPING and c not in swept_columns and c != "case"]
    numeric = _numeric(cases, outputs)
    if swept_columns and numeric:
        _plot(page, cases, swept_columns, numeric)
    page.heading("Cases", "cases")
    page.paragraph("Click a column's name to sort by it; a case's name opens its own report.", "note")
    columns = ["case", "status", *swept_columns, *[c for c in outputs if c != "status"]]
    rows = []
    for record in cases.to_dict("records"):
        row = []
        for column in columns:
            value = record.get(column)
            if column == "case":
                value = _case_link(record, folder)
            row.append(None if isinstance(value, float) and math.isnan(value) else value)
        rows.append(row)
    classes = ["" if r.get("status") == "ok" else "failed" for r in cases.to_dict("records")]
    page.add(f'<div class="scroll">{html_table(columns, rows, sortable=True, classes=classes)}</div>')
    page.heading("Inputs", "inputs")
    try:
        digest = sha256_file(scenario_path)
    except OSError:
        digest = "unreadable"
    page.add(
        html_table(
            ["", ""], [["scenario", str(scenario_path)], ["scenario SHA-256", digest], ["--set", "  ".join(sets)]]
        )
    )
    software_section(page, [["the cases' wall time, added up", float(np.nansum(cases.get("wall_time_s", [])))]])
    return page.html()


def _case_link(record: dict, folder: Path):
    name = record.get("case") or record.get("case_id")
    report = folder / "cases" / str(record.get("case_id")) / "report.html"
    if report.is_file():
        return Raw(f'<a href="cases/{escape(record.get("case_id"))}/report.html">{escape(name)}</a>')
    return name


def _plot(page: Page, cases, swept_columns: list, numeric: list) -> None:
    """Any output against any swept value: two menus and a Plotly scatter, redrawn on a change."""
    page.heading("Any output against any swept value", "plot")
    preferred = next((c for c in ("peak_pressure_MPa", "contact_area_mm2") if c in numeric), numeric[0])
    menus = (
        "<p><label>output <select id='y-menu'>"
        + "".join(f"<option{' selected' if c == preferred else ''}>{escape(c)}</option>" for c in numeric)
        + "</select></label><label>against <select id='x-menu'>"
        + "".join(f"<option>{escape(c)}</option>" for c in swept_columns)
        + "</select></label></p>"
    )
    page.add(menus)
    columns = {c: [_plain(v) for v in cases[c].tolist()] for c in [*swept_columns, *numeric]}
    status = [str(s) for s in cases.get("status", ["ok"] * len(cases))]
    names = [str(n) for n in cases.get("case", cases.get("case_id", [""] * len(cases)))]
    figure = {
        "data": [],
        "layout": {"margin": {"t": 20}, "hovermode": "closest", "legend": {"title": {"text": "status"}}},
        "columns": columns,
        "status": status,
        "names": names,
        "colours": _STATUS_COLOURS,
    }
    script = """
      var draw = function () {
        var x = document.getElementById('x-menu').value, y = document.getElementById('y-menu').value;
        var groups = {};
        figure.status.forEach(function (s, i) { (groups[s] = groups[s] || []).push(i); });
        var data = Object.keys(groups).map(function (s) {
          var rows = groups[s];
          return {type: 'scatter', mode: 'markers', name: s, marker: {size: 10, color: figure.colours[s] || '#c62828'},
                  x: rows.map(function (i) { return figure.columns[x][i]; }),
                  y: rows.map(function (i) { return figure.columns[y][i]; }),
                  text: rows.map(function (i) { return figure.names[i]; }),
                  hovertemplate: '%{text}<br>' + x + ' %{x}<br>' + y + ' %{y:.4g}<extra></extra>'};
        });
        var layout = Object.assign({}, figure.layout, {xaxis: {title: {text: x}}, yaxis: {title: {text: y}}});
        Plotly.react(div, data, layout);
      };
      document.getElementById('x-menu').addEventListener('change', draw);
      document.getElementById('y-menu').addEventListener('change', draw);
      draw();
    """
    page.plotly("sweep-plot", figure, css="plot", script=script)


def _plain(value):
    """A JSON value of a cell: NaN as null, numpy scalars as Python's."""
    if hasattr(value, "item"):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value if isinstance(value, (int, float, str, bool)) or value is None else str(value)
