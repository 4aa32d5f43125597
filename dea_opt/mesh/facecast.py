"""Casting some faces of mesh 1: the rules of a cast on a chosen set of faces, at any pose.

Written math: ``formulations/finite.md`` ("Re-casting"). The same decisions as
:func:`dea_opt.mesh.cast_springs` (the nearest face of mesh 2 facing the ray inside the window
``-allowed <= gap <= max_gap``, within ``max_angle`` of facing, rejected behind mesh 1's own far
side, thickness measured through each cartilage) for the faces of mesh 1 a caller asks about
(the springs of a finite-kinematics solve that follow body 2, :mod:`dea_opt.finite`), so
that keeping springs up to date costs rays in proportion to what moved.

What does not depend on the pose is measured once per mesh and kept with it
(:mod:`dea_opt.mesh.faces`: :class:`Mesh1`, :class:`Mesh2`, :class:`FarSide`).
"""

from __future__ import annotations

import math

import numpy as np

from .._checks.thresholds import ANGLE_SLACK
from .faces import FarSide, Mesh1, Mesh2
from .raycast import _caster, _first_per_ray
from .springs import LOST_REASONS, _outcomes
from .walk import Planes, dot

__all__ = ["FaceCast", "FarSide", "Mesh1", "Mesh2", "cast_faces", "follow_faces", "measure", "off_face"]

_SPRING = -1


class FaceCast:
    """What the rays of some faces of mesh 1 met: a spring or the reason for none, per face."""

    def __init__(self, cast, faces, outcome, q, m, faces2, gap, h1, h2, far2=None):
        self.cast, self.faces, self.outcome = cast, faces, outcome
        self.q, self.m, self.faces2, self.gap, self.h1, self.h2 = q, m, faces2, gap, h1, h2
        # the far face of mesh 2 each thickness was measured to (-1: none; -2: not measured)
        self.far2 = np.full(len(faces), -2, dtype=np.int64) if far2 is None else far2
        self.first2 = np.full(len(faces), -1, dtype=np.int64)  # what each ray met first (cast_faces)
        self.clear = np.zeros(len(faces))  # how far each hit may move on its face (0: not known)

    @property
    def spring(self) -> np.ndarray:
        return self.outcome == _SPRING

    @property
    def dropped(self) -> np.ndarray:
        """Faces whose ray met mesh 2 deeper than the window allows (the validity's count)."""
        return self.outcome == LOST_REASONS.index("overlap")

    def subset(self, index) -> FaceCast:
        """The faces ``index`` selects (a boolean mask or indices): their springs or reasons."""
        index = np.flatnonzero(index) if np.asarray(index).dtype == bool else index
        return FaceCast(
            self.cast,
            *(
                np.take(getattr(self, name), index, axis=0)  # by index: a mask costs twice as much
                for name in ("faces", "outcome", "q", "m", "faces2", "gap", "h1", "h2", "far2")
            ),
        )

    def reasons(self, mask) -> dict:
        """``{reason: count}`` of the faces ``mask`` selects that made no spring."""
        codes = self.outcome[mask]
        return {reason: int((codes == i).sum()) for i, reason in enumerate(LOST_REASONS) if (codes == i).any()}

    def thickness2_at(self, faces2, points) -> np.ndarray:
        """Body 2's cartilage thickness measured from ``points`` (own frame) on ``faces2``."""
        return Mesh2.of(self.cast).thickness(self.cast.options["thickness2"], faces2, points)[0]


class _Crossings:
    """The crossings of mesh 2 a cast judges for K rays: ``ray``, ``face``, ``t``, ``cos`` (one entry
    a crossing), ``unique`` (at most one a ray), and ``first`` (K,): the face a ray met first, when
    it faces the ray (-1 otherwise), from which the ray can be followed at the next pose."""

    def __init__(self, ray, face, t, cos, unique, first):
        self.ray, self.face, self.t, self.cos, self.unique = ray, face, t, cos, unique
        self.first = first


def _crossings(mesh2: Mesh2, origins, directions, look, max_gap, depth, eps1, met=None) -> _Crossings:
    """The crossings of mesh 2 facing the rays, from ``-look`` to ``max_gap``.

    The first crossing from ``-look`` on: followed across mesh 2's edges from ``met`` (K,) where
    given (>= 0), cast (one first-hit query) for the others and where the walk finds nothing
    facing the ray ahead of ``-look``. Where the first crossing is a face facing the ray in front
    of mesh 1's own far side (a smooth cartilage surface met once, the usual case) it is the only
    candidate, else the ray is cast again for all its crossings (as the cast does for every ray).
    """
    eps = mesh2.planes.eps
    start, stop = -(look + eps), np.maximum(max_gap, look) + eps
    k = len(origins)
    first, t = np.full(k, -1, dtype=np.int64), np.full(k, np.nan)
    cos = np.zeros(k)
    known = np.zeros(k, dtype=bool)
    if met is not None and (met >= 0).any():
        walk = np.flatnonzero(met >= 0)
        face, dist, found, _, along = mesh2.walker.follow(met[walk], origins[walk], directions[walk])
        c = -along
        with np.errstate(invalid="ignore"):
            good = found & (c > 0) & (dist >= start[walk])
        walk = walk[good]
        first[walk], t[walk], cos[walk], known[walk] = face[good], dist[good], c[good], True
    todo = np.flatnonzero(~known)
    if len(todo):
        face, dist = mesh2.first(origins[todo] + start[todo, None] * directions[todo], directions[todo])
        first[todo], t[todo] = face, dist + start[todo]
        hit = todo[face >= 0]
        cos[hit] = -dot(np.take(mesh2.planes.normals, first[hit], axis=0), directions[hit])
    found = first >= 0
    with np.errstate(invalid="ignore"):
        simple = found & (cos > 0) & (t <= stop) & ~(-t >= depth - eps1)
        missed = ~found | (t > stop)  # nothing ahead inside the window: no hit at all
    again = np.flatnonzero(~simple & ~missed)
    ray = np.flatnonzero(simple)
    facing_first = np.where(found & (cos > 0), first, -1)
    if not len(again):
        return _Crossings(ray, first[ray], t[ray], cos[ray], True, facing_first)
    caster = _caster(mesh2.mesh, mesh2.engine)
    more_ray, more_face, more_t = caster.hits(origins[again], directions[again], start[again], stop[again])
    more_cos = -dot(np.take(mesh2.planes.normals, more_face, axis=0), directions[again[more_ray]])
    facing = more_cos > 0
    return _Crossings(
        np.concatenate([ray, again[more_ray[facing]]]),
        np.concatenate([first[ray], more_face[facing]]),
        np.concatenate([t[ray], more_t[facing]]),
        np.concatenate([cos[ray], more_cos[facing]]),
        False,
        facing_first,
    )


def _empty(cast, faces, points=None) -> FaceCast:
    """No spring for any of ``faces`` yet; ``points`` (q, m: (K, 3) each) when the caller
    has them already (else NaN: three fresh arrays of 1e4 rows cost more than the pass that fills them)."""
    k = len(faces)
    q, m = (np.full((k, 3), np.nan) for _ in range(2)) if points is None else points
    return FaceCast(
        cast,
        faces,
        np.full(k, LOST_REASONS.index("no_hit"), dtype=np.int8),
        q,
        m,
        np.full(k, -1, dtype=np.int64),
        np.full(k, np.nan),
        np.full(k, np.nan),
        np.full(k, np.nan),
        np.full(k, -2, dtype=np.int64),
    )


def _rays(pose, faces, mesh1: Mesh1):
    """The rays of faces ``faces`` of mesh 1 in mesh 2's own frame at ``pose``: ``(origins, directions)``."""
    R, shift = pose[:3, :3], pose[:3, 3]
    return (np.take(mesh1.centroids, faces, axis=0) - shift) @ R, np.take(mesh1.normals, faces, axis=0) @ R


def measure(out: FaceCast, mesh1: Mesh1, mesh2: Mesh2, far=None) -> None:
    """The thicknesses of ``out``'s springs (``far``, (K,): the far faces to try first); a spring
    whose thickness cannot be measured, or is not positive, is none (outcome ``thickness``)."""
    sel = np.flatnonzero(out.spring)
    if not len(sel):
        return
    out.h1[sel] = mesh1.thickness(out.faces[sel])
    out.h2[sel], out.far2[sel] = mesh2.thickness(
        out.cast.options["thickness2"], out.faces2[sel], out.q[sel], None if far is None else far[sel]
    )
    total = out.h1[sel] + out.h2[sel]
    bad = ~(np.isfinite(total) & (total > 0))
    out.outcome[sel[bad]] = LOST_REASONS.index("thickness")


def cast_faces(
    cast, pose, faces, allowed, mesh1: Mesh1, mesh2: Mesh2 | None = None, *, met=None, far=None, thickness=True
) -> FaceCast:
    """Cast the faces ``faces`` of mesh 1 (K,) onto mesh 2 at ``pose`` (4x4), each ray allowed the
    overlap ``allowed`` (K,), by the rules of :func:`dea_opt.mesh.cast_springs`.

    ``met`` (K,): the faces of mesh 2 the rays met first at a pose nearby (-1: none known); a ray
    is followed from there across mesh 2's edges (:class:`~dea_opt.mesh.walk.Walker`: a smooth
    surface met once) and cast only where that finds nothing facing it. ``far`` (K,): the far
    faces each thickness was last measured to (-2: none). Without ``thickness`` the springs'
    thicknesses are left to :func:`measure` (NaN). ``FaceCast.first2`` holds what each ray met
    first, for the next call's ``met``.
    """
    mesh2 = Mesh2.of(cast) if mesh2 is None else mesh2
    options = cast.options
    max_gap = options["max_gap"]
    faces = np.asarray(faces, dtype=np.int64)
    k = len(faces)
    out = _empty(cast, faces)
    out.first2 = np.full(k, -1, dtype=np.int64)
    if not k:
        return out
    _, depth = mesh1.behind(faces)
    look = np.where(np.isfinite(depth), np.maximum(depth, allowed), allowed)
    origins, directions = _rays(pose, faces, mesh1)
    crossings = _crossings(mesh2, origins, directions, look, max_gap, depth, mesh1.eps, met)
    out.first2 = crossings.first
    ray, face, t, cos = crossings.ray, crossings.face, crossings.t, crossings.cos
    through = -t >= depth[ray] - mesh1.eps
    window = (t >= -allowed[ray]) & (t <= max_gap)
    inside = window & ~through
    aligned_all = cos >= math.cos(math.radians(options["max_angle"])) - ANGLE_SLACK
    if crossings.unique:  # one crossing a ray (the usual case): the rules of _outcomes, no sort
        outside = ~through & ~window
        outcome = out.outcome
        outcome[ray[outside & (t > max_gap)]] = LOST_REASONS.index("gap")
        outcome[ray[outside & (t < -allowed[ray]) & aligned_all]] = LOST_REASONS.index("overlap")
        outcome[ray[through & window]] = LOST_REASONS.index("through_layer")
        hit = np.flatnonzero(inside)
        has = ray[hit]
    else:
        rejected = np.zeros(k, dtype=bool)
        rejected[ray[through & window]] = True
        pick = _first_per_ray(ray[inside], np.abs(t[inside]), k)
        has = np.flatnonzero(pick >= 0)
        hit = np.flatnonzero(inside)[pick[has]]
        if (~inside).any():
            out.outcome = _outcomes(k, ray, t, cos, ~through & ~window, rejected, allowed, options)
    aligned = aligned_all[hit]
    out.outcome[has[~aligned]] = LOST_REASONS.index("angle")
    sel, hit = has[aligned], hit[aligned]
    out.outcome[sel] = _SPRING
    out.gap[sel], out.faces2[sel] = t[hit], face[hit]
    out.q[sel] = origins[sel] + t[hit][:, None] * directions[sel]
    out.m[sel] = np.take(mesh2.planes.normals, face[hit], axis=0)
    if thickness:
        measure(out, mesh1, mesh2, far)
    return out


def follow_faces(cast, pose, faces, met, allowed, mesh1: Mesh1, mesh2: Mesh2, cast_rest: bool = True) -> FaceCast:
    """:func:`cast_faces` (without thicknesses) for rays that each have a face of mesh 2 to follow
    from (``met``, (K,): what they, or a face next to them, met first at a pose nearby).

    A ray whose walk (:class:`~dea_opt.mesh.walk.Walker`) ends on a face facing it, ahead of the
    back of its window and in front of mesh 1's far side, has that face as its first crossing,
    the only candidate of a cast (:func:`cast_faces`, a smooth surface met once), and is judged
    by the same rules here with no ray cast. The others are cast (``cast_rest``), or left with
    outcome -2 for the caller to cast with others.
    """
    options = cast.options
    max_gap, eps2 = options["max_gap"], mesh2.planes.eps
    faces = np.asarray(faces, dtype=np.int64)
    k = len(faces)
    if not k:
        return _empty(cast, faces)
    R, shift = pose[:3, :3], pose[:3, 3]
    # whole rows gathered (one cache line a face), then the rays as rows (3, K)
    oT = np.ascontiguousarray(((np.take(mesh1.centroids, faces, axis=0) - shift) @ R).T)
    dT = np.ascontiguousarray((np.take(mesh1.normals, faces, axis=0) @ R).T)
    face, t, found, margin, along = mesh2.walker.follow(met, oT, dT, rows=True)
    cos = -along  # where found
    depth = mesh1.depth_behind(faces)
    look = np.where(np.isfinite(depth), np.maximum(depth, allowed), allowed)
    with np.errstate(invalid="ignore"):
        met_facing = found & (cos > 0)
        ahead = met_facing & (t >= -(look + eps2))
        beyond = ahead & (t > np.maximum(max_gap, look) + eps2)  # nothing in the window: no hit
        simple = ahead & ~beyond & ~(-t >= depth - mesh1.eps)
        window = simple & (t >= -allowed) & (t <= max_gap)
        aligned = cos >= math.cos(math.radians(options["max_angle"])) - ANGLE_SLACK
    point = np.ascontiguousarray((oT + t * dT).T)  # where each ray crossed (NaN where it did not)
    spring = window & aligned
    out = _empty(
        cast,
        faces,
        (
            # whole arrays where most rays make springs: one pass each rather than a gather and a scatter
            np.where(spring[:, None], point, np.nan),
            np.where(spring[:, None], np.take(mesh2.planes.normals, face, axis=0), np.nan),
        ),
    )
    out.first2[met_facing] = face[met_facing]
    outcome = out.outcome
    outcome[simple & (t > max_gap)] = LOST_REASONS.index("gap")
    with np.errstate(invalid="ignore"):
        outcome[simple & (t < -allowed) & aligned] = LOST_REASONS.index("overlap")
    outcome[window & ~aligned] = LOST_REASONS.index("angle")
    sel = np.flatnonzero(spring)
    outcome[sel] = _SPRING
    out.gap[sel], out.faces2[sel] = t[sel], face[sel]
    out.clear[sel] = mesh2.planes.clearance(face[sel], margin[sel])
    rest = np.flatnonzero(~(simple | beyond))
    if len(rest):
        if not cast_rest:
            outcome[rest] = -2
            return out
        again = cast_faces(cast, pose, faces[rest], allowed[rest], mesh1, mesh2, met=None, thickness=False)
        for name in ("outcome", "q", "m", "faces2", "gap", "first2", "clear"):
            getattr(out, name)[rest] = getattr(again, name)
    return out


def off_face(hits, valid, faces, transform, mesh2, tolerance: float = 1e-9) -> np.ndarray:
    """Which hits left the face of mesh 2 their target plane belongs to (bool, (N,)).

    ``hits`` (N, 3, world frame) are taken back to mesh 2's own frame by ``transform`` (its
    pose, 4x4) and their barycentric coordinates in faces ``faces`` (N,) computed; a coordinate
    below ``-tolerance`` puts a hit outside. Springs whose ray misses its plane (``~valid``)
    count as off. ``mesh2`` is a trimesh or a :class:`Mesh2`.
    """
    planes = mesh2.planes if isinstance(mesh2, Mesh2) else Planes(mesh2)
    R, shift = transform[:3, :3], transform[:3, 3]
    own = (np.nan_to_num(hits) - shift) @ R
    with np.errstate(invalid="ignore"):
        return ~(planes.inside(own, faces, tolerance) & valid)
