"""Finite kinematics, re-casting: the springs of a mesh layer follow body 2 as it moves.

Written math: ``formulations/finite.md`` ("Re-casting"). Within a solve each spring's gap is
taken to the tangent plane of the face of mesh 2 its ray met, exact while the hit stays on that
face. After a converged solve the springs are brought up to date at the solved pose, by the
rules of a cast (:func:`dea_opt.mesh.cast_springs`, the window following the pose as in
:func:`dea_opt.mesh.recast`), on the faces of mesh 1 where anything can have changed:

* the springs whose hit left its face meet mesh 2 again, their rays followed across its edges
  from where they left (:func:`dea_opt.mesh.follow_faces`), cast where that settles nothing (a
  new face, or lost: beyond the window, turned past ``max_angle``, back through body 1's own
  layer, no face of mesh 2 facing it); a hit that moved less than its clearance on its face
  is not tested; a ray turned past ``max_angle`` on its face is met again there (lost);
* every spring whose hit moved more than ``recast_shift`` since its thickness was measured is
  measured again at its hit; springs beyond ``max_gap`` are dropped (they carry nothing);
* the faces of mesh 1 next to the springs (the springs' ring) are cast: springs coming into
  range are picked up there, overlaps deeper than the window counted as dropped
  (:mod:`~dea_opt.finite.growth`). A partial update casts no ray: after a long step it follows
  the faces near the contact whose ray met mesh 2 and one ring at the contact's edges; a
  complete one grows the rings around every spring, the window's far edge included.

Once the hits moved more than ``full_shift`` (5 mm) from where every face was last cast (a
contact away from the springs could have appeared), the whole mesh is re-cast
(:func:`dea_opt.mesh.recast`). The solve goes on from the same pose until a complete update
changes nothing that carries load; every event is counted.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..formulations.finite import Targets
from ..mesh import Mesh1, Mesh2, cast_faces, follow_faces, recast
from ..mesh.springs import LOST_REASONS, NoSpringsError
from .growth import Growth
from .springs import Springs, face_labels, put_rows

__all__ = ["MeshTracker"]


@dataclass
class Update:
    """The springs brought up to date: the new system, its state at the solved pose, and whether
    a loaded spring changed (so that the equilibrium must be solved again)."""

    system: object
    state: object
    resolve: bool
    #: Why no spring is left at the pose (a whole re-cast made none): the solve ends there, failed.
    none_left: str | None = None


class MeshTracker(Growth):
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

    #: The events of the solve under way (:meth:`begin`): updates, re-casts, springs gained and lost.
    counts: dict

    def __init__(self, cast, *, recast_shift: float = 0.01, full_shift: float = 5.0, thickness_tol: float = 1e-6):
        self.cast = cast
        self.frame = np.asarray(cast.pose, dtype=float)
        self.recast_shift, self.full_shift, self.thickness_tol = recast_shift, full_shift, thickness_tol
        self.mesh1, self.mesh2 = Mesh1.of(cast), Mesh2.of(cast)
        self._take(cast)
        self._first_layer, self._first_cast = cast.layer, cast
        self.begin()

    def _take(self, cast) -> None:
        """Start from a whole cast (the first, or a full re-cast)."""
        self.cast, self.full = cast, np.asarray(cast.pose, dtype=float)
        self.updated_at = self.full  # mesh 2's pose where the springs were last brought up to date
        self.springs = Springs(cast.layer, cast.thickness1, cast.thickness2)
        # Per face of mesh 1, the face of mesh 2 its ray met first facing it at its last cast (-1
        # where not known).
        n = len(cast.mesh1.faces)
        met = getattr(cast, "met", None)
        self.met = (
            np.array(met, dtype=np.int64) if met is not None and len(met) == n else np.full(n, -1, dtype=np.int64)
        )
        self.met[self.springs.faces1] = self.springs.faces2
        self._slot = np.zeros(len(cast.mesh1.faces), dtype=np.int64)
        # The first cast's layer is the problem's own; a whole re-cast's is rebuilt with its labels.
        self._layer = cast.layer if not hasattr(self, "_first_layer") else None
        self.dropped_faces = np.asarray(cast.dropped.faces["overlap"], dtype=np.int64)

    def begin(self, frame=None, *, resume: bool = False) -> None:
        """Start counting a solve's events; ``frame`` (4x4) is mesh 2's pose at zero displacement
        from now on (a load path's prescribed pose), else it is kept. ``resume``: the solve goes on
        from where the last one stopped (more updates): its events stay counted, the springs lost
        through the layer included (the ``lost_through_layer`` check counts them all)."""
        from ..mesh import check_pose

        if frame is not None:
            self.frame = np.asarray(check_pose(frame, "frame"), dtype=float)
        self.complete = False  # the next update is partial (see update)
        self.last = None  # the pose of the last update
        if resume and hasattr(self, "counts"):
            self.counts["dropped"] = len(self.dropped_faces)
            return
        self.counts = {
            "recasts": 0,
            "updates": 0,
            "gained": 0,
            "lost": 0,
            "left_face": 0,
            "dropped": len(self.dropped_faces),
        }
        self.lost: dict = {}
        self.crushed_faces: list = []  # faces of mesh 1 whose springs were lost through the layer while loaded
        self.crushed_at: np.ndarray | None = None  # body 2's coordinates (6,) where the first of them were lost

    @property
    def origin(self):
        """The :class:`~dea_opt.mesh.SpringCast` the springs started from (``cast`` is the last whole re-cast)."""
        return self._first_cast

    def targets(self) -> Targets:
        s = self.springs
        return Targets.cast_planes(s.q, s.m, self.frame, s.faces2)

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
        if gap is None and self._layer is not None:
            return self._layer
        from ..layer import SpringLayer

        s = self.springs
        # every array comes from the checked meshes and the rules of a cast; the springs' own are
        # handed over read-only (the next update copies them before it changes them: Springs.own)
        layer = SpringLayer._checked(
            s.points,
            s.normals,
            s.areas,
            self.thickness,
            s.gap if gap is None else np.asarray(gap, dtype=float),
            s.faces1,
            self._first_layer.surface,
            self._labels(s.faces1),
            (s.q, s.m, s.faces2),
        )
        if gap is None:
            self._layer = layer
        return layer

    def _labels(self, faces):
        """The labels of faces ``faces`` of mesh 1 (:func:`~dea_opt.finite.springs.face_labels`)."""
        return face_labels(self._first_cast, self.mesh1.centroids, faces)

    def _lose(self, reason: str, count: int) -> None:
        if count:
            self.lost[reason] = self.lost.get(reason, 0) + int(count)
            self.counts["lost"] += int(count)

    def update(self, system, state, complete: bool = True):
        """After a converged solve: the system with its springs brought up to date at the solved pose,
        or None when nothing changed. A partial update (not ``complete``) keeps the springs it has
        up to date and casts no ray: after a long step it follows the faces where the contact
        spreads (:meth:`_grow` with ``near``); the faces next to the springs at the window's far
        edge, where they carry nothing, are cast only in a complete update (a solve's
        intermediate poses need not look there)."""
        pose = system.transform(state.y)
        since_full, since_last = self._moved(pose, self.full, self.last)
        self.last = self.updated_at = pose
        if since_full > self.full_shift:
            self.complete = True
            return self._recast_all(system, state, pose)
        self.springs.own()  # what the last answer holds is left as it was
        springs, options = self.springs, self.cast.options
        gaps = state.gaps
        rows = system.planes
        pT, nT = (rows.pT, rows.nT) if rows is not None else (springs.points.T, springs.normals.T)
        # The hits in mesh 2's own frame, R^T (p + s n - shift), and which left their face: a hit
        # that moved less than its clearance since it was last found on its face is still on it;
        # the others are tested (barycentric coordinates; one compiled pass, Planes.track). A ray
        # turned past max_angle on its face is met again there too (a cast loses it).
        track = self.mesh2.planes.track(
            pT, nT, gaps.s, gaps.valid, pose, springs.faces2, springs.tested, springs.clear, springs.measured,
            springs.m, (self.recast_shift, options["max_gap"], options["max_angle"]),
        )  # fmt: skip
        ownT, left, moved, beyond = track.own, track.left, track.moved, track.beyond
        loaded = state.eps < 0
        before_faces, before_h = springs.faces2.copy(), self.thickness.copy()
        # 1. Springs whose hit left its face: met again (followed across mesh 2's edges, else cast),
        #    allowed the overlap they have now.
        index = np.flatnonzero(left)
        again = follow_faces(
            self.cast,
            pose,
            springs.faces1[index],
            track.next[index],
            np.maximum(options["max_overlap"], options["max_overlap"] - np.nan_to_num(gaps.s[index])),
            self.mesh1,
            self.mesh2,
        )
        self._remember(springs.faces1[index], again)
        found = again.spring
        met = np.flatnonzero(found)
        at = index[met]
        hits = np.take(again.q, met, axis=0)
        springs.retarget(at, hits, np.take(again.m, met, axis=0))
        put_rows(springs.measured, at, hits)
        put_rows(springs.tested, at, hits)
        springs.faces2[at], springs.gap[at], springs.clear[at] = again.faces2[met], again.gap[met], again.clear[met]
        for reason, count in again.reasons(~found).items():
            self._lose(reason, count)
        gone = np.flatnonzero(~found)
        if len(gone):
            through = again.outcome[gone] == LOST_REASONS.index("through_layer")
            self._crushed(springs.faces1[index[gone[through & loaded[index[gone]]]]], state.y)
        on = np.flatnonzero(~left)
        springs.gap[on] = np.where(gaps.valid[on], gaps.s[on], springs.gap[on])
        # 2. Their thickness where the hits are now, and that of springs whose hit moved on its face.
        stay = np.flatnonzero(moved & ~beyond)
        put_rows(springs.measured, stay, ownT[:, stay].T)
        remeasure = np.concatenate([at, stay])
        keep = ~beyond
        keep[index[~found]] = False
        if len(remeasure):
            h2, springs.far2[remeasure] = self.mesh2.thickness(
                options["thickness2"],
                springs.faces2[remeasure],
                np.take(springs.measured, remeasure, axis=0),
                springs.far2[remeasure],
            )
            springs.h2[remeasure] = h2
            total = springs.h1[remeasure] + h2
            bad = remeasure[~(np.isfinite(total) & (total > 0))]
            keep[bad] = False
            self._lose("thickness", len(bad))
        self._lose("gap", int(beyond.sum()))
        # where each spring stood before (the lost ones' places go to the last springs)
        before = springs.keep(keep) if not keep.all() else np.arange(len(keep))
        # 3. The faces next to the springs, ring after ring while springs come into range there
        #    (their window's edge: only in a complete update).
        if complete:
            gained = self._grow(pose)
        else:  # the contact's edges, after a step long enough to move them (else the complete update sees them)
            gained = self._grow(pose, self._NEAR) if since_last > self._LONG else 0
        self.counts["updates"] += 1
        self.counts["gained"] += gained
        self.counts["left_face"] += len(index) - int(track.turned.sum())
        self._layer = None
        kept = len(before)
        if not (springs.faces2[:kept] != before_faces[before]).any() and not gained and keep.all():
            ratio = self.thickness[loaded] / before_h[loaded]
            if not len(ratio) or np.abs(ratio - 1).max() <= self.thickness_tol:
                return None  # nothing changed
        new_system = self.springs_of(system)
        # Springs that carry nothing before and after change no force: no new solve for them.
        changed = np.zeros(len(keep), dtype=bool)
        changed[index] = True
        changed[:] |= ~keep
        after = new_system.state(state.y, state.law)
        thicker = np.abs(self.thickness[:kept] / before_h[before] - 1) > self.thickness_tol
        moved_loaded = (changed[before] | thicker) & (loaded[before] | (after.eps[:kept] < 0))
        resolve = bool((changed & loaded).any() or moved_loaded.any() or (after.eps[kept:] < 0).any())
        return Update(new_system, after, resolve)

    #: Gap (mm) within which springs border the contact in a partial update: the faces next to
    #: them may carry load at the next equilibrium (an edge of the contact, where the surfaces
    #: turn past ``max_angle`` or the window cut the layer).
    _NEAR = 0.5
    #: A step (mm, the hits' largest motion since the last update) after which a partial update
    #: looks at the contact's edges.
    _LONG = 0.05

    def _recast_all(self, system, state, pose):
        try:
            new = recast(self._first_cast, pose)  # the window of the first cast's pose, as _allowed's
        except NoSpringsError as error:
            return self._none_left(state, error)
        self.counts["recasts"] += 1
        own = (np.nan_to_num(state.gaps.hit) - pose[:3, 3]) @ pose[:3, :3]
        self.counts["left_face"] += int(
            (~(self.mesh2.planes.inside(own, self.springs.faces2) & state.gaps.valid)).sum()
        )
        self.counts["gained"] += len(new.gained)
        for reason, faces in new.lost.items():
            self._lose(reason, len(faces))
        through = np.asarray(new.lost.get("through_layer", ()), dtype=np.int64)
        self._crushed(through[np.isin(through, self.springs.faces1[state.eps < 0])], state.y)
        self._take(new.cast)
        self.counts["dropped"] = len(self.dropped_faces)
        new_system = self.springs_of(system)
        return Update(new_system, new_system.state(state.y, state.law), True)

    def _none_left(self, state, error) -> Update:
        """No spring at the pose (a whole re-cast made none, ``error``): every spring is lost, those
        that carried load through the layer where the rays went back through it (the load drove
        body 2 through the cartilage). The springs are left as they were; the solve ends failed."""
        self.counts["recasts"] += 1
        self._lose("through_layer" if error.through_layer else "no_hit", len(self.springs))
        if error.through_layer:
            self._crushed(self.springs.faces1[state.eps < 0], state.y)
            why = f"the rays of {error.through_layer} faces of mesh 1 met mesh 2 only behind mesh 1's far side"
        else:
            why = "no face of mesh 1 faces mesh 2 within the proximity window there"
        return Update(None, state, False, none_left=why)

    def _crushed(self, faces, y) -> None:
        """Count ``faces`` of mesh 1, whose springs carried load, as lost through the layer at body 2's
        coordinates ``y`` (6,): the first such are kept (``crushed_at``)."""
        if len(faces):
            if not self.crushed_faces:
                self.crushed_at = np.array(y, dtype=float)
            self.crushed_faces.append(np.array(faces, dtype=np.int64))

    @property
    def crushed_through(self) -> int:
        """The springs this solve lost through the layer while they carried load."""
        return sum(len(faces) for faces in self.crushed_faces)

    def lost_through_layer(self, pose) -> int:
        """The springs this solve lost through the layer while they carried load whose rays, at
        mesh 2's ``pose`` (4x4), still meet mesh 2 behind mesh 1's far side: the overlap is deeper
        than mesh 1's cartilage there, so the lumped layer would still carry them, but the cast
        cannot place them (the ``lost_through_layer`` validity check)."""
        if not self.crushed_faces:
            return 0
        faces = np.unique(np.concatenate(self.crushed_faces))
        faces = faces[~np.isin(faces, self.springs.faces1)]
        if not len(faces):
            return 0
        again = cast_faces(self.cast, pose, faces, self._allowed(faces, pose), self.mesh1, self.mesh2, thickness=False)
        return int((again.outcome == LOST_REASONS.index("through_layer")).sum())

    def springs_of(self, system):
        """``system`` with this tracker's springs and targets (the load and coordinates kept)."""
        s = self.springs
        rows = (s.pT, s.nT, s.arms, s.mT, s.qm)
        return system.with_springs(s.points, s.normals, s.areas, self.thickness, self.targets(), rows)

    def moved_from_update(self, pose) -> float:
        """How far (mm) the springs' hits on body 2 moved between their last update and ``pose``."""
        return self._moved(pose, self.updated_at)[0]

    def short_step(self, pose) -> bool:
        """Whether the hits moved no more than ``recast_shift`` since the last update (a partial
        update would see nothing there, so the next one may as well be complete)."""
        return self.last is not None and self._moved(pose, self.last)[0] <= self.recast_shift

    def _moved(self, pose, since, last=None) -> tuple[float, float]:
        """How far (mm) the springs' hits on body 2 moved between ``since`` and ``pose``, and between
        ``last`` and ``pose`` (inf without ``last``)."""
        hits = self.springs.q
        if not len(hits):
            return 0.0, 0.0
        rows = np.ascontiguousarray(hits.T)
        moved = []
        for p in (since,) if last is None else (since, last):
            change = pose - p
            shift = change[:3, :3] @ rows
            shift += change[:3, 3:]
            moved.append(float(np.sqrt((shift[0] * shift[0] + shift[1] * shift[1] + shift[2] * shift[2]).max())))
        return moved[0], moved[1] if last is not None else np.inf
