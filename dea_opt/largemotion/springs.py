"""Finite kinematics, re-casting: the per-spring arrays a :class:`~dea_opt.largemotion.MeshTracker`
keeps up to date, in one order, and the casts it joins."""

from __future__ import annotations

import numpy as np

from ..mesh import FaceCast

__all__ = ["Springs", "joined"]


class Springs:
    """The springs' per-spring arrays, in one order (faces of mesh 1 with their points, normals and
    areas, their targets on mesh 2 in its own frame, thicknesses, and the far face of mesh 2 each
    ``h2`` was measured to)."""

    FIELDS = (
        "faces1",
        "points",
        "normals",
        "areas",
        "h1",
        "h2",
        "q",
        "m",
        "faces2",
        "measured",
        "gap",
        "far2",
        "tested",
        "clear",
    )

    def __init__(self, layer, h1, h2):
        # copies: the layer's arrays are read-only, these are updated in place
        self.faces1 = np.array(layer.source_face, dtype=np.int64)
        self.points, self.normals = np.array(layer.points, dtype=float), np.array(layer.normals, dtype=float)
        self.areas = np.array(layer.areas, dtype=float)
        self.h1, self.h2 = np.array(h1, dtype=float), np.array(h2, dtype=float)
        self.q = np.array(layer.target_points, dtype=float)  # mesh 2's own frame
        self.m = np.array(layer.target_normals, dtype=float)
        self.faces2 = np.array(layer.target_faces, dtype=np.int64)
        self.measured = self.q.copy()  # where each h2 was measured (own frame)
        self.gap = np.array(layer.gap, dtype=float)
        self.far2 = np.full(len(self.faces1), -2, dtype=np.int64)  # not known yet
        # where each hit was last found on its face, and how far it may move from there on it
        self.tested, self.clear = self.q.copy(), np.zeros(len(self.faces1))

    def own(self) -> None:
        """Copy the arrays a layer was given (:meth:`MeshTracker.layer_with_gap` hands them over
        read-only rather than copying them: most solves end there): before any change in place."""
        for name in self.FIELDS:
            value = getattr(self, name)
            if not value.flags.writeable:
                setattr(self, name, value.copy())

    def keep(self, index) -> None:
        index = np.flatnonzero(index) if np.asarray(index).dtype == bool else index
        for name in self.FIELDS:
            setattr(self, name, np.take(getattr(self, name), index, axis=0))

    def extend(self, mesh1, fresh, new) -> None:
        """Add the springs ``new`` (bool) of the :class:`~dea_opt.mesh.FaceCast` ``fresh``."""
        faces = fresh.faces[new]
        more = {
            "faces1": faces,
            "points": np.take(mesh1.centroids, faces, axis=0),
            "normals": np.take(mesh1.normals, faces, axis=0),
            "areas": np.take(mesh1.areas, faces),
            "h1": fresh.h1[new],
            "h2": fresh.h2[new],
            "q": fresh.q[new],
            "m": fresh.m[new],
            "faces2": fresh.faces2[new],
            "measured": fresh.q[new],
            "gap": fresh.gap[new],
            "far2": fresh.far2[new],
            "tested": fresh.q[new],
            "clear": np.zeros(int(np.count_nonzero(new))),
        }
        for name in self.FIELDS:
            setattr(self, name, np.concatenate([getattr(self, name), more[name]]))


def joined(casts) -> FaceCast:
    """The :class:`~dea_opt.mesh.FaceCast` of several, one after the other."""
    names = ("faces", "outcome", "q", "m", "faces2", "gap", "h1", "h2", "far2")
    return FaceCast(casts[0].cast, *(np.concatenate([getattr(c, name) for c in casts]) for name in names))
