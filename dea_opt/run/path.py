"""A load path: solve it frame by frame (streamed), re-cast its peak frame, write the outputs."""

from __future__ import annotations

import numpy as np

from .log import one_line
from .outcome import RunOutcome
from .static import recast_solution

__all__ = ["peak_recast", "run_path_outputs"]


def _frames_text(frames) -> str:
    shown = ", ".join(map(str, frames[:10]))
    return shown + (", ..." if len(frames) > 10 else "")


def run_path_outputs(
    scenario,
    problem,
    method,
    options,
    out,
    progress,
    extra_summary=None,
    stop: bool = False,
    cast=None,
    pictures=None,
    data=None,
    suspicions=(),
) -> RunOutcome:
    """Solve the load path of ``scenario`` and write its outputs into ``out`` (staged by the caller).

    The frames are streamed: each frame's ``.vtu`` is written as it is solved
    (``series_frames/``) and no solution or pressure is kept per frame, so memory does not
    grow with frames x springs. When the springs were cast from meshes (``cast``, or the
    meshes of a path with poses), the peak frame is solved once more and its springs re-cast
    at its solved pose (:func:`peak_recast`): its ``dropped_springs`` check is evaluated and
    the re-cast force goes into ``summary.json`` (``recast``). ``pictures``: a
    :class:`~dea_opt.run.pictures.PictureWorker` that draws the PNGs while the rest is written.
    ``data``: the path's frames read already (:func:`dea_opt.scenario.read_load_path`);
    ``suspicions``: what the check before solving found (they head the verdict and
    ``summary.json``'s ``suspicious_input``). Frames without a certified answer are told grouped
    by cause, one complete line each (:func:`dea_opt.run.diagnose.failure_lines`).
    """
    from ..loadpath import PathOutputs, solve_path
    from ..progress import stage
    from ..scenario import pose_caster, read_load_path
    from .diagnose import LoadSource, failure_lines

    if data is None:
        data = read_load_path(scenario.load_path)
    caster = layer_for_pose = None
    poses = data.poses
    if poses is not None:
        caster = pose_caster(scenario)
        if caster is not None:

            def layer_for_pose(pose):
                return caster(pose).layer

    formats, anatomy = scenario.output.formats, scenario.output.anatomy
    loads = data.load_objects()
    maps = _checked_maps(scenario.output.maps, len(loads)) if "png" in formats else []
    keep = ["peak", *maps] if "png" in formats or "html" in formats else []
    result = solve_path(
        problem,
        loads,
        data.poses,
        method=method,
        times=data.times,
        body=data.body,
        certificate_tol=scenario.solve.certificate_tol,
        stop_on_error=stop,
        outputs=PathOutputs(
            keep_solutions=False,
            keep_pressures=False,
            series=out / "series_frames" if "vtk" in formats else None,
            threshold=scenario.output.exposure_threshold,
            keep_frames=tuple(keep),
        ),
        layer_for_pose=layer_for_pose,
        progress=progress,
        **options,
    )
    notes = []
    recast = None
    if cast is not None or caster is not None:
        stage("re-casting the springs at the peak frame's solved pose")

        def frame_cast(k):
            return cast if caster is None or poses is None else caster(poses[k])

        recast = peak_recast(
            result,
            loads,
            data.body,
            frame_cast,
            method,
            options,
            scenario.solve.certificate_tol,
            frame_pose=lambda k: None if poses is None else poses[k],
        )
        if recast is not None and "error" in recast:
            notes.append(recast["error"])
    stage("writing outputs")
    extra = {"title": scenario.title, **(extra_summary or {})}
    if suspicions:
        extra["suspicious_input"] = list(suspicions)
    if recast is not None:
        extra["recast"] = recast
    summary = result.summary(anatomy)
    files = result.write(
        out,
        [f for f in formats if f != "html"],
        extra_summary=extra,
        anatomy=anatomy,
        summary=summary,
        pictures=pictures,
        title=scenario.title or None,
        maps=maps,
    )
    validity = summary["validity"]
    outside = validity["frames_outside_validity"]
    checks = validity["failed_checks"]
    certified = summary["frames"] - len(summary["failed_frames"])
    # No certified frame: nothing to judge, valid or not (None: not assessed), and no shares.
    valid = None if not certified else not outside
    headline = {
        "method": method,
        "success": result.success,
        "frames": summary["frames"],
        "n_springs": summary["n_springs"],
        "failed_frames": len(summary["failed_frames"]),
        "peak_pressure_MPa": summary["peak_pressure_MPa"],
        "peak_time_s": summary["peak_time_s"],
        "contact_area_mm2": summary["max_contact_area_mm2"],
        "max_compressive_strain": summary["max_compressive_strain"],
        "iterations": summary["iterations_total"],
        "solve_time_s": summary["solve_time_total_s"],
        "worst_residual": summary["worst_certificate_residual"],
        "max_pressure_time_integral_MPa_s": summary["exposure"]["max_pressure_time_integral_MPa_s"],
        "valid": valid,
        "frames_outside_validity": len(outside),
        "validity_failed": ";".join(checks),
        **({"recast_force_error": recast.get("force_error")} if recast is not None else {}),
        **_region_headline(result),
    }
    if summary["peak_frame"] is None:
        message = f"{summary['frames']} frames by {method}: no frame has a certified answer"
    else:
        message = (
            f"{summary['frames']} frames by {method}: peak pressure {summary['peak_pressure_MPa']:.4g} MPa at "
            f"{summary['peak_time_s']:.3g} s, largest contact area {summary['max_contact_area_mm2']:.4g} mm^2, "
            f"{summary['solve_time_total_s']:.2f} s solving"
        )
    if not result.success:
        failed = failure_lines(result.failures(), loads, problem, LoadSource.of(scenario), data.body, len(loads))
        message = (
            f"{len(result.failures())} of {summary['frames']} frames without a certified answer: "
            f"{'; '.join(failed)} (status and message of each in frames.csv); {message}"
        )
    reasons = []
    suspicious = [f"input: suspicious: {line}" for line in suspicions]
    if outside:
        parts = [
            f"{name} in {len(c['frames'])} frame(s) (worst {c['worst']:.4g} at frame {c['worst_frame']})"
            for name, c in validity["checks"].items()
        ]
        first = (
            f"{len(outside)} of {summary['frames']} frame(s) outside validity ({_frames_text(outside)}), "
            f"failed checks: {', '.join(checks)}"
        )
        reasons = [first, *parts]
        lines = [f"validity: NOT VALID: {reasons[0]}", *(f"  {r}" for r in reasons[1:])]
    elif not certified:
        lines = [f"validity: not judged: none of the {summary['frames']} frames has a certified answer"]
    else:
        lines = [f"validity: valid (every one of the {certified} certified frames)"]
    lines = suspicious + lines
    if recast is not None and "error" not in recast:
        lines.append(f"re-cast at the solved pose of the peak frame {recast['frame']}: {recast['describe']}")
    if summary["motion"] and summary["peak_frame"] is not None:
        lines.append(f"motion found (free dofs, frames.csv): {_motion_text(summary['motion'])}")
        along = _anatomical_motion_text(summary.get("motion_anatomical", {}))
        if along:
            lines.append(f"motion found along the anatomical axes: {along}")
    regions = [_region_text(name, r) for name, r in summary["regions"].items()] if certified else []
    failures: dict = {}
    for frame in result.failures():
        failures[frame["status"]] = failures.get(frame["status"], 0) + 1
    return RunOutcome(
        "path",
        result.success,
        message,
        files,
        headline,
        result,
        warnings=notes,
        valid=valid,
        validity=lines,
        reasons=reasons,
        regions=regions,
        failures=failures,
    )


def _checked_maps(maps, n: int) -> list[int]:
    """``[output] maps``, each a frame of the path's ``n``."""
    from ..errors import ScenarioError

    beyond = [k for k in maps if k >= n]
    if beyond:
        raise ScenarioError(
            f"[output] maps names frame {beyond[0]}, but the load path has {n} frames (0 to {n - 1}): "
            f"give frame indices as frames.csv counts them"
        )
    return sorted(set(maps))


def _region_text(name: str, r: dict) -> str:
    """One region of a path over its certified frames (no share where no frame's share exists)."""
    share = r["mean_force_share"]
    if share is None or not np.isfinite(share):
        text = f"region {name}: no share of the contact force (no certified frame carried any)"
    else:
        text = (
            f"region {name}: {share:.1%} of the contact force on average ({r['min_force_share']:.1%} to "
            f"{r['max_force_share']:.1%}: its springs' resultant along the contact force)"
        )
    if r["peak_frame"] is None:
        return text
    return (
        f"{text}, peak {r['peak_pressure_MPa']:.4g} MPa at {r['peak_time_s']:.3g} s, largest contact area "
        f"{r['max_contact_area_mm2']:.4g} mm^2"
    )


def _region_headline(result) -> dict:
    """A sweep row's columns of each region over the certified frames: ``<region>_peak_pressure_MPa``,
    ``<region>_contact_area_mm2`` (the largest) and ``<region>_mean_force_share``."""
    row = {}
    for name, r in result.region_summary().items():
        prefix = result.regions[name]
        row[f"{prefix}_peak_pressure_MPa"] = r["peak_pressure_MPa"]
        row[f"{prefix}_contact_area_mm2"] = r["max_contact_area_mm2"]
        row[f"{prefix}_mean_force_share"] = r["mean_force_share"]
    return row


def _motion_text(motion: dict) -> str:
    """``body2_uz -1.31 to -0.62 mm, body2_ry -0.0072 to 0.0091 rad (-0.41 to 0.52 deg)``."""
    from ..units import split_unit

    parts = []
    for column, m in motion.items():
        text = f"{split_unit(column)[0]} {m['min']:.4g} to {m['max']:.4g} {m['unit']}"
        if m["unit"] == "rad":
            text += f" ({np.degrees(m['min']):.3g} to {np.degrees(m['max']):.3g} deg)"
        parts.append(text)
    return ", ".join(parts)


def _anatomical_motion_text(motion: dict) -> str:
    """``body2 translation proximal -1.31 to -0.62 mm, rotation about anterior -0.41 to 0.52 deg``:
    the ranges of ``motion_anatomical``, rotations in degrees, each body and kind named once."""
    parts = []
    named_body = named_kind = None
    for column, m in motion.items():
        body, kind, axis = column.split("_")[:3]  # body2_translation_medial_mm
        # Free dofs along coordinate axes that are anatomical axes too reach no other axis:
        # their exactly-zero ranges would only lengthen the line.
        if m["min"] == 0.0 == m["max"]:
            continue
        low, high, unit = m["min"], m["max"], m["unit"]
        if unit == "rad":
            low, high, unit = np.degrees(low), np.degrees(high), "deg"
        words = [body] if body != named_body else []
        if (body, kind) != (named_body, named_kind):
            words.append(kind)
        words.append(f"about {axis}" if kind == "rotation" else axis)
        parts.append(f"{' '.join(words)} {low:.3g} to {high:.3g} {unit}")
        named_body, named_kind = body, kind
    return ", ".join(parts)


def peak_recast(
    result, loads, body: int, frame_cast, method: str, options: dict, certificate_tol: float, frame_pose=None
):
    """Re-cast the springs at the solved pose of a load path's peak frame (the certified frame of
    the largest peak pressure), and evaluate that frame's ``dropped_springs`` check.

    The frames are not kept, so the peak frame is solved once more (the same answer: the
    problem has one) and :func:`recast_solution` re-casts it: one solve and one cast, not
    one per frame. The table's row of that frame gets ``validity_dropped_springs`` (and, when
    the window dropped springs, ``valid`` False and ``dropped_springs`` in
    ``validity_failed``); every other frame keeps it not evaluated (NaN).

    Parameters
    ----------
    result : PathResult
        Its ``table`` is updated.
    loads : list of Load
    body : int
    frame_cast : callable
        ``k -> SpringCast`` of frame ``k`` (small kinematics).
    frame_pose : callable, optional
        ``k -> (4, 4) or None``: frame ``k``'s pose of body 2's mesh. With finite kinematics the
        frame is solved at that pose from the problem's own SpringCast (its ``targets``), which
        the answer's springs follow and the re-cast starts from.
    method, options, certificate_tol :
        As the path was solved.

    Returns
    -------
    dict or None
        ``recast_solution``'s report with ``frame`` and ``time_s``; None without a certified frame.
    """
    import warnings

    from ..errors import DeaError, ValidityWarning
    from ..solver import solve

    table = result.table
    certified = table.loc[table["success"]]
    if not len(certified) or not certified["peak_pressure_MPa"].notna().any():
        return None
    row = certified["peak_pressure_MPa"].idxmax()
    k = int(table.loc[row, "frame"])
    where = {"frame": k, "time_s": float(table.loc[row, "time_s"])}
    finite = getattr(result.problem, "kinematics", "small") == "finite"
    try:
        if finite:  # the springs follow the problem's own cast; the frame's pose is the solve's frame
            cast, problem = result.problem.targets, result.problem
            frame = None if frame_pose is None else frame_pose(k)
            extra = {} if frame is None else {"frame": frame}
        else:
            cast, extra = frame_cast(k), {}
            problem = result.problem.with_layer(cast.layer) if result.moving else result.problem
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", ValidityWarning)
            solution = solve(
                problem.with_load(loads[k], body=body),
                method,
                certificate_tol=certificate_tol,
                strict=False,
                **options,
                **extra,
            )
    except DeaError as exc:
        return {**where, "error": f"the peak frame {k} was not re-cast at its solved pose: {one_line(str(exc))}"}
    solution, recast = recast_solution(solution, cast)
    if "error" in recast:
        return {**where, "error": f"frame {k}: {recast['error']}"}
    check = solution.validity["dropped_springs"]
    table.loc[row, "validity_dropped_springs"] = check.value
    if check.passed is False:
        failed = [n for n in str(table.loc[row, "validity_failed"]).split(";") if n]
        table.loc[row, "validity_failed"] = ";".join([*failed, check.name])
        table.loc[row, "valid"] = False
    return {**where, **recast}
