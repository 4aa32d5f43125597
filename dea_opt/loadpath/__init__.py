"""Load paths: one quasi-static solve per frame, warm-started, and the exposure over the cycle.

:func:`solve_path` (:mod:`~dea_opt.loadpath.solve`) walks a sequence of loads with one
:class:`~dea_opt.loadpath.stepper.Stepper` carrying the warm start; a frame that fails is
recorded and the path goes on. It returns a :class:`PathResult`
(:mod:`~dea_opt.loadpath.result`: the per-frame table of :mod:`~dea_opt.loadpath.table`, the
writers) with the contact-stress :class:`Exposure` of every site, accumulated frame by frame
(:mod:`~dea_opt.loadpath.exposure`); what it keeps and streams is a :class:`PathOutputs`
(:mod:`~dea_opt.loadpath.outputs`); :mod:`~dea_opt.loadpath.series` writes the frames'
ParaView files as they are solved; :mod:`~dea_opt.loadpath.frames` counts and checks the frames
and the memory the path will keep. Units: mm, N, N mm, MPa, s.
"""

from .exposure import Exposure, ExposureAccumulator, exposure
from .frames import check_frames, path_memory
from .outputs import PathOutputs
from .result import PathResult
from .series import FrameSeries, write_pvd
from .solve import solve_path
from .table import REGION_COLUMNS, TABLE_COLUMNS

__all__ = [
    "REGION_COLUMNS",
    "TABLE_COLUMNS",
    "Exposure",
    "ExposureAccumulator",
    "FrameSeries",
    "PathOutputs",
    "PathResult",
    "check_frames",
    "exposure",
    "path_memory",
    "solve_path",
    "write_pvd",
]
