"""Drawing values of springs (or faces) on a map: vector triangles, or a raster at screen resolution.

A map of a few thousand springs is drawn triangle by triangle. Above :data:`RASTER_LIMIT`
samples a triangle per spring is more than the picture can show (a PNG is about a million
pixels) and costs about 2 GB and 35 s per million springs in matplotlib, so the samples are
binned into a pixel grid instead (each pixel the largest value that falls in it, so a peak is
never averaged away) and drawn as one image: O(N) time, and memory of the image. Region
outlines and labels are drawn on either. Units: mm on the axes.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

__all__ = ["RASTER_LIMIT", "MapGeometry", "draw_contact_edge", "draw_regions", "draw_values", "map_geometry"]

#: Above this many springs (or faces), maps are rasterized.
RASTER_LIMIT = 100_000
#: Pixels along the longer side of a raster map.
RASTER_PIXELS = 700


@dataclass(frozen=True, eq=False)
class MapGeometry:
    """What a map draws, in map coordinates (mm).

    Attributes
    ----------
    xy : ndarray (P, 2)
        The vertices of ``triangles``.
    triangles : ndarray (T, 3) or None
        Triangles; None when the springs cannot be triangulated (drawn as dots). For springs
        on points they are made when first asked for (a raster needs none).
    on : {"faces", "points"}
        Values sit on the triangles (one per face) or on the vertices (one per spring).
    samples : ndarray (S, 2)
        Where each value sits (face centroids, or the points): what a raster bins.
    spacing : float
        Typical distance between samples (mm).
    """

    xy: np.ndarray
    faces: np.ndarray | None
    on: str
    samples: np.ndarray
    spacing: float
    layer: object = None

    @property
    def triangles(self) -> np.ndarray | None:
        if self.on == "faces":
            return self.faces
        from .triangulate import point_triangulation

        return point_triangulation(self.layer)

    @property
    def raster(self) -> bool:
        return len(self.samples) > RASTER_LIMIT

    @cached_property
    def extent(self) -> tuple:
        if self.raster or self.on == "points":
            used = self.samples
        else:
            assert self.faces is not None  # a map on faces has them
            used = self.xy[np.unique(self.faces)]
        return used.min(axis=0), used.max(axis=0)


def map_geometry(layer, frame, sites: str = "springs") -> MapGeometry:
    """The geometry of a map of ``layer`` in ``frame`` (:class:`~dea_opt.io.mapframe.MapFrame`).

    ``sites="springs"``: one value per spring (on its face, or on its point). ``sites="faces"``:
    one value per face of ``layer.surface`` (the exposure of moving meshes).
    """
    if sites == "faces" or (layer.surface is not None and layer.source_face is not None):
        vertices, faces = layer.surface
        faces = np.asarray(faces) if sites == "faces" else np.asarray(faces)[layer.source_face]
        xy = frame.project(vertices)
        if len(faces) > RASTER_LIMIT:
            centroids = (xy[faces[:, 0]] + xy[faces[:, 1]] + xy[faces[:, 2]]) / 3.0
        else:
            centroids = xy[faces].mean(axis=1)
        a, b, c = (np.asarray(vertices)[faces[:, i]] for i in range(3))
        areas = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1) if sites == "faces" else layer.areas
        return MapGeometry(xy, faces, "faces", centroids, _spacing(areas))
    xy = frame.project(layer.points)
    return MapGeometry(xy, None, "points", xy, _spacing(layer.areas), layer)


def _spacing(areas) -> float:
    """``sqrt`` of the median area (of an even sample of at most 10^5: a raster needs no more)."""
    areas = np.asarray(areas, dtype=float)
    if not len(areas):
        return 1.0
    return float(np.sqrt(np.median(areas[:: max(1, len(areas) // 100_000)])))


def draw_values(
    ax, geometry: MapGeometry, values, cmap, norm, *, contact=None, grey=None, edge=None, outline: bool = True
) -> bool:
    """Draw ``values`` (one per sample); where ``contact`` is False, grey. Returns whether the
    contact edge was (or, ``outline=False``, would have been) outlined: for springs on points,
    the zero line of ``edge`` (the strain, interpolated across the triangles) when given, else
    the line between the springs in contact and the others."""
    values = np.asarray(values, dtype=float)
    if geometry.raster:
        return _raster(ax, geometry, values, cmap, norm, contact, grey, outline)
    if geometry.triangles is None or not len(geometry.triangles):
        shown = np.ones(len(values), bool) if contact is None else contact
        if contact is not None and (~contact).any():
            ax.scatter(*geometry.samples[~contact].T, s=4, color=grey(0.5))
        ax.scatter(*geometry.samples[shown].T, s=4, c=values[shown], cmap=cmap, norm=norm)
        return False
    if geometry.on == "faces":
        return _faces(ax, geometry, values, cmap, norm, contact, grey, outline)
    return _points(ax, geometry, values, cmap, norm, contact, grey, edge, outline)


def _faces(ax, geometry, values, cmap, norm, contact, grey, outline=True) -> bool:
    from matplotlib.collections import LineCollection
    from matplotlib.tri import Triangulation

    xy, tris = geometry.xy, geometry.triangles
    if contact is None:
        ax.tripcolor(
            Triangulation(xy[:, 0], xy[:, 1], tris), facecolors=values, cmap=cmap, norm=norm, edgecolors="none"
        )
        return False
    if (~contact).any():
        ax.tripcolor(
            Triangulation(xy[:, 0], xy[:, 1], tris[~contact]),
            facecolors=np.zeros((~contact).sum()),
            cmap=grey,
            vmin=0,
            vmax=1,
            edgecolors="none",
        )
    if contact.any():
        ax.tripcolor(
            Triangulation(xy[:, 0], xy[:, 1], tris[contact]),
            facecolors=values[contact],
            cmap=cmap,
            norm=norm,
            edgecolors="none",
        )
    edges = boundary_edges(tris[contact])
    if outline:
        ax.add_collection(LineCollection(xy[edges], colors="k", linewidths=0.8))
    return len(edges) > 0


def _points(ax, geometry, values, cmap, norm, contact, grey, edge, outline=True) -> bool:
    from matplotlib.collections import LineCollection
    from matplotlib.tri import Triangulation

    xy, tris = geometry.xy, geometry.triangles
    tri = Triangulation(xy[:, 0], xy[:, 1], tris)
    if contact is None:
        ax.tripcolor(tri, values, cmap=cmap, norm=norm, shading="gouraud")
        return False
    ax.tripcolor(tri, np.zeros(len(xy)), cmap=grey, vmin=0, vmax=1, shading="gouraud")
    touching = contact[tris].any(axis=1)
    if touching.any():
        loaded = Triangulation(xy[:, 0], xy[:, 1], tris[touching])
        ax.tripcolor(loaded, np.where(contact, values, 0.0), cmap=cmap, norm=norm, shading="gouraud")
    if 0 < contact.sum() < len(contact):
        if outline and edge is not None:
            ax.tricontour(tri, np.asarray(edge, dtype=float), levels=[0.0], colors="k", linewidths=0.8)
        elif outline:
            ax.tricontour(tri, contact.astype(float), levels=[0.5], colors="k", linewidths=0.8)
        return True
    if contact.all():
        if outline:
            ax.add_collection(LineCollection(xy[boundary_edges(tris)], colors="k", linewidths=0.8))
        return True
    return False


def _pixels(geometry: MapGeometry):
    """The raster grid: ``(flat pixel index of each sample, (ny, nx), low corner, pixel size)``."""
    low, high = geometry.extent
    span = np.maximum(high - low, 1e-9)
    pixel = max(float(span.max()) / RASTER_PIXELS, 1.5 * geometry.spacing)
    nx, ny = (np.floor(span / pixel).astype(int) + 1).tolist()
    ix = np.minimum(((geometry.samples[:, 0] - low[0]) / pixel).astype(np.int64), nx - 1)
    iy = np.minimum(((geometry.samples[:, 1] - low[1]) / pixel).astype(np.int64), ny - 1)
    return iy * nx + ix, (ny, nx), low, pixel


def _fill(image: np.ndarray, present: np.ndarray):
    """Pixels without a sample but surrounded by pixels with one (a finer mesh than the
    raster here, a coarser one there) take the largest neighbour: no speckles of background."""
    from scipy.ndimage import binary_closing, maximum_filter

    holes = binary_closing(present, structure=np.ones((3, 3), bool)) & ~present
    if holes.any():
        grown = maximum_filter(np.where(present, image, -np.inf), size=3, mode="constant", cval=-np.inf)
        image = np.where(holes & np.isfinite(grown), grown, image)
    return image, present | holes


def _raster(ax, geometry, values, cmap, norm, contact, grey, outline=True) -> bool:
    flat, shape, low, pixel = _pixels(geometry)
    size = shape[0] * shape[1]
    count = np.bincount(flat, minlength=size).reshape(shape)
    extent = (low[0], low[0] + shape[1] * pixel, low[1], low[1] + shape[0] * pixel)
    shown = np.isfinite(values) if contact is None else contact & np.isfinite(values)
    image = np.full(size, -np.inf)
    np.maximum.at(image, flat[shown], values[shown])
    image, _ = _fill(image.reshape(shape), image.reshape(shape) > -np.inf)
    image[~np.isfinite(image)] = np.nan
    style = {"origin": "lower", "extent": extent, "interpolation": "nearest", "aspect": "equal"}
    if contact is not None:
        _, inside = _fill(np.zeros(shape), count > 0)
        ax.imshow(np.where(inside, 0.0, np.nan), cmap=grey, vmin=0, vmax=1, **style)
    ax.imshow(image, cmap=cmap, norm=norm, **style)
    if contact is None:
        return False
    touching = np.bincount(flat, weights=contact.astype(float), minlength=size).reshape(shape)
    with np.errstate(invalid="ignore", divide="ignore"):
        fraction = np.where(count > 0, touching / count, 0.0)
    fraction, _ = _fill(fraction, count > 0)
    if 0 < fraction.max() and fraction.min() < 1:
        if outline:
            x = low[0] + (np.arange(shape[1]) + 0.5) * pixel
            y = low[1] + (np.arange(shape[0]) + 0.5) * pixel
            ax.contour(x, y, fraction, levels=[0.5], colors="k", linewidths=0.8)
        return True
    return False


def draw_contact_edge(ax, geometry: MapGeometry, contact, mask, colour, edge=None) -> bool:
    """Draw the part of the contact edge that lies in one region (``mask``) in ``colour``: where
    the springs in ``contact`` end inside the region, not the region's own border. On faces,
    the outline of the faces in contact whose face is in the region; on points, the zero line of
    ``edge`` (the strain) over the region's triangles; on a raster, where half of a pixel's
    springs of the region are in contact. Returns whether anything was drawn."""
    from matplotlib.collections import LineCollection
    from matplotlib.tri import Triangulation

    contact, mask = np.asarray(contact, bool), np.asarray(mask, bool)
    if not (contact & mask).any() or (contact | ~mask).all():
        return False  # the region is all in contact, or out of it: no edge of contact in it
    style = {"colors": colour, "linewidths": 1.4}
    if geometry.raster:
        flat, shape, low, pixel = _pixels(geometry)
        size = shape[0] * shape[1]
        count = np.bincount(flat[mask], minlength=size).reshape(shape)
        hit = np.bincount(flat[mask & contact], minlength=size).reshape(shape)
        fraction = np.ma.masked_where(count == 0, hit / np.maximum(count, 1))
        x = low[0] + (np.arange(shape[1]) + 0.5) * pixel
        y = low[1] + (np.arange(shape[0]) + 0.5) * pixel
        ax.contour(x, y, fraction, levels=[0.5], **style)
        return True
    tris = geometry.triangles
    if tris is None or not len(tris):
        return False
    if geometry.on == "faces":
        edges, owner = _boundary_with_owner(tris[contact])
        edges = edges[mask[np.flatnonzero(contact)[owner]]]
        ax.add_collection(LineCollection(geometry.xy[edges], **style))
        return len(edges) > 0
    inside = mask[tris].all(axis=1)
    if edge is None or not inside.any():
        return False
    xy = geometry.xy
    ax.tricontour(Triangulation(xy[:, 0], xy[:, 1], tris, mask=~inside), np.asarray(edge, float), levels=[0.0], **style)
    return True


def _label_place(geometry: MapGeometry, mask, avoid) -> np.ndarray:
    """Where a region's name goes: the sample of the region farthest from the other regions, the
    layer's outline and the points of ``avoid`` (of a thinned sample: a few thousand at most)."""
    from scipy.spatial import cKDTree

    samples = geometry.samples
    every = max(1, len(samples) // 4000)
    ours = samples[mask][::every]
    blockers = [samples[~mask][::every]]
    triangles = geometry.triangles if not geometry.raster else None
    if triangles is not None and len(triangles):
        blockers.append(geometry.xy[np.unique(boundary_edges(triangles))])
    if len(avoid):
        blockers.append(np.repeat(np.asarray(avoid, dtype=float).reshape(-1, 2), 4, axis=0))
    blocked = np.concatenate([b for b in blockers if len(b)]) if any(len(b) for b in blockers) else None
    if blocked is None or not len(ours):
        return samples[mask].mean(axis=0)
    depth, _ = cKDTree(blocked).query(ours)
    return ours[int(np.argmax(depth))]


def _boundary_with_owner(triangles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`boundary_edges` of ``triangles`` and, for each, the triangle it belongs to."""
    triangles = np.asarray(triangles, dtype=np.int64)
    if not len(triangles):
        return np.zeros((0, 2), dtype=np.int64), np.zeros(0, dtype=np.int64)
    edges = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1)
    owner = np.tile(np.arange(len(triangles)), 3)
    width = int(edges[:, 1].max()) + 1
    keys = edges[:, 0] * width + edges[:, 1]
    _, first, counts = np.unique(keys, return_index=True, return_counts=True)
    once = first[counts == 1]
    return edges[once], owner[once]


def boundary_edges(triangles: np.ndarray) -> np.ndarray:
    """Edges (E, 2) that belong to one triangle only: the outline of a set of triangles."""
    if len(triangles) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    triangles = np.asarray(triangles, dtype=np.int64)
    edges = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1)
    # One integer per edge, in the rows' lexicographic order: numpy.unique of rows (axis=0)
    # sorts a structured view, about ten times slower.
    width = int(edges[:, 1].max()) + 1
    keys, counts = np.unique(edges[:, 0] * width + edges[:, 1], return_counts=True)
    once = keys[counts == 1]
    return np.stack([once // width, once % width], axis=1)


def draw_regions(ax, geometry: MapGeometry, labels, avoid=()) -> None:
    """Outline the borders between the regions of ``labels`` (one per sample) and write each
    region's name deep inside it, away from the points of ``avoid`` (map coordinates: the
    centres of pressure marked on the map)."""
    from matplotlib.collections import LineCollection
    from matplotlib.tri import Triangulation

    labels = np.asarray(labels)
    names = np.unique(labels)
    if len(names) < 2:
        return
    style: dict[str, Any] = {"colors": "w", "linewidths": 1.2, "linestyles": "--"}
    raster = geometry.raster or geometry.triangles is None
    triangles = geometry.triangles if geometry.triangles is not None else np.empty((0, 3), dtype=np.int64)
    if raster:
        flat, shape, low, pixel = _pixels(geometry)
        x = low[0] + (np.arange(shape[1]) + 0.5) * pixel
        y = low[1] + (np.arange(shape[0]) + 0.5) * pixel
        codes = np.searchsorted(names, labels)
        votes = np.bincount(flat * len(names) + codes, minlength=shape[0] * shape[1] * len(names))
        votes = votes.reshape(shape[0] * shape[1], len(names))
        majority = votes.argmax(axis=1).reshape(shape)
        present = _fill(np.zeros(shape), votes.sum(axis=1).reshape(shape) > 0)[1]
    elif geometry.on == "faces":
        outline = {tuple(e) for e in boundary_edges(triangles).tolist()}
    else:
        tri = Triangulation(geometry.xy[:, 0], geometry.xy[:, 1], geometry.triangles)
    for name in names:
        mask = labels == name
        if raster:
            # the border of the pixels where this region has most springs, where the layer is
            inside = np.ma.masked_where(~present, (majority == np.searchsorted(names, name)).astype(float))
            if inside.min() < 0.5 < inside.max():
                ax.contour(x, y, inside, levels=[0.5], **style)
        elif geometry.on == "faces":
            # the edges of the region's outline that are not the outline of the whole layer
            edges = [e for e in boundary_edges(triangles[mask]).tolist() if tuple(e) not in outline]
            if edges:
                ax.add_collection(LineCollection(geometry.xy[np.array(edges)], **style))
        else:
            # half way between a region's springs and its neighbours': one line per border
            ax.tricontour(tri, mask.astype(float), levels=[0.5], **style)
        where = _label_place(geometry, mask, avoid)
        ax.text(
            where[0],
            where[1],
            str(name),
            ha="center",
            va="center",
            fontsize="small",
            fontweight="bold",
            color="k",
            bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "none", "alpha": 0.7},
            zorder=6,
        )
