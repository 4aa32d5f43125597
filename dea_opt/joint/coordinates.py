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
from ..formulations.finite.rotations import left_jacobian, pose_matrix, rotation

__all__ = ["LOAD_FRAMES", "BodyLoad", "Coordinates", "rotation_vector_motion"]

#: The frames a load's components may be given in.
LOAD_FRAMES = ("ground", "body")


def cross(a, b) -> np.ndarray:
    """``a x b`` over the last axis (3), written out: the products ``np.cross`` makes, without its
    cost on a few vectors (a solve takes tens of thousands of them)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.shape == (3,) and b.shape == (3,):  # two vectors: in floats, the same products
        x0, x1, x2 = a.tolist()
        y0, y1, y2 = b.tolist()
        return np.array([x1 * y2 - x2 * y1, x2 * y0 - x0 * y2, x0 * y1 - x1 * y0])
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def _cross_columns(w, p) -> np.ndarray:
    """``w_j x p`` for each column ``w_j`` of ``w`` (3, k) and a vector ``p`` (3,), as columns (3, k)."""
    p0, p1, p2 = np.asarray(p, dtype=float).tolist()
    return np.array([w[1] * p2 - w[2] * p1, w[2] * p0 - w[0] * p2, w[0] * p1 - w[1] * p0])


def _axis_rotation(axis, angle) -> np.ndarray:
    return rotation(np.asarray(axis) * angle)


def _rigid_inverse(T) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = T[:3, :3].T
    out[:3, 3] = -T[:3, :3].T @ T[:3, 3]
    return out


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
        if (self.slopes == 0).any():
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
        set_(self, "_frame_inverse", _rigid_inverse(frame))
        a = self._values(self.start)
        R1, R2, R3 = self._rotations(a)
        X = np.eye(4)
        X[:3, :3], X[:3, 3] = R1 @ R2 @ R3, a[:3] @ self.translation_axes
        set_(self, "_start", X)
        set_(self, "_start_inverse", _rigid_inverse(X))

    # --- the joint's transform ------------------------------------------------------------
    def _values(self, q) -> np.ndarray:
        return self.slopes * np.asarray(q, dtype=float) + self.intercepts

    def _rotations(self, a) -> list[np.ndarray]:
        return [_axis_rotation(self.rotation_axes[k], a[3 + k]) for k in range(3)]

    def _parts(self, q) -> tuple:
        """``(X, R1, R2)``: the joint's transform and its first two rotations (cached for the last ``q``)."""
        key = tuple(np.asarray(q, dtype=float).tolist())
        cache = self.__dict__.setdefault("_cache", {})
        if cache.get("key") != key:
            a = self._values(q)
            R1, R2, R3 = self._rotations(a)
            X = np.eye(4)
            X[:3, :3] = R1 @ R2 @ R3
            X[:3, 3] = a[:3] @ self.translation_axes
            cache.update(key=key, parts=(X, R1, R2))
        return cache["parts"]

    def transform(self, q) -> np.ndarray:
        """``X(q)`` (4, 4), mm."""
        return self._parts(q)[0].copy()

    def motion(self, q) -> np.ndarray:
        """``D(q)`` (4, 4): the body's rigid motion from its start pose, in the world (mm)."""
        X = self._parts(q)[0]
        F, F_inverse = self.frame, self.__dict__["_frame_inverse"]
        if self.inverted:
            return F @ _rigid_inverse(X) @ self.__dict__["_start"] @ F_inverse
        return F @ X @ self.__dict__["_start_inverse"] @ F_inverse

    def rates(self, q, point) -> np.ndarray:
        """``B`` (6, 6): the velocity of the world point ``point`` (where the motion put it, mm) and
        the body's angular velocity per unit rate of each coordinate (columns in dof order)."""
        X, R1, R2 = self._parts(q)
        p = X[:3, 3]
        G = self.frame @ _rigid_inverse(X) if self.inverted else self.frame
        sign = -1.0 if self.inverted else 1.0
        # columns: the local angular velocity and translation rate per unit of each coordinate
        w_local = np.zeros((3, 6))
        dp = np.zeros((3, 6))
        dp[:, :3] = (self.slopes[:3, None] * self.translation_axes).T  # type: ignore[index]
        turned = np.stack([self.rotation_axes[0], R1 @ self.rotation_axes[1], R1 @ R2 @ self.rotation_axes[2]], axis=1)
        w_local[:, 3:] = turned * self.slopes[3:]  # type: ignore[index]
        v_local = dp - _cross_columns(w_local, p)
        w = sign * G[:3, :3] @ w_local
        v = sign * (G[:3, :3] @ v_local) - _cross_columns(w, G[:3, 3])
        B = np.empty((6, 6))
        B[:3] = _cross_columns(w, point) + v
        B[3:] = w
        return B

    def inverse(self, motion, guess=None) -> np.ndarray:
        """The coordinates ``q`` (6,) of the body's motion ``motion`` (4x4, from its start pose): the
        inverse of :meth:`motion`, the rotations nearest ``guess`` (default :attr:`start`).

        The three angles of ``R = Rot(a_1, e_1) Rot(a_2, e_2) Rot(a_3, e_3)`` are SciPy's Davenport
        angles where ``e_2`` is perpendicular to ``e_1`` and ``e_3``, refined (and otherwise found)
        by least squares from ``guess`` and from them; the translations solve ``p = sum a_k e_k``.
        An :class:`~dea_opt.errors.InputError` where no angles give the rotation to 1e-9.
        """
        from scipy.optimize import least_squares
        from scipy.spatial.transform import Rotation

        D = np.asarray(motion, dtype=float)
        F, F_inverse, start = self.frame, self.__dict__["_frame_inverse"], self.__dict__["_start"]
        X = start @ F_inverse @ _rigid_inverse(D) @ F if self.inverted else F_inverse @ D @ F @ start
        R, p = X[:3, :3], X[:3, 3]
        guess = self.start if guess is None else np.asarray(guess, dtype=float)
        a_guess = self._values(guess)[3:]
        axes = self.rotation_axes

        def residual(a):
            M = _axis_rotation(axes[0], a[0]) @ _axis_rotation(axes[1], a[1]) @ _axis_rotation(axes[2], a[2])
            return (M - R).ravel()

        starts = [a_guess]
        if abs(axes[0] @ axes[1]) < 1e-9 and abs(axes[1] @ axes[2]) < 1e-9:
            found = Rotation.from_matrix(R).as_davenport(axes, "intrinsic")
            starts += [found + 2 * np.pi * np.round((a_guess - found) / (2 * np.pi))]
        best = None
        for a0 in starts:
            fit = least_squares(residual, a0, xtol=1e-15, ftol=1e-15, gtol=1e-15)
            if np.abs(fit.fun).max() <= 1e-9 and (
                best is None or np.abs(fit.x - a_guess).sum() < np.abs(best - a_guess).sum()
            ):
                best = fit.x
        if best is None:
            raise InputError(
                f"no angles about the rotation axes of {self.describe()} give this pose's rotation (to 1e-9): the "
                f"motion turns the body about an axis its joint does not have"
            )
        a = np.concatenate([np.linalg.solve(self.translation_axes.T, p), best])
        return (a - self.intercepts) / self.slopes

    def describe(self) -> str:
        names = self.names or ("ux", "uy", "uz", "rx", "ry", "rz")
        return "a CustomJoint's coordinates (" + ", ".join(names) + ")" + (", inverted" if self.inverted else "")


def rotation_vector_motion(u6, reference) -> tuple[np.ndarray, np.ndarray]:
    """``(D, B)`` of the default coordinates: the translation ``t`` of the reference ``c`` and the
    rotation vector ``theta`` (``x' = c + t + R(theta) (x - c)``), and ``diag(I, J(theta))``."""
    u6 = np.asarray(u6, dtype=float)
    B = np.eye(6)
    if not u6.any():  # the start pose (a fixed body): both are exactly the identity
        return np.eye(4), B
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
        return np.concatenate([F, M + cross(point - c, F)])
