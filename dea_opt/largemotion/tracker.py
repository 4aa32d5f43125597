"""Finite kinematics, re-casting: the springs of a mesh layer follow body 2 as it moves.

Written math: ``formulations/finite.md`` ("Re-casting"). Within a solve each spring's gap is
taken to the tangent plane of the face of mesh 2 its ray met, exact while the hit stays on that
face. After a converged solve the springs are brought up to date at the solved pose, by the
rules of a cast (:func:`dea_opt.mesh.cast_springs`, the window following the pose as in
:func:`dea_opt.mesh.recast`), on the faces of mesh 1 where anything can have changed:

* the springs whose hit left its face are cast again (a new face, or lost: beyond the window,
  turned past ``max_angle``, back through body 1's own layer, no face of mesh 2 facing it);
* every spring whose hit moved more than ``recast_shift`` since its thickness was measured is
  measured again at its hit; springs beyond ``max_gap`` are dropped (they carry nothing);
* the faces of mesh 1 next to the springs (the springs' ring) are cast: springs coming into
  range are picked up there, overlaps deeper than the window counted as dropped.

Once the hits moved more than ``full_shift`` (5 mm) from where every face was last cast (a
contact away from the springs could have appeared), the whole mesh is re-cast
(:func:`dea_opt.mesh.recast`). The solve goes
on from the same pose until nothing changes; every event is counted.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..formulations.finite import Targets
from ..mesh import Mesh1, cast_faces, off_face, recast

__all__ = ["MeshTracker"]


class _Springs:
    """The springs' per-spring arrays, in one order (faces of mesh 1, their targets on mesh 2)."""

    def __init__(self, layer, h1, h2):
        # copies: the layer's arrays are read-only, these are updated in place
        self.faces1 = np.array(layer.source_face, dtype=np.int64)
        self.h1, self.h2 = np.array(h1, dtype=float), np.array(h2, dtype=float)
        self.q = np.array(layer.target_points, dtype=float)  # mesh 2's own frame
        self.m = np.array(layer.target_normals, dtype=float)
        self.faces2 = np.array(layer.target_faces, dtype=np.int64)
        self.measured = self.q.copy()  # where each h2 was measured (own frame)
        self.gap = np.array(layer.gap, dtype=float)

    def keep(self, index) -> None:
        for name in ("faces1", "h1", "h2", "q", "m", "faces2", "measured", "gap"):
            setattr(self, name, getattr(self, name)[index])

    def extend(self, faces1, h1, h2, q, m, faces2, gap) -> None:
        self.faces1 = np.concatenate([self.faces1, faces1])
        self.h1, self.h2 = np.concatenate([self.h1, h1]), np.concatenate([self.h2, h2])
        self.q, self.m = np.vstack([self.q, q]), np.vstack([self.m, m])
        self.faces2 = np.concatenate([self.faces2, faces2])
        self.measured = np.vstack([self.measured, q])
        self.gap = np.concatenate([self.gap, gap])


@dataclass
class Update:
    """The springs brought up to date: the new system, its state at the solved pose, and whether
    a loaded spring changed (so that the equilibrium must be solved again)."""

    system: object
    state: object
    resolve: bool


class MeshTracker:
    """Keeps a finite-kinematics layer cast against mesh 2 as body 2 moves, and counts the events.

    Parameters
    ----------
    cast : SpringCast
        The cast that made the problem's layer (:func:`dea_opt.mesh.cast_springs`); ``cast.pose``
        is mesh 2's pose at zero displacement.
    recast_shift : float
        A spring's thickness is measured again once its hit moved more than this (mm).
    full_shift : float
        The whole of mesh 1 is cast again once the hits moved more than this (mm) since it last
        was: a contact that appears away from the springs is found then.
    thickness_tol : float
        Relative change of a loaded spring's thickness below which an update changed nothing.
    """

    def __init__(self, cast, *, recast_shift: float = 0.01, full_shift: float = 5.0, thickness_tol: float = 1e-6):
        self.cast = cast
        self.frame = np.asarray(cast.pose, dtype=float)
        self.recast_shift, self.full_shift, self.thickness_tol = recast_shift, full_shift, thickness_tol
        self.mesh1 = Mesh1.of(cast)
        self._take(cast)
        self._first_layer = cast.layer
        self.begin()

    def _take(self, cast) -> None:
        """Start from a whole cast (the first, or a full re-cast)."""
        self.cast, self.full = cast, np.asarray(cast.pose, dtype=float)
        self.springs = _Springs(cast.layer, cast.thickness1, cast.thickness2)
        # The first cast's layer is the problem's own; a whole re-cast's is rebuilt with its labels.
        self._layer = cast.layer if not hasattr(self, "_first_layer") else None
        self.dropped_faces = np.asarray(cast.dropped.faces["overlap"], dtype=np.int64)

    def begin(self, frame=None) -> None:
        """Start counting a solve's events; ``frame`` (4x4) is mesh 2's pose at zero displacement
        from now on (a load path's prescribed pose), else it is kept."""
        from ..mesh import check_pose

        if frame is not None:
            self.frame = np.asarray(check_pose(frame, "frame"), dtype=float)
        self.counts = {
            "recasts": 0,
            "updates": 0,
            "gained": 0,
            "lost": 0,
            "left_face": 0,
            "dropped": len(self.dropped_faces),
        }
        self.lost: dict = {}

    def targets(self) -> Targets:
        s = self.springs
        n = len(s.faces1)
        return Targets(s.q, s.m, np.zeros(n), np.zeros(n, bool), self.frame, s.faces2)

    @property
    def thickness(self) -> np.ndarray:
        return self.springs.h1 + self.springs.h2

    @property
    def layer(self):
        """The springs as a :class:`~dea_opt.layer.SpringLayer` (gaps at the last update's pose)."""
        return self.layer_with_gap(None)

    def changed_from(self, layer) -> bool:
        """Whether the springs are no longer those of ``layer`` (the problem's own)."""
        return self._layer is not layer

    def layer_with_gap(self, gap):
        """The springs as a :class:`~dea_opt.layer.SpringLayer` with gaps ``gap`` (N,), or those of
        the last update's pose (None)."""
        if gap is not None:
            from ..layer import SpringLayer

            s, m1 = self.springs, self.cast.mesh1
            normals = -m1.face_normals[s.faces1] if self.cast.options["flip"] else m1.face_normals[s.faces1]
            return SpringLayer(
                m1.triangles_center[s.faces1],
                normals,
                m1.area_faces[s.faces1],
                self.thickness,
                gap,
                source_face=s.faces1,
                surface=(m1.vertices, m1.faces),
                labels=self._labels(s.faces1),
                target_points=s.q,
                target_normals=s.m,
                target_faces=s.faces2,
            )
        if self._layer is None:
            from ..layer import SpringLayer

            s, m1 = self.springs, self.cast.mesh1
            normals = -m1.face_normals[s.faces1] if self.cast.options["flip"] else m1.face_normals[s.faces1]
            self._layer = SpringLayer(
                m1.triangles_center[s.faces1],
                normals,
                m1.area_faces[s.faces1],
                self.thickness,
                s.gap,
                source_face=s.faces1,
                surface=(m1.vertices, m1.faces),
                labels=self._labels(s.faces1),
                target_points=s.q,
                target_normals=s.m,
                target_faces=s.faces2,
            )
        return self._layer

    def _labels(self, faces):
        """The labels of faces ``faces`` of mesh 1: the first layer's own (a scenario's regions, the
        parts of mesh 2 met) where it had the face, else the label of its nearest spring. When the
        first layer's labels are the cast's per-face labels, those."""
        first = self._first_layer
        if first.labels is None:
            return None
        own = self.cast.options.get("labels")
        if own is not None and np.array_equal(np.asarray(own)[first.source_face], first.labels):
            return np.asarray(own)[faces]
        labels = np.asarray(first.labels)
        where = np.full(len(self.cast.mesh1.faces), -1, dtype=np.int64)
        where[first.source_face] = np.arange(len(first.source_face))
        index = where[faces]
        missing = index < 0
        if missing.any():
            from scipy.spatial import cKDTree

            if getattr(self, "_label_tree", None) is None:
                self._label_tree = cKDTree(first.points)
            index[missing] = self._label_tree.query(self.cast.mesh1.triangles_center[faces[missing]])[1]
        return labels[index]

    def _lose(self, reason: str, count: int) -> None:
        if count:
            self.lost[reason] = self.lost.get(reason, 0) + int(count)
            self.counts["lost"] += int(count)

    def update(self, system, state):
        """After a converged solve: the system with its springs brought up to date at the solved pose,
        or None when nothing changed."""
        pose = system.transform(state.y)
        if self._moved(pose, self.full) > self.full_shift:
            return self._recast_all(system, state, pose)
        springs, options = self.springs, self.cast.options
        gaps = state.gaps
        left = off_face(gaps.hit, gaps.valid, springs.faces2, pose, self.cast.mesh2)
        own = (np.nan_to_num(gaps.hit) - pose[:3, 3]) @ pose[:3, :3]
        moved = ~left & (np.linalg.norm(own - springs.measured, axis=1) > self.recast_shift)
        beyond = ~left & (gaps.s > options["max_gap"])
        loaded = state.eps < 0
        before_faces, before_h = springs.faces2.copy(), self.thickness.copy()
        # 1. Springs whose hit left its face: cast again, allowed the overlap they have now.
        index = np.flatnonzero(left)
        again = cast_faces(
            self.cast,
            pose,
            springs.faces1[index],
            np.maximum(options["max_overlap"], options["max_overlap"] - np.nan_to_num(gaps.s[index])),
            self.mesh1,
        )
        found = again.spring
        at = index[found]
        springs.q[at], springs.m[at], springs.faces2[at] = again.q[found], again.m[found], again.faces2[found]
        springs.h2[at], springs.measured[at], springs.gap[at] = again.h2[found], again.q[found], again.gap[found]
        for reason, count in again.reasons(~found).items():
            self._lose(reason, count)
        # 2. Springs whose hit moved on its face: their thickness where the hit is now.
        stay = np.flatnonzero(moved & ~beyond)
        if len(stay):
            springs.h2[stay] = again.thickness2_at(springs.faces2[stay], own[stay])
            springs.measured[stay] = own[stay]
        on = np.flatnonzero(~left)
        springs.gap[on] = np.where(gaps.valid[on], gaps.s[on], springs.gap[on])
        self._lose("gap", int(beyond.sum()))
        keep = ~beyond
        keep[index[~found]] = False
        springs.keep(keep)
        # 3. The faces next to the springs, ring after ring while springs come into range there.
        gained, dropped, tried = 0, [], np.zeros(len(self.cast.mesh1.faces), dtype=bool)
        tried[springs.faces1] = True
        ring = self._ring(springs.faces1, tried)
        while len(ring):
            tried[ring] = True
            fresh = cast_faces(self.cast, pose, ring, self._allowed(ring, pose), self.mesh1)
            new = fresh.spring
            springs.extend(
                fresh.faces[new],
                fresh.h1[new],
                fresh.h2[new],
                fresh.q[new],
                fresh.m[new],
                fresh.faces2[new],
                fresh.gap[new],
            )
            dropped.append(fresh.faces[fresh.dropped])
            gained += int(new.sum())
            ring = self._ring(fresh.faces[new], tried)
        self.dropped_faces = np.concatenate(dropped) if dropped else np.zeros(0, dtype=np.int64)
        self.counts.update(dropped=len(self.dropped_faces), updates=self.counts["updates"] + 1)
        self.counts["gained"] += gained
        self.counts["left_face"] += len(index)
        self._layer = None
        kept = int(keep.sum())
        if not (springs.faces2[:kept] != before_faces[keep]).any() and not gained and keep.all():
            ratio = self.thickness[loaded] / before_h[loaded]
            if not len(ratio) or np.abs(ratio - 1).max() <= self.thickness_tol:
                return None  # nothing changed
        new_system = self.springs_of(system)
        # Springs that carry nothing before and after change no force: no new solve for them.
        changed = np.zeros(len(keep), dtype=bool)
        changed[index] = True
        changed[:] |= ~keep
        after = new_system.state(state.y, state.law)
        kept_index = np.flatnonzero(keep)
        thicker = np.abs(self.thickness[:kept] / before_h[keep] - 1) > self.thickness_tol
        moved_loaded = (changed[kept_index] | thicker) & (loaded[keep] | (after.eps[:kept] < 0))
        resolve = bool((changed & loaded).any() or moved_loaded.any() or (after.eps[kept:] < 0).any())
        return Update(new_system, after, resolve)

    def _recast_all(self, system, state, pose):
        new = recast(self.cast, pose)
        self.counts["recasts"] += 1
        self.counts["left_face"] += int(
            off_face(state.gaps.hit, state.gaps.valid, self.springs.faces2, pose, self.cast.mesh2).sum()
        )
        self.counts["gained"] += len(new.gained)
        for reason, faces in new.lost.items():
            self._lose(reason, len(faces))
        self._take(new.cast)
        self.counts["dropped"] = len(self.dropped_faces)
        new_system = self.springs_of(system)
        return Update(new_system, new_system.state(state.y, state.law), True)

    def springs_of(self, system):
        """``system`` with this tracker's springs and targets (the load and coordinates kept)."""
        s, m1 = self.springs, self.cast.mesh1
        normals = m1.face_normals[s.faces1]
        return system.with_springs(
            m1.triangles_center[s.faces1],
            -normals if self.cast.options["flip"] else normals,
            m1.area_faces[s.faces1],
            self.thickness,
            self.targets(),
        )

    def _moved(self, pose, since) -> float:
        """How far (mm) the springs' hits on body 2 moved between ``since`` and ``pose``."""
        hits = self.springs.q
        if not len(hits):
            return 0.0
        shift = hits @ (pose[:3, :3] - since[:3, :3]).T + (pose[:3, 3] - since[:3, 3])
        return float(np.sqrt(np.einsum("ij,ij->i", shift, shift).max()))

    def _ring(self, faces1, tried, rings: int = 3) -> np.ndarray:
        """The faces of mesh 1 within ``rings`` edges of ``faces1`` not ``tried`` yet."""
        start, neighbours = self._neighbours()
        out, current = [], np.asarray(faces1, dtype=np.int64)
        seen = tried.copy()
        for _ in range(rings):
            if not len(current):
                break
            counts = start[current + 1] - start[current]
            offsets = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
            near = neighbours[np.repeat(start[current], counts) + offsets]
            fresh = np.zeros(len(seen), dtype=bool)
            fresh[near] = True
            fresh &= ~seen
            current = np.flatnonzero(fresh)
            seen |= fresh
            out.append(current)
        return np.concatenate(out) if out else np.zeros(0, dtype=np.int64)

    def _neighbours(self):
        """Mesh 1's faces sharing an edge, as compressed rows ``(start (F + 1,), neighbours)``."""
        mesh = self.cast.mesh1
        cache = getattr(mesh, "_cache", None)  # trimesh empties it when the mesh changes
        csr = cache["dea_opt_face_neighbours"] if cache is not None else None
        if csr is None:
            pairs = np.asarray(mesh.face_adjacency, dtype=np.int64)
            both = np.concatenate([pairs, pairs[:, ::-1]])
            both = both[np.argsort(both[:, 0], kind="stable")]
            csr = (np.searchsorted(both[:, 0], np.arange(len(mesh.faces) + 1)), both[:, 1])
            if cache is not None:
                cache["dea_opt_face_neighbours"] = csr
        return csr

    def _allowed(self, faces, pose) -> np.ndarray:
        """The overlap a face's ray may take: ``max_overlap`` plus how far mesh 2 came toward it since
        the last whole cast (the window following the pose, as in :func:`dea_opt.mesh.recast`)."""
        m1, options = self.cast.mesh1, self.cast.options
        point = m1.triangles_center[faces]
        normal = -m1.face_normals[faces] if options["flip"] else m1.face_normals[faces]
        motion = pose @ np.linalg.inv(self.full)
        toward = -np.einsum("ij,ij->i", normal, point @ motion[:3, :3].T + motion[:3, 3] - point)
        return options["max_overlap"] + np.maximum(toward, 0.0)
