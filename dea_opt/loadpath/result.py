"""The result of a load path and its files: the per-frame table, CSV, JSON, a ParaView series and plots.

Units: mm, N, N mm, MPa, s.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from ..errors import InputError
from ..io.atomic import write_atomic, write_data
from ..io.summary import write_json
from ..problem import ContactProblem
from .exposure import Exposure

__all__ = ["PathResult", "write_pvd"]


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
        return write_json({**self.summary(), **(extra or {})}, path)

    def to_pvd(self, path) -> Path:
        """A ParaView time series: ``path`` (``.pvd``) and one ``.vtu`` per frame beside it.

        The frames go into the folder ``<stem>_frames`` next to ``path``.
        """
        from ..io import to_vtk

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

        from ..io import contact_surface

        if not self.solutions:
            raise InputError("the exposure surface needs a frame's solution: solve with keep_solutions=True")
        surface = contact_surface(self.solutions[0], cells="surface" if self.moving else "springs")
        data = {name: np.ascontiguousarray(value, dtype=float) for name, value in self.exposure.fields().items()}
        mesh = meshio.Mesh(surface.points, [(surface.cell_type, surface.cells)],
                           cell_data={name: [value] for name, value in data.items()})
        return write_atomic(path, lambda tmp: meshio.write(tmp, mesh, file_format="vtu"))

    def plot_cycle(self, path, title: str | None = None) -> Path:
        """Peak pressure and contact area over the path (PNG); failed frames marked."""
        from ..io.plots import plot_cycle

        return plot_cycle(self.table, path, title=title)

    def plot_exposure(self, path, title: str | None = None) -> Path:
        """The exposure map: pressure-time integral and time above the threshold (PNG)."""
        from ..io.plots import plot_exposure

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
