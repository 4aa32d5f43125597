"""The shape of a contact as the checks before a run see it, and what is wrong with a load on it.

:class:`ContactShape` is what the checks of :mod:`dea_opt.run.preflight` and the grouping of a
load path's failed frames (:mod:`dea_opt.run.diagnose`) need to know about the springs: their
centre, mean normal, size and area. :func:`frame_cause` says what is wrong with one load on it,
in the terms a user can act on (a sign, a column, a unit), or None; :func:`frame_causes` says it of
every frame of a path at once.
Units: mm, N, N mm, MPa.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["ContactShape", "frame_cause", "frame_causes", "moment_arms", "pressing_fraction", "pulls_apart_proven"]

#: A force within this cosine of the contact's surface (60 degrees from its normal) lies along it.
ALONG_SURFACE = 0.5
#: A moment about the contact's centre needing a lever arm of more than this many of the layer's
#: radii is far beyond what the contact can balance: units, not mechanics.
MOMENT_ARMS = 100.0


@dataclass(frozen=True, eq=False)
class ContactShape:
    """The springs of a layer, summed up.

    Attributes
    ----------
    centre : ndarray (3,)
        The area-weighted centroid of the springs' points (mm): the centre of the contact, what a
        scenario's ``reference = "contact"`` takes.
    normal : ndarray (3,) or None
        The area-weighted mean of the springs' normals, made unit (from body 1 to body 2); None
        when the normals cancel out (a closed surface: no one direction to press along).
    normals : ndarray (N, 3)
        Every spring's normal.
    radius : float
        Half the layer's extent (mm), as the validity's ``extent`` check measures it: the
        diagonal of the springs' bounding box, or the square root of their area if larger.
    area : float
        The springs' total area (mm^2).
    low, high : ndarray (3,)
        The springs' bounding box (mm).
    thickness : float
        The springs' area-weighted mean thickness (mm).
    """

    centre: np.ndarray
    normal: np.ndarray | None
    normals: np.ndarray
    radius: float
    area: float
    low: np.ndarray
    high: np.ndarray
    thickness: float

    @classmethod
    def of(cls, layer) -> ContactShape:
        points = np.asarray(layer.points, dtype=float)
        normals = np.asarray(layer.normals, dtype=float)
        areas = np.asarray(layer.areas, dtype=float)
        total = float(areas.sum())
        centre = areas @ points / total
        mean = areas @ normals / total
        length = float(np.linalg.norm(mean))
        low, high = points.min(axis=0), points.max(axis=0)
        extent = max(float(np.linalg.norm(high - low)), math.sqrt(total))
        return cls(
            centre=centre,
            normal=mean / length if length > 0.3 else None,
            normals=normals,
            radius=extent / 2.0,
            area=total,
            low=low,
            high=high,
            thickness=float(areas @ np.asarray(layer.thickness, dtype=float) / total),
        )

    def distance(self, point) -> float:
        """Distance (mm) from ``point`` to the centre of the contact."""
        return float(np.linalg.norm(np.asarray(point, dtype=float) - self.centre))

    def far(self, point) -> bool:
        """``point`` lies farther from the contact's centre than the layer's radius."""
        return self.distance(point) > self.radius


#: Springs times frames whose dot products :func:`frame_causes` holds at once (8 MB).
_BLOCK = 1 << 20


def _rows(values) -> np.ndarray:
    return np.asarray(values, dtype=float).reshape(-1, 3)


def pressing_fraction(shape: ContactShape, force, body: int) -> float:
    """The part of ``force`` (N, on ``body``) that presses the bodies together along the
    contact's mean normal, over its size: 1 straight into the other body, 0 along the surface,
    -1 straight away from it; NaN without a mean normal or a force."""
    return float(_fractions(shape, _rows(force), body)[0])


def _fractions(shape: ContactShape, forces: np.ndarray, body: int) -> np.ndarray:
    """:func:`pressing_fraction` of each row of ``forces`` (T, 3)."""
    sizes = np.linalg.norm(forces, axis=1)
    if shape.normal is None:
        return np.full(len(forces), math.nan)
    with np.errstate(divide="ignore", invalid="ignore"):
        along = np.where(sizes > 0.0, (forces @ shape.normal) / sizes, math.nan)
    return -along if body == 2 else along


def pulls_apart_proven(shape: ContactShape, force, body: int, free_translations) -> bool:
    """True when no compressive spring force can balance ``force`` along the free translations
    of ``body``: every spring's normal, seen along those translations, points the force's way.

    The proof: on body 2 a spring in compression pushes along its normal ``n_i`` with
    ``lambda_i >= 0`` (on body 1 along ``-n_i``), so equilibrium along the free translations
    (projection ``P``) needs ``P f = -sum lambda_i P n_i`` (body 2). If ``P f . P n_i >= 0`` for
    every spring, then ``|P f|^2 = -sum lambda_i P f . P n_i <= 0``, a contradiction for
    ``P f != 0``.
    """
    return bool(_proven(shape, _rows(force), body, free_translations)[0])


def _proven(shape: ContactShape, forces: np.ndarray, body: int, free_translations) -> np.ndarray:
    """:func:`pulls_apart_proven` of each row of ``forces`` (T, 3): the springs' dot products
    with a block of frames at a time (at most :data:`_BLOCK` of them)."""
    mask = np.array([axis in free_translations for axis in "xyz"], dtype=float)
    projected = forces * mask
    proven = np.zeros(len(forces), dtype=bool)
    if not len(shape.normals):
        return proven
    normals = shape.normals * mask
    step = max(1, _BLOCK // len(normals))
    for start in range(0, len(forces), step):
        dots = normals @ projected[start : start + step].T
        proven[start : start + step] = (dots >= 0.0).all(axis=0) if body == 2 else (dots <= 0.0).all(axis=0)
    return proven & projected.any(axis=1)


def frame_cause(shape: ContactShape, problem, force, moment, point, body: int) -> str | None:
    """What is wrong with one load (``force`` N, ``moment`` N mm about ``body``'s reference,
    the force acting at ``point`` or at the reference) on this contact, or None:

    - ``"pulls_apart_proven"``: :func:`pulls_apart_proven` (no spring can carry it);
    - ``"pulls_apart"``: the force points away from the other body (more than 60 degrees off
      the surface, on the far side);
    - ``"along_surface"``: the force lies within 30 degrees of the contact's surface;
    - ``"moment_units"``: its moment about the contact's centre needs a lever arm of more than
      :data:`MOMENT_ARMS` layer radii (about a free rotation of the body).
    """
    return frame_causes(shape, problem, force, moment, point, body)[0]


def frame_causes(shape: ContactShape, problem, forces, moments, point, body: int) -> list:
    """:func:`frame_cause` of each frame of a path (``forces``, ``moments``: (T, 3)), computed on
    the arrays at once: a hundred thousand frames are checked before a run in milliseconds."""
    the_body = problem.body1 if body == 1 else problem.body2
    free = set(the_body.free)
    translations = [dof[1] for dof in ("ux", "uy", "uz") if dof in free]
    forces = _rows(forces)
    causes = np.full(len(forces), None, dtype=object)
    causes[moment_arms(shape, problem, forces, moments, point, body) > MOMENT_ARMS * shape.radius] = "moment_units"
    fractions = _fractions(shape, forces, body)
    finite = np.isfinite(fractions)
    causes[finite & (np.abs(fractions) < ALONG_SURFACE)] = "along_surface"
    causes[finite & (fractions <= -ALONG_SURFACE)] = "pulls_apart"
    if translations:
        causes[_proven(shape, forces, body, translations)] = "pulls_apart_proven"
    causes[np.linalg.norm(forces, axis=1) == 0.0] = None
    return causes.tolist()


def moment_arm(shape: ContactShape, problem, force, moment, point, body: int) -> float:
    """The lever arm (mm) the load's moment about the contact's centre needs, counted along the
    body's free rotations only (the held ones take theirs): ``|M_c| / |F|``, with ``M_c = M +
    (p - c) x F`` (``p`` the force's point, else the body's reference)."""
    return float(moment_arms(shape, problem, force, moment, point, body)[0])


def moment_arms(shape: ContactShape, problem, forces, moments, point, body: int) -> np.ndarray:
    """:func:`moment_arm` of each frame of a path (``forces``, ``moments``: (T, 3); ``point``
    shared by the frames, or None), computed on the arrays at once."""
    the_body = problem.body1 if body == 1 else problem.body2
    rotations = [dof[1] for dof in ("rx", "ry", "rz") if dof in set(the_body.free)]
    forces, moments = _rows(forces), _rows(moments)
    sizes = np.linalg.norm(forces, axis=1)
    arms = np.zeros(len(forces))
    loaded = sizes > 0.0
    if not rotations or not loaded.any():
        return arms
    at = np.asarray(point if point is not None else the_body.reference, dtype=float)
    about_centre = moments[loaded] + np.cross(at - shape.centre, forces[loaded])
    mask = np.array([axis in rotations for axis in "xyz"], dtype=float)
    arms[loaded] = np.linalg.norm(about_centre * mask, axis=1) / sizes[loaded]
    return arms


def vector_text(vector, digits: int = 4) -> str:
    """``(0, 0, -1000)``: a vector as a scenario would write it, without trailing zeros."""
    return "(" + ", ".join(f"{float(v):.{digits}g}" for v in vector) + ")"
