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

    #: The arrays an update changes in place (the others only :meth:`keep` and :meth:`extend` change).
    CHANGED = ("h2", "q", "m", "faces2", "measured", "gap", "far2", "tested", "clear")

    def __init__(self, layer, h1, h2):
        # the cast's arrays, read-only: copied by the first update that changes them (own)
        self.faces1 = _held(layer.source_face, np.int64)
        self.points, self.normals = _held(layer.points, float), _held(layer.normals, float)
        self.areas = _held(layer.areas, float)
        self.h1, self.h2 = _held(h1, float), _held(h2, float)
        self.q = _held(layer.target_points, float)  # mesh 2's own frame
        self.m = _held(layer.target_normals, float)
        self.faces2 = _held(layer.target_faces, np.int64)
        self.measured = self.q  # where each h2 was measured (own frame)
        self.gap = _held(layer.gap, float)
        self.far2 = np.full(len(self.faces1), -2, dtype=np.int64)  # not known yet
        # where each hit was last found on its face, and how far it may move from there on it
        self.tested, self.clear = self.q, np.zeros(len(self.faces1))

    def own(self) -> None:
        """Copy the arrays held read-only (the cast's, which the springs start from, and those
        :meth:`MeshTracker.layer_with_gap` handed to an answer: most solves end there) before
        any change in place. Arrays that share one object are copied apart. Those an update
        never changes in place (the faces of mesh 1 and what they give) stay shared."""
        for name in self.CHANGED:
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


def _held(values, dtype) -> np.ndarray:
    """``values`` as an array of ``dtype``, read-only: itself where it already is one (a cast's
    checked, read-only arrays), else a copy."""
    array = np.asarray(values, dtype=dtype)
    if array is values and not array.flags.writeable:
        return array
    array = np.array(array)  # another's array, writable: a copy of our own, held read-only too
    array.setflags(write=False)
    return array


def joined(casts) -> FaceCast:
    """The :class:`~dea_opt.mesh.FaceCast` of several, one after the other."""
    names = ("faces", "outcome", "q", "m", "faces2", "gap", "h1", "h2", "far2")
    return FaceCast(casts[0].cast, *(np.concatenate([getattr(c, name) for c in casts]) for name in names))
