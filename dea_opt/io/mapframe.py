"""The frame a map is drawn in: anatomical when one is given, else the best-fit plane of the springs.

A :class:`MapFrame` says where the map's origin is (mm), which directions are the screen's
right, up and toward the viewer, and how to label them. With an
:class:`~dea_opt.anatomy.AnatomicalFrame` the map is an anatomical view (superior, anterior,
medial, ...) with labelled sides; without one, the best-fit plane of the springs seen from
body 2, labelled by the nearest coordinate axes. Either way the picture is never mirrored:
right x up points toward the viewer.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks.thresholds import AXIS_ALIGNED

__all__ = ["MapFrame", "best_fit_frame", "map_frame"]

#: A map axis within this angle (degrees) of a coordinate axis is labelled ``~ x``.
_NEAR_AXIS = 20.0
#: The view's name by the direction the viewer looks from.
_VIEWS = {
    "proximal": "superior",
    "distal": "inferior",
    "anterior": "anterior",
    "posterior": "posterior",
    "medial": "medial",
    "lateral": "lateral",
}


def best_fit_frame(points, weights=None, normals=None) -> tuple:
    """An orthonormal frame whose first two axes span the best-fit plane of ``points``.

    Parameters
    ----------
    points : ndarray, shape (N, 3)
        In mm.
    weights : ndarray, shape (N,), optional
        E.g. spring areas; default equal.
    normals : ndarray, shape (N, 3), optional
        When given, the third axis points to the same side as their weighted mean.

    Returns
    -------
    origin : ndarray, shape (3,)
        Weighted centroid (mm).
    axes : ndarray, shape (3, 3)
        Rows ``e1, e2, e3``: ``e3`` the plane normal (least spread, by PCA), ``e1`` the
        coordinate axis most nearly in the plane projected onto it (so a plane normal to
        z gives ``e1 = x``), ``e2 = e3 x e1`` (right-handed).
    """
    points = np.asarray(points, dtype=float)
    w = np.ones(len(points)) if weights is None else np.asarray(weights, dtype=float)
    origin = w @ points / w.sum()
    # The 3 x 3 scatter matrix accumulated by coordinate pairs: no (N, 3) temporary.
    scatter = np.empty((3, 3))
    for i in range(3):
        ci = points[:, i] - origin[i]
        for j in range(i, 3):
            scatter[i, j] = scatter[j, i] = (w * ci) @ (points[:, j] - origin[j])
    _, vectors = np.linalg.eigh(scatter)  # ascending spread
    e3 = vectors[:, 0]
    if normals is not None:
        mean = w @ np.asarray(normals, dtype=float)
        if mean @ e3 < 0:
            e3 = -e3
    k = int(np.argmin(np.abs(e3)))  # the coordinate axis most nearly in the plane
    e1 = np.eye(3)[k] - e3[k] * e3
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(e3, e1)
    return origin, np.array([e1, e2, e3])


@dataclass(frozen=True)
class MapFrame:
    """Where and how a map is drawn.

    Attributes
    ----------
    origin : ndarray, shape (3,)
        The map's (0, 0), in mm.
    axes : ndarray, shape (3, 3)
        Rows: the screen's right, its up, and toward the viewer (right-handed).
    xlabel, ylabel : str
        Axis labels, with units.
    sides : dict {"left", "right", "bottom", "top": str}
        Names written at the map's edges (anatomical frames only; else empty).
    note : str
        One line saying what the frame is (view, origin).
    """

    origin: np.ndarray
    axes: np.ndarray
    xlabel: str
    ylabel: str
    sides: dict
    note: str

    def project(self, points) -> np.ndarray:
        """Map coordinates (..., 2) in mm of ``points`` (..., 3)."""
        # no (N, 3) temporary: project, then shift
        return np.asarray(points, dtype=float) @ self.axes[:2].T - self.origin @ self.axes[:2].T


def _nearest_axis(axis) -> str:
    axis = np.asarray(axis, dtype=float)
    k = int(np.argmax(np.abs(axis)))
    sign = "-" if axis[k] < 0 else ""
    if abs(axis[k]) > 1 - AXIS_ALIGNED:
        return f"{sign}{'xyz'[k]} (mm)"
    if abs(axis[k]) >= np.cos(np.radians(_NEAR_AXIS)):
        return f"~ {sign}{'xyz'[k]} (mm)"
    return ""


def _best_fit(points, areas, normals) -> MapFrame:
    origin, axes = best_fit_frame(points, areas, normals)
    xlabel = _nearest_axis(axes[0]) or "in-plane axis 1 (mm)"
    ylabel = _nearest_axis(axes[1]) or "in-plane axis 2 (mm)"
    where = ", ".join(f"{round(float(c), 1) + 0.0:.1f}" for c in origin)
    note = (
        f"best-fit plane of the springs, seen from body 2; origin at the layer centroid ({where}) mm; "
        f"no anatomical frame given"
    )
    return MapFrame(origin, axes, xlabel, ylabel, {}, note)


def _anatomical(points, areas, normals, anatomy) -> MapFrame:
    origin = anatomy.origin_for(points, areas)
    mean = areas @ normals if normals is not None else np.zeros(3)
    if not np.linalg.norm(mean) > 0:
        mean = best_fit_frame(points, areas)[1][2]
    names = ("medial", "anterior", "proximal")
    dots = [float(anatomy.direction(n) @ mean) for n in names]
    k = int(np.argmax(np.abs(dots)))
    toward = (
        names[k] if dots[k] >= 0 else {"medial": "lateral", "anterior": "posterior", "proximal": "distal"}[names[k]]
    )
    e3 = anatomy.direction(toward)
    up = "anterior" if names[k] == "proximal" else "proximal"
    e2 = anatomy.direction(up)
    e1 = np.cross(e2, e3)
    right = _name_of(anatomy, e1)
    opposite = {
        "medial": "lateral",
        "lateral": "medial",
        "anterior": "posterior",
        "posterior": "anterior",
        "proximal": "distal",
        "distal": "proximal",
    }
    sides = {
        "right": right.capitalize(),
        "left": opposite[right].capitalize(),
        "top": up.capitalize(),
        "bottom": opposite[up].capitalize(),
    }
    where = anatomy.origin_name
    note = f"{_VIEWS[toward]} view (seen from {toward}); origin at the {where}; {anatomy.side} limb"
    return MapFrame(origin, np.array([e1, e2, e3]), f"{right} (mm)", f"{up} (mm)", sides, note)


def _name_of(anatomy, vector) -> str:
    best, name = -2.0, ""
    for candidate in ("medial", "lateral", "anterior", "posterior", "proximal", "distal"):
        dot = float(anatomy.direction(candidate) @ vector)
        if dot > best:
            best, name = dot, candidate
    return name


def map_frame(points, areas=None, normals=None, anatomy=None) -> MapFrame:
    """The :class:`MapFrame` of springs at ``points`` (mm), in ``anatomy`` when given.

    With an :class:`~dea_opt.anatomy.AnatomicalFrame`, the viewer looks along the anatomical
    axis closest to the springs' mean normal, from body 2's side (a tibial plateau is seen
    from proximal: a superior view); up is proximal, or anterior for a superior or inferior
    view. Without one: the best-fit plane seen from body 2.
    """
    points = np.asarray(points, dtype=float)
    areas = np.ones(len(points)) if areas is None else np.asarray(areas, dtype=float)
    if anatomy is None:
        return _best_fit(points, areas, normals)
    from ..anatomy import AnatomicalFrame

    return _anatomical(
        points, areas, None if normals is None else np.asarray(normals, dtype=float), AnatomicalFrame.from_dict(anatomy)
    )
