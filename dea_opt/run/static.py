"""One static load: solve, re-cast springs cast from meshes at the solved pose, write the outputs."""

from __future__ import annotations

import numpy as np

from .log import one_line
from .outcome import RunOutcome

__all__ = ["recast_solution", "run_static"]


def run_static(scenario, problem, method, options, out, cast=None, suspicions=()) -> RunOutcome:
    """Solve one load, re-cast its springs at the solved pose and write the outputs into ``out``;
    ``suspicions`` (:func:`dea_opt.run.preflight.check_inputs`) head the verdict and the JSON."""
    from .. import io
    from ..io.summary import summary_dict, write_json
    from ..progress import stage
    from ..solver import solve

    stage(f"solving ({method})")
    solution = solve(problem, method, certificate_tol=scenario.solve.certificate_tol, strict=False, **options)
    notes = []
    recast = None
    if cast is not None:
        stage("re-casting the springs at the solved pose")
        solution, recast = recast_solution(solution, cast)
        if "error" in recast:
            notes.append(recast["error"])
    stage("writing outputs")
    formats, anatomy = scenario.output.formats, scenario.output.anatomy
    files = {}
    if "vtk" in formats:
        files["vtk"] = io.to_vtk(solution, out / "contact.vtu")
    if "csv" in formats:
        files["csv"] = io.to_csv(solution, out / "contact.csv")
    if "json" in formats:
        summary = summary_dict(solution, anatomy=anatomy)
        if recast is not None:
            summary["recast"] = recast
        if suspicions:
            summary["suspicious_input"] = list(suspicions)
        files["json"] = write_json(summary, out / "contact.json")
    if "png" in formats:
        files["png"] = io.plot_pressure(solution, out / "contact.png", anatomy=anatomy, title=scenario.title or None)
    name, value = solution.certificate.worst()
    validity = solution.validity
    headline = {
        "method": solution.method,
        "success": solution.success,
        "n_springs": len(solution.pressure),
        "peak_pressure_MPa": solution.peak_pressure,
        "mean_pressure_MPa": solution.mean_pressure,
        "contact_area_mm2": solution.contact_area,
        "max_compressive_strain": solution.max_compressive_strain,
        "iterations": solution.iterations,
        "solve_time_s": solution.solve_time,
        "worst_residual": value,
        **validity.columns(),
        **({"recast_force_error": recast.get("force_error")} if recast is not None else {}),
        **_region_headline(solution),
    }
    if solution.success:
        message = (
            f"{solution.method}: peak pressure {solution.peak_pressure:.4g} MPa, contact area "
            f"{solution.contact_area:.4g} mm^2, {solution.iterations} iterations, certificate passed"
        )
    else:
        message = (
            f"{solution.method} returned no certified answer (status '{solution.status}': {solution.message}; "
            f"{solution.failure}); "
            f"the outputs hold the uncertified answer"
        )
    lines = [f"input: suspicious: {line}" for line in suspicions]
    lines.append(f"validity: {validity.summary()}")
    lines += [f"  {check.describe()}" for check in validity.checks]
    if recast is not None and "error" not in recast:
        lines.append(f"re-cast at the solved pose: {recast['describe']}")
    return RunOutcome(
        "static",
        solution.success,
        message,
        files,
        headline,
        solution,
        warnings=notes,
        valid=validity.valid,
        validity=lines,
        reasons=[c.describe() for c in validity.failed],
        regions=_static_regions(solution),
    )


def _region_headline(solution) -> dict:
    """A sweep row's columns of each labelled region: ``<region>_peak_pressure_MPa``,
    ``<region>_contact_area_mm2`` and ``<region>_force_share`` (the region prefixes of a load
    path's table)."""
    if solution.problem.layer.labels is None or not np.isfinite(solution.pressure).all():
        return {}
    from ..anatomy.regions import regional_statistics
    from ..loadpath.table import region_prefixes

    found = regional_statistics(solution)
    prefixes = region_prefixes(found)
    row = {}
    for name, r in found.items():
        prefix = prefixes[name]
        row[f"{prefix}_peak_pressure_MPa"] = r.peak_pressure
        row[f"{prefix}_contact_area_mm2"] = r.contact_area
        row[f"{prefix}_force_share"] = r.share
    return row


def _static_regions(solution) -> list[str]:
    """One line per labelled region of a static answer."""
    if solution.problem.layer.labels is None or not np.isfinite(solution.pressure).all():
        return []
    from ..anatomy.regions import regional_statistics

    total = float(np.linalg.norm(solution.contact_force))
    return [
        f"region {name}: "
        # no share of a contact force of 0 N (no load): said so, not nan%
        + (
            f"{r.share:.1%} of the contact force ({r.share * total:.4g} N of {total:.4g} N along it; "
            f"its springs' resultant {r.resultant:.4g} N)"
            if np.isfinite(r.share)
            else "no share of the contact force (the springs carry none)"
        )
        + f", peak {r.peak_pressure:.4g} MPa, contact area {r.contact_area:.4g} mm^2"
        for name, r in regional_statistics(solution).items()
    ]


def recast_solution(solution, cast) -> tuple:
    """``(solution, recast)``: the springs of ``cast`` re-cast at the pose ``solution`` reached
    (:func:`dea_opt.mesh.recast_at_solution`) and the solution carrying the count the window
    dropped there (its ``dropped_springs`` validity check evaluated).

    ``recast`` is JSON-ready: the counts (``springs``, ``kept``, ``gained``, ``lost``,
    ``dropped``, ``rejected``), the force ``force_N`` and moment ``moment_Nmm`` (about body 2's
    reference) the re-cast springs carry at that pose beside the solution's own
    (``solution_force_N``, ``solution_moment_Nmm``), their relative difference ``force_error`` and a one-line
    ``describe``; or ``{"error": ...}`` when the answer is not certified or the re-cast failed
    (the solution is then returned as it is).
    """
    from ..errors import DeaError
    from ..mesh import recast_at_solution

    if not solution.success or not np.isfinite(solution.u).all():
        return solution, {"error": "springs not re-cast at the solved pose: the answer is not certified"}
    try:
        again = recast_at_solution(solution, cast)
    except DeaError as exc:
        return solution, {"error": f"springs not re-cast at the solved pose: {one_line(str(exc))}"}
    info = {
        "springs": len(again.cast.layer),
        "kept": again.kept,
        "gained": len(again.gained),
        "lost": {reason: len(faces) for reason, faces in again.lost.items()},
        "dropped": again.dropped,
        "rejected": again.rejected,
        **{
            f"{name}_{unit}": np.asarray(getattr(again, name), dtype=float).tolist()
            for name, unit in (("force", "N"), ("moment", "Nmm"), ("solution_force", "N"), ("solution_moment", "Nmm"))
        },
        "force_error": again.force_error,
        "describe": again.describe(),
    }
    return solution.with_validity(dropped=again.dropped), info
