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

The :class:`PathResult` holds a per-frame table (pandas), the per-frame solutions, and the
contact-stress exposure of every spring over the cycle (:class:`Exposure`): the time integral
of pressure, the time above a threshold and the integral of the excess over it, the measures
of Kern & Anderson (J Biomech 2015) and of Anderson's group before them. It writes a CSV, a
ParaView time series (``.pvd`` of per-frame ``.vtu`` files), a plot of peak pressure and
contact area over the cycle, and the exposure map (``.vtu`` and ``.png``).

Units: mm, N, N mm, MPa, s.
"""

from __future__ import annotations

import time
import warnings

import numpy as np

from .._tolerances import LINEAR_VALIDITY
from ..errors import InputError, LoadNotSupportedError, SolverError, ValidityWarning
from ..formulations.energy import single_threaded_blas
from ..problem import ContactProblem, Load
from ..solution import Solution
from .exposure import exposure
from .result import PathResult
from .stepper import Stepper

__all__ = ["TABLE_COLUMNS", "solve_path"]

#: Columns of :attr:`PathResult.table`, with units.
TABLE_COLUMNS = {
    "frame": "frame index",
    "time": "s",
    "Fx": "N", "Fy": "N", "Fz": "N", "Mx": "N mm", "My": "N mm", "Mz": "N mm",
    "peak_pressure": "MPa",
    "mean_pressure": "MPa, over the contact",
    "contact_area": "mm^2",
    "cop_x": "mm", "cop_y": "mm", "cop_z": "mm",
    "resultant": "N, magnitude of the springs' force on body 2",
    "max_compressive_strain": "1",
    "n_springs": "springs this frame",
    "iterations": "solver iterations",
    "build_time": "s (model building and compiling; first frame, or every frame with poses)",
    "solve_time": "s",
    "certificate_residual": "largest certificate residual (relative)",
    "certificate_worst": "which residual it is",
    "success": "certificate passed",
    "status": "solver status",
}


# --- frames -----------------------------------------------------------------------------

def _frames(loads, times) -> tuple[list[Load], np.ndarray]:
    """Loads as a list of :class:`Load` and the frame times (s)."""
    import pandas as pd

    if isinstance(loads, pd.DataFrame):
        missing = [c for c in ("Fx", "Fy", "Fz") if c not in loads]
        if missing:
            raise InputError(f"loads must have columns Fx, Fy, Fz (and optionally time, Mx, My, Mz); "
                             f"missing {', '.join(missing)}")
        if times is None and "time" in loads:
            times = loads["time"].to_numpy(dtype=float)
        columns = [loads[c] if c in loads else 0.0 * loads["Fx"] for c in ("Fx", "Fy", "Fz", "Mx", "My", "Mz")]
        loads = np.column_stack([np.asarray(c, dtype=float) for c in columns])
    if isinstance(loads, np.ndarray) or (len(loads) and not isinstance(loads[0], Load)):
        array = np.asarray(loads, dtype=float)
        if array.ndim != 2 or array.shape[1] not in (3, 6):
            raise InputError(f"loads must be a sequence of Load, or an array of shape (T, 3) or (T, 6) "
                             f"(Fx, Fy, Fz[, Mx, My, Mz]), got shape {array.shape}")
        loads = [Load(force=row[:3], moment=row[3:] if len(row) == 6 else 0.0) for row in array]
    loads = list(loads)
    if not loads:
        raise InputError("loads is empty: a load path needs at least one frame")
    for i, load in enumerate(loads):
        if not isinstance(load, Load):
            raise InputError(f"loads[{i}] must be a dea_opt.Load, got {type(load).__name__}")
    times = np.arange(len(loads), dtype=float) if times is None else np.asarray(times, dtype=float)
    if times.shape != (len(loads),) or not np.isfinite(times).all():
        raise InputError(f"times must be {len(loads)} finite numbers (one per frame), got shape {times.shape}")
    if len(times) > 1 and not (np.diff(times) > 0).all():
        raise InputError("times must increase from frame to frame")
    return loads, times


def _frame_error(exc: Exception, k: int, t: float) -> Exception:
    message = f"frame {k} (time {t:g} s): {exc}"
    if isinstance(exc, LoadNotSupportedError):
        return LoadNotSupportedError(message, direction=exc.direction)
    if isinstance(exc, SolverError):
        return SolverError(message, status=exc.status, solution=exc.solution)
    return type(exc)(message)


# --- the public entry point -------------------------------------------------------------

def solve_path(problem: ContactProblem, loads, poses=None, *, method: str = "auto", times=None, body: int = 2,
               certificate_tol: float = 1e-6, strict: bool = False, keep_solutions: bool = True,
               layer_for_pose=None, threshold: float = 1.0, progress: bool = False, **options) -> "PathResult":
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
    strict : bool
        Raise :class:`SolverError` at the first frame that fails its certificate. Default:
        record it (``success`` False in the table) and go on.
    keep_solutions : bool
        Keep every frame's :class:`Solution` (needed for the ``.pvd`` series).
    layer_for_pose : callable, optional
        ``layer_for_pose(pose) -> SpringLayer``: the springs of body 2's mesh moved by
        ``pose`` (e.g. a closure over :func:`dea_opt.mesh.springs_from_meshes`).
    threshold : float
        Pressure threshold (MPa) of the exposure measures.
    progress : bool
        Show a progress bar (on a terminal).
    **options
        For the formulation: ``tol``, ``solver`` (qp), ``form``, ``max_iter`` (nlp),
        ``gtol``, ``xtol`` (newton).

    Returns
    -------
    PathResult

    Raises
    ------
    InputError
        Bad loads, times or poses; ``qp`` with a nonlinear law.
    LoadNotSupportedError
        A frame's load cannot be carried (the message names the frame).
    SolverError
        With ``strict``, the first frame whose answer fails its certificate.
    """
    # BLAS on one thread throughout: the frames are many small memory-bound products,
    # which a second thread only slows down.
    with single_threaded_blas():
        return _solve_path(problem, loads, poses, method=method, times=times, body=body, certificate_tol=certificate_tol, strict=strict, keep_solutions=keep_solutions, layer_for_pose=layer_for_pose, threshold=threshold, progress=progress, **options)


def _solve_path(problem: ContactProblem, loads, poses=None, *, method: str = "auto", times=None, body: int = 2,
               certificate_tol: float = 1e-6, strict: bool = False, keep_solutions: bool = True,
               layer_for_pose=None, threshold: float = 1.0, progress: bool = False, **options) -> "PathResult":
    """The body of :func:`solve_path`."""
    from ..solver import check_load_supported, check_method

    if not isinstance(problem, ContactProblem):
        raise InputError(f"problem must be a ContactProblem, got {type(problem).__name__}")
    check_method(method, problem.law)  # a registered formulation that takes the law
    if body not in (1, 2):
        raise InputError(f"body must be 1 or 2, got {body!r}")
    loads, times = _frames(loads, times)
    poses, layer_for_pose = _check_poses(problem, poses, layer_for_pose, len(loads))
    stepper = Stepper(method, options, certificate_tol)
    base = problem
    start = time.perf_counter()
    base.system()  # computes the geometry once, to be shared by every frame
    setup = time.perf_counter() - start
    rows, pressures, sites, solutions = [], [], [], []
    bar = _progress(len(loads), progress)
    try:
        for k, (load, t) in enumerate(zip(loads, times)):
            new_geometry = k == 0
            if poses is not None:
                base = problem.with_layer(layer_for_pose(poses[k]))
                new_geometry = True
            frame = base.with_load(load, body=body)  # shares the spring arrays
            try:
                solution = stepper.solve(frame, new_geometry, setup if k == 0 else 0.0)
                if not solution.success:
                    check_load_supported(frame)
            except (LoadNotSupportedError, SolverError) as exc:
                raise _frame_error(exc, k, t) from None
            if strict and not solution.success:
                name, value = solution.certificate.worst()
                raise SolverError(f"frame {k} (time {t:g} s): {solution.method} returned no certified answer; "
                                  f"certificate residual {name} = {value:.3g} > {certificate_tol:g}",
                                  status=solution.status, solution=solution)
            rows.append(_row(k, t, frame, solution, body))
            pressures.append(np.array(solution.pressure))
            sites.append(_sites(frame.layer, poses is not None))
            if keep_solutions:
                solutions.append(solution)
            bar.update()
    finally:
        bar.close()
    import pandas as pd

    table = pd.DataFrame(rows, columns=list(TABLE_COLUMNS))
    _warn_path_validity(table, problem.law)
    result = PathResult(
        table=table, times=times, pressures=pressures, solutions=solutions if keep_solutions else None,
        exposure=exposure(times, pressures, sites, threshold, _site_count(problem.layer, poses is not None)),
        method=method, problem=problem, moving=poses is not None,
    )
    return result


def _check_poses(problem, poses, layer_for_pose, n):
    if poses is None:
        return None, None
    poses = np.asarray(poses, dtype=float)
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
    from tqdm.auto import tqdm

    # disable=None turns the bar off when stderr is not a terminal (logs, tests).
    return tqdm(total=total, desc="frames", unit="frame", disable=None if enabled else True, leave=False)


def _row(k, t, frame: ContactProblem, solution: Solution, body: int) -> dict:
    load = getattr(frame, f"body{body}").load_vector
    cop = solution.center_of_pressure
    name, value = solution.certificate.worst()
    return {
        "frame": k, "time": float(t),
        "Fx": load[0], "Fy": load[1], "Fz": load[2], "Mx": load[3], "My": load[4], "Mz": load[5],
        "peak_pressure": solution.peak_pressure, "mean_pressure": solution.mean_pressure,
        "contact_area": solution.contact_area,
        "cop_x": cop[0], "cop_y": cop[1], "cop_z": cop[2],
        "resultant": float(np.linalg.norm(solution.contact_force)),
        "max_compressive_strain": solution.max_compressive_strain,
        "n_springs": len(solution.pressure), "iterations": solution.iterations,
        "build_time": solution.build_time, "solve_time": solution.solve_time,
        "certificate_residual": value, "certificate_worst": name,
        "success": solution.success, "status": solution.status,
    }


def _warn_path_validity(table, law) -> None:
    crushed = table["max_compressive_strain"] >= 1.0
    beyond = table["max_compressive_strain"] > LINEAR_VALIDITY
    if crushed.any():
        warnings.warn(f"{int(crushed.sum())} frame(s) crush a spring through its whole thickness (strain <= -1); "
                      f"those results are not physical", ValidityWarning, stacklevel=3)
    elif law.is_linear and beyond.any():
        warnings.warn(f"{int(beyond.sum())} frame(s) exceed {LINEAR_VALIDITY:.0%} compressive strain, beyond the "
                      f"range where the linear law is valid (Volokh, Chao & Armand); consider AteshianLaw",
                      ValidityWarning, stacklevel=3)


def _sites(layer, moving: bool) -> np.ndarray:
    """Where each spring's pressure accumulates: its face of mesh 1 when the springs move."""
    if moving and layer.source_face is not None:
        return np.asarray(layer.source_face)
    return np.arange(len(layer))


def _site_count(layer, moving: bool) -> int:
    if moving and layer.surface is not None:
        return len(layer.surface[1])
    return len(layer)
