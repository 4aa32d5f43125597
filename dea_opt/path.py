"""The former name of :mod:`dea_opt.loadpath`, kept so that ``from dea_opt.path import solve_path`` works."""

from .loadpath import (
    TABLE_COLUMNS,
    Exposure,
    PathResult,
    exposure,
    solve_path,
    write_pvd,
)

__all__ = ["TABLE_COLUMNS", "Exposure", "PathResult", "exposure", "solve_path", "write_pvd"]
