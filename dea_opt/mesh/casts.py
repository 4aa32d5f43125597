"""What a cast of springs holds: the pose it was cast at (checked), the springs with what each ray
met (:class:`SpringCast`), and the faces that made no spring, by reason (:class:`Dropped`).

:mod:`dea_opt.mesh.springs` casts them; :mod:`dea_opt.mesh.recast` and
:mod:`dea_opt.mesh.facecast` cast them again at another pose.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._checks.thresholds import POSE_LAST_ROW, POSE_ROTATION
from ..errors import InputError
from ..layer import SpringLayer

__all__ = ["DROP_REASONS", "LOST_REASONS", "Dropped", "SpringCast", "check_pose"]


def check_pose(pose, name: str = "pose") -> np.ndarray | None:
    """Validate a 4x4 rigid transform (rotation with det +1, last row 0 0 0 1).

    Returns the pose as a float array, or None for None. Raises :class:`InputError`.
    """
    if pose is None:
        return None
    try:
        T = np.array(pose, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a 4x4 rigid transform, got {type(pose).__name__}") from None
    if T.shape != (4, 4):
        raise InputError(f"{name} must be a 4x4 rigid transform, got shape {T.shape}")
    if not np.isfinite(T).all():
        raise InputError(f"{name} must be finite, got NaN or inf")
    if not np.allclose(T[3], [0, 0, 0, 1], rtol=0, atol=POSE_LAST_ROW):
        raise InputError(f"{name} must have last row (0, 0, 0, 1), got {T[3].tolist()}")
    R = T[:3, :3]
    error = float(np.abs(R.T @ R - np.eye(3)).max())
    if error > POSE_ROTATION:
        raise InputError(
            f"{name} is not rigid: its 3x3 block must be a rotation (R^T R = I), but "
            f"|R^T R - I| = {error:.3g} (scaling or shear?)"
        )
    det = float(np.linalg.det(R))
    if det < 0:
        raise InputError(
            f"{name} is not rigid: its 3x3 block is a reflection (det = {det:.3g}), expected a rotation with det +1"
        )
    return T


#: Why a face of mesh 1 whose ray met mesh 2 made no spring (see :class:`Dropped`).
DROP_REASONS = ("overlap", "through_layer", "angle", "thickness")
#: Further outcomes of a face in a re-cast: its ray met mesh 2 only beyond ``max_gap``, or
#: met no face of mesh 2 that faces it.
LOST_REASONS = DROP_REASONS + ("gap", "no_hit")
_SPRING = -1  # outcome code of a face that made a spring; others index LOST_REASONS


@dataclass(frozen=True, eq=False)
class Dropped:
    """The faces of mesh 1 whose ray met mesh 2 but made no spring, by reason.

    Reasons (:data:`DROP_REASONS`):

    ``overlap``
        The ray met a face of mesh 2 that faces it, in front of mesh 1's own far side, but
        deeper than the overlap the window allows: a spring that would carry load, dropped by
        the window. This is the count of ``dropped_springs`` in :mod:`dea_opt.validity`.
    ``through_layer``
        Rejected: every face of mesh 2 the ray met inside the window lies behind mesh 1's
        own far side (the ray went back through the spring layer itself).
    ``angle``
        The face met inside the window is more than ``max_angle`` from facing the spring.
    ``thickness``
        The thickness could not be measured or is zero (a warning says which side).

    Attributes
    ----------
    faces : dict {reason: ndarray of int}
        The faces of mesh 1 (as checked, :attr:`SpringCast.mesh1`) dropped for each reason.
    """

    faces: dict = field(default_factory=dict)

    def __post_init__(self):
        faces = {r: np.asarray(self.faces.get(r, ()), dtype=np.int64) for r in DROP_REASONS}
        object.__setattr__(self, "faces", faces)

    @property
    def counts(self) -> dict:
        """``{reason: number of faces}``, every reason present."""
        return {reason: len(f) for reason, f in self.faces.items()}

    @property
    def total(self) -> int:
        return sum(self.counts.values())

    def __getitem__(self, reason: str) -> int:
        return self.counts[reason]

    def describe(self) -> str:
        """``"none"`` or e.g. ``"overlap 3, through_layer 12"``."""
        parts = [f"{r} {c}" for r, c in self.counts.items() if c]
        return ", ".join(parts) if parts else "none"

    def __repr__(self) -> str:
        return f"Dropped({self.describe()})"


@dataclass(frozen=True, eq=False)
class SpringCast:
    """The springs cast from mesh 1 onto mesh 2, with what each ray met.

    Attributes
    ----------
    layer : SpringLayer
        The springs (see :func:`springs_from_meshes`), with their targets on mesh 2.
    hit_face : ndarray of int, shape (N,)
        The face of mesh 2 each spring's ray met (``layer.target_faces``).
    hit_point : ndarray, shape (N, 3)
        Where it met it, in mesh 1's frame (mm); ``points + gap * normals``.
    thickness1, thickness2 : ndarray, shape (N,)
        The two cartilage thicknesses whose sum is ``layer.thickness`` (mm).
    mesh1, mesh2 : trimesh.Trimesh
        The checked meshes (mesh 2 in its own frame, before ``pose``).
    pose : ndarray, shape (4, 4)
        The rigid transform applied to mesh 2.
    dropped : Dropped
        The faces of mesh 1 whose ray met mesh 2 but made no spring, by reason.
    options : dict
        The options of the cast, resolved to the checked meshes (thickness specifications,
        window, labels, engine), so that :func:`~dea_opt.mesh.recast` repeats it at another pose.
    """

    layer: SpringLayer
    hit_face: np.ndarray
    hit_point: np.ndarray
    thickness1: np.ndarray
    thickness2: np.ndarray
    mesh1: object
    mesh2: object
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))
    dropped: Dropped = field(default_factory=Dropped)
    options: dict = field(default_factory=dict)
    outcome: np.ndarray | None = field(default=None, repr=False)
    """Per face of mesh 1: -1 for a spring, else the index of its reason in :data:`LOST_REASONS`."""
    met: np.ndarray | None = field(default=None, repr=False)
    """Per face of mesh 1: the face of mesh 2 its ray met first facing it (-1: none), within the
    window or beyond it, where springs that follow body 2 start looking at another pose (None:
    not kept)."""
