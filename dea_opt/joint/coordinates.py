"""How a body of a joint moves with its six coordinates, and the loads that follow it.

Written math: ``formulations/joint.md`` ("Coordinates" and "Loads at points, in the ground or
body frame"). Under finite kinematics a body's six coordinates are, by default, the translation
of its reference and its rotation vector (:func:`rotation_vector_motion`). A :class:`Coordinates`
makes them those of an OpenSim ``CustomJoint`` instead: three rotations about given axes in order
(each about its axis as the ones before turned it), then three translations along axes of the
joint's fixed frame, each axis value a linear function of one coordinate. A motion file of the
model's coordinates (``knee_flex_r`` ...) then prescribes some of them frame by frame and leaves
the others free. A :class:`BodyLoad` is a force and a moment on a body, at a point of the body,
with components in the ground frame (fixed in space) or in the body's frame (turning with it).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks.inputs import vector3
from ..errors import InputError
from ..formulations._parts.finite_geometry import left_jacobian, pose_matrix, rotation

__all__ = ["LOAD_FRAMES", "BodyLoad", "Coordinates", "rotation_vector_motion"]

#: The frames a load's components may be given in.
LOAD_FRAMES = ("ground", "body")


def _axis_rotation(axis, angle) -> np.ndarray:
    return rotation(np.asarray(axis) * angle)


def _matrix(value, field: str, shape: tuple) -> np.ndarray:
    try:
        out = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{field} must be numbers of shape {shape}, got {value!r}") from None
    if out.shape != shape or not np.isfinite(out).all():
        raise InputError(f"{field} must be finite numbers of shape {shape}, got shape {out.shape}")
    return out


@dataclass(frozen=True, eq=False)
class Coordinates:
    """A body's six coordinates as an OpenSim ``CustomJoint``'s (finite kinematics only).

    The joint's frame ``frame`` (4x4, mm, in the joint's world frame) is fixed. With the axis values
    ``a_k = slopes[k] q_k + intercepts[k]`` of the coordinates ``q`` (rad for the rotations, mm for
    the translations), the joint's transform is

        X(q) = T(Rot(a_1, e_1) Rot(a_2, e_2) Rot(a_3, e_3), a_4 e_4 + a_5 e_5 + a_6 e_6)

    (the rotations body-fixed in order, then the translations along axes of ``frame``), and the body
    moves by ``D(q) = frame X(q) X(q_s)^-1 frame^-1`` (``inverted=False``: the body is the joint's
    child) or ``D(q) = frame X(q)^-1 X(q_s) frame^-1`` (``inverted=True``: the body is the joint's
    parent, moving on a child held in place, e.g. the femur on a fixed tibia), ``q_s = start``: the
    identity at the start pose, where the joint's elements are given. The body's dofs name the
    coordinates: ``rx``, ``ry``, ``rz`` the three rotations (rad) and ``ux``, ``uy``, ``uz`` the
    three translations (mm), in the axes' order; a prescribed value is the coordinate's, and a dof
    neither free nor prescribed is held at its start value.

    Parameters
    ----------
    frame : array_like, shape (4, 4)
        The joint's fixed frame in the world at the start pose (the parent frame ``F`` of an
        OpenSim joint whose child moves; the child frame ``M`` where the parent moves), mm.
    rotation_axes, translation_axes : array_like, shape (3, 3)
        One unit axis per row, in ``frame`` (normalised here; no two collinear).
    start : array_like, shape (6,)
        The coordinates at the start pose, in dof order (``ux, uy, uz, rx, ry, rz``: mm, rad).
    slopes, intercepts : array_like, shape (6,)
        The linear functions of the axes, in dof order (default 1 and 0); an intercept of a
        translation in mm, of a rotation in rad.
    inverted : bool
    names : sequence of 6 str, optional
        The coordinates' names in dof order (e.g. OpenSim's), for tables.
    """

    frame: np.ndarray
    rotation_axes: np.ndarray
    translation_axes: np.ndarray
    start: np.ndarray
    slopes: np.ndarray | None = None
    intercepts: np.ndarray | None = None
    inverted: bool = False
    names: tuple | None = None

    def __post_init__(self):
        set_ = object.__setattr__
        frame = _matrix(self.frame, "Coordinates.frame", (4, 4))
        R = frame[:3, :3]
        if np.abs(R.T @ R - np.eye(3)).max() > 1e-9 or np.linalg.det(R) < 0 or np.abs(frame[3] - [0, 0, 0, 1]).max():
            raise InputError("Coordinates.frame must be a rigid transform (a rotation and a translation, mm)")
        set_(self, "frame", frame)
        for field in ("rotation_axes", "translation_axes"):
            axes = _matrix(getattr(self, field), f"Coordinates.{field}", (3, 3))
            norms = np.linalg.norm(axes, axis=1)
            if (norms < 1e-12).any():
                raise InputError(f"Coordinates.{field} has an axis of zero length: {axes.tolist()}")
            axes = axes / norms[:, None]
            for i, j in ((0, 1), (0, 2), (1, 2)):
                if np.linalg.norm(np.cross(axes[i], axes[j])) < 1e-5:
                    raise InputError(f"Coordinates.{field}: axes {i + 1} and {j + 1} are collinear")
            set_(self, field, axes)
        set_(self, "start", _matrix(self.start, "Coordinates.start", (6,)))
        set_(self, "slopes", _matrix(np.ones(6) if self.slopes is None else self.slopes, "Coordinates.slopes", (6,)))
        if (self.slopes == 0).any():  # type: ignore[union-attr]
            raise InputError(
                f"Coordinates.slopes must be nonzero (a coordinate that moves its axis), got {self.slopes}"
            )
        set_(
            self,
            "intercepts",
            _matrix(np.zeros(6) if self.intercepts is None else self.intercepts, "Coordinates.intercepts", (6,)),
        )
        if not isinstance(self.inverted, bool):
            raise InputError(f"Coordinates.inverted must be True or False, got {self.inverted!r}")
        if self.names is not None:
            names = tuple(self.names)
            if len(names) != 6 or not all(isinstance(n, str) and n for n in names):
                raise InputError(f"Coordinates.names must be 6 names in dof order, got {self.names!r}")
            set_(self, "names", names)
        set_(self, "_start_inverse", np.linalg.inv(self.transform(self.start)))

    # --- the joint's transform ------------------------------------------------------------
    def _values(self, q) -> np.ndarray:
        return self.slopes * np.asarray(q, dtype=float) + self.intercepts  # type: ignore[operator]

    def _rotations(self, a) -> list[np.ndarray]:
        return [_axis_rotation(self.rotation_axes[k], a[3 + k]) for k in range(3)]

    def transform(self, q) -> np.ndarray:
        """``X(q)`` (4, 4), mm."""
        a = self._values(q)
        R1, R2, R3 = self._rotations(a)
        X = np.eye(4)
        X[:3, :3] = R1 @ R2 @ R3
        X[:3, 3] = a[:3] @ self.translation_axes
        return X

    def motion(self, q) -> np.ndarray:
        """``D(q)`` (4, 4): the body's rigid motion from its start pose, in the world (mm)."""
        X = self.transform(q)
        F = self.frame
        if self.inverted:
            return F @ np.linalg.inv(X) @ np.linalg.inv(self._start_inverse) @ np.linalg.inv(F)
        return F @ X @ self._start_inverse @ np.linalg.inv(F)

    def rates(self, q, point) -> np.ndarray:
        """``B`` (6, 6): the velocity of the world point ``point`` (where the motion put it, mm) and
        the body's angular velocity per unit rate of each coordinate (columns in dof order)."""
        a = self._values(q)
        R1, R2, _ = self._rotations(a)
        X = self.transform(q)
        p = X[:3, 3]
        G = self.frame @ np.linalg.inv(X) if self.inverted else self.frame
        sign = -1.0 if self.inverted else 1.0
        B = np.zeros((6, 6))
        point = np.asarray(point, dtype=float)
        for j in range(6):
            if j < 3:  # a translation: dp along its axis
                w_local, dp = np.zeros(3), self.slopes[j] * self.translation_axes[j]  # type: ignore[index]
            else:  # a rotation about its axis, turned by the rotations before it
                k = j - 3
                before = np.eye(3) if k == 0 else (R1 if k == 1 else R1 @ R2)
                w_local, dp = self.slopes[j] * before @ self.rotation_axes[k], np.zeros(3)  # type: ignore[index]
            v_local = dp - np.cross(w_local, p)
            w = sign * G[:3, :3] @ w_local
            v = sign * (G[:3, :3] @ v_local) - np.cross(w, G[:3, 3])
            B[:3, j] = np.cross(w, point) + v
            B[3:, j] = w
        return B

    def describe(self) -> str:
        names = self.names or ("ux", "uy", "uz", "rx", "ry", "rz")
        return "a CustomJoint's coordinates (" + ", ".join(names) + ")" + (", inverted" if self.inverted else "")


def rotation_vector_motion(u6, reference) -> tuple[np.ndarray, np.ndarray]:
    """``(D, B)`` of the default coordinates: the translation ``t`` of the reference ``c`` and the
    rotation vector ``theta`` (``x' = c + t + R(theta) (x - c)``), and ``diag(I, J(theta))``."""
    u6 = np.asarray(u6, dtype=float)
    B = np.eye(6)
    B[3:, 3:] = left_jacobian(u6[3:])
    return pose_matrix(u6, reference), B


@dataclass(frozen=True, eq=False)
class BodyLoad:
    """A force and a moment on a body of a joint, at a point of it, in the ground or body frame.

    Parameters
    ----------
    body : str
        The body's name in the joint.
    force : array_like, shape (3,)
        N.
    moment : array_like, shape (3,)
        N mm (a couple: the same about every point).
    point : array_like, shape (3,), optional
        Where the force acts: a point of the body, given in the world frame at the start pose (mm),
        which moves with the body. Default: the body's reference.
    frame : {"ground", "body"}
        ``"ground"``: the components are fixed in space (a weight, a load cell's reading in the
        laboratory). ``"body"``: they are given in the world axes at the start pose and turn with
        the body (a load measured in the bone's own frame, a follower load). Small kinematics
        take both at the start pose; finite kinematics turn a body-frame load with the body and
        move every point with it.
    """

    body: str = ""
    force: tuple = (0.0, 0.0, 0.0)
    moment: tuple = (0.0, 0.0, 0.0)
    point: tuple | None = None
    frame: str = "ground"

    def __post_init__(self):
        if not isinstance(self.body, str) or not self.body:
            raise InputError(f"BodyLoad.body must be the name of a body of the joint, got {self.body!r}")
        object.__setattr__(self, "force", vector3("BodyLoad.force", self.force, "N"))
        object.__setattr__(self, "moment", vector3("BodyLoad.moment", self.moment, "N mm"))
        if self.point is not None:
            object.__setattr__(self, "point", vector3("BodyLoad.point", self.point, "mm"))
        if self.frame not in LOAD_FRAMES:
            raise InputError(f"BodyLoad.frame must be one of {LOAD_FRAMES}, got {self.frame!r}")

    def wrench(self, reference, motion=None) -> np.ndarray:
        """``(F, M)`` (6,) in the world about the body's reference where ``motion`` (4x4, the body's
        motion from its start pose; None: the start) put it: N, N mm."""
        c = np.asarray(reference, dtype=float)
        point = c if self.point is None else np.asarray(self.point, dtype=float)
        F, M = np.asarray(self.force, dtype=float), np.asarray(self.moment, dtype=float)
        if motion is not None:
            R, t = motion[:3, :3], motion[:3, 3]
            point, c = R @ point + t, R @ c + t
            if self.frame == "body":
                F, M = R @ F, R @ M
        return np.concatenate([F, M + np.cross(point - c, F)])
