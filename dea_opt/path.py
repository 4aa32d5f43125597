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

import json
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from .io import write_data
from .errors import InputError, LoadNotSupportedError, SolverError, ValidityWarning
from .io import write_atomic
from .problem import ContactProblem, Load
from .solution import Solution
from .formulations.energy import single_threaded_blas
from .solver import certified_solution

__all__ = ["solve_path", "PathResult", "Exposure", "exposure", "write_pvd", "TABLE_COLUMNS"]

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

_LINEAR_VALIDITY = 0.3


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


# --- one solver per method, keeping its state between frames ---------------------------

class _Stepper:
    """Solves frame after frame with one method, carrying the warm start."""

    def __init__(self, method: str, options: dict, certificate_tol: float):
        self.method = method
        self.options = options
        self.certificate_tol = certificate_tol
        self.x = None
        self.model = None

    def solve(self, problem: ContactProblem, new_geometry: bool, setup: float = 0.0) -> Solution:
        """Solve one frame; ``setup`` (s) is geometry building to charge to this frame."""
        from .solver import solve

        if problem.free_indices.size == 0:
            return solve(problem, "newton", certificate_tol=self.certificate_tol, strict=False)
        start = time.perf_counter()
        system = problem.system()
        build = setup + (time.perf_counter() - start if new_geometry else 0.0)
        if new_geometry:
            self.model = None
        if self.method in ("newton", "auto"):
            solution = self._newton(problem, system, build)
        else:
            solution = self._model(problem, system, build)
        if solution.success:
            self.x = solution.u[problem.free_indices]
        return solution

    def _newton(self, problem, system, build) -> Solution:
        from .formulations import newton
        from .solver import solve

        options = {k: v for k, v in self.options.items() if k in ("gtol", "xtol", "max_iter")}
        result = newton.solve(system, problem.law, x0=self.x, **options)
        solution = certified_solution(problem, result, "newton", self.certificate_tol, build)
        if not solution.success and self.method == "auto":
            # The previous frame's start may be poor (a jump in the load): solve cold,
            # falling back to the constrained formulation as dea_opt.solve does.
            fallback = {k: v for k, v in self.options.items() if k not in ("gtol", "xtol", "max_iter")}
            solution = solve(problem, "auto", certificate_tol=self.certificate_tol, strict=False, **fallback)
        return solution

    def _model(self, problem, system, build) -> Solution:
        from .formulations import FormulationResult
        from .formulations.nlp import NLPModel
        from .formulations.qp import QPModel

        options = dict(self.options)
        if self.model is None:
            if self.method == "qp":
                self.model = QPModel(system, problem.law, solver=options.pop("solver", "CLARABEL"))
            else:
                names = ("form", "tol", "max_iter", "ipopt_options")
                nlp_options = {k: options.pop(k) for k in names if k in options}
                self.model = NLPModel(system, problem.law, **nlp_options)
            build += self.model.build_time
        else:
            options.pop("solver", None)
        try:
            if self.method == "qp":
                result = self.model.solve(system.load, **{k: v for k, v in options.items() if k == "tol"})
            else:
                result = self.model.solve(system.load, warm_start=True)
        except SolverError as exc:
            # As dea_opt.solve does: a solver that raised gives a failed frame, not an abort.
            result = FormulationResult(x=np.full(system.n_dofs, np.nan), stress=np.full(system.n_springs, np.nan),
                                       success=False, status=exc.status or "solver_error", message=str(exc))
        return certified_solution(problem, result, self.method, self.certificate_tol, build)


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
    from .solver import METHODS, check_load_supported

    if not isinstance(problem, ContactProblem):
        raise InputError(f"problem must be a ContactProblem, got {type(problem).__name__}")
    if method not in METHODS:
        raise InputError(f"method must be one of {METHODS}, got {method!r}")
    if method == "qp" and not problem.law.is_linear:
        raise InputError(f"method 'qp' needs a LinearLaw, got {problem.law.describe()}: use method='nlp' or "
                         f"method='newton' for nonlinear laws")
    if body not in (1, 2):
        raise InputError(f"body must be 1 or 2, got {body!r}")
    loads, times = _frames(loads, times)
    poses, layer_for_pose = _check_poses(problem, poses, layer_for_pose, len(loads))
    stepper = _Stepper(method, options, certificate_tol)
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
    beyond = table["max_compressive_strain"] > _LINEAR_VALIDITY
    if crushed.any():
        warnings.warn(f"{int(crushed.sum())} frame(s) crush a spring through its whole thickness (strain <= -1); "
                      f"those results are not physical", ValidityWarning, stacklevel=3)
    elif law.is_linear and beyond.any():
        warnings.warn(f"{int(beyond.sum())} frame(s) exceed {_LINEAR_VALIDITY:.0%} compressive strain, beyond the "
                      f"range where the linear law is valid (Volokh, Chao & Armand); consider AteshianLaw",
                      ValidityWarning, stacklevel=3)


# --- exposure ---------------------------------------------------------------------------

def _sites(layer, moving: bool) -> np.ndarray:
    """Where each spring's pressure accumulates: its face of mesh 1 when the springs move."""
    if moving and layer.source_face is not None:
        return np.asarray(layer.source_face)
    return np.arange(len(layer))


def _site_count(layer, moving: bool) -> int:
    if moving and layer.surface is not None:
        return len(layer.surface[1])
    return len(layer)


@dataclass(frozen=True, eq=False)
class Exposure:
    """Contact-stress exposure of every site (spring, or face of mesh 1 when body 2's mesh moves).

    Pressure is taken as piecewise linear in time between frames, and every integral is
    exact for that.

    Attributes
    ----------
    threshold : float
        Pressure threshold (MPa).
    pressure_time_integral : ndarray
        ``int p dt`` (MPa s).
    time_above : ndarray
        Time with ``p > threshold`` (s).
    exposure_above : ndarray
        ``int max(p - threshold, 0) dt`` (MPa s): the exposure over a threshold.
    peak : ndarray
        Largest pressure over the path (MPa).
    duration : float
        Time from the first to the last frame (s).
    """

    threshold: float
    pressure_time_integral: np.ndarray
    time_above: np.ndarray
    exposure_above: np.ndarray
    peak: np.ndarray
    duration: float

    def fields(self) -> dict:
        """The per-site arrays by name (for files)."""
        return {
            "pressure_time_integral": self.pressure_time_integral,
            "time_above_threshold": self.time_above,
            "exposure_above_threshold": self.exposure_above,
            "peak_pressure": self.peak,
        }

    def summary(self) -> dict:
        return {
            "threshold": self.threshold,
            "duration": self.duration,
            "max_pressure_time_integral": float(self.pressure_time_integral.max(initial=0.0)),
            "max_time_above_threshold": float(self.time_above.max(initial=0.0)),
            "max_exposure_above_threshold": float(self.exposure_above.max(initial=0.0)),
            "sites_above_threshold": int((self.time_above > 0).sum()),
        }


def exposure(times, pressures, sites=None, threshold: float = 1.0, n_sites: int | None = None) -> Exposure:
    """Contact-stress exposure over a path.

    Parameters
    ----------
    times : array_like (T,)
        Frame times (s), increasing.
    pressures : sequence of T arrays
        Pressure per spring at each frame (MPa).
    sites : sequence of T integer arrays, optional
        The site of each spring at each frame (default: spring ``i`` is site ``i``).
    threshold : float
        MPa.
    n_sites : int, optional
        Number of sites (default: the largest site index + 1).
    """
    times = np.asarray(times, dtype=float)
    threshold = float(threshold)
    if not threshold >= 0:
        raise InputError(f"threshold must be a pressure >= 0 (MPa), got {threshold!r}")
    if sites is None:
        sites = [np.arange(len(p)) for p in pressures]
    if n_sites is None:
        n_sites = int(max((s.max(initial=-1) for s in sites), default=-1)) + 1
    P = np.zeros((len(times), n_sites))
    for k, (p, s) in enumerate(zip(pressures, sites)):
        np.maximum.at(P[k], s, np.nan_to_num(p, nan=0.0))
    dt = np.diff(times)[:, None]
    p0, p1 = P[:-1], P[1:]
    integral = (0.5 * (p0 + p1) * dt).sum(axis=0)
    above, excess = _above(p0, p1, dt, threshold)
    return Exposure(threshold, integral, above, excess, P.max(axis=0, initial=0.0),
                    float(times[-1] - times[0]) if len(times) else 0.0)


def _above(p0, p1, dt, threshold):
    """Time above ``threshold`` and the integral of the excess, segment by segment, exact for linear p(t)."""
    e0, e1 = p0 - threshold, p1 - threshold
    both = (e0 > 0) & (e1 > 0)
    one = (e0 > 0) ^ (e1 > 0)
    high = np.maximum(e0, e1)
    with np.errstate(invalid="ignore", divide="ignore"):
        fraction = np.where(one, high / np.abs(p1 - p0), 0.0)
    time_above = np.where(both, dt, np.where(one, fraction * dt, 0.0)).sum(axis=0)
    excess = np.where(both, 0.5 * (e0 + e1) * dt, np.where(one, 0.5 * high * fraction * dt, 0.0)).sum(axis=0)
    return time_above, excess


# --- the result and its files -----------------------------------------------------------

@dataclass(eq=False)
class PathResult:
    """The frames of a load path and the exposure over it.

    Attributes
    ----------
    table : pandas.DataFrame
        One row per frame, columns :data:`TABLE_COLUMNS`.
    times : ndarray (T,)
        s.
    pressures : list of ndarray
        Pressure per spring per frame (MPa).
    solutions : list of Solution or None
        Every frame's solution (``keep_solutions=True``).
    exposure : Exposure
    method : str
    problem : ContactProblem
        The problem the path started from.
    moving : bool
        True when body 2's mesh moved (springs cast again each frame).
    """

    table: object
    times: np.ndarray
    pressures: list
    solutions: list | None
    exposure: Exposure
    method: str
    problem: ContactProblem
    moving: bool = False
    files: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.times)

    @property
    def success(self) -> bool:
        """True when every frame passed its certificate."""
        return bool(self.table["success"].all())

    @property
    def failed_frames(self) -> list[int]:
        return self.table.loc[~self.table["success"], "frame"].astype(int).tolist()

    def summary(self) -> dict:
        """Headline numbers of the path (plain Python values, for JSON)."""
        table = self.table
        k = int(table["peak_pressure"].idxmax())
        return {
            "method": self.method,
            "law": self.problem.law.describe(),
            "frames": len(table),
            "success": self.success,
            "failed_frames": self.failed_frames,
            "n_springs": int(table["n_springs"].max()),
            "peak_pressure": float(table.loc[k, "peak_pressure"]),
            "peak_frame": int(table.loc[k, "frame"]),
            "peak_time": float(table.loc[k, "time"]),
            "max_contact_area": float(table["contact_area"].max()),
            "max_compressive_strain": float(table["max_compressive_strain"].max()),
            "iterations_total": int(table["iterations"].sum()),
            "iterations_mean": float(table["iterations"].mean()),
            "build_time_total": float(table["build_time"].sum()),
            "solve_time_total": float(table["solve_time"].sum()),
            "solve_time_after_first_mean": float(table["solve_time"].iloc[1:].mean()) if len(table) > 1 else None,
            "worst_certificate_residual": float(table["certificate_residual"].max()),
            "exposure": self.exposure.summary(),
        }

    # writers -----------------------------------------------------------------------------
    def to_csv(self, path) -> Path:
        """The per-frame table as CSV (columns :data:`TABLE_COLUMNS`)."""
        return write_data(path, self.table.to_csv(index=False, lineterminator="\n"))

    def to_json(self, path, extra: dict | None = None) -> Path:
        """:meth:`summary` (plus ``extra``) as JSON."""
        data = {**self.summary(), **(extra or {})}
        return write_data(path, json.dumps(_plain(data), indent=2) + "\n")

    def to_pvd(self, path) -> Path:
        """A ParaView time series: ``path`` (``.pvd``) and one ``.vtu`` per frame beside it.

        The frames go into the folder ``<stem>_frames`` next to ``path``.
        """
        from .io import to_vtk

        if self.solutions is None:
            raise InputError("the .pvd series needs the frames' solutions: solve with keep_solutions=True")
        path = Path(path)
        if path.suffix.lower() != ".pvd":
            raise InputError(f"path must end in .pvd, got {str(path)!r}")
        folder = path.with_name(f"{path.stem}_frames")
        files = []
        for k, solution in enumerate(self.solutions):
            files.append(to_vtk(solution, folder / f"frame_{k:04d}.vtu"))
        return write_pvd(path, self.times, files)

    def exposure_to_vtk(self, path) -> Path:
        """The exposure fields on the contact surface (``.vtu``; cell data per site)."""
        import meshio

        from .io import contact_surface

        if not self.solutions:
            raise InputError("the exposure surface needs a frame's solution: solve with keep_solutions=True")
        surface = contact_surface(self.solutions[0], cells="surface" if self.moving else "springs")
        data = {name: np.ascontiguousarray(value, dtype=float) for name, value in self.exposure.fields().items()}
        mesh = meshio.Mesh(surface.points, [(surface.cell_type, surface.cells)],
                           cell_data={name: [value] for name, value in data.items()})
        return write_atomic(path, lambda tmp: meshio.write(tmp, mesh, file_format="vtu"))

    def plot_cycle(self, path, title: str | None = None) -> Path:
        """Peak pressure and contact area over the path (PNG); failed frames marked."""
        from ._plots import plot_cycle

        return plot_cycle(self.table, path, title=title)

    def plot_exposure(self, path, title: str | None = None) -> Path:
        """The exposure map: pressure-time integral and time above the threshold (PNG)."""
        from ._plots import plot_exposure

        # With moving meshes the sites are the faces of mesh 1, which every frame's layer shares.
        return plot_exposure(self.problem.layer, self.exposure, path, moving=self.moving, title=title)

    def write(self, directory, formats=("csv", "json", "vtk", "png"), extra_summary: dict | None = None) -> dict:
        """Write the outputs into ``directory``; returns ``{name: path}``.

        ``csv``: ``frames.csv``; ``json``: ``summary.json``; ``vtk``: ``series.pvd`` with
        ``series_frames/`` and ``exposure.vtu``; ``png``: ``cycle.png`` and ``exposure.png``.
        """
        directory = Path(directory)
        unknown = set(formats) - {"csv", "json", "vtk", "png"}
        if unknown:
            raise InputError(f"formats must be among csv, json, vtk, png, got {sorted(unknown)}")
        files = {}
        if "csv" in formats:
            files["table"] = self.to_csv(directory / "frames.csv")
        if "vtk" in formats and self.solutions:
            files["series"] = self.to_pvd(directory / "series.pvd")
            files["exposure_vtk"] = self.exposure_to_vtk(directory / "exposure.vtu")
        if "png" in formats:
            files["cycle_plot"] = self.plot_cycle(directory / "cycle.png")
            files["exposure_map"] = self.plot_exposure(directory / "exposure.png")
        if "json" in formats:
            files["summary"] = directory / "summary.json"
            extra = {**(extra_summary or {}), "files": {k: str(v) for k, v in files.items()}}
            self.to_json(files["summary"], extra)
        self.files.update(files)
        return files


def write_pvd(path, times, files) -> Path:
    """A ParaView collection (``.pvd``) of ``files`` at ``times`` (s); paths stored relative to it."""
    path = Path(path)
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
             "  <Collection>"]
    for t, file in zip(times, files):
        relative = Path(file).resolve().relative_to(path.parent.resolve()).as_posix()
        lines.append(f'    <DataSet timestep="{float(t):.9g}" group="" part="0" file={quoteattr(relative)}/>')
    lines += ["  </Collection>", "</VTKFile>", ""]
    return write_data(path, "\n".join(lines))


def _plain(value):
    """JSON-ready: numpy scalars and arrays to Python, NaN to None."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, (np.bool_, bool)):
        return bool(value)
    if isinstance(value, (np.integer,)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        return float(value) if np.isfinite(value) else None
    return value
