"""The result of a load path and its files: the per-frame table, CSV, JSON, a ParaView series and plots.

Every column of the table and every key of the summary ends with its unit (``peak_pressure_MPa``;
:mod:`dea_opt.units`).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from importlib import import_module
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..errors import InputError, ValidityWarning
from ..files.atomic import write_data
from ..io.summary import anatomy_json, write_json
from ..problem import ContactProblem
from ..validity import CHECK_UNITS, check_column
from .anatomical import COP_COLUMNS, anatomical_columns, anatomical_frame_table, anatomical_origin
from .exposure import Exposure
from .maps import map_jobs
from .series import FrameSeries, write_pvd
from .table import MOTION_UNITS, motion_columns

if TYPE_CHECKING:
    import pandas as pd

__all__ = ["FORMATS", "PathResult", "write_pvd"]

#: What :meth:`PathResult.write` can write.
FORMATS = ("csv", "json", "vtk", "png")


def _largest(values) -> int | None:
    """The position of the largest of ``values`` (a Series), NaN skipped; None when all are NaN."""
    array = values.to_numpy(dtype=float)
    return None if np.isnan(array).all() else int(np.nanargmax(array))


def _nan_or(value):
    return float(value) if value is not None and math.isfinite(value) else math.nan


@dataclass(eq=False)
class PathResult:
    """The frames of a load path and the exposure over it.

    Attributes
    ----------
    table : pandas.DataFrame
        One row per frame: :data:`~dea_opt.loadpath.table.TABLE_COLUMNS`, the validity
        checks, and :data:`~dea_opt.loadpath.table.REGION_COLUMNS` per region. A frame
        without a certified answer has ``success`` False, its ``status`` and ``message``,
        and NaN results.
    times : ndarray (T,)
        s.
    pressures : list of ndarray or None
        Pressure per spring per frame (MPa; NaN for a failed frame), when kept.
    solutions : list of Solution or None
        Every frame's solution when kept (the uncertified one, or None, for a failed frame).
    exposure : Exposure
        Over the certified frames (failed frames are bridged linearly).
    method : str
    problem : ContactProblem
        The problem the path started from.
    moving : bool
        True when body 2's mesh moved (springs cast again each frame).
    regions : dict {name: column prefix}
        The regions with columns in the table (empty without labels).
    frame_files : FrameSeries or None
        The frames' ``.vtu`` files written while solving (``PathOutputs.series``).
    kept : dict
        Solutions kept for their maps (``PathOutputs.keep_frames``): ``{frame: Solution}``,
        and ``"peak": (frame, Solution)`` for the peak frame.
    """

    table: pd.DataFrame
    times: np.ndarray
    pressures: list | None
    solutions: list | None
    exposure: Exposure
    method: str
    problem: ContactProblem
    moving: bool = False
    files: dict = field(default_factory=dict)
    regions: dict = field(default_factory=dict)
    frame_files: FrameSeries | None = None
    kept: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.times)

    # --- which frames ---------------------------------------------------------------------
    @property
    def success(self) -> bool:
        """True when every frame has a certified answer."""
        return bool(self.table["success"].all())

    @property
    def failed_frames(self) -> list[int]:
        """Frames without a certified answer."""
        return self.table.loc[~self.table["success"], "frame"].astype(int).tolist()

    @property
    def valid(self) -> bool:
        """True when every frame is certified and inside the model's validity."""
        return bool(self.table["valid"].all())

    @property
    def frames_outside_validity(self) -> list[int]:
        """Certified frames whose answer lies outside the model's validity."""
        table = self.table
        return table.loc[table["success"] & ~table["valid"], "frame"].astype(int).tolist()

    def failures(self) -> list[dict]:
        """``[{frame, time_s, status, message}]`` of every failed frame."""
        failed = ~self.table["success"].to_numpy(dtype=bool)
        if not failed.any():
            return []
        rows = self.table.loc[failed, ["frame", "time_s", "status", "message"]]
        return [
            {"frame": int(r["frame"]), "time_s": float(r["time_s"]), "status": r["status"], "message": r["message"]}
            for r in rows.to_dict("records")
        ]

    def failure_message(self, shown: int = 3, width: int = 160) -> str:
        """One line naming the frames without a certified answer and why (empty when none):
        ``2 of 51 frames have no certified answer: frame 17 (0.34 s) load_not_supported: ...``."""
        failures = self.failures()
        if not failures:
            return ""
        parts = []
        for f in failures[:shown]:
            reason = f["message"] if len(f["message"]) <= width else f["message"][: width - 3] + "..."
            parts.append(f"frame {f['frame']} ({f['time_s']:g} s) {f['status']}: {reason}")
        more = f"; and {len(failures) - shown} more (frames.csv)" if len(failures) > shown else ""
        return f"{len(failures)} of {len(self)} frames have no certified answer: {'; '.join(parts)}{more}"

    def validity_summary(self) -> dict:
        """Which certified frames are outside validity, and why: per failed check its frames,
        its worst value (and at which frame) and that value's ``unit``."""
        table = self.table
        outside = self.frames_outside_validity
        checks: dict = {}
        mask = (table["success"] & ~table["valid"]).to_numpy(dtype=bool)
        # Only the columns read below, and only when a frame is outside: to_dict of every column
        # of every frame was most of a sweep case's summary.
        columns = [c for c in table.columns if c == "frame" or c.startswith("validity_")]
        for row in table.loc[mask, columns].to_dict("records") if mask.any() else []:
            for name in filter(None, str(row["validity_failed"]).split(";")):
                entry = checks.setdefault(
                    name, {"frames": [], "worst": -math.inf, "worst_frame": None, "unit": CHECK_UNITS.get(name, "1")}
                )
                entry["frames"].append(int(row["frame"]))
                value = row.get(check_column(name), math.nan)
                if math.isfinite(value) and value > entry["worst"]:
                    entry["worst"], entry["worst_frame"] = float(value), int(row["frame"])
        return {
            "valid": self.valid,
            "frames_outside_validity": outside,
            "failed_checks": list(checks),
            "checks": checks,
            "failed_frames": self.failed_frames,
        }

    def _ranges(self, columns: pd.DataFrame, units: dict) -> dict:
        """``{column: {unit, min, max, at_peak}}`` of ``columns`` (rows as :attr:`table`'s) over
        the certified frames: the smallest, the largest and the peak frame's value."""
        certified = self.table["success"].to_numpy(dtype=bool)
        k = _largest(self.table.loc[certified, "peak_pressure_MPa"])
        out = {}
        for column, unit in units.items():
            values = columns.loc[certified, column]
            out[column] = {
                "unit": unit,
                "min": _nan_or(values.min()),
                "max": _nan_or(values.max()),
                "at_peak": math.nan if k is None else float(values.iloc[k]),
            }
        return out

    def motion_summary(self) -> dict:
        """Per free dof (its table column, ``body2_uz_mm``): its unit and, over the certified frames,
        the smallest and largest motion found and that of the peak frame (mm, rad)."""
        units = {column: MOTION_UNITS[column.split("_")[1]] for column in motion_columns(self.problem)}
        return self._ranges(self.table, units)

    def anatomical_table(self, anatomy) -> pd.DataFrame:
        """:attr:`table` with the centre of pressure and the motion found along the anatomical
        axes of ``anatomy`` (an AnatomicalFrame or a dict) appended: ``cop_medial_mm``,
        ``cop_anterior_mm``, ``cop_proximal_mm`` (from the frame's origin),
        ``body<b>_translation_<axis>_mm`` and ``body<b>_rotation_<axis>_rad``; see
        :func:`~dea_opt.loadpath.anatomical.anatomical_frame_table`."""
        import pandas as pd

        return pd.concat([self.table, anatomical_frame_table(self.table, self.problem, anatomy)], axis=1)

    def anatomical_summary(self, anatomy) -> dict:
        """What :meth:`summary` adds for an anatomical frame ``anatomy``: ``anatomy`` (the frame
        and ``origin_used_mm``), and over the certified frames, like :meth:`motion_summary`,
        ``center_of_pressure_anatomical`` (``cop_medial_mm``, ...) and ``motion_anatomical``
        (``body2_translation_proximal_mm``, ``body2_rotation_anterior_rad``, ...)."""
        frame, origin = anatomical_origin(self.problem, anatomy)
        columns = anatomical_frame_table(self.table, self.problem, frame)
        units = anatomical_columns(self.problem)
        cop = {c: u for c, u in units.items() if c in COP_COLUMNS}
        motion = {c: u for c, u in units.items() if c not in COP_COLUMNS}
        return {
            "anatomy": anatomy_json(frame, origin),
            "center_of_pressure_anatomical": self._ranges(columns, cop),
            "motion_anatomical": self._ranges(columns, motion),
        }

    def region_summary(self) -> dict:
        """Per region over the certified frames: mean, smallest and largest force share, the
        peak pressure and its frame, the largest contact area."""
        table = self.table.loc[self.table["success"]]
        out = {}
        for name, prefix in self.regions.items():
            share = table[f"{prefix}_force_share"]
            peak = table[f"{prefix}_peak_pressure_MPa"]
            k = _largest(peak)
            out[name] = {
                "columns": prefix,
                "mean_force_share": _nan_or(share.mean()),
                "min_force_share": _nan_or(share.min()),
                "max_force_share": _nan_or(share.max()),
                "peak_pressure_MPa": _nan_or(peak.max()),
                "peak_frame": None if k is None else int(table["frame"].iloc[k]),
                "peak_time_s": math.nan if k is None else float(table["time_s"].iloc[k]),
                "max_contact_area_mm2": _nan_or(table[f"{prefix}_contact_area_mm2"].max()),
            }
        return out

    def warn_validity(self) -> None:
        """One :class:`ValidityWarning` for the frames outside validity (none when there are none)."""
        summary = self.validity_summary()
        if not summary["frames_outside_validity"]:
            return
        parts = [
            f"{name} in {len(c['frames'])} frame(s) (worst {c['worst']:.4g} at frame {c['worst_frame']})"
            for name, c in summary["checks"].items()
        ]
        warnings.warn(
            f"{len(summary['frames_outside_validity'])} of {len(self)} frames are outside the model's "
            f"validity: {'; '.join(parts)}; see the validity columns of the table",
            ValidityWarning,
            stacklevel=4,
        )

    def summary(self, anatomy=None) -> dict:
        """Headline numbers of the path (plain Python values; NaN where no frame has an answer;
        every key of a number ends with its unit, :mod:`dea_opt.units`);
        with an anatomical frame ``anatomy`` (an AnatomicalFrame or a dict) also
        :meth:`anatomical_summary`'s ``anatomy``, ``center_of_pressure_anatomical`` and
        ``motion_anatomical``."""
        table = self.table
        ok = table.loc[table["success"]]
        k = _largest(ok["peak_pressure_MPa"])
        out = {
            "method": self.method,
            "law": self.problem.law.describe(),
            "frames": len(table),
            "success": self.success,
            "failed_frames": self.failed_frames,
            "failures": self.failures()[:50],
            "valid": self.valid,
            "validity": self.validity_summary(),
            "n_springs": int(table["n_springs"].max()),
            "peak_pressure_MPa": math.nan if k is None else float(ok["peak_pressure_MPa"].iloc[k]),
            "peak_frame": None if k is None else int(ok["frame"].iloc[k]),
            "peak_time_s": math.nan if k is None else float(ok["time_s"].iloc[k]),
            "max_contact_area_mm2": _nan_or(ok["contact_area_mm2"].max()),
            "max_compressive_strain": _nan_or(ok["max_compressive_strain"].max()),
            "iterations_total": int(table["iterations"].sum()),
            "iterations_mean": float(table["iterations"].mean()),
            "build_time_total_s": float(table["build_time_s"].sum()),
            "solve_time_total_s": float(table["solve_time_s"].sum()),
            "solve_time_after_first_mean_s": float(table["solve_time_s"].iloc[1:].mean()) if len(table) > 1 else None,
            "worst_certificate_residual": _nan_or(table["certificate_residual"].max()),
            "motion": self.motion_summary(),
            "regions": self.region_summary(),
            "exposure": self.exposure.summary(),
        }
        if anatomy is not None:
            out.update(self.anatomical_summary(anatomy))
        return out

    def frame_solution(self, k: int):
        """Frame ``k``'s certified solution when it was kept (:attr:`solutions`, :attr:`kept`), else None."""
        if k in self.kept:
            return self.kept[k]
        peak = self.kept.get("peak")
        if peak is not None and peak[0] == k:
            return peak[1]
        if self.solutions is not None and 0 <= k < len(self.solutions) and bool(self.table["success"].iloc[k]):
            return self.solutions[k]
        return None

    # --- writers ------------------------------------------------------------------------
    def to_csv(self, path, anatomy=None) -> Path:
        """The per-frame table as CSV (floats in their shortest round-trip text); with an
        anatomical frame ``anatomy``, :meth:`anatomical_table`'s columns after the table's."""
        table = self.table if anatomy is None else self.anatomical_table(anatomy)
        return write_data(path, table.to_csv(index=False, lineterminator="\n", float_format=None))

    def to_json(self, path, extra: dict | None = None, summary: dict | None = None, anatomy=None) -> Path:
        """:meth:`summary` (with ``anatomy``, plus ``extra``) as JSON; ``summary``: one the caller
        already has (the anatomical keys are added when ``anatomy`` is given and it has none)."""
        if summary is None:
            summary = self.summary(anatomy)
        elif anatomy is not None and "motion_anatomical" not in summary:
            summary = {**summary, **self.anatomical_summary(anatomy)}
        return write_json({**summary, **(extra or {})}, path)

    def to_pvd(self, path) -> Path:
        """A ParaView time series: ``path`` (``.pvd``) and one ``.vtu`` per frame.

        The frames written while solving (``PathOutputs.series``) when there are any, else written now
        from the kept solutions into the folder ``<stem>_frames`` next to ``path``.
        """
        path = Path(path)
        if path.suffix.lower() != ".pvd":
            raise InputError(f"path must end in .pvd, got {str(path)!r}")
        if self.frame_files is not None and self.frame_files.files:
            return self.frame_files.write_pvd(path)
        if self.solutions is None:
            raise InputError(
                "the .pvd series needs the frames' solutions (PathOutputs(keep_solutions=True)) or frames "
                "written while solving (PathOutputs(series=<folder>))"
            )
        series = FrameSeries(path.with_name(f"{path.stem}_frames"), len(self))
        for k, (t, solution) in enumerate(zip(self.times, self.solutions)):
            layer = self._frame_layer(k, solution)
            series.write(k, t, layer, solution if self.table["success"].iloc[k] else None)
        return series.write_pvd(path)

    def _frame_layer(self, k, solution):
        if solution is not None:
            return solution.problem.layer
        if self.moving:
            raise InputError(
                f"frame {k} failed before its springs were cast; write the series while solving (PathOutputs(series=<folder>))"
            )
        return self.problem.layer

    def exposure_to_vtk(self, path) -> Path:
        """The exposure fields on the contact surface (``.vtu``): per spring, or per face of
        mesh 1 when body 2's mesh moved."""
        from ..io.surface import SurfaceData, _label_data, layer_surface
        from ..io.vtk import write_surface

        layer = self.problem.layer
        data = {name: np.ascontiguousarray(value, dtype=float) for name, value in self.exposure.fields().items()}
        if self.moving:
            assert layer.surface is not None  # a moving mesh's springs were cast from its surface
            vertices, faces = layer.surface
            surface = SurfaceData(np.asarray(vertices), np.asarray(faces, dtype=np.int64), "triangle", data)
        else:
            if layer.labels is not None:
                data["label"] = _label_data(layer.labels)
            surface = layer_surface(layer, data)
        return write_surface(surface, path)

    def plot_cycle(self, path, title: str | None = None, anatomy=None) -> Path:
        """Applied force and moment, pressure, contact area and the regions' force shares over
        the path (PNG); failed frames and frames outside validity marked."""
        return _draw(self._cycle_job(path, title, anatomy))

    def plot_exposure(self, path, title: str | None = None, anatomy=None) -> Path:
        """The exposure map: pressure-time integral and time above the threshold (PNG)."""
        return _draw(self._exposure_job(path, title, anatomy))

    def _cycle_job(self, path, title=None, anatomy=None) -> tuple:
        """The cycle plot as a picture job ``(module, function, args, kwargs)`` (:mod:`dea_opt.run.pictures`)."""
        kwargs = {"title": title, "regions": self.regions or None, "anatomy": anatomy}
        return "dea_opt.io.cycle", "plot_cycle", (self.table, path), kwargs

    def _exposure_job(self, path, title=None, anatomy=None) -> tuple:
        from ..io.marks import path_verdict

        # With moving meshes the sites are the faces of mesh 1, which every frame's layer shares.
        kwargs = {"moving": self.moving, "title": title, "anatomy": anatomy, "verdict": path_verdict(self.table)}
        return "dea_opt.io.cycle", "plot_exposure", (self.problem.layer, self.exposure, path), kwargs

    def write(
        self,
        directory,
        formats=FORMATS,
        extra_summary: dict | None = None,
        anatomy=None,
        summary: dict | None = None,
        pictures=None,
        title: str | None = None,
        maps=(),
    ) -> dict:
        """Write the outputs into ``directory``; returns ``{name: path}``.

        ``csv``: ``frames.csv``; ``json``: ``summary.json``; ``vtk``: ``series.pvd`` (the
        frames written while solving, or ``series_frames/`` written now from the kept
        solutions) and ``exposure.vtu``; ``png``: ``cycle.png``, ``exposure.png``, the peak
        frame's pressure map ``peak.png`` (when its solution was kept: ``PathOutputs(keep_frames=("peak",))``)
        and ``map_frame_<k>.png`` for each frame of ``maps`` (:mod:`~dea_opt.loadpath.maps`);
        ``title`` heads every picture. With an
        anatomical frame ``anatomy`` the PNGs are drawn in it, ``frames.csv`` ends with
        :meth:`anatomical_table`'s columns and ``summary.json`` holds
        :meth:`anatomical_summary`'s keys. ``summary``: :meth:`summary`, when the caller
        already has it (it is computed once). ``pictures``: a
        :class:`~dea_opt.run.pictures.PictureWorker` to draw the PNGs in while the other files are
        written (the same pictures, drawn here if it fails).
        """
        directory = Path(directory)
        unknown = set(formats) - set(FORMATS) - {"html"}  # the report is the run's (dea_opt.report)
        if unknown:
            raise InputError(f"formats must be among {', '.join(FORMATS)}, got {sorted(unknown)}")
        if pictures is not None and not callable(getattr(pictures, "files", None)):
            raise InputError(
                f"pictures must be a dea_opt.run.pictures.PictureWorker (or None: drawn here), got {type(pictures).__name__}"
            )
        files = {}
        # A PictureWorker draws the PNGs into temporary files reserved beside them and stages them here
        # once drawn (its process does not see this run's staging): published with the rest.
        with _DrawnHere() if pictures is None else pictures.files() as drawn:
            if "png" in formats:  # handed over first: a PictureWorker draws them while the rest is written
                drawn.submit("cycle_plot", directory / "cycle.png", lambda p: self._cycle_job(p, title, anatomy))
                drawn.submit(
                    "exposure_map", directory / "exposure.png", lambda p: self._exposure_job(p, title, anatomy)
                )
                for name, (target, job) in map_jobs(self, directory, title, anatomy, maps).items():
                    drawn.submit(name, target, job)
            if "csv" in formats:
                files["table"] = self.to_csv(directory / "frames.csv", anatomy=anatomy)
            if "vtk" in formats and (self.solutions or (self.frame_files is not None and self.frame_files.files)):
                files["series"] = self.to_pvd(directory / "series.pvd")
            if "vtk" in formats:
                files["exposure_vtk"] = self.exposure_to_vtk(directory / "exposure.vtu")
            files.update(drawn.results())
        if "json" in formats:
            files["summary"] = directory / "summary.json"
            extra = {**(extra_summary or {}), "files": {k: str(v) for k, v in files.items()}}
            self.to_json(files["summary"], extra, summary=summary, anatomy=anatomy)
        self.files.update(files)
        return files


def _draw(job: tuple):
    """Run a picture job ``(module, function, args, kwargs)`` in this process; its value."""
    module, function, args, kwargs = job
    return getattr(import_module(module), function)(*args, **kwargs)


class _DrawnHere:
    """The pictures of :meth:`PathResult.write` without a worker: each drawn in this process into
    its output (written atomically, so staged with the run's other files) when :meth:`results`
    is asked for, as :class:`dea_opt.run.pictures.PictureFiles` does for a worker."""

    def __init__(self):
        self._jobs: dict = {}

    def submit(self, name: str, target, job) -> None:
        self._jobs[name] = (Path(target), job)

    def results(self) -> dict:
        jobs, self._jobs = self._jobs, {}
        for target, job in jobs.values():
            _draw(job(target))
        return {name: target for name, (target, _) in jobs.items()}

    def __enter__(self) -> _DrawnHere:
        return self

    def __exit__(self, *exc) -> None:
        self._jobs = {}
