"""Linear springs between two points and bushings between two body frames: two-sided elements.

Written math: ``formulations/joint.md`` ("Springs and bushings"). A :class:`Spring` pulls and
pushes along the straight line between a point on each of two bodies, ``f = k (L - L_r)``. A
:class:`Bushing` holds a frame fixed to each body, coincident at the start pose, with a linear
stiffness per axis of the first body's copy: ``F_i = k_i d_i`` on the translation ``d`` of the
second copy's origin and ``M_i = c_i theta_i`` on the rotation vector ``theta`` of its rotation
(both in the first copy's axes). Both are linear and two-sided: elements of the joint's energy
``k (L - L_r)^2 / 2`` and ``sum k_i d_i^2 / 2 + c_i theta_i^2 / 2``, rows of strain ``L - L_r``
(mm) and ``(d, theta)`` (mm, rad) of unit divisor. Small kinematics linearise both; finite
kinematics take the exact length and relative pose (:func:`spring_rows`, :func:`bushing_rows`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._checks.inputs import check_range, number_in_range, vector3
from ..errors import InputError
from .rows import line_operator

__all__ = ["Bushing", "ElasticGroup", "Spring", "bushing_rows", "elastic_groups", "spring_rows"]


def _name(field: str, value) -> str:
    if not isinstance(value, str) or not value:
        raise InputError(f"{field} must be the name of a body of the joint (a non-empty str), got {value!r}")
    return value


def _bodies(kind: str, body1, body2) -> None:
    _name(f"{kind}.body1", body1)
    _name(f"{kind}.body2", body2)
    if body1 == body2:
        raise InputError(f"a {kind} couples two different bodies, got body1 = body2 = {body1!r}")


@dataclass(frozen=True, eq=False)
class Spring:
    """A linear spring between a point on each of two bodies: it pulls and pushes, ``f = k (L - L_r)``.

    Parameters
    ----------
    body1, body2 : str
    point1, point2 : array_like, shape (3,)
        The ends in mm, global frame at the start pose (two different points).
    stiffness : float
        ``k`` in N/mm.
    rest_length : float, optional
        ``L_r`` in mm (default: the length at the start pose, where it then carries nothing).
    name : str, optional
    """

    body1: str = ""
    point1: tuple = (0.0, 0.0, 0.0)
    body2: str = ""
    point2: tuple = (0.0, 0.0, 0.0)
    stiffness: float = 0.0
    rest_length: float | None = None
    name: str | None = None

    def __post_init__(self):
        set_ = object.__setattr__
        _bodies("Spring", self.body1, self.body2)
        set_(self, "point1", vector3("Spring.point1", self.point1, "mm"))
        set_(self, "point2", vector3("Spring.point2", self.point2, "mm"))
        if self.start_length <= 0.0:
            raise InputError(
                f"a Spring's ends must be two different points, got point1 = point2 = {self.point1} mm (a spring "
                f"of no length has no direction: use a Bushing)"
            )
        set_(self, "stiffness", number_in_range("Spring.stiffness", self.stiffness, 0.0, low_open=True))
        check_range("Spring.stiffness", self.stiffness, "N/mm", positive=True)
        rest = self.start_length if self.rest_length is None else self.rest_length
        set_(self, "rest_length", number_in_range("Spring.rest_length", rest, 0.0))
        if self.name is not None and (not isinstance(self.name, str) or not self.name):
            raise InputError(f"Spring.name must be a non-empty str, got {self.name!r}")

    @property
    def start_length(self) -> float:
        return math.dist(self.point1, self.point2)


@dataclass(frozen=True, eq=False)
class Bushing:
    """A linear bushing between two bodies: a frame fixed to each, coincident at the start pose.

    Parameters
    ----------
    body1, body2 : str
    frame : array_like, shape (4, 4)
        The bushing's frame (origin and axes) in the global frame at the start pose, mm (default:
        the global frame).
    translational_stiffness : array_like, shape (3,)
        N/mm along each axis of body 1's copy of the frame (>= 0).
    rotational_stiffness : array_like, shape (3,)
        N mm/rad about each axis (>= 0), on the rotation vector of the relative rotation
        (OpenSim's ``BushingForce`` takes body-fixed x-y-z angles: the same to first order).
    name : str, optional
    """

    body1: str = ""
    body2: str = ""
    frame: tuple = ()
    translational_stiffness: tuple = (0.0, 0.0, 0.0)
    rotational_stiffness: tuple = (0.0, 0.0, 0.0)
    name: str | None = None

    def __post_init__(self):
        set_ = object.__setattr__
        _bodies("Bushing", self.body1, self.body2)
        frame = np.eye(4) if (self.frame is None or len(self.frame) == 0) else self.frame
        try:
            F = np.array(frame, dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"Bushing.frame must be a 4x4 rigid transform, got {self.frame!r}") from None
        R = F[:3, :3] if F.shape == (4, 4) else np.zeros((3, 3))
        rigid = (
            F.shape == (4, 4)
            and np.isfinite(F).all()
            and np.abs(R.T @ R - np.eye(3)).max() < 1e-9
            and np.linalg.det(R) > 0
            and np.abs(F[3] - (0, 0, 0, 1)).max() == 0
        )
        if not rigid:
            raise InputError(
                f"Bushing.frame must be a 4x4 rigid transform (rotation, translation in mm), got {frame!r}"
            )
        F.setflags(write=False)
        set_(self, "frame", F)
        for field, unit in (("translational_stiffness", "N/mm"), ("rotational_stiffness", "N mm/rad")):
            k = np.array(vector3(f"Bushing.{field}", getattr(self, field), unit))
            if (k < 0).any():
                raise InputError(f"Bushing.{field} must be >= 0 on each axis ({unit}), got {k.tolist()}")
            set_(self, field, tuple(float(v) for v in k))
        if not any(self.translational_stiffness) and not any(self.rotational_stiffness):
            raise InputError("a Bushing needs a stiffness on at least one axis, got all zero")
        if self.name is not None and (not isinstance(self.name, str) or not self.name):
            raise InputError(f"Bushing.name must be a non-empty str, got {self.name!r}")

    @property
    def stiffness(self) -> np.ndarray:
        """``(k_x, k_y, k_z, c_x, c_y, c_z)`` (N/mm, N mm/rad)."""
        return np.array(self.translational_stiffness + self.rotational_stiffness)


@dataclass(frozen=True, eq=False)
class ElasticGroup:
    """The springs (``kind="spring"``) or bushings (``"bushing"``) between two bodies: their rows.

    ``members`` index ``Joint.springs`` or ``Joint.bushings``; a spring has one row, a bushing one
    per axis of nonzero stiffness (translations ``x, y, z``, then rotations: ``axis`` 0 to 5), row
    ``i`` belonging to ``members[owner[i]]``. ``G`` (N, 12) are the rows over the two bodies'
    6-vectors (or coordinate rates at a pose), ``e0`` (N,) the strains (mm, rad) where ``G``'s motion
    is zero, ``k`` (N,) the stiffness of each row (N/mm, N mm/rad).
    """

    kind: str
    body1: str
    body2: str
    members: tuple
    G: np.ndarray
    e0: np.ndarray
    k: np.ndarray
    owner: np.ndarray
    axis: np.ndarray

    @property
    def name(self) -> str:
        return f"{self.kind}s {self.body1}-{self.body2}"


def spring_rows(springs, p1, p2, c1, c2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(G, e0, k)`` of ``springs`` with ends ``p1``, ``p2`` (n, 3) about references ``c1``, ``c2``."""
    G = line_operator(p1, p2, c1, c2)
    e0 = np.linalg.norm(p2 - p1, axis=1) - np.array([s.rest_length for s in springs])
    return G, e0, np.array([s.stiffness for s in springs])


def bushing_rows(bushings, frames1, frames2, c1, c2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(G, e0, k)`` of ``bushings`` whose copies of their frame on body 1 and body 2 are ``frames1``,
    ``frames2`` (n, 4, 4) about the references ``c1``, ``c2``: 6 rows each, the translation of copy
    2's origin and the rotation vector of copy 1's rotation to copy 2's, in copy 1's axes; their
    rates those of the bodies' velocities and angular velocities (``formulations/joint.md``)."""
    from scipy.spatial.transform import Rotation

    from ..formulations.finite.rotations import left_jacobian

    n = len(bushings)
    G, e0 = np.zeros((6 * n, 12)), np.zeros(6 * n)
    c1, c2 = np.asarray(c1, dtype=float), np.asarray(c2, dtype=float)
    for b, (F1, F2) in enumerate(zip(frames1, frames2)):
        R1, o2 = F1[:3, :3], F2[:3, 3]
        relative = np.linalg.inv(F1) @ F2
        theta = Rotation.from_matrix(relative[:3, :3]).as_rotvec()
        e0[6 * b : 6 * b + 3] = relative[:3, 3]
        e0[6 * b + 3 : 6 * b + 6] = theta
        turn = R1 @ np.linalg.inv(left_jacobian(theta)).T  # column i: the rate of theta_i per unit w2 - w1
        for i in range(3):
            a = R1[:, i]
            row = G[6 * b + i]
            row[0:3], row[3:6] = -a, -np.cross(o2 - c1, a)
            row[6:9], row[9:12] = a, np.cross(o2 - c2, a)
            G[6 * b + 3 + i, 3:6], G[6 * b + 3 + i, 9:12] = -turn[:, i], turn[:, i]
    k = np.concatenate([b.stiffness for b in bushings]) if n else np.zeros(0)
    return G, e0, k


def elastic_groups(joint, motions=None, references=None) -> tuple:
    """The joint's :class:`ElasticGroup` s (springs, then bushings, each by body pair, in order of
    first appearance). ``motions`` ``{body: 4x4}`` and ``references`` ``{body: (3,)}`` put them at
    a pose (default: the start pose, the references where the bodies give them)."""
    out = []
    for kind, items in (("spring", joint.springs), ("bushing", joint.bushings)):
        pairs: dict = {}
        for i, item in enumerate(items):
            pairs.setdefault((item.body1, item.body2), []).append(i)
        for (b1, b2), members in pairs.items():
            chosen = [items[i] for i in members]
            D1 = np.eye(4) if motions is None else motions[b1]
            D2 = np.eye(4) if motions is None else motions[b2]
            c1 = joint.bodies[b1].reference if references is None else references[b1]
            c2 = joint.bodies[b2].reference if references is None else references[b2]
            if kind == "spring":
                p1 = np.array([s.point1 for s in chosen]) @ D1[:3, :3].T + D1[:3, 3]
                p2 = np.array([s.point2 for s in chosen]) @ D2[:3, :3].T + D2[:3, 3]
                G, e0, k = spring_rows(chosen, p1, p2, c1, c2)
                owner, axis = np.arange(len(chosen)), np.zeros(len(chosen), dtype=int)
            else:
                G, e0, k = bushing_rows(chosen, [D1 @ b.frame for b in chosen], [D2 @ b.frame for b in chosen], c1, c2)
                owner, axis = np.repeat(np.arange(len(chosen)), 6), np.tile(np.arange(6), len(chosen))
                keep = k > 0  # an axis of no stiffness is no element
                G, e0, k, owner, axis = G[keep], e0[keep], k[keep], owner[keep], axis[keep]
            out.append(ElasticGroup(kind, b1, b2, tuple(members), G, e0, k, owner, axis))
    return tuple(out)


def elastic_element_group(group: ElasticGroup, cols, dofs, rates=None):
    """The :class:`~dea_opt.formulations.joint.ElementGroup` (two-sided, unit divisor) of ``group``
    over the free columns ``cols`` of its 12 (positions ``dofs`` in the joint's free vector);
    ``rates`` (12, 12) the bodies' velocities per unit coordinate rate at a pose."""
    from ..formulations.joint import ElementGroup

    G = group.G if rates is None else group.G @ rates
    AT = np.ascontiguousarray(G[:, cols].T)
    factor = np.sqrt(group.k)[:, None] * AT.T
    return ElementGroup(
        name=group.name,
        kind="bilateral",
        law=None,
        dofs=dofs,
        AT=AT,
        e0=group.e0.copy(),
        volume=group.k.astype(float),
        force_scale=group.k.astype(float),
        modulus=1.0,
        factor=factor,
        stiffness=_stiffness(group),
    )


def _stiffness(group: ElasticGroup) -> float:
    """The group's stiffness scale (N/mm): its springs' and translational stiffnesses (a rotational
    stiffness acts on rotations, which the joint's scale measures in arc lengths: left out)."""
    return float(group.k[group.axis < 3].sum())


def elastic_results(joint, groups, forces) -> list[dict]:
    """One row per spring and bushing (springs first), with units in the keys: a spring's
    ``force_N`` (tension positive), ``length_mm`` and ``extension_mm``; a bushing's force along
    and moment about each axis of body 1's copy of its frame (``k d`` and ``c theta``: N, N mm;
    what it applies to body 1, and minus it to body 2) and its deflections (mm, rad; zero on an
    axis of no stiffness, which it does not measure)."""
    rows: dict = {}
    for group, f in zip(groups, forces):
        f = np.asarray(f, dtype=float)
        for j, i in enumerate(group.members):
            mine = np.flatnonzero(group.owner == j)
            if group.kind == "spring":
                s = joint.springs[i]
                rows[("spring", i)] = {
                    "name": s.name or f"spring {i}",
                    "kind": "spring",
                    "body1": s.body1,
                    "body2": s.body2,
                    "force_N": float(f[mine[0]]),
                    "extension_mm": float(group.e0[mine[0]]),
                    "length_mm": float(group.e0[mine[0]] + s.rest_length),
                }
                continue
            b = joint.bushings[i]
            row: dict = {"name": b.name or f"bushing {i}", "kind": "bushing", "body1": b.body1, "body2": b.body2}
            values, deflections = np.zeros(6), np.zeros(6)
            values[group.axis[mine]], deflections[group.axis[mine]] = f[mine], group.e0[mine]
            for a in range(3):
                row[f"force_{'xyz'[a]}_N"], row[f"deflection_{'xyz'[a]}_mm"] = values[a], deflections[a]
            for a in range(3):
                row[f"moment_{'xyz'[a]}_Nmm"], row[f"rotation_{'xyz'[a]}_rad"] = values[3 + a], deflections[3 + a]
            rows[("bushing", i)] = {k: float(v) if isinstance(v, np.floating) else v for k, v in row.items()}
    order = [("spring", i) for i in range(len(joint.springs))] + [("bushing", i) for i in range(len(joint.bushings))]
    return [rows[key] for key in order if key in rows]
