"""Running a joint scenario: a static load or a load/motion path, and the outputs per layer and bundle.

A static run writes, per contact layer, ``<layer>.vtu``, ``<layer>.csv``, ``<layer>.json`` and
``<layer>.png`` (the formats of ``[output]``), ``ligaments.csv`` (one row per bundle: ``name,
body1, body2, force_N, strain, length_mm, slack_length_mm``), ``elastic.csv`` (one row per spring
or bushing, when there are any) and ``joint.json`` (bodies, layers, bundles, certificate,
validity). A path is :mod:`dea_opt.run.joint_path`. Units are in the column names.
"""

from __future__ import annotations

import csv
import io as _io

from .outcome import RunOutcome

__all__ = ["run_joint_scenario"]

LIGAMENT_COLUMNS = ("name", "body1", "body2", "force_N", "strain", "length_mm", "slack_length_mm")
_UNITS = {"u": "mm", "r": "rad"}


def _csv(rows: list[dict], columns) -> str:
    text = _io.StringIO()
    writer = csv.DictWriter(text, fieldnames=list(columns), lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow({k: (repr(v) if isinstance(v, float) else v) for k, v in row.items()})
    return text.getvalue()


def run_joint_scenario(scenario, out, method: str, *, progress: bool = False, stop_on_error: bool = False):
    """Solve a :class:`~dea_opt.scenario.joint_schema.JointScenario` and write its outputs into ``out``
    (the staging folder of :func:`~dea_opt.run.runner.publish_run`); returns the :class:`RunOutcome`."""
    from ..scenario.joint_build import build_joint
    from ..scenario.joint_path import read_joint_path

    joint, _ = build_joint(scenario)
    if scenario.load_path is None:
        return _static(scenario, joint, method, out)
    from .joint_path import run_joint_path

    return run_joint_path(scenario, joint, read_joint_path(scenario, joint), method, out, stop_on_error)


def _static(scenario, joint, method, out) -> RunOutcome:
    from .. import io
    from ..files.atomic import write_data
    from ..io.summary import write_json
    from ..joint import solve_joint

    solution = solve_joint(joint, method, certificate_tol=scenario.solve.certificate_tol, strict=False)
    formats, files = scenario.output.formats, {}
    verdict = _joint_verdict(solution)
    for contact, layer in zip(joint.contacts, solution.contacts):
        stem = _stem(contact.name)
        if "vtk" in formats:
            files[f"{stem}.vtu"] = io.to_vtk(layer, out / f"{stem}.vtu")
        if "csv" in formats:
            files[f"{stem}.csv"] = io.to_csv(layer, out / f"{stem}.csv")
        if "json" in formats:
            files[f"{stem}.json"] = io.to_json(layer, out / f"{stem}.json")
        if "png" in formats:
            title = f"{scenario.title}: {contact.name}" if scenario.title else contact.name
            files[f"{stem}.png"] = io.plot_pressure(
                layer, out / f"{stem}.png", anatomy=scenario.output.anatomy, title=title, verdict=verdict
            )
    if joint.ligaments:
        files["ligaments"] = write_data(out / "ligaments.csv", _csv(solution.ligaments.rows(), LIGAMENT_COLUMNS))
    if solution.elastic:
        columns: dict = {}
        for row in solution.elastic:
            columns.update(dict.fromkeys(row))
        files["elastic"] = write_data(out / "elastic.csv", _csv(solution.elastic, list(columns)))
    files["joint"] = write_json(solution.summary(), out / "joint.json")
    validity = solution.validity
    headline = {
        "method": solution.method,
        "success": solution.success,
        "status": str(solution.status),
        "iterations": solution.iterations,
        "solve_time_s": solution.solve_time,
        "worst_residual": solution.certificate.worst()[1],
        "valid": validity.valid,
        "validity_failed": ";".join(validity.failed),
    }
    for contact, layer in zip(joint.contacts, solution.contacts):
        headline[f"{contact.name}.peak_pressure_MPa"] = layer.peak_pressure
    if solution.success:
        message = (
            f"{solution.method}: the joint's {len(joint.bodies)} bodies in equilibrium, {solution.iterations} "
            f"iterations, certificate passed; "
            + ", ".join(f"{c.name} peak {s.peak_pressure:.4g} MPa" for c, s in zip(joint.contacts, solution.contacts))
        )
    else:
        message = (
            f"{solution.method} returned no certified answer for the joint (status {str(solution.status)!r}: "
            f"{solution.message}; {solution.failure}); the outputs hold the uncertified answer"
        )
    lines = [f"validity: {validity.summary()}"] + [f"  {c.describe()}" for c in validity.checks]
    return RunOutcome(
        "static",
        solution.success,
        message,
        files,
        headline,
        solution,
        valid=validity.valid,
        validity=lines,
        reasons=list(validity.failed),
    )


def _joint_verdict(solution):
    """The joint answer's verdict for its layers' maps (their own would judge one layer alone):
    ``(mark, reason)``, or :data:`~dea_opt.io.marks.CLEAN` for a certified answer inside validity."""
    from ..io.marks import CLEAN

    if not solution.success:
        return "NO CERTIFIED ANSWER", f"{solution.method}: status {solution.status}"
    if not solution.validity.valid:
        return "OUTSIDE VALIDITY", ", ".join(map(str, solution.validity.failed))
    return CLEAN


def _status(value: str):
    from ..status import Status

    try:
        return Status(value)
    except ValueError:
        return Status.SOLVER_ERROR


def _stem(name: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in name)
