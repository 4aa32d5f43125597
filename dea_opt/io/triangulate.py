"""A triangulated surface through the springs of a layer that came without a mesh.

Generated layers (a plate, a sphere on a bed, a socket) and springs tables have points and
normals but no faces. Their VTK files and maps are drawn on triangles whose vertices are the
springs: the springs' data become point data, interpolated across each triangle.

The triangles are the Delaunay triangulation of the springs in a 2-D chart of the layer:

* the best-fit plane when every normal lies within 85 degrees of the mean normal (the layer
  is then a graph over that plane: plates, beds, caps of less than 85 degrees);
* else the stereographic projection of the normals (the Gauss map), one-to-one on a cap of a
  sphere of any coverage (a socket);
* else, as a last resort, the springs grouped by the axis their normal is closest to, each
  group in its own plane (a box): the groups are not stitched together.

A tensor grid in the chart (nx x ny springs, as from ``plate_layer`` or a table of a grid) is
triangulated from its indices, in O(N) time and memory whatever its size. Triangles whose
circumradius exceeds five times the spacing of their springs (``sqrt(area)``) bridge a hole
or the concave part of the outline and are dropped. The result is cached per layer.
"""

from __future__ import annotations

import math
import weakref

import numpy as np

__all__ = ["point_triangulation"]

_PLANE_ANGLE = 85.0  # degrees
_BRIDGE = 5.0  # circumradius / spacing above which a triangle bridges a gap
_CACHE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
#: Bytes per spring of a Delaunay triangulation (Qhull's working memory and the result).
DELAUNAY_BYTES = 900.0


def point_triangulation(layer) -> np.ndarray | None:
    """Triangles (T, 3) of spring indices through the springs of ``layer``, or None.

    None when the layer has fewer than three springs, when they are collinear, or when a
    Delaunay triangulation of an unstructured layer would not fit in memory (the caller
    then writes the springs as points).
    """
    try:
        return _CACHE[layer]
    except (KeyError, TypeError):
        pass
    triangles = _triangulate(layer.points, layer.normals, layer.areas)
    try:
        _CACHE[layer] = triangles
    except TypeError:  # not weak-referenceable: no cache
        pass
    return triangles


def _triangulate(points, normals, areas):
    from .mapframe import best_fit_frame

    n = len(points)
    if n < 3:
        return None
    origin, axes = best_fit_frame(points, areas, normals)
    mean = areas @ normals
    length = float(np.linalg.norm(mean))
    mean = mean / length if length > 0 else axes[2]
    cos = normals @ mean
    if cos.min() > math.cos(math.radians(_PLANE_ANGLE)):
        return _chart(points, areas, points @ axes[:2].T - origin @ axes[:2].T)
    if cos.min() > -1.0 + 1e-6:
        # Stereographic projection of the normals from -mean onto the plane normal to mean.
        e1 = axes[0] - (axes[0] @ mean) * mean
        e1 /= max(np.linalg.norm(e1), 1e-300)
        e2 = np.cross(mean, e1)
        chart = np.column_stack([normals @ e1, normals @ e2]) / (1.0 + cos)[:, None]
        triangles = _chart(points, areas, chart)
        if triangles is not None and len(triangles) >= n:
            return triangles
    return _by_axis(points, normals, areas)


def _by_axis(points, normals, areas):
    """Springs grouped by the signed axis their normal is closest to, each group in its plane."""
    from .mapframe import best_fit_frame

    k = np.abs(normals).argmax(axis=1)
    side = np.sign(normals[np.arange(len(normals)), k])
    group = 2 * k + (side > 0)
    found = []
    for g in np.unique(group):
        index = np.flatnonzero(group == g)
        if len(index) < 3:
            continue
        origin, axes = best_fit_frame(points[index], areas[index], normals[index])
        triangles = _chart(points[index], areas[index], points[index] @ axes[:2].T - origin @ axes[:2].T)
        if triangles is not None:
            found.append(index[triangles])
    return np.concatenate(found) if found else None


def _chart(points, areas, xy):
    """Triangles of the springs at chart coordinates ``xy`` (N, 2), bridges dropped."""
    triangles = _grid(xy)
    if triangles is not None:
        return triangles  # a complete grid: no triangle bridges anything
    triangles = _delaunay(xy)
    if triangles is None or not len(triangles):
        return None
    return _drop_bridges(points, areas, triangles)


def _index_dtype(n: int):
    """int32 indices while they fit: half the memory of int64 for the largest layers."""
    return np.int32 if n < np.iinfo(np.int32).max else np.int64


def _grid(xy):
    """Triangles of a tensor grid from its indices, or None when ``xy`` is not one."""
    n = len(xy)
    if n < 4:
        return None
    low, high = xy.min(axis=0), xy.max(axis=0)
    span = float((high - low).max())
    if span == 0.0:
        return None
    tolerance = 1e-6 * span
    iu, nu = _levels(xy[:, 0], low[0], tolerance)
    if nu < 2 or n % nu:
        return None
    iv, nv = _levels(xy[:, 1], low[1], tolerance)
    if nv < 2 or nu * nv != n:
        return None
    dtype = _index_dtype(n)
    where = np.full(n, -1, dtype=dtype)
    iu *= nv
    iu += iv
    del iv
    where[iu] = np.arange(n, dtype=dtype)
    del iu
    if (where < 0).any():  # two springs on one grid point: not a tensor grid
        return None
    where = where.reshape(nu, nv)
    m = (nu - 1) * (nv - 1)
    triangles = np.empty((2 * m, 3), dtype=dtype)
    corners = (where[:-1, :-1], where[1:, :-1], where[1:, 1:], where[:-1, 1:])  # a, b, c, d: views
    for row, (i, j, k) in enumerate(((0, 1, 2), (0, 2, 3))):
        for column, corner in enumerate((i, j, k)):
            triangles[row * m : (row + 1) * m, column] = corners[corner].reshape(-1)
    return triangles


def _levels(values, low, tolerance):
    """The index of each value among the distinct levels (within ``tolerance``), and their number."""
    keys = np.rint((values - low) / tolerance).astype(np.int64)
    levels = np.unique(keys)  # a sort; searchsorted then beats unique's argsort for the inverse
    if 2 * len(levels) > len(keys):
        return None, 0  # too many levels for a grid
    return np.searchsorted(levels, keys), len(levels)


def _delaunay(xy):
    from scipy.spatial import Delaunay, QhullError

    from .._checks.memory import available_memory

    if DELAUNAY_BYTES * len(xy) > 0.5 * available_memory():
        return None
    try:
        # Qbb Qc Qz Q12: scipy's defaults; QJ joggles cocircular points (grids) into general position.
        return Delaunay(xy, qhull_options="QJ").simplices.astype(_index_dtype(len(xy)))
    except (QhullError, ValueError):
        return None


def _drop_bridges(points, areas, triangles):
    a, b, c = (points[triangles[:, i]] for i in range(3))
    la = np.linalg.norm(b - c, axis=1)
    lb = np.linalg.norm(c - a, axis=1)
    lc = np.linalg.norm(a - b, axis=1)
    twice_area = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    spacing = np.sqrt(areas[triangles].max(axis=1))
    with np.errstate(divide="ignore", invalid="ignore"):
        radius = la * lb * lc / (2.0 * twice_area)
    keep = (twice_area > 0) & (radius <= _BRIDGE * spacing)
    return np.ascontiguousarray(triangles[keep])
