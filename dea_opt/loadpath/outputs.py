"""What a load path keeps and writes as it goes (:class:`PathOutputs`), beyond its per-frame table.

:func:`~dea_opt.loadpath.solve_path` takes one ``outputs=PathOutputs(...)`` instead of five
keywords of its own: whether the frames' solutions and pressures are kept in memory, the folder
the frames' ``.vtu`` files are streamed into, the regions every frame is split into and the
pressure threshold of the exposure. Units: MPa.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import InputError

__all__ = ["PathOutputs"]


@dataclass(frozen=True)
class PathOutputs:
    """What :func:`~dea_opt.loadpath.solve_path` keeps and writes besides the per-frame table.

    Parameters
    ----------
    keep_solutions : bool
        Keep every frame's :class:`~dea_opt.solution.Solution` (the uncertified one, or None, for
        a failed frame): what :meth:`PathResult.to_pvd` writes the series from without
        ``series``, and what :func:`dea_opt.sensitivity.path_sensitivities` needs.
    keep_pressures : bool
        Keep every frame's pressure per spring (:attr:`PathResult.pressures`; NaN for a failed
        frame). With both False, memory does not grow with the springs x frames.
    series : str or Path, optional
        A folder to write each frame's ``.vtu`` into as it is solved (``frame_NNNN.vtu``;
        :class:`~dea_opt.loadpath.series.FrameSeries`), so that the ParaView series needs no kept
        solutions; :meth:`PathResult.write` then writes the ``.pvd`` naming them. Use
        ``<output>/series_frames``.
    regions : array_like (N,) or callable, optional
        A region label per spring, or ``regions(layer) -> labels`` (e.g. a closure over
        :func:`dea_opt.anatomy.regions.label_by_axis`); default the layer's ``labels``. Each
        region gets per-frame columns (:data:`~dea_opt.loadpath.table.REGION_COLUMNS`).
    threshold : float
        Pressure threshold (MPa, >= 0) of the exposure measures (time above it, the excess over
        it; checked by :class:`~dea_opt.loadpath.exposure.ExposureAccumulator`).
    keep_frames : iterable of int or "peak"
        Frames whose certified solution to keep however ``keep_solutions`` is set
        (:attr:`PathResult.kept`), ``"peak"`` for the certified frame of the largest peak pressure
        (kept as the frames stream by: one solution in memory): what :meth:`PathResult.write`
        draws the pressure maps of.

    Examples
    --------
    A long path that keeps nothing per frame and streams its ParaView frames to disk:

    >>> PathOutputs(keep_solutions=False, keep_pressures=False, series="out/series_frames")  # doctest: +SKIP
    """

    keep_solutions: bool = True
    keep_pressures: bool = True
    series: str | Path | None = None
    regions: Any = None
    threshold: float = 1.0
    keep_frames: Any = ()

    def __post_init__(self):
        for name in ("keep_solutions", "keep_pressures"):
            if not isinstance(getattr(self, name), bool):
                raise InputError(f"PathOutputs.{name} must be True or False, got {getattr(self, name)!r}")
        if self.series is not None and not isinstance(self.series, (str, Path)):
            raise InputError(f"PathOutputs.series must be a folder (str or Path), got {self.series!r}")

    @classmethod
    def of(cls, outputs) -> PathOutputs:
        """``outputs`` itself, or the defaults for None; an :class:`InputError` for anything else."""
        if outputs is None:
            return cls()
        if not isinstance(outputs, cls):
            raise InputError(f"outputs must be a PathOutputs, got {type(outputs).__name__}")
        return outputs
