"""Running a joint scenario: a static load or a load/motion path, and the outputs per layer and bundle.

A static run writes, per contact layer, ``<layer>.vtu``, ``<layer>.csv``, ``<layer>.json`` and
``<layer>.png`` (the formats of ``[output]``), ``ligaments.csv`` (one row per bundle: ``name,
body1, body2, force_N, strain, length_mm, slack_length_mm``) and ``joint.json`` (bodies, layers,
bundles, certificate, validity). A path writes ``frames.csv`` (per frame: status, each body's
motion, each layer's peak pressure, area, force and centre of pressure), ``ligaments.csv`` (per
bundle and frame) and ``summary.json``. Units are in the column names.
"""

from __future__ import annotations

import csv
import io as _io
import math

import numpy as np

from ..kinematics import DOFS
from .outcome import RunOutcome

__all__ = ["run_joint_scenario", "solve_joint_path"]

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
    from ..scenario.joint_build import build_joint, read_joint_path

    joint, _ = build_joint(scenario)
    if scenario.load_path is None:
        return _static(scenario, joint, method, out)
    path = read_joint_path(scenario, joint)
    return _path(scenario, joint, path, method, out, stop_on_error)


def _static(scenario, joint, method, out) -> RunOutcome:
    from .. import io
    from ..files.atomic import write_data
    from ..io.summary import write_json
    from ..joint import solve_joint

    solution = solve_joint(joint, method, certificate_tol=scenario.solve.certificate_tol, strict=False)
    formats, files = scenario.output.formats, {}
    for contact, layer in zip(joint.contacts, solution.contacts):
        stem = _stem(contact.name)
        if "vtk" in formats:
            files[f"{stem}.vtu"] = io.to_vtk(layer, out / f"{stem}.vtu")
        if "csv" in formats:
            files[f"{stem}.csv"] = io.to_csv(layer, out / f"{stem}.csv")
        if "json" in formats:
            files[f"{stem}.json"] = io.to_json(layer, out / f"{stem}.json")
        if "png" in formats:
            files[f"{stem}.png"] = io.plot_pressure(layer, out / f"{stem}.png", anatomy=scenario.output.anatomy)
    if joint.ligaments:
        files["ligaments"] = write_data(out / "ligaments.csv", _csv(solution.ligaments.rows(), LIGAMENT_COLUMNS))
    files["joint"] = write_json(solution.summary(), out / "joint.json")
    validity = solution.validity
    headline = {
        "method": solution.method,
        "success": solution.success,
        "status": str(solution.status),
        "iterations": solution.iterations,
        "solve_time": solution.solve_time,
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


def _status(value: str):
    from ..status import Status

    try:
        return Status(value)
    except ValueError:
        return Status.SOLVER_ERROR


def _stem(name: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_" else "_" for ch in name)


def solve_joint_path(joint, path, method: str = "auto", *, certificate_tol: float = 1e-6, stop_on_error: bool = False):
    """Every frame of ``path`` (:class:`~dea_opt.scenario.joint_build.JointPath`) solved in turn, each
    from the previous frame's answer; returns the list of :class:`~dea_opt.joint.JointSolution`
    (a frame that raises a :class:`~dea_opt.errors.DeaError` is None, or re-raised with
    ``stop_on_error``)."""
    from ..errors import DeaError
    from ..joint import solve_joint

    solutions, previous = [], None
    for k in range(len(path)):
        frame = path.frame(joint, k)
        start: np.ndarray | None = (
            previous.x if previous is not None and previous.joint.free_names == frame.free_names else None
        )
        try:
            s = solve_joint(frame, method, certificate_tol=certificate_tol, strict=False, x0=start)
        except DeaError:
            if stop_on_error:
                raise
            s = None
        if s is not None and not s.success and start is not None:
            s = solve_joint(frame, method, certificate_tol=certificate_tol, strict=False)  # cold, once
        solutions.append(s)
        previous = s if s is not None and s.success else previous
    return solutions


def _path(scenario, joint, path, method, out, stop_on_error) -> RunOutcome:
    from ..files.atomic import write_data
    from ..io.summary import write_json

    solutions = solve_joint_path(
        joint, path, method, certificate_tol=scenario.solve.certificate_tol, stop_on_error=stop_on_error
    )
    frames, bundles = [], []
    for k, (t, s) in enumerate(zip(path.time, solutions)):
        row: dict = {"frame": k, "time_s": float(t)}
        row["status"] = "load_not_supported" if s is None else str(s.status)
        row["success"] = s is not None and s.success
        row["valid"] = s is not None and s.validity.valid
        for name in joint.bodies:
            u = s.bodies[name].u if s is not None else np.full(6, math.nan)
            for j, dof in enumerate(DOFS):
                row[f"{name}.{dof}_{_UNITS[dof[0]]}"] = float(u[j])
        for c_index, contact in enumerate(joint.contacts):
            layer = s.contacts[c_index] if s is not None else None
            row[f"{contact.name}.peak_pressure_MPa"] = layer.peak_pressure if layer else math.nan
            row[f"{contact.name}.contact_area_mm2"] = layer.contact_area if layer else math.nan
            row[f"{contact.name}.force_N"] = float(np.linalg.norm(layer.contact_force)) if layer else math.nan
            cop = layer.center_of_pressure if layer else np.full(3, math.nan)
            for a, v in zip("xyz", cop):
                row[f"{contact.name}.center_of_pressure_{a}_mm"] = float(v)
        frames.append(row)
        for i, lig in enumerate(joint.ligaments):
            r = s.ligaments[i] if s is not None else None
            bundles.append(
                {
                    "frame": k,
                    "time_s": float(t),
                    "name": lig.name or f"ligament {i}",
                    "body1": lig.body1,
                    "body2": lig.body2,
                    "force_N": r["force_N"] if r else math.nan,
                    "strain": r["strain"] if r else math.nan,
                    "length_mm": r["length_mm"] if r else math.nan,
                }
            )
    files = {"frames": write_data(out / "frames.csv", _csv(frames, list(frames[0])))}
    if bundles:
        files["ligaments"] = write_data(out / "ligaments.csv", _csv(bundles, list(bundles[0])))
    good = [s for s in solutions if s is not None and s.success]
    failures: dict = {}
    for row in frames:
        if not row["success"]:
            failures[row["status"]] = failures.get(row["status"], 0) + 1
    summary = {
        "frames": len(frames),
        "certified": len(good),
        "valid": sum(1 for s in good if s.validity.valid),
        "failures": failures,
        "peak_pressure_MPa": {
            c.name: max((s.contacts[i].peak_pressure for s in good), default=math.nan)
            for i, c in enumerate(joint.contacts)
        },
        "largest_ligament_force_N": {
            (lig.name or f"ligament {i}"): max((float(s.ligaments.force[i]) for s in good), default=math.nan)
            for i, lig in enumerate(joint.ligaments)
        },
    }
    files["summary"] = write_json(summary, out / "summary.json")
    success = len(good) == len(frames)
    valid = all(s.validity.valid for s in good) if good else None
    message = f"{len(good)} of {len(frames)} frames certified" + ("" if success else f" ({failures})")
    outcome_failures = {_status(k): n for k, n in failures.items()}
    outside = [f"frame {row['frame']}" for row in frames if row["success"] and not row["valid"]]
    return RunOutcome(
        "path",
        success,
        message,
        files,
        {"frames": len(frames), "certified": len(good)},
        solutions,
        valid=valid,
        validity=[f"validity: {summary['valid']} of {len(good)} certified frames valid"],
        reasons=outside,
        failures=outcome_failures,
    )
