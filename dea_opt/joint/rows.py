"""The rows of a joint's elements: straight lines between two bodies, and a layer in its own basis.

``formulations/joint.md`` ("Ligaments", "Gradient and tangent"): a straight line's length per
unit small motion of its two bodies (:func:`line_operator`), a contact layer's rows kept in its
own six-row basis (:class:`LayerBasis`), and the bundles of one law between two bodies
(:class:`LigamentGroup`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .coordinates import cross

__all__ = ["LayerBasis", "LigamentGroup", "layer_basis", "line_operator"]


def line_operator(point1, point2, reference1, reference2) -> np.ndarray:
    """Rows ``dL / du`` of straight lines from ``point1`` (on body 1) to ``point2`` (on body 2), shape
    (N, 12), for small motions ``u`` (body 1 then body 2) about the references: with ``e`` the unit
    direction, ``[-e, -(p1 - c1) x e, e, (p2 - c2) x e]`` (``formulations/joint.md``, "Ligaments")."""
    p1, p2 = np.atleast_2d(point1), np.atleast_2d(point2)
    e = p2 - p1
    e = e / np.linalg.norm(e, axis=1)[:, None]
    rows = np.empty((p1.shape[0], 12))
    rows[:, 0:3] = -e
    rows[:, 3:6] = -cross(p1 - np.asarray(reference1, dtype=float), e)
    rows[:, 6:9] = e
    rows[:, 9:12] = cross(p2 - np.asarray(reference2, dtype=float), e)
    return rows


@dataclass(frozen=True, eq=False)
class LayerBasis:
    """A layer's rows in its own basis: each spring's translation and rotation about the layer's
    centroid ``o`` (weights ``S / h``), ``E = [n, (p - o) x n]``, over ``h`` (``rows``, 6 x N); a
    motion of its two bodies' 12 dofs moves it by ``motion(dofs)`` (6 x m, exact: a rotation about a
    reference ``c`` is the rotation about ``o`` and the translation ``e x (o - c)``, minus for body
    1), so that the layer's ``AT = motion^T rows``, as :meth:`dea_opt.ContactProblem._factor` builds
    its factor (``formulations/joint.md``, "Gradient and tangent")."""

    rows: np.ndarray
    centroid: np.ndarray
    references: tuple
    gram: np.ndarray  # E diag(S / h) E^T (6 x 6)
    radius: float
    weight_sum: float

    def motion(self, dofs) -> np.ndarray:
        """``C`` (6, m): the layer's motion per unit of each of ``dofs`` (indices into the 12-vector)."""
        return self.full[:, list(dofs)]

    @cached_property
    def full(self) -> np.ndarray:
        """:meth:`motion` of all 12 dofs (6, 12)."""
        C = np.zeros((6, 12))
        for col, j in enumerate(range(12)):
            body, k = divmod(int(j), 6)
            sign = 1.0 if body == 1 else -1.0
            if k < 3:
                C[k, col] = sign
            else:
                e = np.zeros(3)
                e[k - 3] = 1.0
                C[:3, col] = sign * np.cross(e, self.centroid - np.asarray(self.references[body]))
                C[k, col] = sign
        return C

    def factor(self, dofs) -> np.ndarray:
        """``F`` (r, m) with ``F^T F = A^T diag(V) A`` over ``dofs``, from the 6 x 6 Gram matrix in arc
        lengths, eigenvalues below the one test of "unresisted" dropped (as the two-body factor)."""
        from ..formulations._parts.resistance import unresisted

        Dg = np.array([1.0, 1.0, 1.0, self.radius, self.radius, self.radius])
        vals, vecs = np.linalg.eigh(self.gram / np.outer(Dg, Dg))
        keep = ~unresisted(vals, max(self.weight_sum, float(vals[-1])))
        L = Dg[:, None] * vecs[:, keep] * np.sqrt(vals[keep])
        return L.T @ self.motion(dofs)


def layer_basis(layer, reference1, reference2) -> LayerBasis:
    """The :class:`LayerBasis` of ``layer`` between bodies of references ``reference1``, ``reference2``."""
    weight = layer.areas / layer.thickness
    total = float(weight.sum())
    o = weight @ layer.points / total if len(layer) else np.zeros(3)
    E = np.empty((6, len(layer)))
    E[:3] = layer.normals.T
    E[3:] = np.cross(layer.points - o, layer.normals).T
    gram = (E * weight) @ E.T
    radius = float(np.sqrt(weight @ np.sum((layer.points - o) ** 2, axis=1) / total)) if len(layer) else 1.0
    rows = np.ascontiguousarray(E / layer.thickness)
    return LayerBasis(rows, o, (tuple(reference1), tuple(reference2)), gram, radius if radius > 1e-100 else 1.0, total)


@dataclass(frozen=True, eq=False)
class LigamentGroup:
    """The bundles of one law between two bodies: which they are and their full rows."""

    body1: str
    body2: str
    law: str
    members: tuple  # indices into Joint.ligaments
    G: np.ndarray  # (N, 12) rows dL/du of body1's and body2's 6-vectors
    slack: np.ndarray  # (N,) L0, mm
    start: np.ndarray  # (N,) L at the start pose, mm

    @cached_property
    def index(self) -> np.ndarray:
        """:attr:`members` as an index array (into arrays over all of a joint's bundles)."""
        return np.asarray(self.members, dtype=np.int64)
