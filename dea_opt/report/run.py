"""The report of one run (``report.html``): a static load, a load path, the demo or a joint, on one page.

The verdict comes first (valid, outside validity with its reasons, or no certified answer), then
the validity checks with their values, limits and advice, each compartment's share of the load,
an interactive 3-D map of the pressure (the static answer, or a load path's peak frame), the
pictures the run drew (its cycle and exposure plots), the certificate, the inputs and their
SHA-256, the timings and the software. Every number comes from the run's own results.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..files.atomic import staged_file, write_data
from .page import Page, escape, table
from .sections import (
    certificate_section,
    checks_table,
    files_section,
    inputs_section,
    software_section,
    verdict_banner,
)
from .view3d import pressure_view

__all__ = ["REPORT_NAME", "run_report", "write_run_report"]

#: The report's file in a run's output folder.
REPORT_NAME = "report.html"

#: The pictures a report embeds, by their name among a run's files, with their captions.
_PICTURES = {
    "png": "The pressure map (MPa), each compartment's contact edge and centre of pressure.",
    "peak_map": "The peak frame's pressure map (MPa), each compartment's contact edge and centre of pressure.",
    "cycle_plot": "The load path: applied force and moment, pressure, contact area and each compartment's share.",
    "exposure_map": "Contact-stress exposure: pressure-time integral and time above the threshold.",
}


def write_run_report(folder, outcome, scenario, *, command: str = "run", elapsed: float = math.nan, extra=None):
    """Write ``report.html`` into ``folder`` (atomically; staged with the run's other outputs) and
    return its path. ``extra``: more sections, e.g. the demo's comparison (``{"comparison": rows}``)."""
    path = Path(folder) / REPORT_NAME
    return write_data(path, run_report(outcome, scenario, Path(folder), command=command, elapsed=elapsed, extra=extra))


def run_report(outcome, scenario, folder: Path, *, command: str = "run", elapsed: float = math.nan, extra=None) -> str:
    """The HTML of a run's report (see the module's docstring)."""
    title = scenario.title or (Path(scenario.source).stem if scenario.source else "dea-opt run")
    page = Page(title, f"dea-opt {command} · {_kind(outcome)} · output folder {folder}")
    verdict_banner(page, outcome.status, outcome.valid, outcome.message, outcome.reasons, outcome.warnings)
    said = "\n".join([outcome.message, *outcome.validity, *outcome.regions])
    page.add(f"<details><summary>What the run printed</summary><pre>{escape(said)}</pre></details>")
    result = outcome.result
    if outcome.kind == "static" and hasattr(result, "problem"):
        _static(page, result, outcome, scenario)
    elif outcome.kind == "path" and hasattr(result, "table"):
        _path(page, result, outcome, scenario)
    else:
        _joint(page, result, outcome)
    if extra and extra.get("comparison"):
        _comparison(page, extra["comparison"])
    inputs_section(page, scenario, command)
    software_section(page, _timings(outcome, elapsed))
    files_section(page, outcome.files, folder)
    return page.html()


def _kind(outcome) -> str:
    return {"static": "one load", "path": "a load path"}.get(outcome.kind, outcome.kind)


def _pictures(page: Page, files: dict) -> None:
    shown = False
    for name, caption in _PICTURES.items():
        if name in files:
            if not shown:
                page.heading("Figures", "figures")
                shown = True
            page.picture(staged_file(files[name]), caption)
    for name, path in files.items():
        if name.startswith("map_frame_"):
            page.picture(staged_file(path), f"The pressure map of frame {name.rsplit('_', 1)[1]} (MPa).")


def _view(page: Page, solution, title: str) -> None:
    page.heading("Pressure on the cartilage (3-D)", "view")
    if not np.isfinite(solution.pressure).all():
        page.paragraph("No 3-D view: the answer has no finite pressure.", "note")
        return
    figure, note = pressure_view(solution, title)
    page.paragraph(
        "Drag to rotate, scroll to zoom, hover a face for its pressure. Grey: out of contact; diamonds: the "
        "centres of pressure." + (f" {note}." if note else "")
    )
    page.plotly("view3d", figure)


def _region_rows(solution) -> list:
    from ..anatomy.regions import regional_statistics

    total = float(np.linalg.norm(solution.contact_force))
    rows = []
    for name, r in regional_statistics(solution).items():
        cop = ", ".join(f"{v:.1f}" for v in r.center_of_pressure) if np.isfinite(r.center_of_pressure).all() else "–"
        rows.append(
            [name, 100.0 * r.share, r.share * total, r.resultant, r.peak_pressure, r.mean_pressure, r.contact_area, cop]
        )
    return rows


_REGION_HEADER = [
    "compartment",
    "share of the contact force (%)",
    "its part (N)",
    "resultant (N)",
    "peak pressure (MPa)",
    "mean pressure (MPa)",
    "contact area (mm²)",
    "centre of pressure (x, y, z mm)",
]


def _static(page: Page, solution, outcome, scenario) -> None:
    cop = solution.center_of_pressure
    numbers = [
        ["peak pressure (MPa)", solution.peak_pressure],
        ["mean pressure (MPa)", solution.mean_pressure],
        ["contact area (mm²)", solution.contact_area],
        ["resultant (N)", float(np.linalg.norm(solution.contact_force))],
        ["centre of pressure (mm)", ", ".join(f"{v:.2f}" for v in cop) if np.isfinite(cop).all() else "–"],
        ["largest compressive strain", solution.max_compressive_strain],
        ["springs", len(solution.pressure)],
        ["method", solution.method],
        ["law", solution.problem.law.describe()],
    ]
    page.add(table(["", ""], numbers))
    page.heading("Validity", "validity")
    page.paragraph(
        "Whether the answer still lies inside the model (small strains and rotations, sizes and pressures of a "
        "joint): a failed check means the number is outside what the model can claim, whatever its certificate."
    )
    checks_table(page, solution.validity.checks)
    if solution.problem.layer.labels is not None and np.isfinite(solution.pressure).all():
        page.heading("Compartments", "compartments")
        page.add(table(_REGION_HEADER, _region_rows(solution)))
    _view(page, solution, scenario.title or "")
    _pictures(page, outcome.files)
    certificate_section(page, solution.certificate)


def _path(page: Page, result, outcome, scenario) -> None:
    summary = result.summary()
    peak = result.kept.get("peak")
    numbers = [
        ["frames", summary["frames"]],
        ["without a certified answer", len(summary["failed_frames"])],
        ["outside validity", len(summary["validity"]["frames_outside_validity"])],
        ["peak pressure (MPa)", summary["peak_pressure_MPa"]],
        ["at (s)", summary["peak_time_s"]],
        ["largest contact area (mm²)", summary["max_contact_area_mm2"]],
        ["largest compressive strain", summary["max_compressive_strain"]],
        ["method", summary["method"]],
        ["law", summary["law"]],
    ]
    page.add(table(["", ""], numbers))
    page.heading("Validity", "validity")
    validity = summary["validity"]
    if validity["checks"]:
        rows = [
            [name, len(c["frames"]), ", ".join(map(str, c["frames"][:20])), c["worst"], c["unit"], c["worst_frame"]]
            for name, c in validity["checks"].items()
        ]
        page.add(table(["failed check", "frames", "which", "worst value", "unit", "at frame"], rows))
    else:
        page.paragraph("Every certified frame lies inside the model's validity.")
    if peak is not None:
        k, solution = peak
        page.add(f"<h3>The peak frame's checks (frame {k})</h3>")
        row = result.table.loc[result.table["frame"] == k].iloc[0]
        values = {"dropped_springs": row.get("validity_dropped_springs", math.nan)}
        checks_table(page, solution.validity.checks, {n: v for n, v in values.items() if np.isfinite(v)})
    if result.regions:
        page.heading("Compartments", "compartments")
        rows = [
            [
                name,
                100.0 * r["mean_force_share"],
                100.0 * r["min_force_share"],
                100.0 * r["max_force_share"],
                r["peak_pressure_MPa"],
                r["peak_time_s"],
                r["max_contact_area_mm2"],
            ]
            for name, r in summary["regions"].items()
        ]
        header = [
            "compartment",
            "mean share (%)",
            "smallest share (%)",
            "largest share (%)",
            "peak pressure (MPa)",
            "at (s)",
            "largest contact area (mm²)",
        ]
        page.add(table(header, rows))
        if peak is not None:
            page.add(f"<h3>At the peak frame (frame {peak[0]})</h3>")
            page.add(table(_REGION_HEADER, _region_rows(peak[1])))
    if peak is not None:
        _view(page, peak[1], f"{scenario.title + ': ' if scenario.title else ''}peak frame {peak[0]}")
    _pictures(page, outcome.files)
    _frames(page, result.table)
    if peak is not None:
        certificate_section(
            page,
            peak[1].certificate,
            f"The peak frame's; over every frame the largest residual was {summary['worst_certificate_residual']:.3g}.",
        )


def _frames(page: Page, frames) -> None:
    page.heading("Frames", "frames")
    page.paragraph("Click a column's name to sort by it. Every column of frames.csv is in the file.", "note")
    columns = [
        c
        for c in (
            "frame",
            "time_s",
            "Fx_N",
            "Fy_N",
            "Fz_N",
            "peak_pressure_MPa",
            "contact_area_mm2",
            "resultant_N",
            "max_compressive_strain",
            "valid",
            "validity_failed",
            "status",
        )
        if c in frames
    ]
    rows = frames[columns].to_numpy(dtype=object).tolist()
    classes = ["failed" if not (s and v) else "" for s, v in zip(frames["success"], frames["valid"])]
    page.add(f'<div class="scroll">{table(columns, rows, sortable=True, classes=classes)}</div>')


def _joint(page: Page, result, outcome) -> None:
    """A joint's answer (``[[bodies]]``): its checks, each layer and bundle, each layer in 3-D."""
    last = result
    if outcome.kind == "path":
        _joint_frames(page, result["frames"])
        if result["shown"] is None:
            _pictures(page, outcome.files)
            return
        frame, time_s, last, force = result["shown"]
        page.paragraph(
            f"The tables and 3-D views below are frame {frame} (time {time_s:.4g} s), the certified frame "
            f"whose contact layers carry the largest force ({force:.4g} N); every frame is in frames.csv."
        )
    if last is None:
        return
    page.heading("Validity", "validity")
    checks_table(page, last.validity.checks)
    page.heading("Contact layers", "layers")
    rows = [
        [name, s.peak_pressure, s.contact_area, float(np.linalg.norm(s.contact_force))]
        for name, s in zip((c.name for c in last.joint.contacts), last.contacts)
    ]
    page.add(table(["layer", "peak pressure (MPa)", "contact area (mm²)", "force (N)"], rows))
    if len(last.ligaments):
        bundles = last.ligaments.rows()
        page.add(table(list(bundles[0]), [list(b.values()) for b in bundles]))
    for k, (contact, layer) in enumerate(zip(last.joint.contacts, last.contacts)):
        if np.isfinite(layer.pressure).all() and len(layer.pressure):
            figure, _ = pressure_view(layer, contact.name)
            page.plotly(f"view3d_{k}", figure)
    _pictures(page, outcome.files)
    certificate_section(page, last.certificate)


def _joint_frames(page: Page, rows: list) -> None:
    """A joint path's frames (the rows of ``frames.csv``): status, validity and each layer's and
    compartment's force and peak pressure per frame, sortable."""
    if not rows:
        return
    keep = [
        c
        for c in rows[0]
        if c in ("frame", "time_s", "status", "valid") or c.endswith(("force_N", "peak_pressure_MPa"))
    ]
    page.heading("Frames", "frames")
    page.add(f'<div class="scroll">{table(keep, [[r[c] for c in keep] for r in rows], sortable=True)}</div>')


def _comparison(page: Page, rows: list) -> None:
    page.heading("The gait-peak frame by every method and law", "comparison")
    columns = [c for c in rows[0] if c != "status"]
    page.add(table(columns, [[r[c] for c in columns] for r in rows], sortable=True))


def _timings(outcome, elapsed: float) -> list:
    headline = outcome.headline
    rows = []
    if "solve_time_s" in headline:
        rows.append(["solving" + (" (every frame)" if outcome.kind == "path" else ""), headline["solve_time_s"]])
    if np.isfinite(elapsed):
        rows.append(["the run, until this report (reading, casting, solving, writing)", elapsed])
    return rows
