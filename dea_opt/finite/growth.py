"""Finite kinematics, re-casting: the faces of mesh 1 next to the springs, where springs come into range.

Written math: ``formulations/finite.md`` ("Re-casting"). Part of :class:`~dea_opt.finite.tracker.MeshTracker`
(its update's third step): the faces whose ray met mesh 2 near the window at their last cast are
followed to mesh 2 at the pose, then the faces around the springs are cast, ring after ring,
while springs come into range there.
"""

from __future__ import annotations

import numpy as np

from ..mesh import Mesh1, Mesh2, SpringCast, cast_faces, follow_faces, measure
from ..mesh.walk import dot, window_faces
from .springs import Springs, joined, ring

__all__ = ["Growth"]


class Growth:
    """The growth of a :class:`~dea_opt.finite.tracker.MeshTracker`'s springs into the faces next
    to them (its ``springs``, ``met``, meshes and cast)."""

    cast: SpringCast
    mesh1: Mesh1
    mesh2: Mesh2
    springs: Springs
    met: np.ndarray  # (F,) per face of mesh 1, the face of mesh 2 its ray met first (-1: not known)
    counts: dict
    dropped_faces: np.ndarray
    _slot: np.ndarray
    _first_cast: SpringCast

    #: mm beyond the window within which a face's tangent-plane gap makes it a candidate: the
    #: plane of the face its ray met departs from a curved mesh 2 as the hit moves on it.
    _REACH = 1.0

    def _candidates(self, pose, tried, near=None) -> np.ndarray:
        """The faces of mesh 1 not ``tried`` whose ray met mesh 2 at their last cast (``met``) and
        whose gap to that face's tangent plane at ``pose`` lies within the window widened by
        ``_REACH`` (below ``near`` mm, given: where the contact spreads): where springs most likely
        came into range."""
        options = self.cast.options
        low = -(options["max_overlap"] + 2.0 * self._REACH)  # the window follows the pose: wide
        high = options["max_gap"] + self._REACH if near is None else near
        mesh1 = self.mesh1
        return window_faces(self.met, tried, mesh1.centroids, mesh1.normals, self.mesh2.planes, pose, low, high)

    def _near_spring(self, faces) -> np.ndarray:
        """For faces of mesh 1, the face of mesh 2 a spring next to each meets now (-1: none), where
        its ray most likely meets mesh 2 too."""
        springs = self.springs
        met = self._slot  # scratch (F,): here the face of mesh 2 each spring's face meets
        met[:] = -1
        met[springs.faces1] = springs.faces2
        near = np.take(self.mesh1.neighbours, faces, axis=0)
        found = np.where(near >= 0, met[near.clip(0)], -1)
        return found.max(axis=1)

    def _remember(self, faces, fresh) -> None:
        """Keep what the rays of ``faces`` met first (a :class:`~dea_opt.mesh.FaceCast`'s ``first2``)."""
        self.met[faces] = fresh.first2

    def _grow(self, pose, near=None) -> int:
        """Cast the faces next to the springs at ``pose``, ring after ring (each twice as wide as
        the last, at most 24 faces) while springs come into range there; add those springs. The
        number gained; what the window dropped there is kept for the count.

        With ``near`` (mm), a partial update: no ray is cast. The faces whose ray met mesh 2 and
        whose tangent-plane gap is below ``near`` now (where the contact spreads after a long
        step) and one ring next to the springs with a gap below it (the contact's edges, not the
        window's far edge) are followed from what they, or the face they were reached from, met
        (:func:`~dea_opt.mesh.follow_faces`); what lies beyond, and what a walk cannot settle,
        waits for the complete update, which casts its rings (:func:`~dea_opt.mesh.cast_faces`)."""
        springs = self.springs
        dropped, tried = [], np.zeros(len(self.mesh1.areas), dtype=bool)
        tried[springs.faces1] = True
        width = 3
        seeds = slice(None) if near is None else springs.gap < near
        grown = []
        known = np.zeros(0, dtype=np.int64)
        # the faces whose ray met mesh 2 within the window's reach (a partial update: near the
        # contact), followed first
        candidates = self._candidates(pose, tried, near)
        if len(candidates):
            allowed = self._allowed(candidates, pose)
            start = self._near_spring(candidates)
            start = np.where(start >= 0, start, self.met[candidates])
            fresh = follow_faces(self.cast, pose, candidates, start, allowed, self.mesh1, self.mesh2, cast_rest=False)
            settled = fresh.outcome != -2  # the others are left to the rings' casts
            self.met[candidates[settled]] = fresh.first2[settled]
            grown.append(fresh.subset(fresh.spring))
            dropped.append(fresh.faces[fresh.dropped])
            tried[candidates[fresh.spring]] = True
            known = candidates[settled & ~fresh.spring]  # judged: the rings pass them, not cast them
        is_known = np.zeros(len(tried), dtype=bool)
        is_known[known] = True
        ring, guess = self._ring(springs.faces1[seeds], springs.faces2[seeds], tried, width)
        if grown:  # and around the springs the candidates gave
            more = grown[0]
            extra, extra_guess = self._ring(more.faces, more.faces2, tried, width)
            ring, guess = np.concatenate([ring, extra]), np.concatenate([guess, extra_guess])
        while len(ring):
            if len(known):
                cast = ~is_known[ring]
                ring, guess = ring[cast], guess[cast]
                if not len(ring):
                    break
            allowed = self._allowed(ring, pose)
            if near is None:
                fresh = cast_faces(self.cast, pose, ring, allowed, self.mesh1, self.mesh2, thickness=False)
            else:
                fresh = follow_faces(self.cast, pose, ring, guess, allowed, self.mesh1, self.mesh2, cast_rest=False)
            self._remember(fresh.faces, fresh)
            new = fresh.spring
            grown.append(fresh.subset(new))
            dropped.append(fresh.faces[fresh.dropped])
            width = min(2 * width, 24)
            if near is not None:
                break  # one ring: what lies beyond waits for the complete update
            ring, guess = self._ring(fresh.faces[new], fresh.faces2[new], tried, width)
        if near is None:
            self.dropped_faces = np.concatenate(dropped) if dropped else np.zeros(0, dtype=np.int64)
            self.counts["dropped"] = len(self.dropped_faces)
        if not grown:
            return 0
        fresh = grown[0] if len(grown) == 1 else joined(grown)
        measure(fresh, self.mesh1, self.mesh2)
        new = fresh.spring
        springs.extend(self.mesh1, fresh, new)
        return int(new.sum())

    def _ring(self, faces1, met, tried, rings: int = 3) -> tuple[np.ndarray, np.ndarray]:
        """:func:`~dea_opt.finite.springs.ring` on mesh 1's faces, with what each met at its last cast."""
        return ring(self.mesh1.neighbours, self._slot, self.met, faces1, met, tried, rings)

    def _allowed(self, faces, pose) -> np.ndarray:
        """The overlap a face's ray may take: ``max_overlap`` plus how far mesh 2 came toward it from
        the pose of the cast the springs started from (the window following the pose, as in
        :func:`dea_opt.mesh.recast` of that cast, which the whole re-casts also are): the same
        window whatever path led to ``pose``, the one ``recast_at_solution`` counts drops in."""
        motion = pose @ np.linalg.inv(self._first_cast.pose)
        points = np.take(self.mesh1.centroids, faces, axis=0)  # whole rows: one cache line a face
        moved = points @ (motion[:3, :3] - np.eye(3)).T + motion[:3, 3]
        toward = -dot(np.take(self.mesh1.normals, faces, axis=0), moved)
        return self.cast.options["max_overlap"] + np.maximum(toward, 0.0)
