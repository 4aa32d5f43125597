"""Load paths: one quasi-static solve per frame, warm-started, and what a cycle exposes the cartilage to.

:func:`solve_path` walks a sequence of loads (a gait cycle, say) and solves each frame:

* ``newton`` (and ``auto``) starts every frame from the previous frame's displacement;
* ``qp`` compiles one cvxpy model (:class:`~dea_opt.formulations.qp.QPModel`) and re-solves it
  with the load as a Parameter;
* ``nlp`` builds one IPOPT problem (:class:`~dea_opt.formulations.nlp.NLPModel`) and re-solves
  it from the previous frame's point (an interior-point method gains little from a warm
  start; the saving is the build).

With ``poses`` (a rigid transform of body 2's mesh per frame) the springs are cast again each
frame, so the gaps change; QP and NLP models are then rebuilt each frame, Newton still starts
from the previous displacement.

A frame that fails (a load the springs cannot carry, an answer that fails its certificate, a
solver error) does not stop the path: it is recorded with its status and message, NaN results
and no exposure, the next frame starts cold, and the path goes on (``stop_on_error=True``
raises at the first failed frame instead). Memory does not grow with the frames beyond the
per-frame table: the exposure is accumulated frame by frame, the frames' ``.vtu`` files can be
written as they are solved (:class:`PathOutputs` ``series``), and the solutions and pressures are
kept only when asked; the estimate is checked before the first frame (:class:`~dea_opt.errors.SizeLimitError`).

The :class:`PathResult` holds the per-frame table (:mod:`~dea_opt.loadpath.table`: numbers,
validity and regions of every frame), the contact-stress exposure of every site over the
cycle (:class:`Exposure`: the time integral of pressure, the time above a threshold and the
integral of the excess over it, the measures of Kern & Anderson, J Biomech 2015), and the
writers. Units: mm, N, N mm, MPa, s.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import replace

import numpy as np

from .._checks.inputs import as_numeric
from .._checks.threads import single_threaded_blas
from ..errors import (
    DeaError,
    InputError,
    LoadNotSupportedError,
    SolverError,
    ValidityWarning,
)
from ..finite.stepper import FiniteStepper, check_finite_poses, frame_layer, moves
from ..problem import ContactProblem
from ..status import Status
from .exposure import ExposureAccumulator
from .frames import check_frames, frame_count, read_frames
from .outputs import PathOutputs
from .result import PathResult
from .series import FrameSeries
from .stepper import Stepper
from .table import TABLE_COLUMNS, FrameRegions, failed_row, make_table, motion_columns, solved_row

__all__ = ["TABLE_COLUMNS", "PathOutputs", "solve_path"]


# --- one frame --------------------------------------------------------------------------


def _solve_frame(stepper, frame, new_geometry, setup):
    """``(solution, status, message, error)``: status and message are empty for a certified
    answer; ``solution`` is None when there is no answer at all, ``error`` what was raised."""
    from ..solver import check_load_supported

    try:
        with warnings.catch_warnings():
            # One warning for the whole path at the end, not one per frame.
            warnings.simplefilter("ignore", ValidityWarning)
            solution = stepper.solve(frame, new_geometry, setup)
        if solution.success:
            return solution, "", "", None
        check_load_supported(frame)
    except LoadNotSupportedError as exc:
        return None, Status.NOT_SUPPORTED, str(exc), exc
    except SolverError as exc:
        return exc.solution, Status.of_error(exc), str(exc), exc
    message = (
        f"{solution.method} returned no certified answer (status '{solution.status}'): {solution.failure}; "
        f"{solution.message}"
    )
    return solution, solution.status, message, None


def _stop(k, t, status, message, solution, error):
    text = f"frame {k} (time {t:g} s): {message}"
    if isinstance(error, LoadNotSupportedError):
        return LoadNotSupportedError(text, direction=error.direction)
    if status == Status.POSE_ERROR:
        return InputError(text)
    return SolverError(text, status=status, solution=solution)


# --- the public entry point -------------------------------------------------------------


def solve_path(
    problem: ContactProblem,
    loads,
    poses=None,
    *,
    method: str = "auto",
    times=None,
    body: int = 2,
    kinematics: str | None = None,
    layer_for_pose=None,
    certificate_tol: float = 1e-6,
    stop_on_error: bool = False,
    outputs: PathOutputs | None = None,
    progress: bool = False,
    **options,
) -> PathResult:
    """Solve ``problem`` under each load of a path, warm-starting every frame from the last.

    Parameters
    ----------
    problem : ContactProblem
        Geometry, law and bodies; its own load is replaced frame by frame.
    loads : sequence of Load, array_like (T, 3) or (T, 6), or pandas.DataFrame
        The load on ``body`` per frame: ``Fx, Fy, Fz`` (N) and optionally ``Mx, My, Mz``
        (N mm, about the body's reference). A DataFrame may carry a ``time`` column (s).
    poses : array_like (T, 4, 4), optional
        Rigid transform of body 2's mesh per frame; the springs are cast again each frame
        (needs ``layer_for_pose``, or a layer with a ``with_pose`` method).
    method : {"auto", "newton", "qp", "nlp"}
        ``auto`` is Newton with a cold :func:`dea_opt.solve` fallback for frames whose
        warm-started answer fails its certificate.
    times : array_like (T,), optional
        Frame times (s); default the DataFrame's ``time`` column, else 0, 1, 2, ...
    body : {1, 2}
        The body the loads act on.
    certificate_tol : float
        Bound on every certificate residual.
    stop_on_error : bool
        Raise at the first frame without a certified answer: :class:`LoadNotSupportedError`
        for a load the springs cannot carry, :class:`SolverError` otherwise, naming the
        frame. Default: record the frame (``success`` False, its ``status`` and
        ``message`` in the table, NaN results), start the next frame cold and go on.
    layer_for_pose : callable, optional
        ``layer_for_pose(pose) -> SpringLayer``: the springs of body 2's mesh moved by
        ``pose`` (e.g. a closure over :func:`dea_opt.mesh.springs_from_meshes`).
    outputs : PathOutputs, optional
        What the path keeps and writes besides its per-frame table (:class:`PathOutputs`: the
        frames' solutions and pressures, kept by default; a folder their ``.vtu`` files are
        streamed into; the regions of the table's columns; the exposure's pressure threshold).
    progress : bool
        Show a progress bar on a terminal (tqdm; nothing when stderr is not a terminal).
    kinematics : {"small", "finite"}, optional
        Overrides ``problem.kinematics``. With ``"finite"`` (``formulations/finite.md``) every
        frame starts from the previous frame's pose and re-cast springs; ``poses`` then
        prescribe body 2's mesh pose per frame with the free dofs acting on top of it (the gait
        set-up: flexion from the kinematics, the rest found), re-cast from the problem's
        ``targets=`` SpringCast rather than by ``layer_for_pose``.
    **options
        For the formulation: ``tol``, ``solver`` (qp), ``form``, ``max_iter`` (nlp),
        ``gtol``, ``xtol`` (newton).

    Returns
    -------
    PathResult

    Raises
    ------
    InputError
        Bad loads, times, poses, regions or options; ``qp`` with a nonlinear law.
    SizeLimitError
        What the path would keep does not fit in the free memory (checked before the first
        frame, with the estimate).
    LoadNotSupportedError, SolverError
        With ``stop_on_error``, the first frame without a certified answer (named).
    """
    # BLAS on one thread throughout: the frames are many small memory-bound products,
    # which a second thread only slows down.
    with single_threaded_blas():
        return _solve_path(
            problem,
            loads,
            poses,
            method=method,
            times=times,
            body=body,
            certificate_tol=certificate_tol,
            stop=bool(stop_on_error),
            outputs=PathOutputs.of(outputs),
            layer_for_pose=layer_for_pose,
            progress=progress,
            kinematics=kinematics,
            options=options,
        )


def _check_inputs(problem, method, body):
    from ..solver import check_method

    if not isinstance(problem, ContactProblem):
        raise InputError(f"problem must be a ContactProblem, got {type(problem).__name__}")
    check_method(method, problem.law)  # a registered formulation that takes the law
    if body not in (1, 2):
        raise InputError(f"body must be 1 or 2, got {body!r}")


def _labels(regions, layer):
    labels = regions(layer) if callable(regions) else (layer.labels if regions is None else regions)
    if labels is None:
        return None
    labels = np.asarray(labels)
    if labels.shape != (len(layer),):
        raise InputError(f"regions must give one label per spring, shape ({len(layer)},), got {labels.shape}")
    return labels


def _solve_path(
    problem,
    loads,
    poses,
    *,
    method,
    times,
    body,
    certificate_tol,
    stop,
    outputs,
    layer_for_pose,
    progress,
    kinematics,
    options,
) -> PathResult:
    """The body of :func:`solve_path`."""
    keep_solutions, keep_pressures, regions = outputs.keep_solutions, outputs.keep_pressures, outputs.regions
    if kinematics is not None and isinstance(problem, ContactProblem):
        problem = replace(problem, kinematics=kinematics)
    finite = isinstance(problem, ContactProblem) and problem.kinematics == "finite"
    if not finite:
        _check_inputs(problem, method, body)
    elif body != 2:
        raise InputError(
            f"kinematics='finite' moves body 2 against a fixed body 1: loads act on body 2, got body={body!r}"
        )
    # The size check first, from the frames' count and the springs alone: everything before it is
    # O(springs), nothing reads, converts or validates a frame (the loads, times and poses are
    # checked after it).
    n_frames = frame_count(loads)
    moving = moves(problem, poses) if finite else poses is not None
    labels = _labels(regions, problem.layer)
    n_regions = 0 if labels is None else len(np.unique(labels))
    check_frames(
        n_frames,
        len(problem.layer),
        keep_solutions=keep_solutions,
        keep_pressures=keep_pressures,
        moving=moving,
        n_regions=n_regions,
    )
    loads, times = read_frames(loads, times)
    wanted, keep_peak = _kept_frames(outputs.keep_frames, len(loads))
    kept: dict = {}
    if finite:
        poses = check_finite_poses(problem, poses, len(loads))
    else:
        poses, layer_for_pose = _check_poses(problem, poses, layer_for_pose, len(loads))
    n_sites = _site_count(problem.layer, moving)
    stepper = FiniteStepper(method, options, certificate_tol) if finite else Stepper(method, options, certificate_tol)
    accumulator = ExposureAccumulator(n_sites, outputs.threshold)
    frames = FrameSeries(outputs.series, len(loads), background=True) if outputs.series is not None else None
    start = time.perf_counter()
    problem.system()  # computes the geometry once, to be shared by every frame
    setup = time.perf_counter() - start
    base_regions = FrameRegions(labels) if labels is not None else None
    motion = motion_columns(problem)
    rows, pressures, solutions = [], [], []
    bar = _progress(len(loads), progress)
    failed = 0
    try:
        for k in range(len(loads)):
            load, t = loads[k], float(times[k])
            base, frame_regions, new_geometry, status = problem, base_regions, k == 0, ""
            if isinstance(stepper, FiniteStepper):
                stepper.pose = None if poses is None else poses[k]
            elif moving:
                new_geometry = True
                try:
                    base = problem.with_layer(layer_for_pose(poses[k]))
                except DeaError as exc:  # no springs at this pose, a pose the mesh check refuses
                    status, message, solution, error = (
                        Status.POSE_ERROR,
                        f"casting the springs at this pose: {exc}",
                        None,
                        exc,
                    )
                if base_regions is not None and not status:
                    frame_regions = FrameRegions(_labels(regions, base.layer), base_regions.prefixes)
            frame = base.with_load(load, body=body)  # shares the spring arrays
            vector = getattr(frame, f"body{body}").load_vector
            if not status:
                solution, status, message, error = _solve_frame(stepper, frame, new_geometry, setup if k == 0 else 0.0)
            if status:
                if stop:
                    raise _stop(k, t, status, message, solution, error) from None
                failed += 1
                stepper.reset()  # the next frame starts cold, not from a failed state
                rows.append(
                    failed_row(k, t, vector, len(frame.layer), status, message, solution, frame_regions, motion)
                )
                accumulator.skip(t)
                bar.set_postfix(failed=failed, refresh=False)
            else:
                assert solution is not None  # a frame without a status has its certified answer
                layer = frame_layer(frame, solution)
                if finite and base_regions is not None:
                    frame_regions = FrameRegions(_labels(regions, layer), base_regions.prefixes)
                rows.append(solved_row(k, t, vector, solution, frame_regions, motion))
                accumulator.add(t, solution.pressure, _sites(layer, moving))
                _keep(kept, k, solution, wanted, keep_peak)
            certified = None if status else solution
            if keep_pressures:
                pressures.append(
                    np.array(certified.pressure) if certified is not None else np.full(len(frame.layer), np.nan)
                )
            if keep_solutions:
                solutions.append(solution)
            if frames is not None:
                frames.write(k, t, frame_layer(frame, certified), certified)
            bar.update()
        if frames is not None:
            frames.finish()  # every frame's file written (a write's error raised) before the result
    finally:
        bar.close()
        if frames is not None:
            frames.close()  # stopped early: no frame left being written into the folder
    table = make_table(rows, base_regions.prefixes if base_regions is not None else None, motion)
    result = PathResult(
        table=table,
        times=times,
        pressures=pressures if keep_pressures else None,
        solutions=solutions if keep_solutions else None,
        exposure=accumulator.result(),
        method=method,
        problem=problem,
        moving=moving,
        regions=dict(base_regions.prefixes) if base_regions is not None else {},
        frame_files=frames,
        kept=kept,
    )
    result.warn_validity()
    return result


def _kept_frames(keep_frames, n: int) -> tuple[set, bool]:
    """``(frame indices, keep the peak frame)`` of ``keep_frames``, each index checked."""
    if isinstance(keep_frames, (str, int)):
        keep_frames = [keep_frames]
    wanted, peak = set(), False
    for item in keep_frames:
        if item == "peak":
            peak = True
            continue
        if isinstance(item, bool) or not isinstance(item, (int, np.integer)) or not 0 <= item < n:
            raise InputError(f"keep_frames must hold frame indices in [0, {n - 1}] or 'peak', got {item!r}")
        wanted.add(int(item))
    return wanted, peak


def _keep(kept: dict, k: int, solution, wanted: set, keep_peak: bool) -> None:
    """Keep frame ``k``'s certified ``solution`` if it was asked for, or if it is the peak so far
    (``kept["peak"]``, replacing the last peak)."""
    if k in wanted:
        kept[k] = solution
    if keep_peak:
        best = kept.get("peak")
        if best is None or solution.peak_pressure > best[1].peak_pressure:
            kept["peak"] = (k, solution)


def _check_poses(problem, poses, layer_for_pose, n):
    if poses is None:
        return None, None
    poses = as_numeric("poses", poses)
    if poses.shape != (n, 4, 4):
        raise InputError(f"poses must have shape ({n}, 4, 4), one per frame, got {poses.shape}")
    if layer_for_pose is None:
        layer_for_pose = getattr(problem.layer, "with_pose", None)
    if not callable(layer_for_pose):
        raise InputError(
            "poses move body 2's mesh, so the springs must be cast again each frame, but this layer was not "
            "built from meshes: give layer_for_pose=lambda pose: springs_from_meshes(mesh1, mesh2, pose=pose, ...) "
            "or use a [geometry] of kind 'meshes' in the scenario"
        )
    return poses, layer_for_pose


def _progress(total: int, enabled: bool):
    from ..progress import bar

    # Off when stderr is not a terminal (logs, pipes, tests): dea_opt.progress.
    return bar(total, "solving frames", "frame", enabled)


def _sites(layer, moving: bool) -> np.ndarray | None:
    """Where each spring's pressure accumulates: its face of mesh 1 when the springs move."""
    if moving and layer.source_face is not None:
        return np.asarray(layer.source_face)
    return None


def _site_count(layer, moving: bool) -> int:
    if moving and layer.surface is not None:
        return len(layer.surface[1])
    return len(layer)
