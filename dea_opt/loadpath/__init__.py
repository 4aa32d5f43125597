"""Load paths: one quasi-static solve per frame, warm-started, and the exposure over the cycle.

:func:`solve_path` (:mod:`~dea_opt.loadpath.solve`) walks a sequence of loads with one
:class:`~dea_opt.loadpath.stepper.Stepper` carrying the warm start; it returns a
:class:`PathResult` (:mod:`~dea_opt.loadpath.result`: the per-frame table, the solutions,
the writers) with the contact-stress :class:`Exposure` of every site
(:mod:`~dea_opt.loadpath.exposure`). Units: mm, N, N mm, MPa, s.
"""

from .exposure import Exposure, exposure
from .result import PathResult, write_pvd
from .solve import TABLE_COLUMNS, solve_path

__all__ = ["TABLE_COLUMNS", "Exposure", "PathResult", "exposure", "solve_path", "write_pvd"]
