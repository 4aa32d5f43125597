"""Every output of one solution at once: VTK, CSV, JSON and the pressure map in one directory."""

from __future__ import annotations

import os
from pathlib import Path

from ..errors import InputError
from .plots import plot_pressure
from .summary import summary_dict, write_json
from .surface import contact_surface
from .tables import to_csv
from .vtk import VTK_EXTENSIONS, to_vtk

__all__ = ["write_results"]


def write_results(
    solution,
    directory,
    *,
    stem: str = "contact",
    vtk: str = ".vtu",
    cells: str = "springs",
    labels=None,
    planes=None,
    regions=None,
    view: str = "plane",
    anatomy=None,
) -> dict:
    """Write ``<stem>.vtu`` (or ``.vtp``), ``.csv``, ``.json`` and ``.png`` into ``directory``.

    Parameters
    ----------
    solution : Solution
    directory : str or os.PathLike
        Created when missing.
    stem : str
        File name without extension.
    vtk : {".vtu", ".vtp"}
    cells : {"springs", "surface"}
        See :func:`contact_surface`.
    labels, planes, regions :
        Regions for the JSON summary; see :func:`summary_dict`.
    view : {"plane", "3d"}
        See :func:`plot_pressure`.
    anatomy : AnatomicalFrame or dict, optional
        The joint's anatomical frame: the map is drawn in it and the JSON gives the centres
        of pressure in it.

    Returns
    -------
    dict {"vtk", "csv", "json", "png": pathlib.Path}

    Examples
    --------
    >>> from dea_opt.anatomy.regions import split_by_axis
    >>> paths = write_results(s, "out", stem="knee",
    ...                       regions=split_by_axis(s, "x"))  # doctest: +SKIP
    >>> assert max(vtk_differences(s, paths["vtk"]).values()) == 0  # doctest: +SKIP
    """
    if not isinstance(stem, str) or not stem or os.sep in stem or (os.altsep and os.altsep in stem):
        raise InputError(f"stem must be a plain file name without directories, got {stem!r}")
    if vtk not in VTK_EXTENSIONS:
        raise InputError(f"vtk must be '.vtu' or '.vtp', got {vtk!r}")
    if isinstance(directory, (str, os.PathLike)) and Path(directory).exists() and not Path(directory).is_dir():
        raise InputError(f"directory must be a directory, got the file {os.fspath(directory)!r}")
    if not isinstance(directory, (str, os.PathLike)):
        raise InputError(f"directory must be a path (str or os.PathLike), got {type(directory).__name__}")
    if view not in ("plane", "3d"):
        raise InputError(f"view must be 'plane' or '3d', got {view!r}")
    # check everything before the first file is written
    summary = summary_dict(solution, labels=labels, planes=planes, regions=regions, anatomy=anatomy)
    contact_surface(solution, cells=cells)
    base = Path(directory)
    out = {"vtk": to_vtk(solution, base / f"{stem}{vtk}", cells=cells)}
    out["csv"] = to_csv(solution, base / f"{stem}.csv")
    out["json"] = write_json(summary, base / f"{stem}.json")
    out["png"] = plot_pressure(solution, base / f"{stem}.png", view=view, anatomy=anatomy)
    return out
