"""Finite kinematics, re-casting: the per-spring arrays a :class:`~dea_opt.finite.MeshTracker`
keeps up to date, in one order, and the casts it joins.

Written math: ``formulations/finite.md`` ("Re-casting")."""

from __future__ import annotations

import math

import numpy as np

from ..formulations.finite.system import arms_of
from ..mesh import FaceCast

__all__ = ["Springs", "face_labels", "joined", "put_rows", "ring"]


class Springs:
    """The springs' per-spring arrays, in one order (faces of mesh 1 with their points, normals and
    areas, their targets on mesh 2 in its own frame, thicknesses, and the far face of mesh 2 each
    ``h2`` was measured to).

    Each array is the head of a longer one kept with room to spare: springs lost leave holes
    that the last springs fill (:meth:`keep`) and springs gained are written after them
    (:meth:`extend`), neither copying the rest (an update loses and gains a few springs of
    1e4). The order therefore changes as springs come and go. Written by hand: no library keeps
    a table of columns that shrinks and grows in place.

    The rows a :class:`~dea_opt.formulations.finite.FiniteSystem` passes over (:data:`ROWS`:
    points, normals, arms, target normals as rows (k, N), and ``q . m``) are kept here too, up to
    date as springs come, go and meet new faces (:meth:`retarget`), rather than built anew
    for every system.
    """

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

    #: The rows kept for the systems: ``pT, nT`` (3, N), ``arms`` (6, N), ``mT`` (3, N), ``qm`` (N,).
    ROWS = ("pT", "nT", "arms", "mT", "qm")
    pT: np.ndarray
    nT: np.ndarray
    arms: np.ndarray
    mT: np.ndarray
    qm: np.ndarray

    def __init__(self, layer, h1, h2):
        # the cast's arrays, read-only: copied by the first update, which changes them (own)
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
        self._room: dict = {}  # per field, the array whose head it is (once owned)
        self._rows: dict = {}  # per row, the array whose head it is
        self._append_rows(_rows_of(self.points, self.normals, self.q, self.m), 0)

    def __len__(self) -> int:
        return len(self.faces1)

    def own(self) -> None:
        """Copy every array into one of our own with room to spare when any is held read-only
        (the cast's, which the springs start from, or what :meth:`MeshTracker.layer_with_gap`
        handed to an answer: most solves end there), before any change in place. Arrays that
        share one object are copied apart."""
        if self._room and all(getattr(self, name).flags.writeable for name in self.FIELDS):
            return
        n = len(self)
        size = n + n // 2 + 256  # half again as many: a contact that spreads as body 2 moves fits
        self._room = {}
        for name in self.FIELDS:
            value = getattr(self, name)
            room = np.empty((size, *value.shape[1:]), dtype=value.dtype)
            room[:n] = value
            self._room[name] = room
            setattr(self, name, room[:n])

    def keep(self, kept) -> np.ndarray:
        """Keep the springs ``kept`` (bool, (N,)): the last ones kept fill the holes of those lost.
        Returns, for each spring now, where it stood before (M,)."""
        self.own()
        n = len(kept)
        lost = np.flatnonzero(~kept)
        m = n - len(lost)
        holes = lost[lost < m]
        movers = np.flatnonzero(kept[m:]) + m
        for name in self.FIELDS:
            value = getattr(self, name)
            value[holes] = value[movers]
            setattr(self, name, value[:m])
        for name in self.ROWS:
            value = getattr(self, name)
            value[..., holes] = value[..., movers]
            setattr(self, name, value[..., :m])
        where = np.arange(m)
        where[holes] = movers
        return where

    def extend(self, mesh1, fresh, new) -> None:
        """Add the springs ``new`` (bool) of the :class:`~dea_opt.mesh.FaceCast` ``fresh``."""
        self.own()
        new = np.flatnonzero(new)
        faces = fresh.faces[new]
        q = np.take(fresh.q, new, axis=0)
        more = {
            "faces1": faces,
            "points": np.take(mesh1.centroids, faces, axis=0),
            "normals": np.take(mesh1.normals, faces, axis=0),
            "areas": np.take(mesh1.areas, faces),
            "h1": fresh.h1[new],
            "h2": fresh.h2[new],
            "q": q,
            "m": np.take(fresh.m, new, axis=0),
            "faces2": fresh.faces2[new],
            "measured": q,
            "gap": fresh.gap[new],
            "far2": fresh.far2[new],
            "tested": q,
            "clear": np.zeros(len(faces)),
        }
        n, k = len(self), len(faces)
        for name in self.FIELDS:
            room = self._room[name]
            if n + k > len(room):  # out of room: a longer array, half again as long
                longer = np.empty((n + k + (n + k) // 2 + 256, *room.shape[1:]), dtype=room.dtype)
                longer[:n] = room[:n]
                self._room[name] = room = longer
            room[n : n + k] = more[name]
            setattr(self, name, room[: n + k])
        self._append_rows(_rows_of(more["points"], more["normals"], more["q"], more["m"]), n)

    def retarget(self, index, q, m) -> None:
        """The springs ``index`` (K,) met mesh 2 anew at ``q`` with normals ``m`` (K, 3, own frame)."""
        self.own()
        put_rows(self.q, index, q)
        put_rows(self.m, index, m)
        for row in range(3):  # row by row: a (3, K) fancy assignment takes twice as long
            self.mT[row, index] = m[:, row]
        self.qm[index] = _dot(q, m)

    def _append_rows(self, rows, n) -> None:
        """Write ``rows`` (:data:`ROWS`, K springs each) after the first ``n`` springs."""
        for name in self.ROWS:
            value = rows[name]
            k = value.shape[-1]
            room = self._rows.get(name)
            if room is None or n + k > room.shape[-1]:  # out of room: half again as long
                longer = np.empty((*value.shape[:-1], n + k + (n + k) // 2 + 256))
                if room is not None:
                    longer[..., :n] = room[..., :n]
                self._rows[name] = room = longer
            room[..., n : n + k] = value
            setattr(self, name, room[..., : n + k])


def _rows_of(points, normals, q, m) -> dict:
    """:data:`Springs.ROWS` of springs at ``points`` along ``normals`` with plane targets through
    ``q`` with normals ``m`` (K, 3 each)."""
    pT = np.ascontiguousarray(np.asarray(points, dtype=float).T)
    nT = np.ascontiguousarray(np.asarray(normals, dtype=float).T)
    return {"pT": pT, "nT": nT, "arms": arms_of(pT, nT), "mT": np.asarray(m, dtype=float).T, "qm": _dot(q, m)}


def _dot(a, b) -> np.ndarray:
    """Row-wise dot products of (K, 3) arrays."""
    return (np.asarray(a, dtype=float) * np.asarray(b, dtype=float)) @ np.ones(3)


def put_rows(rows, index, values) -> None:
    """``rows[index] = values`` for a C-contiguous (N, k) array, each row written whole: through
    views of the rows as single items of ``8 k`` bytes (a row-wise fancy assignment, or ``np.put``
    through the flat view, writes item by item and takes two to four times as long)."""
    values = np.asarray(values)
    index = np.asarray(index)
    if not rows.flags.c_contiguous or values.shape != (len(index), *rows.shape[1:]) or index.dtype == bool:
        rows[index] = values  # no whole rows to write through
        return
    item = np.dtype((np.void, rows.itemsize * math.prod(rows.shape[1:])))
    whole = np.ascontiguousarray(values, dtype=rows.dtype)
    rows.view(item).reshape(len(rows))[index] = whole.view(item).reshape(len(index))


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


def _face_labels(cast):
    """The cast's labels per face of mesh 1 when its layer's labels are those of its faces (None
    otherwise): decided once a cast (comparing strings costs a third of a millisecond a solve),
    kept in the cast, whose layer never changes."""
    key = "_dea_opt_face_labels"
    if key not in cast.__dict__:
        own, layer = cast.options.get("labels"), cast.layer
        same = (
            own is not None
            and layer.labels is not None
            and np.array_equal(np.asarray(own)[layer.source_face], layer.labels)
        )
        cast.__dict__[key] = np.asarray(own) if same else None
    return cast.__dict__[key]


def face_labels(cast, centroids, faces):
    """The labels of faces ``faces`` of mesh 1 for springs that follow ``cast`` (its layer's labels,
    a scenario's regions or the parts of mesh 2 met; None without): the cast's layer's own where
    it had the face, else the label of its nearest spring (``centroids``, (F, 3): mesh 1's face
    centroids). When that layer's labels are the cast's per-face labels, those."""
    first = cast.layer
    if first.labels is None:
        return None
    per_face = _face_labels(cast)
    if per_face is not None:
        return per_face[faces]
    labels = np.asarray(first.labels)
    where = np.full(len(cast.mesh1.faces), -1, dtype=np.int64)
    where[first.source_face] = np.arange(len(first.source_face))
    index = where[faces]
    missing = index < 0
    if missing.any():
        from scipy.spatial import cKDTree

        key = "_dea_opt_label_tree"  # kept in the cast, as _face_labels
        if key not in cast.__dict__:
            cast.__dict__[key] = cKDTree(first.points)
        index[missing] = cast.__dict__[key].query(centroids[faces[missing]])[1]
    return labels[index]


def ring(table, slot, known, faces1, met, tried, rings: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """``(faces, guess)``: the faces of mesh 1 within ``rings`` edges of ``faces1`` not ``tried``
    yet (now marked tried), and for each a face of mesh 2 to follow its ray from: what it met
    at its last cast (``known``, (F,), -1 where none), else what the face of ``faces1`` it was
    reached from met (``met``, (K,)). ``table`` (F, w): each face's neighbours (-1: none);
    ``slot`` (F,): scratch."""
    width = table.shape[1]
    out, current, guess = [], np.asarray(faces1, dtype=np.int64), np.asarray(met, dtype=np.int64)
    for _ in range(rings):
        if not len(current):
            break
        near = np.take(table, current, axis=0).ravel()
        new = (near >= 0) & ~tried[near.clip(0)]
        near, via = near[new], np.repeat(guess, width)[new]
        slot[near] = np.arange(len(near))
        first = slot[near] == np.arange(len(near))  # one entry a face (the last one written)
        current, guess = near[first], via[first]
        tried[current] = True
        out.append((current, guess))
    if not out:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    faces = np.concatenate([f for f, _ in out])
    guess = np.concatenate([g for _, g in out])
    own = known[faces]
    return faces, np.where(own >= 0, own, guess)
