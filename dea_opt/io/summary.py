"""JSON: the summary of a solution, and the one sanitiser every JSON file of dea_opt goes through.

:func:`jsonable` makes plain JSON values of what dea_opt reports (numpy scalars and arrays,
objects with ``as_dict``, paths), NaN and infinities becoming ``null``, so the files are
strict JSON. Every number's unit is the suffix of its key (``peak_pressure_MPa``; or, in an
object with a ``unit`` key, that key): :mod:`dea_opt.units`.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from .._version import __version__
from ..errors import InputError
from ..files.atomic import file_path, write_data
from .surface import label_codes

__all__ = ["anatomy_json", "jsonable", "read_json", "summary_dict", "to_json", "write_json"]


def jsonable(value):
    """Plain JSON values: NaN and infinities become ``None``, arrays become lists.

    Mappings and sequences are converted item by item, objects with ``as_dict`` through
    it, numpy scalars to Python ones, paths to strings, anything else to ``str``.
    """
    if isinstance(value, Mapping):
        return {str(k): jsonable(v) for k, v in value.items()}
    if hasattr(value, "as_dict"):
        return jsonable(value.as_dict())
    if isinstance(value, np.ndarray):
        return jsonable(value.tolist())
    if isinstance(value, (list, tuple)):
        return [jsonable(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, str):
        return value
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    return str(value)


def write_json(data, path, indent: int = 2) -> Path:
    """Write ``jsonable(data)`` as strict JSON (atomically) and return the path."""
    return write_data(path, json.dumps(jsonable(data), indent=indent, allow_nan=False) + "\n")


def summary_dict(solution, *, labels=None, planes=None, regions=None, anatomy=None) -> dict:
    """Everything :func:`to_json` writes, as JSON-safe Python values (NaN -> ``None``).

    Builds on :meth:`Solution.summary` (method, status, law, ``n_springs``, peak and mean
    pressure, contact area, centre of pressure, contact force and moment, ``u``,
    iterations, build and solve times, certificate, reactions) and adds ``message``,
    ``force_magnitude_sum_N`` (the sum of the springs' force magnitudes: no force on anything;
    the contact force is ``contact_force_N``), ``moment_about_mm`` (the point the moment is taken
    about: body 2's reference, where the motion took it for finite kinematics), ``regions``,
    ``label_codes`` (text labels only), ``info`` (the solver's own report: counts and relative
    residuals) and the dea_opt version. Every key of a number ends with its unit
    (:mod:`dea_opt.units`).

    Parameters
    ----------
    solution : Solution
    labels, planes :
        Passed to :func:`dea_opt.anatomy.regions.regional_statistics`. Without both, the layer's
        labels make the regions when it has any.
    regions : mapping {name: RegionStats}, optional
        Further regions, e.g. from :func:`dea_opt.anatomy.regions.split_by_axis`.
    anatomy : AnatomicalFrame or dict, optional
        Adds ``anatomy`` (the frame) and, for the contact and every region,
        ``center_of_pressure_anatomical``: ``{medial_mm, anterior_mm, proximal_mm}`` from the
        frame's origin (the layer's centroid unless it names one).

    Returns
    -------
    dict
    """
    from ..anatomy.regions import RegionStats, regional_statistics

    layer = solution.problem.layer
    found = {}
    if labels is not None or planes is not None:
        found = regional_statistics(solution, labels=labels, planes=planes)
    elif layer.labels is not None:
        found = regional_statistics(solution)
    if regions is not None:
        if not hasattr(regions, "items"):
            raise InputError(f"regions must be a mapping {{name: RegionStats}}, got {type(regions).__name__}")
        for name, stats in regions.items():
            if not isinstance(stats, RegionStats):
                raise InputError(f"regions[{name!r}] must be a RegionStats, got {type(stats).__name__}")
            if str(name) in found:
                raise InputError(f"regions repeats the region name {name!r}")
            found[str(name)] = stats
    out = {"dea_opt_version": __version__, **solution.summary()}
    out.update(
        message=solution.message,
        force_magnitude_sum_N=solution.total_normal_force,
        moment_about_mm=[float(v) for v in solution.moment_point],
        regions={name: stats.as_dict() for name, stats in found.items()},
        info=solution.info,
    )
    if layer.labels is not None and not np.issubdtype(layer.labels.dtype, np.integer):
        out["label_codes"] = label_codes(layer.labels)
    if anatomy is not None:
        _add_anatomy(out, solution, found, anatomy)
    return jsonable(out)


def anatomy_json(frame, origin) -> dict:
    """An anatomical frame as JSON: its unit vectors (``medial``, ``anterior``, ``proximal``), its
    ``side``, the ``origin_mm`` it names (None: the layer's centroid) and ``origin_used_mm``."""
    out = frame.as_dict()
    out["origin_mm"] = out.pop("origin")
    out["origin_used_mm"] = np.asarray(origin, dtype=float).tolist()
    return out


def _add_anatomy(out: dict, solution, regions: dict, anatomy) -> None:
    """The anatomical frame and the centres of pressure in it (mm from its origin)."""
    from ..anatomy import AnatomicalFrame

    frame = AnatomicalFrame.from_dict(anatomy)
    origin = frame.layer_origin(solution.problem.layer)

    def where(point):
        values = frame.coordinates(point, origin)
        return dict(zip(("medial_mm", "anterior_mm", "proximal_mm"), values.tolist()))

    out["anatomy"] = anatomy_json(frame, origin)
    out["center_of_pressure_anatomical"] = where(solution.center_of_pressure)
    for name, stats in regions.items():
        out["regions"][name]["center_of_pressure_anatomical"] = where(stats.center_of_pressure)


def to_json(solution, path, *, labels=None, planes=None, regions=None, anatomy=None, indent: int = 2) -> Path:
    """Write the summary of ``solution`` as JSON (see :func:`summary_dict` for the keys).

    The file is strict JSON: NaN (e.g. the centre of pressure without contact) is
    written as ``null``.

    Parameters
    ----------
    solution : Solution
    path : str or os.PathLike
    labels, planes, regions :
        Regions to report; see :func:`summary_dict`.
    anatomy : AnatomicalFrame or dict, optional
        Centres of pressure in the anatomical frame too; see :func:`summary_dict`.
    indent : int

    Returns
    -------
    pathlib.Path
    """
    return write_json(
        summary_dict(solution, labels=labels, planes=planes, regions=regions, anatomy=anatomy), path, indent
    )


def read_json(path) -> dict:
    """Read a JSON file (e.g. written by :func:`to_json`)."""
    target = file_path(path)
    if not target.is_file():
        raise InputError(f"path: no such file {str(target)!r}")
    with open(target, encoding="utf-8") as handle:
        return json.load(handle)
