"""The anatomical frame of a joint: which way is medial, anterior and proximal, and where the origin is.

Maps drawn in this frame have labelled sides (Medial/Lateral, Anterior/Posterior,
Proximal/Distal), coordinates in mm from a named origin, and are never mirrored: the picture
is what one sees looking at the layer from body 2.

The three directions follow the ISB convention (Wu et al., J Biomech 2002): anterior,
proximal and the subject's right make a right-handed frame (``anterior x proximal = right``).
For a right limb the right is lateral, for a left limb it is medial, so two directions and
the side give the third. Give the frame by directions (:meth:`AnatomicalFrame.from_directions`),
by three landmarks (:meth:`AnatomicalFrame.from_landmarks`), or from a scenario's table
(:meth:`AnatomicalFrame.from_dict`). Units: mm.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks.inputs import as_float_array
from ..errors import InputError

__all__ = ["AXES", "AnatomicalFrame"]

#: The anatomical directions and their opposites.
AXES = {"medial": "lateral", "anterior": "posterior", "proximal": "distal"}
_OPPOSITE = {**AXES, **{v: k for k, v in AXES.items()}}
_SIDES = ("right", "left")
#: Three directions given together must be within 10 degrees of perpendicular (cosine).
_PERPENDICULAR = 0.174
#: Two directions given together must be at least 45 degrees apart (cosine).
_APART = 0.707


def _direction(name: str, value) -> np.ndarray:
    vector = as_float_array(name, value, (3,))
    length = float(np.linalg.norm(vector))
    if not length > 1e-12:
        raise InputError(f"{name} must be a nonzero direction, got {vector.tolist()}")
    return vector / length


def _side(side) -> str | None:
    if side is None:
        return None
    if not isinstance(side, str) or side.strip().lower() not in _SIDES:
        raise InputError(f"anatomy.side must be 'right' or 'left' (the limb), got {side!r}")
    return side.strip().lower()


@dataclass(frozen=True)
class AnatomicalFrame:
    """Orthonormal anatomical directions and an origin.

    Attributes
    ----------
    medial, anterior, proximal : ndarray, shape (3,)
        Unit vectors in the coordinates of the meshes (mm), mutually perpendicular.
    origin : ndarray, shape (3,) or None
        The origin of the maps (mm); None for the layer's centroid (area-weighted).
    origin_name : str
        What the origin is, for labels: ``"layer centroid"`` or a landmark's name.
    side : {"right", "left"}
        The limb, from the handedness of the three directions.
    """

    medial: np.ndarray
    anterior: np.ndarray
    proximal: np.ndarray
    origin: np.ndarray | None = None
    origin_name: str = "layer centroid"
    side: str = "right"

    def __post_init__(self):
        set_ = object.__setattr__
        names = ("medial", "anterior", "proximal")
        vectors = [_direction(f"anatomy.{n}", getattr(self, n)) for n in names]
        for i in range(3):
            for j in range(i + 1, 3):
                cos = abs(float(vectors[i] @ vectors[j]))
                if cos > _PERPENDICULAR:
                    angle = np.degrees(np.arccos(min(cos, 1.0)))
                    raise InputError(
                        f"anatomy.{names[i]} and anatomy.{names[j]} must be perpendicular, got "
                        f"{90 - angle:.3g} degrees off"
                    )
        # Exactly orthonormal, proximal kept, medial made perpendicular to it, anterior from both.
        proximal = vectors[2]
        medial = vectors[0] - (vectors[0] @ proximal) * proximal
        medial /= np.linalg.norm(medial)
        right_handed = float(np.cross(medial, proximal) @ vectors[1]) > 0
        side = "right" if right_handed else "left"
        anterior = np.cross(medial, proximal) if right_handed else np.cross(proximal, medial)
        for name, value in zip(names, (medial, anterior, proximal)):
            value = np.array(value, dtype=float)
            value.setflags(write=False)
            set_(self, name, value)
        set_(self, "side", side)
        if self.origin is not None:
            origin = as_float_array("anatomy.origin", self.origin, (3,)).copy()
            origin.setflags(write=False)
            set_(self, "origin", origin)
        if not isinstance(self.origin_name, str) or not self.origin_name:
            raise InputError(f"anatomy.origin_name must be a nonempty string, got {self.origin_name!r}")

    # --- constructors -------------------------------------------------------------------
    @classmethod
    def from_directions(
        cls, medial=None, anterior=None, proximal=None, *, side=None, origin=None, origin_name: str | None = None
    ) -> AnatomicalFrame:
        """From two or three directions (mm coordinates); with two, ``side`` gives the third.

        Parameters
        ----------
        medial, anterior, proximal : array_like, shape (3,), optional
            At least two of them.
        side : {"right", "left"}, optional
            The limb; needed when one direction is missing.
        origin : array_like, shape (3,), optional
            Default the layer's centroid.
        origin_name : str, optional
            Default ``"origin"`` when ``origin`` is given.

        Two directions need only be far from parallel: proximal (else medial) is kept and the
        other made perpendicular to it. Three must be within 10 degrees of perpendicular.
        """
        given = {n: v for n, v in (("medial", medial), ("anterior", anterior), ("proximal", proximal)) if v is not None}
        if len(given) < 2:
            raise InputError(
                f"anatomy needs two of medial, anterior and proximal (and side), got {sorted(given) or 'none'}"
            )
        side = _side(side)
        vectors = {n: _direction(f"anatomy.{n}", v) for n, v in given.items()}
        if len(vectors) == 2:
            # The first of proximal, medial, anterior is kept; the other made perpendicular to it.
            (first, a), (second, b) = sorted(
                vectors.items(), key=lambda item: ("proximal", "medial", "anterior").index(item[0])
            )
            if abs(float(a @ b)) > _APART:
                raise InputError(
                    f"anatomy.{first} and anatomy.{second} must be far from parallel (more than 45 "
                    f"degrees apart), got {np.degrees(np.arccos(min(abs(float(a @ b)), 1.0))):.3g}"
                )
            vectors[second] = (b - (b @ a) * a) / np.linalg.norm(b - (b @ a) * a)
            if side is None:
                missing = next(n for n in AXES if n not in vectors)
                raise InputError(
                    f"anatomy gives two directions, so side ('right' or 'left') must say which way {missing} points"
                )
            vectors = _third(vectors, side)
        frame = cls(
            vectors["medial"],
            vectors["anterior"],
            vectors["proximal"],
            origin,
            origin_name or ("origin" if origin is not None else "layer centroid"),
        )
        if side is not None and frame.side != side:
            raise InputError(f"anatomy: medial, anterior and proximal make a {frame.side} limb, but side is {side!r}")
        return frame

    @classmethod
    def from_landmarks(cls, landmarks, *, side=None, origin=None) -> AnatomicalFrame:
        """From three landmarks (mm): two on either end of one axis and one along another.

        Parameters
        ----------
        landmarks : mapping {name: point (3,)}
            Three points named by the direction they mark: one pair of opposites
            (``medial`` and ``lateral``, e.g. the epicondyles; or ``anterior`` and
            ``posterior``; or ``proximal`` and ``distal``) and a third named by another
            direction (e.g. ``proximal``: the hip centre). The pair's axis is kept exactly;
            the third is measured from the pair's midpoint and made perpendicular to it.
        side : {"right", "left"}
            The limb: which way the remaining direction points.
        origin : str or array_like (3,), optional
            ``"midpoint"`` (of the pair), a landmark's name, or a point; default the
            layer's centroid.
        """
        if not hasattr(landmarks, "items") or len(landmarks) != 3:
            raise InputError(f"anatomy.landmarks must be a table of three named points, got {landmarks!r}")
        points = {}
        for name, point in landmarks.items():
            key = str(name).strip().lower()
            if key not in _OPPOSITE:
                raise InputError(
                    f"anatomy.landmarks: {name!r} is not a direction; name each landmark by the "
                    f"direction it marks: {', '.join(_OPPOSITE)}"
                )
            points[key] = as_float_array(f"anatomy.landmarks.{name}", point, (3,))
        pairs = [n for n in points if _OPPOSITE[n] in points]
        if len(pairs) != 2:
            raise InputError(
                f"anatomy.landmarks must hold one pair of opposite directions (medial and lateral, "
                f"anterior and posterior, or proximal and distal) and a third, got {sorted(points)}"
            )
        first, second = pairs
        third = next(n for n in points if n not in pairs)
        if _OPPOSITE[third] in pairs or third in pairs:
            raise InputError(f"anatomy.landmarks: {third!r} lies along the same axis as {first!r} and {second!r}")
        midpoint = 0.5 * (points[first] + points[second])
        axis = _canonical(first, points[first] - points[second])
        along = points[third] - midpoint
        along = along - (along @ axis[1]) * axis[1]
        vectors = {axis[0]: axis[1], **dict([_canonical(third, along)])}
        side = _side(side)
        if side is None:
            raise InputError("anatomy.landmarks: side ('right' or 'left') must say which limb it is")
        vectors = _third(vectors, side)
        origin_name = "layer centroid"
        if isinstance(origin, str):
            key = origin.strip().lower()
            if key == "midpoint":
                origin, origin_name = midpoint, f"{first}-{second} midpoint"
            elif key in points:
                origin, origin_name = points[key], f"{key} landmark"
            else:
                raise InputError(
                    f"anatomy.origin must be 'midpoint', a landmark ({', '.join(points)}) or a point, got {origin!r}"
                )
        elif origin is not None:
            origin_name = "origin"
        return cls(vectors["medial"], vectors["anterior"], vectors["proximal"], origin, origin_name)

    @classmethod
    def from_dict(cls, spec) -> AnatomicalFrame:
        """From a plain table (a scenario's ``anatomy``): ``{medial, anterior, proximal, side,
        origin, origin_name}`` or ``{landmarks = {...}, side, origin}``."""
        if isinstance(spec, AnatomicalFrame):
            return spec
        if not hasattr(spec, "items"):
            raise InputError(
                f"anatomy must be a table (a dict in Python) or an AnatomicalFrame, got {type(spec).__name__}"
            )
        spec = dict(spec)
        allowed = {"medial", "anterior", "proximal", "side", "origin", "origin_name", "landmarks"}
        unknown = sorted(set(spec) - allowed)
        if unknown:
            raise InputError(
                f"anatomy: unknown key{'s' if len(unknown) > 1 else ''} {', '.join(unknown)}; "
                f"expected {', '.join(sorted(allowed))}"
            )
        if "landmarks" in spec:
            extra = sorted(set(spec) & {"medial", "anterior", "proximal", "origin_name"})
            if extra:
                raise InputError(f"anatomy: give landmarks or directions, not both (also got {', '.join(extra)})")
            return cls.from_landmarks(spec["landmarks"], side=spec.get("side"), origin=spec.get("origin"))
        origin = spec.get("origin")
        if isinstance(origin, str):
            if origin.strip().lower() not in ("centroid", "layer centroid"):
                raise InputError(f"anatomy.origin must be 'centroid' or a point (3 numbers, mm), got {origin!r}")
            origin = None
        return cls.from_directions(
            spec.get("medial"),
            spec.get("anterior"),
            spec.get("proximal"),
            side=spec.get("side"),
            origin=origin,
            origin_name=spec.get("origin_name"),
        )

    # --- use ----------------------------------------------------------------------------
    def direction(self, name: str) -> np.ndarray:
        """The unit vector of ``name`` (any of the six directions)."""
        key = str(name).lower()
        if key in AXES:
            return getattr(self, key)
        if key in _OPPOSITE:
            return -getattr(self, _OPPOSITE[key])
        raise InputError(f"direction must be one of {', '.join(_OPPOSITE)}, got {name!r}")

    def origin_for(self, points, weights=None) -> np.ndarray:
        """The origin (mm): the given one, or the weighted centroid of ``points``."""
        if self.origin is not None:
            return np.asarray(self.origin)
        points = np.asarray(points, dtype=float)
        w = np.ones(len(points)) if weights is None else np.asarray(weights, dtype=float)
        return w @ points / w.sum()

    def layer_origin(self, layer) -> np.ndarray:
        """The origin (mm, shape (3,)) of coordinates on ``layer``: the given one, or the
        area-weighted centroid of its springs (what every anatomical output measures from)."""
        return self.origin_for(layer.points, layer.areas)

    def coordinates(self, points, origin=None) -> np.ndarray:
        """``(medial, anterior, proximal)`` coordinates (mm) of ``points`` (..., 3) from ``origin``."""
        origin = self.origin if origin is None else origin
        origin = np.zeros(3) if origin is None else np.asarray(origin, dtype=float)
        return (np.asarray(points, dtype=float) - origin) @ np.array([self.medial, self.anterior, self.proximal]).T

    def as_dict(self) -> dict:
        return {
            "medial": self.medial.tolist(),
            "anterior": self.anterior.tolist(),
            "proximal": self.proximal.tolist(),
            "side": self.side,
            "origin": None if self.origin is None else self.origin.tolist(),
            "origin_name": self.origin_name,
        }


def _canonical(name: str, vector) -> tuple[str, np.ndarray]:
    """``(axis name, unit vector)`` with the vector turned to the axis's positive direction."""
    vector = _direction(f"anatomy.landmarks.{name}", vector)
    return (name, vector) if name in AXES else (_OPPOSITE[name], -vector)


def _third(vectors: dict, side: str) -> dict:
    """The missing one of medial, anterior, proximal from the other two and the side."""
    right_sign = -1.0 if side == "right" else 1.0  # the subject's right is -medial on a right limb
    missing = [n for n in AXES if n not in vectors]
    if not missing:
        return vectors
    out = dict(vectors)
    if missing == ["anterior"]:
        right = right_sign * out["medial"]
        out["anterior"] = np.cross(out["proximal"] - (out["proximal"] @ right) * right, right)
    elif missing == ["proximal"]:
        right = right_sign * out["medial"]
        anterior = out["anterior"] - (out["anterior"] @ right) * right
        out["proximal"] = np.cross(right, anterior)
    else:  # medial: right = anterior x proximal
        right = np.cross(out["anterior"], out["proximal"])
        out["medial"] = right_sign * right
    return {n: v / np.linalg.norm(v) for n, v in out.items()}
