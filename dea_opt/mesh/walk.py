"""A triangle mesh's faces as planes, and rays followed across its edges from a face they met before.

Written math: ``formulations/finite.md`` ("Re-casting"). Springs that follow body 2 meet mesh 2
again and again at poses a fraction of a face apart: a ray whose hit left its face crosses the
same surface on a face next to it. :class:`Walker` finds that face by stepping across the edge
the hit left through (the edge opposite its most negative barycentric coordinate) until the
ray's point on a face's plane lies inside the face; a ray that leaves the mesh's boundary or
needs more steps is left to a ray cast (:mod:`dea_opt.mesh.facecast`). Written by hand: the
ray casters at hand (Embree through trimesh, the numpy grid) start every query from scratch,
and a cartilage surface met once along a ray is a sheet whose neighbouring faces the mesh's
edges name. The walk's loop is compiled (``_walk.c``, built at install where a C compiler is at
hand: one pass over the rays rather than a dozen numpy passes a step, a third of a finite solve's
updates on the knee) and in numpy otherwise, operation for operation the same numbers; so are
the pass that finds where springs' hits are at a pose and which left their face
(:meth:`Planes.track`) and the scan of the faces whose ray meets the plane it met before within
a window (:func:`window_faces`).
"""

from __future__ import annotations

import math
import threading
from typing import Any, NamedTuple

import numpy as np

from .._checks.dependencies import compiled
from .._checks.thresholds import ANGLE_SLACK
from .raycast import _self_epsilon

__all__ = ["Planes", "Track", "Walk", "Walker", "compiled_walk", "dot", "dot3", "window_faces"]

#: Barycentric slack (relative to the face) inside which a point still lies on a face.
ON_FACE = 1e-9
_ONES = np.ones(3)


def compiled_walk() -> Any:
    """The compiled walk (``dea_opt.mesh._walk``, built from ``_walk.c`` at install where a C
    compiler is at hand), or None where it was not built: the numpy walk is used instead."""
    return compiled(f"{__package__}._walk")


def dot(a, b) -> np.ndarray:
    """Row-wise dot products of (K, 3) arrays (twice as fast as ``einsum`` for three columns)."""
    return (a * b) @ _ONES


class Planes:
    """A triangle mesh's faces as planes and barycentric maps, plain arrays: reading a trimesh
    property checks the mesh's hash every time, and these are read many times a solve.

    ``records`` (F, 12) holds, per face, its unit normal ``n`` (3), its plane's offset ``n . v0``,
    and the two rows ``B1, B2`` (3 each) with their offsets ``B . v0`` of the barycentric map
    ``(b1, b2) = (B1 . x - B1 . v0, B2 . x - B2 . v0)``. A pass over K rays gathers the K records
    whole (one cache line a face: gathered row by row, the same numbers miss the cache twelve
    times) and works on them as rows (12, K) (on (K, 3) arrays the products take several times
    longer).
    """

    def __init__(self, mesh):
        triangles = np.array(mesh.triangles, dtype=float)
        self.normals = np.array(mesh.face_normals, dtype=float)
        self.corner = triangles[:, 0].copy()
        self.offset = dot(self.normals, self.corner)
        e1, e2 = triangles[:, 1] - self.corner, triangles[:, 2] - self.corner
        d11, d12, d22 = dot(e1, e1), dot(e1, e2), dot(e2, e2)
        det = d11 * d22 - d12 * d12
        with np.errstate(divide="ignore", invalid="ignore"):
            # the Gram matrix's inverse applied to the edges
            B1 = (d22[:, None] * e1 - d12[:, None] * e2) / det[:, None]
            B2 = (d11[:, None] * e2 - d12[:, None] * e1) / det[:, None]
        records = np.empty((len(self.offset), 12))
        records[:, 0:3], records[:, 3] = self.normals, self.offset
        records[:, 4:7], records[:, 7] = B1, dot(B1, self.corner)
        records[:, 8:11], records[:, 11] = B2, dot(B2, self.corner)
        self.records = records
        # the shortest altitude of each face: a point at barycentric coordinates b lies at least
        # min(b) times it from every edge
        twice_area = np.linalg.norm(np.cross(e1, e2), axis=1)
        longest = np.sqrt(np.maximum(np.maximum(d11, d22), dot(e2 - e1, e2 - e1)))
        with np.errstate(divide="ignore", invalid="ignore"):
            self.altitude = np.where(longest > 0, twice_area / longest, 0.0)
        self.eps = _self_epsilon(mesh)
        self._faces = np.asarray(mesh.faces, dtype=np.int64)
        self._across: np.ndarray | None = None
        self._scratch = threading.local()

    def __getstate__(self) -> dict:
        state = dict(self.__dict__)
        del state["_scratch"]  # buffers, and a thread-local does not pickle
        return state

    def __setstate__(self, state) -> None:
        self.__dict__.update(state)
        self._scratch = threading.local()

    def gathered(self, faces) -> np.ndarray:
        """The records of ``faces`` (K,) as rows (12, K), in buffers kept between calls (per thread:
        planes are shared through their mesh's cache), valid until the next call. Gathered into
        fresh arrays, the megabyte of a pass over 1e4 springs is new memory the kernel maps page
        by page (a page fault every 4 kB, dearer than the pass itself)."""
        k = len(faces)
        buffers = getattr(self._scratch, "buffers", None)
        if buffers is None or buffers[0].shape[0] < k:
            size = max(k, 2 * (0 if buffers is None else buffers[0].shape[0]), 1024)
            buffers = (np.empty((size, 12)), np.empty((12, size)))
            self._scratch.buffers = buffers
        whole, rows = buffers[0][:k], buffers[1][:, :k]
        # mode 'clip': the faces are valid, and under 'raise' numpy writes to a buffer first
        np.take(self.records, faces, axis=0, out=whole, mode="clip")
        np.copyto(rows, whole.T)
        return rows

    def barycentric(self, points, faces, rows: bool = False) -> np.ndarray:
        """``(b0, b1, b2)`` (3, K) of ``points`` (K, 3), or (3, K) with ``rows``, in faces ``faces`` (K,)
        (on their planes)."""
        points = points if rows else np.ascontiguousarray(np.asarray(points).T)
        return _barycentric(self.gathered(np.asarray(faces, dtype=np.int64)), points)

    def beyond(self, faces, bary) -> np.ndarray:
        """The face across the edge a point left each face through: opposite its lowest barycentric
        coordinate (``bary``, (3, K)); the face itself where that edge is the boundary."""
        b = np.nan_to_num(bary, nan=0.0) if np.isnan(bary).any() else bary
        corner = np.where((b[0] <= b[1]) & (b[0] <= b[2]), 0, np.where(b[1] <= b[2], 1, 2))  # the first lowest
        across = self.across.ravel()[3 * np.asarray(faces, dtype=np.int64) + corner]
        return np.where(across >= 0, across, faces)

    def clearance(self, faces, low) -> np.ndarray:
        """A lower bound (mm) on the distance in their faces' planes from points with lowest
        barycentric coordinate ``low`` (K,) to the edges of faces ``faces`` (K,): a point that
        moves less than it stays in its face (0 where ``low`` is not positive)."""
        return np.maximum(low, 0.0) * np.take(self.altitude, faces)

    def track(self, pT, nT, s, valid, pose, faces, tested, clear, measured, m, limits, compiled=None) -> Track:
        """Where the hits of springs on these faces are at mesh 2's ``pose`` (4x4), and which left.

        Spring ``i`` at ``p_i`` along ``n_i`` (rows ``pT``, ``nT`` (3, N)) meets the plane of face
        ``faces[i]`` at gap ``s[i]`` (where ``valid``): its hit, in this mesh's own frame, is
        ``R^T (p + s n - t)``. A hit that moved less than ``clear[i]`` from ``tested[i]`` (N, 3)
        is on its face still; the others are tested (barycentric coordinates, ``ON_FACE``), and
        where on it ``tested`` and ``clear`` (the new :meth:`clearance`) are written in place. A
        hit on its face whose ray turned past ``max_angle`` from facing it (the face's normal
        ``m`` (N, 3)) is met again there, as one that left (a cast judges it lost). Of the hits
        that stayed: those that moved more than ``recast_shift`` (mm) from ``measured`` (N, 3),
        and those with a gap beyond ``max_gap``; ``limits`` is ``(recast_shift, max_gap,
        max_angle)`` (mm, mm, deg). One compiled pass (``_walk.c``) unless ``compiled`` is False
        or it was not built, else numpy, operation for operation the same numbers (:class:`Track`)."""
        shift, max_gap, max_angle = limits
        facing_min = math.cos(math.radians(max_angle)) - ANGLE_SLACK  # as a cast judges the angle
        n = len(faces)
        pT, nT = np.ascontiguousarray(pT, dtype=float), np.ascontiguousarray(nT, dtype=float)
        pose = np.asarray(pose, dtype=float)
        flat = np.ascontiguousarray(np.concatenate([pose[:3, :3].ravel(), pose[:3, 3]]))
        valid = np.ascontiguousarray(valid, dtype=bool)
        s, faces = np.ascontiguousarray(s, dtype=float), np.ascontiguousarray(faces, dtype=np.int64)
        # (a module built before this pass was written has none: numpy then)
        kernel = getattr(compiled_walk(), "track", None) if compiled is None or compiled else None
        if kernel is not None:
            own, status, after = np.empty((3, n)), np.empty(n, dtype=np.uint8), np.empty(n, dtype=np.int64)
            kernel(
                n, len(self.records), ON_FACE, float(shift) ** 2, float(max_gap), facing_min, pT, nT, s,
                valid.view(np.uint8), flat, faces, np.ascontiguousarray(measured, dtype=float), self.records,
                self.altitude, np.ascontiguousarray(self.across, dtype=np.int64),
                np.ascontiguousarray(m, dtype=float), tested, clear, own, status, after,
            )  # fmt: skip
            bits = [(status & bit).astype(bool) for bit in (1, 2, 4, 8)]
            return Track(own, bits[0], bits[1], bits[2], bits[3], after)
        a = np.where(valid, s, 0.0)
        d = [pT[k] - flat[9 + k] for k in range(3)]
        own = np.empty((3, n))
        ray = [(flat[k] * nT[0] + flat[3 + k] * nT[1]) + flat[6 + k] * nT[2] for k in range(3)]  # R^T n
        for k in range(3):  # R^T (p - t) + a R^T n, the kernel's sums in its order
            own[k] = ((flat[k] * d[0] + flat[3 + k] * d[1]) + flat[6 + k] * d[2]) + a * ray[k]
        step = own - tested.T
        check = np.flatnonzero(
            ~valid | (((step[0] * step[0] + step[1] * step[1]) + step[2] * step[2]) >= clear * clear)
        )
        f = faces[check]
        named = (f >= 0) & (f < len(self.records))
        r = self.gathered(np.where(named, f, 0))
        b0, b1, b2 = _barycentric(r, own[:, check])
        low = np.where(named, np.minimum(np.minimum(b0, b1), b2), np.nan)
        on = (low >= -ON_FACE) & valid[check]
        stays = check[on]
        tested[stays] = own[:, stays].T
        clear[stays] = np.where(low[on] > 0.0, low[on], 0.0) * self.altitude[f[on]]
        left = np.zeros(n, dtype=bool)
        left[check] = ~on
        gone = ~on & named
        after = np.full(n, -1, dtype=np.int64)
        after[check[gone]] = self.beyond(f[gone], np.array([b0[gone], b1[gone], b2[gone]]))
        m = np.asarray(m, dtype=float)
        turned = ~left & (-((ray[0] * m[:, 0] + ray[1] * m[:, 1]) + ray[2] * m[:, 2]) < facing_min)
        after[turned] = faces[turned]
        left |= turned
        shifted = own - np.asarray(measured, dtype=float).T
        moved = ~left & (((shifted[0] * shifted[0] + shifted[1] * shifted[1]) + shifted[2] * shifted[2]) > shift**2)
        with np.errstate(invalid="ignore"):
            beyond = ~left & (s > max_gap)
        return Track(own, left, moved, beyond, turned, after)

    def inside(self, points, faces, tolerance: float = ON_FACE, rows: bool = False) -> np.ndarray:
        """Whether ``points`` (K, 3), or (3, K) with ``rows``, lie within faces ``faces`` (K,)
        (barycentric, with ``tolerance``)."""
        b = self.barycentric(points, faces, rows)
        return np.minimum(np.minimum(b[0], b[1]), b[2]) >= -tolerance

    def distance(self, faces, origins, directions) -> np.ndarray:
        """Distance along each ray (K, 3) to the plane of its face, in float64 (inf or NaN along the plane)."""
        normals = np.take(self.normals, faces, axis=0)
        with np.errstate(divide="ignore", invalid="ignore"):
            return (np.take(self.offset, faces) - dot(normals, origins)) / dot(normals, directions)

    @property
    def across(self) -> np.ndarray:
        """``(F, 3)``: the face across the edge opposite each corner (-1 on the boundary, or where
        more than two faces share the edge)."""
        if self._across is None:
            faces = self._faces
            n = len(faces)
            a, b = faces[:, [1, 2, 0]].ravel(), faces[:, [2, 0, 1]].ravel()  # edge k is opposite corner k
            key = np.minimum(a, b) * (int(faces.max(initial=0)) + 1) + np.maximum(a, b)
            order = np.argsort(key, kind="stable")
            sorted_key = key[order]
            across = np.full(3 * n, -1, dtype=np.int64)
            pair = np.flatnonzero(sorted_key[1:] == sorted_key[:-1])
            # exactly two faces on an edge: a third (a non-manifold edge) leaves it to a cast
            single = np.ones(len(pair), dtype=bool)
            if len(pair) > 1:
                single = np.diff(pair, prepend=-2) > 1
                single &= np.diff(pair, append=len(sorted_key) + 2) > 1
            pair = pair[single]
            first, second = order[pair], order[pair + 1]
            across[first], across[second] = second // 3, first // 3
            self._across = across.reshape(n, 3)
        return self._across


def dot3(a, b) -> np.ndarray:
    """Column-wise dot products of (3, K) rows."""
    return np.einsum("ij,ij->j", a, b)


def _barycentric(records, points) -> np.ndarray:
    """``(b0, b1, b2)`` (3, K) of ``points`` (3, K) in the faces of ``records`` (12, K)."""
    out = np.empty((3, records.shape[1]))
    out[1] = dot3(records[4:7], points) - records[7]
    out[2] = dot3(records[8:11], points) - records[11]
    out[0] = 1.0 - out[1] - out[2]
    return out


class Track(NamedTuple):
    """Where springs' hits are on mesh 2 at a pose (:meth:`Planes.track`), per spring (N,)."""

    #: The hits in the mesh's own frame, as rows (3, N).
    own: np.ndarray
    #: The hit left its face (or its gap is not valid there).
    left: np.ndarray
    #: It stayed, and moved more than the shift from where it was measured.
    moved: np.ndarray
    #: It stayed, with a gap beyond ``max_gap``.
    beyond: np.ndarray
    #: On its face, its ray turned past ``max_angle`` from facing it (also ``left``: met again).
    turned: np.ndarray
    #: Where it left: the face across the edge it left through (itself at the boundary, or where it
    #: turned; -1 elsewhere).
    next: np.ndarray


class Walk(NamedTuple):
    """Where rays followed across a mesh's edges crossed it (:meth:`Walker.follow`), per ray (K,)."""

    #: The face whose plane the ray crosses inside it (where not ``found``: the last one tried).
    face: np.ndarray
    #: The distance along the ray to that crossing (NaN where not ``found``).
    t: np.ndarray
    #: False where the walk left the mesh or ran out of steps.
    found: np.ndarray
    #: The crossing's lowest barycentric coordinate in its face (:meth:`Planes.clearance`).
    margin: np.ndarray
    #: ``n . d``: the face's normal against the ray's direction (its sign: entering or leaving).
    along: np.ndarray


class Walker:
    """Rays followed across a mesh's edges: :meth:`follow` from the faces they met before."""

    def __init__(self, planes: Planes, steps: int = 4, compiled: bool | None = None):
        self.planes, self.steps = planes, steps
        #: Whether :meth:`follow` runs the compiled loop (``dea_opt.mesh._walk``, where it was built
        #: at install) or the numpy one; the same numbers either way.
        self.compiled = compiled_walk() is not None if compiled is None else bool(compiled and compiled_walk())

    def follow(self, faces, origins, directions, rows: bool = False) -> Walk:
        """For rays ``origins + t directions`` (K, 3), or (3, K) with ``rows``, that met faces
        ``faces`` (K,) before: the face whose plane each ray crosses inside it, at most ``steps``
        edges away (:class:`Walk`)."""
        face = np.array(faces, dtype=np.int64)
        if rows:
            oT, dT = origins, directions
        else:
            oT = np.asarray(origins, dtype=float).T
            dT = np.asarray(directions, dtype=float).T
        oT = np.ascontiguousarray(oT, dtype=float)
        dT = np.ascontiguousarray(dT, dtype=float)
        # (a walker unpickled where the compiled loop was not built walks in numpy)
        if self.compiled and (kernel := compiled_walk()) is not None:
            return self._follow_compiled(kernel, face, oT, dT)
        return self._follow_numpy(face, oT, dT)

    def _follow_compiled(self, kernel, face, oT, dT) -> Walk:
        """:meth:`follow` in one compiled pass (``_walk.c``): one ray at a time, its steps in a row."""
        k = len(face)
        if oT.shape != (3, k) or dT.shape != (3, k):
            raise ValueError(f"rays must be (3, {k}) rows, got {oT.shape} and {dT.shape}")
        planes = self.planes
        across = np.ascontiguousarray(planes.across, dtype=np.int64)
        t, margin, along = np.empty(k), np.empty(k), np.empty(k)
        found = np.empty(k, dtype=bool)
        # each ray's face is read, then written: ``face`` is the start and the answer
        kernel.follow(
            k, len(planes.records), self.steps, ON_FACE, face, oT, dT, planes.records, across,
            face, t, found.view(np.uint8), margin, along,
        )  # fmt: skip
        return Walk(face, t, found, margin, along)

    def _follow_numpy(self, face, oT, dT) -> Walk:
        """:meth:`follow` in numpy passes over the rays still walking, a step at a time."""
        across = self.planes.across.ravel()
        k = len(face)
        t, margin, along = np.full(k, np.nan), np.zeros(k), np.zeros(k)
        found = np.zeros(k, dtype=bool)
        # a start that names no face ends its walk there, not found (as the compiled loop does)
        active = np.flatnonzero((face >= 0) & (face < len(self.planes.records)))
        o, d = (oT, dT) if len(active) == k else (np.take(oT, active, axis=1), np.take(dT, active, axis=1))
        for step in range(self.steps + 1):
            f = face[active]
            # whole records gathered (96 bytes a face: far fewer cache misses than row by row),
            # then turned into rows for the passes below
            r = self.planes.gathered(f)
            facing = dot3(r[0:3], d)
            with np.errstate(divide="ignore", invalid="ignore"):  # along the plane: inf or NaN
                dist = (r[3] - dot3(r[0:3], o)) / facing
                b = _barycentric(r, o + dist * d)
            low = np.minimum(np.minimum(b[0], b[1]), b[2])
            ok = np.isfinite(dist)
            on = low >= -ON_FACE
            inside = np.flatnonzero(ok & on)
            settled = active[inside]
            t[settled], margin[settled], along[settled] = dist[inside], low[inside], facing[inside]
            found[settled] = True
            out = np.flatnonzero(ok & ~on)  # (a degenerate face's NaN coordinates too: stepped over)
            if step == self.steps or not len(out):
                break
            corner = np.where(b[0, out] == low[out], 0, np.where(b[1, out] == low[out], 1, 2))
            nxt = across[3 * f[out] + corner]  # the face across the edge opposite the lowest corner
            go = nxt >= 0
            keep = out[go]
            active = active[keep]
            face[active] = nxt[go]
            o, d = np.take(oT, active, axis=1), np.take(dT, active, axis=1)
        return Walk(face, t, found, margin, along)


def window_faces(met, tried, centroids, normals, planes: Planes, pose, low: float, high: float, compiled=None):
    """The faces of mesh 1 (indices, increasing) whose ray, from its centroid along its normal
    (``centroids``, ``normals`` (F, 3)), meets the plane of the face of mesh 2 it met before
    (``met`` (F,), -1: none) at mesh 2's ``pose`` (4x4) facing it, at a distance within
    ``[low, high]`` (mm), leaving out the faces ``tried`` (F,) bool.

    One compiled pass over the faces (``_walk.c``) unless ``compiled`` is False or it was not
    built, else numpy, operation for operation the same numbers."""
    pose = np.asarray(pose, dtype=float)
    flat = np.ascontiguousarray(np.concatenate([pose[:3, :3].ravel(), pose[:3, 3]]))
    kernel = getattr(compiled_walk(), "window", None) if compiled is None or compiled else None
    if kernel is not None:
        n1 = len(met)
        out = np.empty(n1, dtype=np.int64)
        count = kernel(
            n1, len(planes.records), float(low), float(high), np.ascontiguousarray(met, dtype=np.int64),
            np.ascontiguousarray(tried, dtype=bool).view(np.uint8), np.ascontiguousarray(centroids, dtype=float),
            np.ascontiguousarray(normals, dtype=float), planes.records, flat, out,
        )  # fmt: skip
        return out[:count]
    known = np.flatnonzero((met >= 0) & (met < len(planes.records)) & ~np.asarray(tried, dtype=bool))
    r = np.take(planes.records, met[known], axis=0)
    m = [(flat[3 * i] * r[:, 0] + flat[3 * i + 1] * r[:, 1]) + flat[3 * i + 2] * r[:, 2] for i in range(3)]
    c, n = np.take(centroids, known, axis=0), np.take(normals, known, axis=0)
    along = (n[:, 0] * m[0] + n[:, 1] * m[1]) + n[:, 2] * m[2]
    ahead = r[:, 3] - (((c[:, 0] - flat[9]) * m[0] + (c[:, 1] - flat[10]) * m[1]) + (c[:, 2] - flat[11]) * m[2])
    with np.errstate(divide="ignore", invalid="ignore"):
        gap = ahead / along
    return known[(along < 0) & (gap >= low) & (gap <= high)]
