"""Regional statistics: how the load splits between parts of the contact.

Regions are sets of springs, given by labels (``SpringLayer.labels`` or an array of your
own), by half-spaces ``{name: (point, normal)}``, or by a cut across one axis
(:func:`split_by_axis`, OpenSim-JAM's medial/lateral, anterior/posterior and
superior/inferior split). Each region reports a :class:`RegionStats`.

A region's force is the resultant of its springs' forces on body 2 (a vector, ``force_vector``,
and its size ``resultant``); its ``share`` of the contact force is that resultant's component
along the contact force (every spring's), over the contact force's size, so the shares of regions
that partition the springs add up to 1 and their parts of the contact force to the whole. The
sum of the springs' force magnitudes (``force_magnitude_sum``, ``sum p_i S_i``) is no force on
anything: where the normals differ it exceeds the resultant (the two compartments of a knee
under 1500 N sum to some 1600 N).

A layer made from one mesh has no labels; :func:`label_by_axis` cuts it in two once, at a
fixed place, and gives the labels a layer (``dataclasses.replace(layer, labels=...)``) or a
load path (``solve_path(..., outputs=PathOutputs(regions=...))``) carries to every output: the frames table, the
plots, the VTK files and the JSON summaries. With an
:class:`~dea_opt.anatomy.AnatomicalFrame` the axis is named (``"medial"``) and the halves
are named by it.

Units: mm, mm^2, N, MPa.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks.inputs import as_float_array, finite_number
from .._checks.thresholds import ZERO_LENGTH
from ..errors import InputError

__all__ = ["RegionStats", "label_by_axis", "region_statistics", "regional_statistics", "split_by_axis"]

_AXES = {"x": 0, "y": 1, "z": 2}


@dataclass(frozen=True)
class RegionStats:
    """The load carried by one region of the contact.

    Attributes
    ----------
    name : str
        The region's name (a label, a half-space name or a side of a split).
    n_springs : int
        Springs in the region.
    area : float
        Area of all the region's springs (mm^2), in contact or not.
    force_vector : ndarray, shape (3,)
        Resultant force of the region's springs on body 2 (N): ``sum p_i S_i n_i``.
    resultant : float
        Its size ``|force_vector|`` (N).
    share : float
        The region's part of the contact force: ``force_vector . F / |F|^2`` with ``F`` the
        resultant of every spring (``Solution.contact_force``), so that the shares of regions
        that partition the springs add up to 1 (and ``share * |F|`` to ``|F|``, in N). NaN when
        the springs carry no force.
    force_magnitude_sum : float
        The sum of the region's spring force magnitudes ``sum p_i S_i`` (N): not a force on
        anything, at least ``resultant``.
    peak_pressure : float
        Largest pressure in the region (MPa); 0 without contact.
    mean_pressure : float
        Area-weighted mean pressure over the region's contact area (MPa); 0 without contact.
    contact_area : float
        Area of the region's springs in contact (mm^2).
    center_of_pressure : ndarray, shape (3,)
        Pressure-weighted centroid of the region's springs (mm); NaN without contact.
    """

    name: str
    n_springs: int
    area: float
    force_vector: np.ndarray
    resultant: float
    share: float
    force_magnitude_sum: float
    peak_pressure: float
    mean_pressure: float
    contact_area: float
    center_of_pressure: np.ndarray

    def as_dict(self) -> dict:
        """Plain Python values (lists for vectors; NaN stays NaN, see ``dea_opt.io``), each name
        ending with its unit (:mod:`dea_opt.units`)."""
        return {
            "name": self.name,
            "n_springs": self.n_springs,
            "area_mm2": self.area,
            "force_vector_N": self.force_vector.tolist(),
            "resultant_N": self.resultant,
            "share": self.share,
            "force_magnitude_sum_N": self.force_magnitude_sum,
            "peak_pressure_MPa": self.peak_pressure,
            "mean_pressure_MPa": self.mean_pressure,
            "contact_area_mm2": self.contact_area,
            "center_of_pressure_mm": self.center_of_pressure.tolist(),
        }


def region_statistics(solution, mask, name: str = "region") -> RegionStats:
    """The :class:`RegionStats` of the springs selected by ``mask``.

    Parameters
    ----------
    solution : Solution
    mask : array_like of bool, shape (N,)
        True for the springs in the region.
    name : str
    """
    layer = solution.problem.layer
    n = len(layer)
    mask = np.asarray(mask)
    if mask.shape != (n,) or mask.dtype != bool:
        raise InputError(f"mask must be booleans of shape ({n},), got shape {mask.shape} and dtype {mask.dtype}")
    every = solution.pressure * layer.areas  # each spring's force magnitude (N)
    total = every @ layer.normals  # the contact force: every spring's resultant on body 2
    weight = every[mask]
    magnitudes = float(weight.sum())
    vector = weight @ layer.normals[mask] if mask.any() else np.zeros(3)
    size = float(total @ total)
    # a contact force that is rounding beside its springs' forces (no load) has no direction
    carried = size > (1e-12 * float(every.sum())) ** 2 and size > 0
    contact = solution.in_contact[mask]
    areas = layer.areas[mask]
    contact_area = float(areas[contact].sum())
    cop = weight @ layer.points[mask] / magnitudes if magnitudes > 0 else np.full(3, np.nan)
    return RegionStats(
        name=str(name),
        n_springs=int(mask.sum()),
        area=float(areas.sum()),
        force_vector=vector,
        resultant=float(np.linalg.norm(vector)),
        share=float(vector @ total) / size if carried else float("nan"),
        force_magnitude_sum=magnitudes,
        peak_pressure=float(solution.pressure[mask].max(initial=0.0)),
        mean_pressure=magnitudes / contact_area if contact_area > 0 else 0.0,
        contact_area=contact_area,
        center_of_pressure=cop,
    )


def _label_masks(labels, n) -> dict:
    labels = np.asarray(labels)
    if labels.shape != (n,):
        raise InputError(f"labels must have shape ({n},), got shape {labels.shape}")
    return {str(value): labels == value for value in np.unique(labels)}


def _unit_vector(name: str, value) -> np.ndarray:
    vector = as_float_array(name, value, (3,))
    length = np.linalg.norm(vector)
    if length <= ZERO_LENGTH:
        raise InputError(f"{name} must be a nonzero vector, got {vector.tolist()}")
    return vector / length


def _plane_masks(planes, points) -> dict:
    if not hasattr(planes, "items"):
        raise InputError(f"planes must be a mapping {{name: (point, normal)}}, got {type(planes).__name__}")
    masks = {}
    for name, spec in planes.items():
        try:
            point, normal = spec
        except (TypeError, ValueError):
            raise InputError(f"planes[{name!r}] must be a pair (point, normal), got {spec!r}") from None
        point = as_float_array(f"planes[{name!r}] point", point, (3,))
        normal = _unit_vector(f"planes[{name!r}] normal", normal)
        masks[str(name)] = (points - point) @ normal >= 0.0
    return masks


def regional_statistics(solution, labels=None, planes=None) -> dict:
    """Resultant force, share of the contact force, peak and mean pressure, contact area and centre
    of pressure per region.

    Parameters
    ----------
    solution : Solution
    labels : array_like, shape (N,), optional
        A region label per spring. Default: the layer's ``labels`` when ``planes`` is not
        given. To get label regions and half-spaces together, pass
        ``labels=solution.problem.layer.labels`` and ``planes``.
    planes : mapping {name: (point (3,), normal (3,))}, optional
        Half-space regions: the springs with ``(x - point) . normal >= 0`` (mm). Half-spaces
        may overlap or leave springs out; their shares then need not add up to 1.

    Returns
    -------
    dict {name: RegionStats}
        Label regions in sorted label order, then the half-spaces in the given order.
        Label regions partition the springs, so their force vectors add up to the contact force
        and their shares to 1.

    Raises
    ------
    InputError
        No regions (no ``labels``, no ``planes`` and a layer without labels), labels of the
        wrong shape, a malformed plane, or a name used twice.
    """
    layer = solution.problem.layer
    n = len(layer)
    if labels is None and planes is None:
        labels = layer.labels
        if labels is None:
            raise InputError(
                "regional_statistics needs regions: the layer has no labels, so pass "
                "labels=(N,) array or planes={name: (point, normal)}"
            )
    masks = _label_masks(labels, n) if labels is not None else {}
    if planes is not None:
        for name, mask in _plane_masks(planes, layer.points).items():
            if name in masks:
                raise InputError(f"planes uses the name {name!r} of a label region; rename it")
            masks[name] = mask
    return {name: region_statistics(solution, mask, name) for name, mask in masks.items()}


def _axis(axis) -> np.ndarray:
    if isinstance(axis, str):
        key = axis.strip().lower()
        sign = -1.0 if key.startswith("-") else 1.0
        key = key.lstrip("+-")
        if key not in _AXES:
            raise InputError(f"axis must be 'x', 'y', 'z' (optionally signed) or a 3-vector, got {axis!r}")
        vector = np.zeros(3)
        vector[_AXES[key]] = sign
        return vector
    return _unit_vector("axis", axis)


def split_by_axis(solution, axis="x", at=None, names=("medial", "lateral")) -> dict:
    """Split the springs in two by a plane across ``axis`` (JAM's medial/lateral split).

    Parameters
    ----------
    solution : Solution
    axis : {"x", "y", "z", "-x", "-y", "-z"} or array_like, shape (3,)
        Direction across which to split; a vector is normalized.
    at : float, "cop", "centroid" or None
        Where to cut, as a coordinate along ``axis`` (mm). ``None`` or ``"cop"``: at the
        centre of pressure (at the area centroid of the springs when nothing is in
        contact); ``"centroid"``: at the area centroid of the springs. The centre of
        pressure separates two contact patches (the knee's compartments); to split one
        patch, give a coordinate.
    names : pair of str
        ``names[0]`` for the springs with coordinate ``< at``, ``names[1]`` for ``>= at``.
        Which side is medial depends on the frame and on the side of the body: check it.

    Returns
    -------
    dict {name: RegionStats}
        Two regions that partition the springs: their force vectors add up to the contact force.
    """
    layer = solution.problem.layer
    direction = _axis(axis)
    try:
        low, high = (str(v) for v in names)
    except (TypeError, ValueError):
        raise InputError(f"names must be a pair of strings, got {names!r}") from None
    if low == high:
        raise InputError(f"names must be two different strings, got {names!r}")
    coordinate = layer.points @ direction
    centroid = float(layer.areas @ coordinate / layer.areas.sum()) if len(layer) else 0.0
    if at is None or (isinstance(at, str) and at == "cop"):
        cop = solution.center_of_pressure
        cut = float(cop @ direction) if np.isfinite(cop).all() else centroid
    elif isinstance(at, str) and at == "centroid":
        cut = centroid
    else:
        if isinstance(at, str):
            raise InputError(f"at must be a number, 'cop', 'centroid' or None, got {at!r}")
        cut = finite_number("at", at)
    below = coordinate < cut
    return {
        low: region_statistics(solution, below, low),
        high: region_statistics(solution, ~below, high),
    }


def label_by_axis(layer, axis="x", at="centroid", names=None, *, anatomy=None) -> np.ndarray:
    """Labels that cut ``layer`` in two across ``axis``, at a fixed coordinate: an auto-split
    of a single mesh (JAM's medial/lateral split) that every frame of a path shares.

    Parameters
    ----------
    layer : SpringLayer
    axis : str or array_like, shape (3,)
        ``"x"``, ``"-y"``, ... or a vector; with ``anatomy``, also an anatomical direction
        (``"medial"``, ``"anterior"``, ``"proximal"`` or their opposites).
    at : float or "centroid"
        Where to cut, as a coordinate along ``axis`` (mm, from the origin of the meshes); by
        default at the springs' area centroid.
    names : pair of str, optional
        ``names[0]`` for the springs with coordinate ``< at``, ``names[1]`` for ``>= at``.
        Default: for an anatomical direction, its opposite then itself (``("lateral",
        "medial")`` for ``axis="medial"``); otherwise ``("medial", "lateral")``, which side is
        which depending on your meshes: check it, or give ``anatomy``.
    anatomy : AnatomicalFrame or dict, optional

    Returns
    -------
    ndarray of str, shape (N,)
    """
    direction, default = _named_axis(axis, anatomy)
    names = default if names is None else names
    try:
        low, high = (str(v) for v in names)
    except (TypeError, ValueError):
        raise InputError(f"names must be a pair of strings, got {names!r}") from None
    if low == high:
        raise InputError(f"names must be two different strings, got {names!r}")
    coordinate = layer.points @ direction
    if isinstance(at, str):
        if at != "centroid":
            raise InputError(f"at must be a number (mm) or 'centroid', got {at!r}")
        cut = float(layer.areas @ coordinate / layer.areas.sum()) if len(layer) else 0.0
    else:
        cut = finite_number("at", at)
    return np.where(coordinate < cut, low, high)


def _named_axis(axis, anatomy) -> tuple:
    if anatomy is not None and isinstance(axis, str) and axis.strip().lower().lstrip("+-") not in _AXES:
        from .frame import _OPPOSITE, AnatomicalFrame

        frame = AnatomicalFrame.from_dict(anatomy)
        key = axis.strip().lower()
        return frame.direction(key), (_OPPOSITE.get(key, "low"), key)
    return _axis(axis), ("medial", "lateral")
