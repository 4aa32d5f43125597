"""Ray casting against triangle meshes: Intel Embree through trimesh, or an exact numpy grid.

Embree (the ``embreex`` package, the optional ``fast`` extra: ``pip install dea-opt[fast]``) is
used when it is installed; otherwise a numpy uniform-grid caster with exact float64
ray/triangle tests, written here because trimesh's own fallback without Embree
(``ray_triangle``) queries its r-tree once per ray and takes minutes on a knee, where this
caster takes about a second (Embree a tenth of that). Both give the same springs
(``tests/mesh/test_mesh.py`` compares them where Embree is installed, and checks the grid caster
against closed forms and in a process where ``embreex`` cannot be imported, on every install).
Every step is vectorized over rays. Lengths in mm.
"""

from __future__ import annotations

import itertools

import numpy as np

from .._checks.thresholds import RAY_EDGE, RAY_PARALLEL, SELF_HIT
from ..errors import InputError, MissingDependencyError
from .readers import as_mesh

__all__ = ["ENGINES", "surface_thickness"]

ENGINES = ("auto", "embree", "grid")


def _expand(starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """``concatenate([arange(s, s + c) for s, c in zip(starts, counts)])``, vectorized."""
    total = int(counts.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    offsets = np.repeat(np.cumsum(counts) - counts, counts)
    return np.repeat(starts, counts) + (np.arange(total) - offsets)


def _box_cells(lo: np.ndarray, hi: np.ndarray):
    """Every integer cell of the boxes ``lo..hi`` (inclusive, (B, 3)): ``(box, cell (C, 3))``."""
    span = np.maximum(hi - lo + 1, 0)
    n = span.prod(axis=1)
    box = np.repeat(np.arange(len(lo)), n)
    local = _expand(np.zeros(len(lo), dtype=np.int64), n)
    s = span[box]
    k = local % s[:, 2]
    j = (local // s[:, 2]) % s[:, 1]
    i = local // (s[:, 2] * s[:, 1])
    return box, lo[box] + np.column_stack([i, j, k])


class _GridCaster:
    """Exact float64 segment/triangle intersection with a uniform-grid broad phase.

    The fallback when Embree is missing, all numpy: triangles are binned in cubic cells of
    about one edge length, each ray is cut into cell-sized pieces, candidates come from the
    cells a piece's box covers, and a Moller-Trumbore test in float64 decides.
    """

    _CHUNK = 1 << 17  # candidate pairs tested at once: small chunks stay in cache

    def __init__(self, mesh):
        self.mesh = mesh
        self.triangles = np.asarray(mesh.triangles, dtype=float)
        v0 = self.triangles[:, 0]
        # (9, F): component rows, so that gathering candidates gives contiguous rows
        self.frames = np.ascontiguousarray(np.hstack([v0, self.triangles[:, 1] - v0, self.triangles[:, 2] - v0]).T)
        edges = np.asarray(mesh.edges_unique_length)
        self.cell = float(edges.mean()) if len(edges) else 1.0
        self.origin = np.asarray(mesh.bounds[0], dtype=float)
        while True:  # a few huge triangles must not flood the grid
            lo, hi = self._cells(self.triangles.min(axis=1), self.triangles.max(axis=1))
            if (hi - lo + 1).prod(axis=1).sum() <= 20 * len(self.triangles) + 10**6:
                break
            self.cell *= 2.0
        self.shape = hi.max(axis=0) + 1
        face, cells = _box_cells(lo, hi)
        key = self._key(cells)
        order = np.argsort(key, kind="stable")
        self.keys, self.faces = key[order], face[order]

    def _cells(self, lo, hi):
        pad = 1e-9 * self.cell
        return (
            np.floor((lo - self.origin - pad) / self.cell).astype(np.int64),
            np.floor((hi - self.origin + pad) / self.cell).astype(np.int64),
        )

    def _key(self, cells):
        return (cells[:, 0] * self.shape[1] + cells[:, 1]) * self.shape[2] + cells[:, 2]

    def _span(self, origins, directions):
        """``(enter, leave)`` per ray: where it is inside the grid's box, padded by a cell (every
        triangle lies inside it); ``enter > leave``, or both infinite, for a ray that misses it."""
        lo = self.origin - self.cell
        hi = self.origin + (self.shape + 1) * self.cell
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            inv = 1.0 / directions
            a, b = (lo - origins) * inv, (hi - origins) * inv
        # fmin/fmax: a NaN (a ray along a face of the box) counts as outside that slab
        enter, leave = np.fmin(a, b).max(axis=1), np.fmax(a, b).min(axis=1)
        return enter, np.where(enter == np.inf, -np.inf, leave)  # parallel to a slab, outside it

    def hits(self, origins, directions, t0, t1):
        """All crossings with ``t0 <= t <= t1`` (scalars or (R,)): ``(ray, face, t)``.

        Each ray is searched only where it crosses the grid's box, so that an unbounded ``t1``
        (``nearest`` up to infinity) costs what the box's width costs."""
        n = len(origins)
        t0 = np.broadcast_to(np.asarray(t0, dtype=float), (n,))
        t1 = np.broadcast_to(np.asarray(t1, dtype=float), (n,))
        enter, leave = self._span(origins, directions)
        first_t, last_t = np.maximum(t0, enter), np.minimum(t1, leave)
        inside = last_t >= first_t
        with np.errstate(invalid="ignore"):
            count = np.where(inside, np.maximum(np.ceil((last_t - first_t) / self.cell), 1), 0).astype(np.int64)
        ray = np.repeat(np.arange(n), count)
        step = _expand(np.zeros(n, dtype=np.int64), count)
        start = first_t[ray] + step * self.cell
        end = np.minimum(start + self.cell, last_t[ray])
        a = origins[ray] + start[:, None] * directions[ray]
        b = origins[ray] + end[:, None] * directions[ray]
        lo, hi = self._cells(np.minimum(a, b), np.maximum(a, b))
        lo, hi = np.maximum(lo, 0), np.minimum(hi, self.shape - 1)  # cells outside hold nothing
        piece, cells = _box_cells(lo, hi)
        keys = self._key(cells)
        first = np.searchsorted(self.keys, keys, "left")
        number = np.searchsorted(self.keys, keys, "right") - first
        out_ray, out_face, out_t = [], [], []
        rows_o, rows_d = np.ascontiguousarray(origins.T), np.ascontiguousarray(directions.T)
        bounds = np.searchsorted(np.cumsum(number), np.arange(0, int(number.sum()), self._CHUNK), "right")
        bounds = np.append(np.unique(bounds), len(keys))
        for lo_i, hi_i in itertools.pairwise(bounds):  # chunks of candidates, not of faces
            cand = _expand(first[lo_i:hi_i], number[lo_i:hi_i])
            r = ray[np.repeat(piece[lo_i:hi_i], number[lo_i:hi_i])]
            f = self.faces[cand]
            t, ok = _moller_trumbore(rows_o[:, r], rows_d[:, r], self.frames[:, f])
            ok &= (t >= t0[r]) & (t <= t1[r])
            out_ray.append(r[ok])
            out_face.append(f[ok])
            out_t.append(t[ok])
        if not out_ray:
            return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0)
        ray, face, t = np.concatenate(out_ray), np.concatenate(out_face), np.concatenate(out_t)
        # a triangle met from several cells is one crossing
        _, unique = np.unique(ray * len(self.triangles) + face, return_index=True)
        return ray[unique], face[unique], t[unique]

    def nearest(self, origins, directions, t_min, t_max):
        """The first crossing with ``t_min < t <= t_max`` per ray: ``(face, t)``, -1/NaN if none.

        Searched in growing windows so that most rays stop after a short segment.
        """
        n = len(origins)
        face, dist = np.full(n, -1, dtype=np.int64), np.full(n, np.nan)
        leave = self._span(origins, directions)[1]
        todo = np.flatnonzero(leave >= t_min)  # a ray that never reaches the box meets nothing
        low, high = t_min, min(t_min + 4 * self.cell, t_max)
        while len(todo):
            ray, f, t = self.hits(origins[todo], directions[todo], low, high)
            keep = t > low if low == t_min else np.ones(len(t), dtype=bool)
            ray, f, t = ray[keep], f[keep], t[keep]
            pick = _first_per_ray(ray, t, len(todo))
            found = pick >= 0
            face[todo[found]], dist[todo[found]] = f[pick[found]], t[pick[found]]
            todo = todo[~found]
            todo = todo[leave[todo] > high]  # a ray whose window has left the box meets nothing more
            if high >= t_max:
                break
            low, high = high, min(t_min + 2 * (high - t_min), t_max)
        return face, dist


def _moller_trumbore(origins, directions, frames):
    """Distance along each ray to its triangle's plane, and whether the ray meets the triangle.

    Arrays are by component: ``origins``, ``directions`` (3, n) and ``frames`` (9, n), each
    triangle as ``(v0, v1 - v0, v2 - v0)``; written out component by component because
    ``np.cross`` on (n, 3) arrays is several times slower.
    """
    ox, oy, oz = origins
    dx, dy, dz = directions
    ax, ay, az, bx, by, bz, cx, cy, cz = frames
    px, py, pz = dy * cz - dz * cy, dz * cx - dx * cz, dx * cy - dy * cx  # d x e2
    det = bx * px + by * py + bz * pz
    ok = np.abs(det) > RAY_PARALLEL * (bx * bx + by * by + bz * bz)
    inv = np.divide(1.0, det, out=np.zeros_like(det), where=ok)
    sx, sy, sz = ox - ax, oy - ay, oz - az
    u = (sx * px + sy * py + sz * pz) * inv
    qx, qy, qz = sy * bz - sz * by, sz * bx - sx * bz, sx * by - sy * bx  # s x e1
    v = (dx * qx + dy * qy + dz * qz) * inv
    t = (cx * qx + cy * qy + cz * qz) * inv
    # edges and vertices belong to every triangle that shares them
    ok &= (u >= -RAY_EDGE) & (v >= -RAY_EDGE) & (u + v <= 1 + RAY_EDGE)
    return t, ok


class _EmbreeCaster:
    """Ray casting with Intel Embree through trimesh (float32 traversal, float64 distances)."""

    def __init__(self, intersector):
        self.intersector = intersector

    def hits(self, origins, directions, t0, t1):
        """All crossings with ``t0 <= t <= t1`` (scalars or (R,)): ``(ray, face, t)``."""
        n = len(origins)
        t0 = np.broadcast_to(np.asarray(t0, dtype=float), (n,))
        t1 = np.broadcast_to(np.asarray(t1, dtype=float), (n,))
        start = origins + t0[:, None] * directions
        ray, face, t = _all_hits(self.intersector, start, directions, t1 - t0)
        t = t + t0[ray]
        keep = t <= t1[ray]
        return ray[keep], face[keep], t[keep]

    def nearest(self, origins, directions, t_min, t_max):
        """The first crossing with ``t_min < t <= t_max`` per ray: ``(face, t)``, -1/NaN if none.

        One first-hit query from ``t_min`` on; the float64 distance to the plane of the face
        it reports is checked, and the rays where float32 traversal returned a face at or
        before ``t_min`` (the starting face itself) are cast again for all their crossings.
        """
        n = len(origins)
        face = np.full(n, -1, dtype=np.int64)
        dist = np.full(n, np.nan)
        if not n:
            return face, dist
        mesh = self.intersector.mesh
        first = np.asarray(self.intersector.intersects_first(origins + t_min * directions, directions), dtype=np.int64)
        found = np.flatnonzero(first >= 0)
        normal = mesh.face_normals[first[found]]
        corner = mesh.triangles[first[found], 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.einsum("ij,ij->i", corner - origins[found], normal) / np.einsum(
                "ij,ij->i", directions[found], normal
            )
        good = t > t_min
        face[found[good]], dist[found[good]] = first[found[good]], t[good]
        again = found[~good]
        if len(again):
            face[again], dist[again] = self._nearest_of_all(origins[again], directions[again], t_min, np.inf)
        beyond = dist > t_max
        face[beyond], dist[beyond] = -1, np.nan
        return face, dist

    def _nearest_of_all(self, origins, directions, t_min, t_max):
        n = len(origins)
        ray, face, t = _all_hits(self.intersector, origins, directions)
        keep = (t > t_min) & (t <= t_max)
        ray, face, t = ray[keep], face[keep], t[keep]
        pick = _first_per_ray(ray, t, n)
        found = pick >= 0
        out_face, out_t = np.full(n, -1, dtype=np.int64), np.full(n, np.nan)
        out_face[found], out_t[found] = face[pick[found]], t[pick[found]]
        return out_face, out_t


def _has_embree() -> bool:
    """Whether trimesh could load its Embree interface. Its own flag: where ``embreex`` is missing,
    trimesh binds ``trimesh.ray.ray_pyembree`` to a placeholder that raises only when used, so
    that importing the name succeeds all the same."""
    from trimesh import ray

    return bool(getattr(ray, "has_embree", False))


def _engine(engine: str) -> str:
    """The engine that will run for ``engine``: ``"embree"`` or ``"grid"`` (validated)."""
    if not isinstance(engine, str) or engine not in ENGINES:
        raise InputError(f"engine must be one of {ENGINES}, got {engine!r}")
    return "grid" if engine == "grid" or (engine == "auto" and not _has_embree()) else "embree"


def _caster(mesh, engine: str):
    """The ray caster for ``mesh``: Embree when possible (``"auto"``), else the numpy grid."""
    if _engine(engine) == "grid":
        cache = getattr(mesh, "_cache", None)  # trimesh empties it when the mesh changes
        cached = cache["dea_opt_grid"] if cache is not None else None
        if cached is None:
            cached = _GridCaster(mesh)
            if cache is not None:
                cache["dea_opt_grid"] = cached
        return cached
    if not _has_embree():
        raise MissingDependencyError(
            "engine='embree' needs the embreex package: pip install embreex (or pip install dea-opt[fast])"
        )
    from trimesh.ray import ray_pyembree

    intersector = mesh.ray
    if not isinstance(intersector, ray_pyembree.RayMeshIntersector):
        intersector = ray_pyembree.RayMeshIntersector(mesh)
    return _EmbreeCaster(intersector)


def _all_hits(intersector, origins: np.ndarray, directions: np.ndarray, reach=None):
    """Every crossing of the rays ``origins + t directions`` (t >= 0) with the mesh, up to ``reach``
    (R,) along each ray when given (mm; the crossings beyond it may be left out).

    Returns ``(ray, face, t)``: the ray index, the face index and the distance along the
    (unit) direction, each of shape (H,). The crossings are trimesh's
    ``intersects_id(multiple_hits=True)``'s: the same queries, each from just past the last
    crossing (and twice as far past it when Embree met the same face again), run here so that a
    ray stops once it is past ``reach`` instead of crossing everything behind (up to 100 times).
    """
    from trimesh import intersections, util

    empty = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0))
    if not len(origins):
        return empty
    mesh = intersector.mesh
    scene = intersector._scene
    ray_origins = np.array(origins, dtype=np.float64)
    ray_directions = util.unitize(np.array(directions, dtype=np.float64))
    base_offset = max(1e-8, mesh.scale * 1e-6)  # trimesh's ray offset (factor 1e-6, floor 1e-8)
    ray_offsets = ray_directions * base_offset
    plane_origins = mesh.triangles[:, 0, :]
    plane_normals = mesh.face_normals
    last_hit = np.full(len(ray_origins), -1, dtype=np.int64)
    live = np.arange(len(ray_origins))
    out_ray, out_face, out_location = [], [], []
    for _ in range(100):
        query = scene.run(ray_origins[live], ray_directions[live])
        hit = query != -1
        if not hit.any():
            break
        hit_rays, hit_tris = live[hit], query[hit]
        dupe = last_hit[hit_rays] == hit_tris
        last_hit[hit_rays] = hit_tris
        ok_rays, ok_tris, dupe_rays = hit_rays[~dupe], hit_tris[~dupe], hit_rays[dupe]
        new_origins, valid = intersections.planes_lines(
            plane_origins=plane_origins[ok_tris],
            plane_normals=plane_normals[ok_tris],
            line_origins=ray_origins[ok_rays],
            line_directions=ray_directions[ok_rays],
        )
        ok_rays, ok_tris = ok_rays[valid], ok_tris[valid]
        out_location.append(new_origins)
        out_face.append(ok_tris)
        out_ray.append(ok_rays)
        ray_origins[ok_rays] = new_origins + ray_offsets[ok_rays]
        ray_offsets[ok_rays] = ray_directions[ok_rays] * base_offset
        ray_offsets[dupe_rays] *= 2.0
        ray_origins[dupe_rays] += ray_offsets[dupe_rays]
        live = np.concatenate([ok_rays, dupe_rays])
        if reach is not None:
            # crossings come in order along a ray: one past its reach has no more to give
            past = np.einsum("ij,ij->i", new_origins - origins[ok_rays], directions[ok_rays]) > reach[ok_rays]
            live = np.concatenate([ok_rays[~past], dupe_rays])
        if not len(live):
            break
    if not out_ray:
        return empty
    ray = np.concatenate(out_ray)
    location = np.concatenate(out_location).reshape(-1, 3)
    # distance recomputed in float64 from the hit's plane point (Embree works in float32)
    t = np.einsum("ij,ij->i", location - origins[ray], directions[ray])
    return ray, np.concatenate(out_face).astype(np.int64), t


def _first_per_ray(ray: np.ndarray, key: np.ndarray, n_rays: int) -> np.ndarray:
    """Per ray, the index of its hit with the smallest ``key``; -1 where the ray has none."""
    out = np.full(n_rays, -1, dtype=np.int64)
    if not len(ray):
        return out
    order = np.lexsort((key, ray))
    sorted_ray = ray[order]
    first = np.ones(len(order), dtype=bool)
    first[1:] = sorted_ray[1:] != sorted_ray[:-1]
    out[sorted_ray[first]] = order[first]
    return out


def _self_epsilon(mesh) -> float:
    """Distance below which a hit is the ray's own starting face (mm)."""
    return SELF_HIT * max(float(mesh.scale), 1.0)


def _through(mesh, caster, origins, directions) -> np.ndarray:
    """Distance from points on ``mesh`` along inward ``directions`` to its far side.

    The nearest crossing beyond the starting face must leave the volume (its face normal
    along the ray); a ray that first enters (it left through a hole) gives NaN.
    """
    face, t = caster.nearest(origins, directions, _self_epsilon(mesh), np.inf)
    found = face >= 0
    leaves = np.zeros(len(face), dtype=bool)
    leaves[found] = np.einsum("ij,ij->i", mesh.face_normals[face[found]], directions[found]) > 0
    return np.where(leaves, t, np.nan)


def _to_bone(bone, caster, origins, directions) -> np.ndarray:
    """Distance along ``directions`` to the first crossing of a bone mesh; NaN if none."""
    return caster.nearest(origins, directions, _self_epsilon(bone), np.inf)[1]


def surface_thickness(mesh, faces=None, *, engine: str = "auto") -> np.ndarray:
    """Cartilage thickness of a closed surface, measured through itself.

    From each face centroid a ray goes along the inward normal (minus the face normal) to the
    far (bone) side of the same surface.

    Parameters
    ----------
    mesh : mesh as accepted by :func:`as_mesh`
        A closed (or nearly closed) cartilage surface with outward normals.
    faces : array_like of int, shape (K,), optional
        The faces to measure (default all).
    engine : {"auto", "embree", "grid"}

    Returns
    -------
    ndarray, shape (K,)
        Thickness in mm; NaN where the ray leaves through a hole or meets nothing.
    """
    m = as_mesh(mesh, name="mesh")
    faces = np.arange(len(m.faces)) if faces is None else _face_index("faces", faces, len(m.faces))
    return _through(m, _caster(m, engine), m.triangles_center[faces], -m.face_normals[faces])


def _face_index(name, faces, n_faces) -> np.ndarray:
    faces = np.asarray(faces)
    if faces.ndim != 1 or not np.issubdtype(faces.dtype, np.integer):
        raise InputError(f"{name} must be a 1-D array of face indices, got {faces.dtype} {faces.shape}")
    if len(faces) and (faces.min() < 0 or faces.max() >= n_faces):
        raise InputError(f"{name} must lie in [0, {n_faces - 1}], got [{faces.min()}, {faces.max()}]")
    return faces
