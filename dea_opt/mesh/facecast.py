"""Casting some faces of mesh 1: the rules of a cast on a chosen set of faces, at any pose.

Written math: ``formulations/finite.md`` ("Re-casting"). The same decisions as
:func:`dea_opt.mesh.cast_springs` (the nearest face of mesh 2 facing the ray inside the window
``-allowed <= gap <= max_gap``, within ``max_angle`` of facing, rejected behind mesh 1's own far
side, thickness measured through each cartilage) for the faces of mesh 1 a caller asks about
(the springs of a finite-kinematics solve that follow body 2, :mod:`dea_opt.largemotion`), so
that keeping springs up to date costs rays in proportion to what moved. What lies behind each
face of mesh 1 does not depend on the pose and is measured once per face.
"""

from __future__ import annotations

import math

import numpy as np

from .._checks.thresholds import ANGLE_SLACK
from .raycast import _caster, _first_per_ray, _self_epsilon
from .springs import LOST_REASONS, _outcomes, _thickness

__all__ = ["FaceCast", "Mesh1", "cast_faces", "off_face"]

_SPRING = -1


class Mesh1:
    """Mesh 1's faces as a cast sees them, and what lies behind each (measured when first asked).

    :meth:`of` keeps one per mesh and cast options in the mesh's trimesh cache (emptied when the
    mesh changes), so that the solves of a load path measure each face once.
    """

    @classmethod
    def of(cls, cast) -> Mesh1:
        mesh = cast.mesh1
        cache = getattr(mesh, "_cache", None)
        key = f"dea_opt_finite_mesh1_{bool(cast.options['flip'])}_{cast.options['engine']}"
        found = cache[key] if cache is not None else None
        if found is None:
            found = cls(cast)
            if cache is not None:
                cache[key] = found
        return found

    def __init__(self, cast):
        m1, options = cast.mesh1, cast.options
        self.mesh, self.options = m1, options
        self.centroids = np.asarray(m1.triangles_center)
        self.normals = -np.asarray(m1.face_normals) if options["flip"] else np.asarray(m1.face_normals)
        n = len(m1.faces)
        self.back_face = np.full(n, -2, dtype=np.int64)  # -2: not measured yet
        self.depth = np.full(n, np.inf)

    def behind(self, faces) -> tuple[np.ndarray, np.ndarray]:
        """``(back_face, depth)`` of ``faces``: the first crossing of mesh 1 behind each, its far side."""
        todo = faces[self.back_face[faces] == -2]
        if len(todo):
            todo = np.unique(todo)
            face, depth = _caster(self.mesh, self.options["engine"]).nearest(
                self.centroids[todo], -self.normals[todo], _self_epsilon(self.mesh), np.inf
            )
            self.back_face[todo] = face
            self.depth[todo] = np.where(face >= 0, depth, np.inf)
        return self.back_face[faces], self.depth[faces]


class FaceCast:
    """What the rays of some faces of mesh 1 met: a spring or the reason for none, per face."""

    def __init__(self, cast, faces, outcome, q, m, faces2, gap, h1, h2):
        self.cast, self.faces, self.outcome = cast, faces, outcome
        self.q, self.m, self.faces2, self.gap, self.h1, self.h2 = q, m, faces2, gap, h1, h2

    @property
    def spring(self) -> np.ndarray:
        return self.outcome == _SPRING

    @property
    def dropped(self) -> np.ndarray:
        """Faces whose ray met mesh 2 deeper than the window allows (the validity's count)."""
        return self.outcome == LOST_REASONS.index("overlap")

    def subset(self, index) -> FaceCast:
        return FaceCast(
            self.cast,
            self.faces[index],
            self.outcome[index],
            self.q[index],
            self.m[index],
            self.faces2[index],
            self.gap[index],
            self.h1[index],
            self.h2[index],
        )

    def reasons(self, mask) -> dict:
        """``{reason: count}`` of the faces ``mask`` selects that made no spring."""
        codes = self.outcome[mask]
        return {reason: int((codes == i).sum()) for i, reason in enumerate(LOST_REASONS) if (codes == i).any()}

    def thickness2_at(self, faces2, points) -> np.ndarray:
        """Body 2's cartilage thickness measured from ``points`` (own frame) on ``faces2``."""
        m2, options = self.cast.mesh2, self.cast.options
        return _thickness(options["thickness2"], m2, faces2, points, -m2.face_normals[faces2], options["engine"])


def _crossings(m2, engine, origins, directions, look, max_gap, depth, eps1):
    """``(ray, face, t, cos)``: the crossings of mesh 2 facing the rays, from ``-look`` to ``max_gap``.

    One first-hit query per ray; where the first crossing is a face facing the ray in front of
    mesh 1's own far side (a smooth cartilage surface met once, the usual case) it is the only
    candidate, else the ray is cast again for all its crossings (as the cast does for every ray).
    """
    caster = _caster(m2, engine)
    eps = _self_epsilon(m2)
    start, stop = -(look + eps), np.maximum(max_gap, look) + eps
    first, t = caster.nearest(origins + start[:, None] * directions, directions, 0.0, np.inf)
    t = t + start
    found = first >= 0
    cos = np.zeros(len(first))
    cos[found] = -np.einsum("ij,ij->i", m2.face_normals[first[found]], directions[found])
    simple = found & (cos > 0) & (t <= stop) & ~(-t >= depth - eps1)
    missed = ~found | (t > stop)  # nothing ahead inside the window: no hit at all
    again = np.flatnonzero(~simple & ~missed)
    ray, face, dist = np.flatnonzero(simple), first[simple], t[simple]
    if len(again):
        more_ray, more_face, more_t = caster.hits(origins[again], directions[again], start[again], stop[again])
        ray = np.concatenate([ray, again[more_ray]])
        face, dist = np.concatenate([face, more_face]), np.concatenate([dist, more_t])
    cosine = -np.einsum("ij,ij->i", m2.face_normals[face], directions[ray])
    facing = cosine > 0
    return ray[facing], face[facing], dist[facing], cosine[facing]


def cast_faces(cast, pose, faces, allowed, mesh1: Mesh1) -> FaceCast:
    """Cast the faces ``faces`` of mesh 1 (K,) onto mesh 2 at ``pose`` (4x4), each ray allowed the
    overlap ``allowed`` (K,), by the rules of :func:`dea_opt.mesh.cast_springs`."""
    m2, options = cast.mesh2, cast.options
    engine, max_gap = options["engine"], options["max_gap"]
    faces = np.asarray(faces, dtype=np.int64)
    k = len(faces)
    outcome = np.full(k, LOST_REASONS.index("no_hit"), dtype=np.int8)
    q, m = np.full((k, 3), np.nan), np.full((k, 3), np.nan)
    faces2, gap = np.full(k, -1, dtype=np.int64), np.full(k, np.nan)
    h1, h2 = np.full(k, np.nan), np.full(k, np.nan)
    if not k:
        return FaceCast(cast, faces, outcome, q, m, faces2, gap, h1, h2)
    back_face, depth = mesh1.behind(faces)
    look = np.where(np.isfinite(depth), np.maximum(depth, allowed), allowed)
    R, shift = pose[:3, :3], pose[:3, 3]
    origins = (mesh1.centroids[faces] - shift) @ R
    directions = mesh1.normals[faces] @ R
    ray, face, t, cos = _crossings(m2, engine, origins, directions, look, max_gap, depth, _self_epsilon(mesh1.mesh))
    through = -t >= depth[ray] - _self_epsilon(mesh1.mesh)
    window = (t >= -allowed[ray]) & (t <= max_gap)
    rejected = np.zeros(k, dtype=bool)
    rejected[ray[through & window]] = True
    inside = window & ~through
    pick = _first_per_ray(ray[inside], np.abs(t[inside]), k)
    has = np.flatnonzero(pick >= 0)
    hit = np.flatnonzero(inside)[pick[has]]
    aligned = cos[hit] >= math.cos(math.radians(options["max_angle"])) - ANGLE_SLACK
    outcome = _outcomes(k, ray, t, cos, ~through & ~window, rejected, allowed, options)
    outcome[has] = np.where(aligned, _SPRING, LOST_REASONS.index("angle"))
    sel, hit = has[aligned], hit[aligned]
    if len(sel):
        gap[sel], faces2[sel] = t[hit], face[hit]
        q[sel] = origins[sel] + t[hit][:, None] * directions[sel]
        m[sel] = m2.face_normals[face[hit]]
        spec1 = options["thickness1"]
        through1 = None
        if spec1 is None:  # the crossing behind the face, where it leaves the layer
            mesh = mesh1.mesh
            leaves = np.einsum("ij,ij->i", mesh.face_normals[back_face[sel].clip(0)], -mesh1.normals[faces[sel]]) > 0
            through1 = np.where((back_face[sel] >= 0) & leaves, depth[sel], np.nan)
        h1[sel] = _thickness(
            spec1, mesh1.mesh, faces[sel], mesh1.centroids[faces[sel]], -mesh1.normals[faces[sel]], engine, through1
        )
        h2[sel] = _thickness(options["thickness2"], m2, faces2[sel], q[sel], -m2.face_normals[faces2[sel]], engine)
        total = h1[sel] + h2[sel]
        bad = ~(np.isfinite(total) & (total > 0))
        outcome[sel[bad]] = LOST_REASONS.index("thickness")
    return FaceCast(cast, faces, outcome, q, m, faces2, gap, h1, h2)


def off_face(hits, valid, faces, transform, mesh2, tolerance: float = 1e-9) -> np.ndarray:
    """Which hits left the face of mesh 2 their target plane belongs to (bool, (N,)).

    ``hits`` (N, 3, world frame) are taken back to mesh 2's own frame by ``transform`` (its
    pose, 4x4) and their barycentric coordinates in faces ``faces`` (N,) computed; a coordinate
    below ``-tolerance`` puts a hit outside. Springs whose ray misses its plane (``~valid``)
    count as off.
    """
    R, shift = transform[:3, :3], transform[:3, 3]
    own = (np.nan_to_num(hits) - shift) @ R
    tri = np.asarray(mesh2.triangles)[faces]
    a, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    w = own - a
    d11, d12, d22 = (np.einsum("ij,ij->i", e1, e1), np.einsum("ij,ij->i", e1, e2), np.einsum("ij,ij->i", e2, e2))
    w1, w2 = np.einsum("ij,ij->i", w, e1), np.einsum("ij,ij->i", w, e2)
    det = d11 * d22 - d12 * d12
    with np.errstate(divide="ignore", invalid="ignore"):
        b1 = (d22 * w1 - d12 * w2) / det
        b2 = (d11 * w2 - d12 * w1) / det
    inside = (b1 >= -tolerance) & (b2 >= -tolerance) & (b1 + b2 <= 1 + tolerance)
    return ~(inside & valid)
