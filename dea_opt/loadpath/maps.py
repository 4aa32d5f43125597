"""The pressure maps of a load path's frames: the peak frame's, and those the scenario asks for.

The frames are streamed, so a map is drawn from a solution :func:`~dea_opt.loadpath.solve_path`
kept for it (``PathOutputs.keep_frames``: the peak frame's as the frames go by, and the chosen frames'),
with the verdict of the frame's row of the table: a frame outside validity is stamped so
(:mod:`dea_opt.io.marks`), the dropped springs the peak frame's re-cast found included.
"""

from __future__ import annotations

import math

from ..errors import InputError
from ..validity import check_column

__all__ = ["PEAK_MAP", "frame_map_name", "frame_verdict", "map_jobs"]

#: The peak frame's map, in the output folder.
PEAK_MAP = "peak.png"


def frame_map_name(k: int) -> str:
    """``map_frame_0012.png``: the map of frame ``k``."""
    return f"map_frame_{k:04d}.png"


def frame_verdict(table, k: int):
    """``(mark, reason)`` of frame ``k``'s row (:data:`~dea_opt.io.marks.CLEAN` when certified
    and valid)."""
    from ..io.marks import CLEAN

    row = table.loc[table["frame"] == k].iloc[0]
    if not row["success"]:
        return "NO CERTIFIED ANSWER", f"frame {k}: {row['status']}"
    if row["valid"]:
        return CLEAN
    parts = []
    for name in filter(None, str(row["validity_failed"]).split(";")):
        value = row.get(check_column(name), math.nan)
        parts.append(f"{name} {value:.4g}" if isinstance(value, float) and math.isfinite(value) else name)
    return "OUTSIDE VALIDITY", f"frame {k}: " + ", ".join(parts)


def map_jobs(result, directory, title=None, anatomy=None, frames=()) -> dict:
    """``{name: (target, job)}``: the picture jobs (:mod:`dea_opt.run.pictures`) of the peak frame's
    map (``peak_map``, :data:`PEAK_MAP`) and of each frame of ``frames`` (``map_frame_<k>``,
    :func:`frame_map_name`), from the solutions ``result`` kept; ``job(path)`` draws into
    ``path``."""
    jobs = {}
    table = result.table
    peak = result.kept.get("peak")
    if peak is not None:
        k, solution = peak
        jobs["peak_map"] = (directory / PEAK_MAP, _job(solution, table, k, title, anatomy, "peak frame"))
    for k in frames:
        solution = result.frame_solution(k)
        if solution is None:
            if not 0 <= k < len(table):
                raise InputError(f"[output] maps names frame {k}, but the load path has {len(table)} frames")
            continue  # a frame without a certified answer has no map (frames.csv says why)
        jobs[f"map_frame_{k}"] = (directory / frame_map_name(k), _job(solution, table, k, title, anatomy, "frame"))
    return jobs


def _job(solution, table, k, title, anatomy, what):
    row = table.loc[table["frame"] == k].iloc[0]
    heading = f"{what} {k}, {row['time_s']:.3g} s"
    kwargs = {
        "title": f"{title}: {heading}" if title else heading,
        "anatomy": anatomy,
        "verdict": frame_verdict(table, k),
    }
    return lambda path: ("dea_opt.io.plots", "plot_pressure", (solution, path), kwargs)
