"""The ParaView time series of a load path: one ``.vtu`` per frame, written as the frame is solved.

A frame that failed is written too, on its layer's surface, with NaN in every field that would
come from an answer (``pressure``, ``strain``, ``spring_force``), so the series has every
frame and a reader sees which ones have no answer. The ``.pvd`` collection names them with
their times. Units: mm, MPa, N, s.
"""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path

from ..files.atomic import write_data
from ..io.surface import SurfaceData, layer_surface, spring_fields
from ..io.vtk import write_surface
from ..io.vtkxml import quoteattr

__all__ = ["FrameSeries", "write_pvd"]


class FrameSeries:
    """Writes ``<folder>/frame_NNNN.vtu`` for each frame as it comes.

    Parameters
    ----------
    folder : str or Path
        Where the frames go (created when missing), e.g. ``out/series_frames``.
    n_frames : int
        The number of frames, for the width of the numbers.
    """

    def __init__(self, folder, n_frames: int):
        self.folder = Path(folder)
        self.digits = max(4, len(str(max(int(n_frames) - 1, 0))))
        self.files: list[Path] = []
        self.times: list[float] = []
        self._layer = None
        self._surface: SurfaceData | None = None

    def write(self, k: int, t: float, layer, solution=None) -> Path:
        """Frame ``k`` at time ``t`` (s): ``solution``'s fields on ``layer``, or NaN (None)."""
        fields = spring_fields(layer, solution, static=self._surface if layer is self._layer else None)
        if layer is not self._layer:
            # The surface and the layer's own fields (gap, normals, labels, ...) are the same in
            # every frame on one layer: made once (the labels' codes sort every label).
            self._layer, self._surface = layer, layer_surface(layer, fields)
        assert self._surface is not None  # made just above for a new layer
        surface = (
            replace(self._surface, cell_data=fields)
            if self._surface.cell_data
            else replace(self._surface, point_data=fields)
        )
        path = write_surface(surface, self.folder / f"frame_{k:0{self.digits}d}.vtu")
        self.files.append(path)
        self.times.append(float(t))
        return path

    def write_pvd(self, path) -> Path:
        """The collection of the frames written so far."""
        return write_pvd(path, self.times, self.files)


def write_pvd(path, times, files) -> Path:
    """A ParaView collection (``.pvd``) of ``files`` at ``times`` (s); paths stored relative to it."""
    path = Path(path)
    lines = [
        '<?xml version="1.0"?>',
        '<VTKFile type="Collection" version="0.1" byte_order="LittleEndian">',
        "  <Collection>",
    ]
    for t, file in zip(times, files):
        relative = Path(os.path.relpath(Path(file).resolve(), path.parent.resolve())).as_posix()
        lines.append(f'    <DataSet timestep="{float(t):.9g}" group="" part="0" file={quoteattr(relative)}/>')
    lines += ["  </Collection>", "</VTKFile>", ""]
    return write_data(path, "\n".join(lines))
