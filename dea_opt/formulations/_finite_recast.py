"""Finite kinematics, re-casting: the springs of a mesh layer follow body 2 as it moves.

Written math: ``formulations/finite.md`` ("Re-casting"). Within a solve each spring's gap is
taken to the tangent plane of the face of mesh 2 its ray met, which is exact while the hit stays
on that face. After a converged solve the springs are re-cast against mesh 2 at the solved pose
(:func:`dea_opt.mesh.recast`, the window following the pose) when a hit left its face or the
hits moved more than ``recast_shift`` since the last cast: springs coming into range are picked
up, springs leaving it are dropped, every thickness is measured again, and the solve goes on
from the same pose, until the springs and their target faces no longer change. Every event is
counted.
"""

from __future__ import annotations

import numpy as np

from ._finite_geometry import Targets

__all__ = ["MeshTracker", "off_face"]


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


class MeshTracker:
    """Re-casts a finite-kinematics layer against mesh 2 as body 2 moves, and counts what happens.

    Parameters
    ----------
    cast : SpringCast
        The cast that made the problem's layer (:func:`dea_opt.mesh.cast_springs`); ``cast.pose``
        is mesh 2's pose at zero displacement.
    recast_shift : float
        Re-cast once the springs' hits on body 2 moved more than this (mm) since the last cast.
    thickness_tol : float
        Relative change of a loaded spring's thickness below which a re-cast changed nothing.
    """

    def __init__(self, cast, *, recast_shift: float = 0.01, thickness_tol: float = 1e-6):
        self.cast = cast
        self.frame = np.asarray(cast.pose, dtype=float)
        self.last = self.frame.copy()  # mesh 2's pose at the last cast
        self.recast_shift, self.thickness_tol = recast_shift, thickness_tol
        self.counts = {"recasts": 0, "gained": 0, "lost": 0, "left_face": 0, "dropped": int(cast.dropped["overlap"])}
        self.lost: dict = {}

    def targets(self) -> Targets:
        return Targets.from_layer(self.cast.layer, pose=self.frame)

    @property
    def layer(self):
        return self.cast.layer

    def moved(self, pose) -> float:
        """How far (mm) the springs' hits moved on body 2 between the last cast and ``pose``."""
        hits = np.asarray(self.cast.layer.target_points)
        if not len(hits):
            return 0.0
        shift = hits @ (pose[:3, :3] - self.last[:3, :3]).T + (pose[:3, 3] - self.last[:3, 3])
        return float(np.sqrt(np.einsum("ij,ij->i", shift, shift).max()))

    def update(self, system, state):
        """After a converged solve: the system with re-cast springs, or None when they are stable."""
        from ..mesh import recast

        pose = system.transform(state.y)
        left = off_face(state.gaps.hit, state.gaps.valid, system.targets.faces, pose, self.cast.mesh2)
        if not left.any() and self.moved(pose) <= self.recast_shift:
            return None
        new = recast(self.cast, pose)
        self.counts["recasts"] += 1
        self.counts["left_face"] += int(left.sum())
        self.counts["gained"] += len(new.gained)
        for reason, faces in new.lost.items():
            if len(faces):
                self.lost[reason] = self.lost.get(reason, 0) + len(faces)
                self.counts["lost"] += len(faces)
        self.counts["dropped"] = int(new.dropped)
        old, layer = self.cast.layer, new.cast.layer
        same = (len(layer) == len(old) and np.array_equal(layer.source_face, old.source_face)
                and np.array_equal(layer.target_faces, old.target_faces))
        loaded = state.eps < 0
        self.cast, self.last = new.cast, pose
        if same and (not loaded.any() or np.abs(layer.thickness[loaded] / old.thickness[loaded] - 1).max()
                     <= self.thickness_tol):
            return None
        return system.with_springs(layer.points, layer.normals, layer.areas, layer.thickness, self.targets())
