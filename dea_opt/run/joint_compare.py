"""``dea-opt compare`` of a joint scenario: the joint solved by each method, one row per method."""

from __future__ import annotations

import csv
import io as _io

__all__ = ["compare_joint_scenario"]

COLUMNS = (
    "method",
    "success",
    "status",
    "iterations",
    "solve_time_s",
    "worst_residual",
    "displacement_difference",
    "pressure_difference",
    "ligament_force_difference",
)


def compare_joint_scenario(scenario, folder, methods=None, force: bool = False) -> None:
    """Solve the scenario's joint by each method (``--methods`` or ``[solve].methods``; default every
    one that solves it), print the table and publish ``compare.csv`` into ``folder``."""
    import typer

    from ..files.atomic import write_data
    from ..joint.compare import compare_joint
    from ..scenario.joint_build import build_joint
    from ..status import RunStatus
    from .log import captured
    from .publish import output_run
    from .runner import run_info

    joint, _ = build_joint(scenario)
    with captured(), output_run(folder, force=force, info=run_info(scenario, "compare")) as publication:
        result = compare_joint(
            joint, methods or scenario.solve.methods, certificate_tol=scenario.solve.certificate_tol, strict=False
        )
        rows = []
        for method, s in result.solutions.items():
            rows.append(
                {
                    "method": method,
                    "success": s.success,
                    "status": str(s.status),
                    "iterations": s.iterations,
                    "solve_time_s": s.solve_time,
                    "worst_residual": s.certificate.worst()[1],
                    "displacement_difference": result.displacement,
                    "pressure_difference": result.pressure,
                    "ligament_force_difference": result.ligament_force,
                }
            )
        text = _io.StringIO()
        writer = csv.DictWriter(text, fieldnames=list(COLUMNS), lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
        path = write_data(publication.folder / "compare.csv", text.getvalue())
        publication.publish(status=RunStatus.OK if all(r["success"] for r in rows) else RunStatus.CERTIFICATE_FAILED)
    for row in rows:
        typer.echo(
            f"{row['method']:8s} {str(row['status']):12s} success={row['success']} iterations={row['iterations']} "
            f"time={row['solve_time_s']:.3g} s worst residual={row['worst_residual']:.2g}"
        )
    typer.echo(
        f"largest difference: displacement {result.displacement:.2g}, pressure {result.pressure:.2g}, "
        f"ligament force {result.ligament_force:.2g} (relative)"
    )
    for method, why in result.skipped.items():
        typer.echo(f"(skipped: {method}: {why})")
    typer.echo(f"  compare  {path}")
