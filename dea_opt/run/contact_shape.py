"""The shape of a contact as the checks before a run see it, and what is wrong with a load on it.

:class:`ContactShape` is what the checks of :mod:`dea_opt.run.preflight` and the grouping of a
load path's failed frames (:mod:`dea_opt.run.diagnose`) need to know about the springs: their
centre, mean normal, size and area. :func:`frame_cause` says what is wrong with one load on it,
in the terms a user can act on (a sign, a column, a unit), or None.
Units: mm, N, N mm, MPa.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["ContactShape", "frame_cause", "pressing_fraction", "pulls_apart_proven"]

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


def pressing_fraction(shape: ContactShape, force, body: int) -> float:
    """The part of ``force`` (N, on ``body``) that presses the bodies together along the
    contact's mean normal, over its size: 1 straight into the other body, 0 along the surface,
    -1 straight away from it; NaN without a mean normal or a force."""
    force = np.asarray(force, dtype=float)
    size = float(np.linalg.norm(force))
    if shape.normal is None or size == 0.0:
        return math.nan
    along = float(force @ shape.normal) / size
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
    mask = np.zeros(3)
    for axis in free_translations:
        mask["xyz".index(axis)] = 1.0
    projected = np.asarray(force, dtype=float) * mask
    if not projected.any() or not len(shape.normals):
        return False
    dots = (shape.normals * mask) @ projected
    return bool((dots >= 0.0).all()) if body == 2 else bool((dots <= 0.0).all())


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
    the_body = problem.body1 if body == 1 else problem.body2
    free = set(the_body.free)
    translations = [dof[1] for dof in ("ux", "uy", "uz") if dof in free]
    force = np.asarray(force, dtype=float)
    size = float(np.linalg.norm(force))
    if size == 0.0:
        return None
    if translations and pulls_apart_proven(shape, force, body, translations):
        return "pulls_apart_proven"
    fraction = pressing_fraction(shape, force, body)
    if math.isfinite(fraction) and fraction <= -ALONG_SURFACE:
        return "pulls_apart"
    if math.isfinite(fraction) and abs(fraction) < ALONG_SURFACE:
        return "along_surface"
    if moment_arm(shape, problem, force, moment, point, body) > MOMENT_ARMS * shape.radius:
        return "moment_units"
    return None


def moment_arm(shape: ContactShape, problem, force, moment, point, body: int) -> float:
    """The lever arm (mm) the load's moment about the contact's centre needs, counted along the
    body's free rotations only (the held ones take theirs): ``|M_c| / |F|``, with ``M_c = M +
    (p - c) x F`` (``p`` the force's point, else the body's reference)."""
    the_body = problem.body1 if body == 1 else problem.body2
    rotations = [dof[1] for dof in ("rx", "ry", "rz") if dof in set(the_body.free)]
    size = float(np.linalg.norm(force))
    if not rotations or size == 0.0:
        return 0.0
    at = np.asarray(point if point is not None else the_body.reference, dtype=float)
    about_centre = np.asarray(moment, dtype=float) + np.cross(at - shape.centre, np.asarray(force, dtype=float))
    mask = np.array([axis in rotations for axis in "xyz"], dtype=float)
    return float(np.linalg.norm(about_centre * mask)) / size


def vector_text(vector, digits: int = 4) -> str:
    """``(0, 0, -1000)``: a vector as a scenario would write it, without trailing zeros."""
    return "(" + ", ".join(f"{float(v):.{digits}g}" for v in vector) + ")"
