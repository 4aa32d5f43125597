"""The ParaView time series of a load path: one ``.vtu`` per frame, written as the frame is solved.

A frame that failed is written too, on its layer's surface, with NaN in every field that would
come from an answer (``pressure``, ``strain``, ``spring_force``), so the series has every
frame and a reader sees which ones have no answer. The ``.pvd`` collection names them with
their times. Units: mm, MPa, N, s.

A load path's solve writes its frames in a thread of its own (``background=True``): each frame's
file is fsynced before it is staged (:mod:`dea_opt.files.atomic`), a wait on the disk of 5-10 ms a
frame that the solve of the next frame need not sit through (the wait releases the GIL). The
frames' files are the same either way; :meth:`FrameSeries.finish` waits for them and raises the
error of a write that failed.
"""

from __future__ import annotations

import os
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np

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
    background : bool
        Write each frame in a thread of this series (one at a time, in order) while the caller goes
        on; :meth:`finish` (or :meth:`write_pvd`) waits for them. Every frame's arrays are copied
        when it is handed over, so the caller may reuse its own.
    """

    #: Frames handed to the thread and not yet written, at most (the caller waits beyond): one, so
    #: that a frame's copy is the only memory the thread adds (a frame of 10^6 springs: ~100 MB).
    _QUEUE = 1

    def __init__(self, folder, n_frames: int, *, background: bool = False):
        self.folder = Path(folder)
        self.digits = max(4, len(str(max(int(n_frames) - 1, 0))))
        self.files: list[Path] = []
        self.times: list[float] = []
        self._layer = None
        self._surface: SurfaceData | None = None
        self._background = background
        self._thread: ThreadPoolExecutor | None = None
        self._pending: list[Future] = []

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
        path = self.folder / f"frame_{k:0{self.digits}d}.vtu"
        if self._background:
            self._hand_over(surface, path)
        else:
            write_surface(surface, path)
        self.files.append(path)
        self.times.append(float(t))
        return path

    def _hand_over(self, surface: SurfaceData, path: Path) -> None:
        """Queue ``surface`` to be written to ``path`` by this series' thread (its arrays copied)."""
        copy = {name: np.array(value) for name, value in (surface.cell_data or surface.point_data).items()}
        surface = replace(surface, cell_data=copy) if surface.cell_data else replace(surface, point_data=copy)
        if self._thread is None:
            self._thread = ThreadPoolExecutor(max_workers=1, thread_name_prefix="dea-opt-series")
        while self._pending and (self._pending[0].done() or len(self._pending) >= self._QUEUE):
            self._pending.pop(0).result()  # waits while the disk is behind; a failed write raises here
        self._pending.append(self._thread.submit(write_surface, surface, path))

    def finish(self) -> None:
        """Wait for the frames handed to the thread; raise the first error of a write that failed."""
        pending, self._pending = self._pending, []
        try:
            for future in pending:
                future.result()
        finally:
            self.close()

    def close(self) -> None:
        """End the thread: frames not begun are dropped, the one being written is waited for (a run
        that stops leaves no file being written into its folder)."""
        thread, self._thread = self._thread, None
        if thread is not None:
            thread.shutdown(wait=True, cancel_futures=True)

    def write_pvd(self, path) -> Path:
        """The collection of the frames written so far (once every frame is written)."""
        self.finish()
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
