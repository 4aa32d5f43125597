"""Finite kinematics, geometry: each spring's target and its gap at body 2's pose.

Written math: ``formulations/finite.md`` ("Targets", "Gap and its derivative"); mm, rad. Body 2
moves by ``x' = c + t + R(theta) (x - c)`` (:mod:`~dea_opt.formulations.finite.rotations`: ``t``
(3,) the translation of its reference ``c`` (3,), ``R`` (3, 3) the exact rotation of the
rotation vector ``theta`` (3,)). Each spring
``i`` (a point ``p_i`` and unit normal ``n_i`` of body 1, which stays fixed) looks along its ray
``p_i + s n_i`` at its target on body 2 (:class:`Targets`, in body 2's own frame): the tangent
plane of a face (a point ``q_i``, the outward normal ``m_i``) or a sphere (centre ``o_i``, radius
``rho_i``). The gap ``s_i`` is where the ray meets the moved target (:func:`evaluate`; ``inf``
where it misses); along a motion of body 2 (translation rate ``v`` of the reference, angular
velocity ``w``) ``ds_i = m_i' . (v + w x (h_i - c')) / (n_i . m_i')``, ``h_i = p_i + s_i n_i``
the hit and ``m_i'`` the target's normal there (:meth:`Gaps.rows`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from ..._checks.dependencies import compiled
from ...errors import InputError

__all__ = [
    "Gaps",
    "PlaneRows",
    "Targets",
    "compiled_system",
    "evaluate",
    "plane_gaps",
]

#: ``|n . m'|`` below which a ray runs along its target (no gap): the target turned away.
FACING = 1e-9
#: Gap (mm) of a spring whose ray misses its target: open, it carries nothing.
MISSED = np.inf


@dataclass(frozen=True, eq=False)
class Targets:
    """Each spring's target on body 2, in body 2's own frame, and where that frame sits.

    A target is the tangent plane of a face (``radius == 0``: a point ``points[i]`` on it and its
    unit outward normal ``normals[i]``, the side body 1 faces) or a sphere (``radius > 0``:
    centre ``points[i]``; ``concave[i]`` when the spring sits inside it, as in a socket, else
    outside a ball). ``frame`` (4x4) places body 2's own frame at zero displacement: mesh 2's
    pose of the cast (identity for targets given in the world frame). ``faces`` are the faces of
    mesh 2 the planes belong to (None for targets not cast from a mesh).

    Build them with :meth:`planes`, :meth:`spheres`, :meth:`facing` or :meth:`from_layer`.
    """

    points: np.ndarray
    normals: np.ndarray
    radius: np.ndarray
    concave: np.ndarray
    frame: np.ndarray
    faces: np.ndarray | None = None

    def __post_init__(self):
        n = len(self.points)
        for name, arr, shape in (
            ("points", self.points, (n, 3)),
            ("normals", self.normals, (n, 3)),
            ("radius", self.radius, (n,)),
            ("concave", self.concave, (n,)),
            ("frame", self.frame, (4, 4)),
        ):
            if np.shape(arr) != shape:
                raise InputError(f"targets.{name} must have shape {shape}, got {np.shape(arr)}")
        if not (np.isfinite(self.points).all() and np.isfinite(self.normals).all() and np.isfinite(self.radius).all()):
            raise InputError("targets must be finite (points, normals, radius)")
        if (self.radius < 0).any():
            raise InputError(f"targets.radius must be >= 0 (0 for a plane), got {self.radius.min():g}")
        plane = self.radius == 0
        length = np.linalg.norm(self.normals[plane], axis=1)
        if plane.any() and np.abs(length - 1).max() > 1e-6:
            raise InputError("targets.normals of planes must be unit vectors")

    def __len__(self) -> int:
        return len(self.points)

    @property
    def is_plane(self) -> np.ndarray:
        """(N,) bool: the targets that are planes (``radius == 0``), not spheres."""
        return self.radius == 0

    def subset(self, index) -> Targets:
        """The targets of the springs ``index`` (an index array or a mask), in the same frame."""
        faces = None if self.faces is None else self.faces[index]
        return Targets(
            self.points[index], self.normals[index], self.radius[index], self.concave[index], self.frame, faces
        )

    def with_frame(self, frame) -> Targets:
        """The same targets with body 2's own frame placed by ``frame`` (4x4) at zero displacement."""
        frame = np.asarray(frame, dtype=float)
        if frame.shape != (4, 4):
            raise InputError(f"targets.frame must have shape (4, 4), got {frame.shape}")
        targets = object.__new__(Targets)  # the rest was checked when these targets were made
        for name in ("points", "normals", "radius", "concave", "faces"):
            object.__setattr__(targets, name, getattr(self, name))
        object.__setattr__(targets, "frame", frame)
        return targets

    @classmethod
    def cast_planes(cls, points, normals, frame, faces) -> Targets:
        """The tangent planes of faces of mesh 2 met by a cast: ``points`` (N, 3) on them, their unit
        ``normals`` (N, 3) in mesh 2's own frame, placed by ``frame`` (4x4). Not checked again: a
        cast measured them (a solve re-casts springs many times)."""
        n = len(points)
        targets = object.__new__(cls)
        for name, value in (
            ("points", points),
            ("normals", normals),
            ("radius", np.zeros(n)),
            ("concave", np.zeros(n, bool)),
            ("frame", frame),
            ("faces", faces),
        ):
            object.__setattr__(targets, name, value)
        return targets

    # --- constructors -------------------------------------------------------------------
    @classmethod
    def planes(cls, points, normals) -> Targets:
        """Planes through ``points`` (N, 3) with unit outward ``normals`` (N, 3), in the world frame
        at zero displacement (mm)."""
        points = _array("points", points, 2)
        normals = _array("normals", normals, 2)
        if normals.shape != points.shape:
            raise InputError(f"normals must have the shape of points {points.shape}, got {normals.shape}")
        length = np.linalg.norm(normals, axis=1)
        if len(length) and not (length > 0).all():
            raise InputError("normals must be nonzero vectors")
        n = len(points)
        return cls(points, normals / length[:, None], np.zeros(n), np.zeros(n, bool), np.eye(4))

    @classmethod
    def spheres(cls, centres, radius, concave=False, n=None) -> Targets:
        """Spheres of centre ``centres`` ((N, 3) or (3,)) and ``radius`` (> 0, mm; (N,) or a
        number): ``concave`` when the springs sit inside them (a socket), else outside (a ball).
        ``n`` broadcasts one sphere to ``n`` springs."""
        centres = np.atleast_2d(_array("centres", centres, None))
        if n is None:
            n = len(centres)
        elif isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
            raise InputError(f"n must be a whole number of springs >= 0, got {n!r}")
        n = int(n)
        if len(centres) not in (1, n):
            raise InputError(f"centres must be one centre (3,) or one per spring ({n}, 3), got shape {centres.shape}")
        centres = np.broadcast_to(centres, (n, 3)).copy()
        radius = _per_spring("radius", radius, float, n)
        if not (np.isfinite(radius).all() and (radius > 0).all()):
            raise InputError(f"radius must be finite and > 0 (mm), got {radius.min() if n else radius}")
        concave = _per_spring("concave", concave, bool, n)
        return cls(centres, np.zeros((n, 3)), radius, concave, np.eye(4))

    @classmethod
    def facing(cls, layer) -> Targets:
        """Each spring's own plane: through ``p + gap n`` with normal ``-n`` (a flat target normal
        to the spring, as for a rigid flat punch on a bed). The default without targets."""
        if not all(hasattr(layer, name) for name in ("points", "normals", "gap")):
            raise InputError(f"layer must be a SpringLayer, got {type(layer).__name__}")
        return cls.planes(layer.points + layer.gap[:, None] * layer.normals, -layer.normals)

    @classmethod
    def from_layer(cls, layer, pose=None) -> Targets:
        """The tangent planes of the faces of mesh 2 a cast layer's springs met.

        ``pose`` is mesh 2's pose of the cast (``cast.pose``); without it, it is recovered from the
        layer (the rigid map from ``target_points`` to the hits ``points + gap normals``) and
        checked to 1e-6 mm.
        """
        if not getattr(layer, "has_targets", False):
            raise InputError(
                "the layer has no targets (target_points, target_normals, target_faces): give "
                "Targets.planes(...) or Targets.spheres(...), or cast the springs from meshes"
            )
        hits = layer.points + layer.gap[:, None] * layer.normals
        frame = _recover_frame(layer.target_points, hits) if pose is None else np.asarray(pose, dtype=float)
        n = len(layer)
        return cls(
            np.array(layer.target_points),
            np.array(layer.target_normals),
            np.zeros(n),
            np.zeros(n, bool),
            frame,
            np.array(layer.target_faces),
        )


def _per_spring(name, value, dtype, n) -> np.ndarray:
    """``value`` (a number or one per spring) as ``n`` values of ``dtype``."""
    try:
        arr = np.asarray(value, dtype=dtype)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number or one per spring ({n}), got {type(value).__name__}") from None
    if arr.ndim > 1 or (arr.ndim == 1 and len(arr) != n):
        raise InputError(f"{name} must be a number or one per spring ({n},), got shape {arr.shape}")
    return np.broadcast_to(arr, (n,)).copy()


def _array(name, value, ndim) -> np.ndarray:
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be numeric, got {type(value).__name__}") from None
    if (ndim == 2 and (arr.ndim != 2 or arr.shape[1] != 3)) or arr.shape[-1:] != (3,):
        raise InputError(f"{name} must have shape (N, 3), got {arr.shape}")
    if not np.isfinite(arr).all():
        raise InputError(f"{name} must be finite")
    return arr


def _recover_frame(own, world) -> np.ndarray:
    """The rigid 4x4 map of points ``own`` (N, 3) onto ``world`` (Kabsch), the identity when it fits."""
    scale = max(float(np.abs(world).max(initial=0.0)), 1.0)
    if not len(own) or np.abs(own - world).max() <= 1e-9 * scale:
        return np.eye(4)
    a, b = own.mean(axis=0), world.mean(axis=0)
    U, _, Vt = np.linalg.svd((own - a).T @ (world - b))
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, b - R @ a
    error = float(np.abs(own @ R.T + T[:3, 3] - world).max())
    if error > 1e-6 * scale:
        raise InputError(
            f"the layer's targets are not one rigid motion away from its hits (off by {error:.3g} mm): "
            f"pass the cast's pose, Targets.from_layer(layer, pose=cast.pose)"
        )
    return T


class Gaps:
    """The springs' gaps at one pose.

    Attributes
    ----------
    s : ndarray (N,)
        Gap along each spring's ray (mm); ``inf`` where it misses its target (open).
    hit : ndarray (N, 3)
        ``p + s n`` (world frame, mm); NaN where missed. Computed when first read (a line
        search reads only the gaps).
    m : ndarray (N, 3)
        The target's unit outward normal at the hit (world frame); ``mT`` is the same as rows (3, N).
    along : ndarray (N,)
        ``n . m`` (< 0 where the target faces the spring).
    valid : ndarray of bool (N,)
        The springs whose ray meets its target (``s`` finite).
    """

    def __init__(self, s, mT, along, points, normals):
        self.s, self.mT, self.along = s, mT, along
        self.valid = np.isfinite(s)
        self._points, self._normals = points, normals

    @property
    def m(self) -> np.ndarray:
        return self.mT.T

    @cached_property
    def hit(self) -> np.ndarray:
        return self._points + np.where(self.valid, self.s, np.nan)[:, None] * self._normals

    def rows(self, centre) -> np.ndarray:
        """``b_i = [m; (h - c') x m] / (n . m)`` (6, N): ``ds_i`` per unit translation of body 2's
        reference and per unit angular velocity; zero where missed."""
        out = np.zeros((6, len(self.s)))
        v = self.valid
        scale = 1.0 / self.along[v]
        out[:3, v] = (self.m[v] * scale[:, None]).T
        out[3:, v] = (np.cross(self.hit[v] - centre, self.m[v]) * scale[:, None]).T
        return out


class PlaneRows:
    """Plane targets and their springs as rows (3, N), for the passes of :func:`plane_gaps`.

    Every pass over the springs reads one contiguous row per component: on (N, 3) arrays the
    same dot products take several times longer (strided reads, and a temporary per product).
    ``qm`` is ``q_i . m_i``, which no rotation changes.
    """

    def __init__(self, targets: Targets, points, normals, pT=None, nT=None):
        self.pT = np.ascontiguousarray(np.asarray(points, dtype=float).T) if pT is None else pT
        self.nT = np.ascontiguousarray(np.asarray(normals, dtype=float).T) if nT is None else nT
        self.mT = np.ascontiguousarray(targets.normals.T)
        qT = np.ascontiguousarray(targets.points.T)
        self.qm = np.einsum("ij,ij->j", qT, self.mT)
        self.points, self.normals = points, normals

    @classmethod
    def of_rows(cls, points, normals, pT, nT, mT, qm) -> PlaneRows:
        """Rows already at hand (each row contiguous; ``qm`` as in the class docstring)."""
        rows = object.__new__(cls)
        rows.pT, rows.nT, rows.mT, rows.qm = pT, nT, mT, qm
        rows.points, rows.normals = points, normals
        return rows


def compiled_system() -> Any:
    """The compiled passes over a system's springs (``_finite.c``, built at install where a C
    compiler is at hand: :func:`plane_gaps` and the tangent's sum), or None where it was not built."""
    return compiled(f"{__package__}._finite")


def _as_rows(a) -> np.ndarray:
    """``a`` (float64, each row contiguous: what the compiled passes read) as it is where it already
    is so (a view of the first columns of a longer buffer too), else a contiguous copy."""
    a = np.asarray(a)
    if a.dtype == np.float64 and a.ndim in (1, 2) and a.strides[-1] == 8:
        if a.ndim == 1 or (a.strides[0] % 8 == 0 and a.strides[0] >= 8 * a.shape[1]):
            return a
    return np.ascontiguousarray(a, dtype=float)


def plane_gaps(rows: PlaneRows, transform, compiled: bool | None = None) -> Gaps:
    """:func:`evaluate` for targets that are all planes, on their :class:`PlaneRows`.

    ``s_i = (R q_i + t - p_i) . R m_i / (n_i . R m_i) = (q_i . m_i + t . m_i' - p_i . m_i') / (n_i . m_i')``,
    in one compiled pass (:func:`compiled_system`) unless ``compiled`` is False or it was not
    built, else in numpy: the same numbers, operation for operation.
    """
    kernel = compiled_system() if compiled is None or compiled else None
    if kernel is not None:
        k = len(rows.qm)
        mT, along, s = np.empty((3, k)), np.empty(k), np.empty(k)
        T = np.ascontiguousarray(transform, dtype=float)
        pT, nT, mT_own, qm = (_as_rows(a) for a in (rows.pT, rows.nT, rows.mT, rows.qm))
        kernel.plane_gaps(k, FACING, MISSED, T, pT, nT, mT_own, qm, mT, along, s)
        return Gaps(s, mT, along, rows.points, rows.normals)
    R, shift = transform[:3, :3], transform[:3, 3]
    mT = R @ rows.mT
    along = np.einsum("ij,ij->j", rows.nT, mT)
    ahead = rows.qm + shift @ mT
    ahead -= np.einsum("ij,ij->j", rows.pT, mT)
    s = np.full(len(along), MISSED)
    np.divide(ahead, along, out=s, where=along < -FACING)
    return Gaps(s, mT, along, rows.points, rows.normals)


def evaluate(targets: Targets, points, normals, transform) -> Gaps:
    """The :class:`Gaps` of springs ``(points, normals)`` ((N, 3), world frame: mm, unit) to their
    ``targets`` moved by ``transform`` (4x4: body 2's own frame to the world, i.e. the displacement
    composed with ``targets.frame``)."""
    plane = targets.is_plane
    if plane.all():
        return plane_gaps(PlaneRows(targets, points, normals), transform)
    R, shift = transform[:3, :3], transform[:3, 3]
    n_springs = len(points)
    s = np.full(n_springs, MISSED)
    m = np.zeros((n_springs, 3))
    along = np.zeros(n_springs)
    for rows in (np.flatnonzero(plane), np.flatnonzero(~plane)):
        if not len(rows):
            continue
        if plane[rows[0]]:
            _plane(
                targets.points[rows], targets.normals[rows], points[rows], normals[rows], R, shift, s, m, along, rows
            )
        else:
            _sphere(
                targets.points[rows] @ R.T + shift,
                targets.radius[rows],
                targets.concave[rows],
                points[rows],
                normals[rows],
                s,
                m,
                along,
                rows,
            )
    return Gaps(s, np.ascontiguousarray(m.T), along, points, normals)


def _plane(q, mq, p, n, R, shift, s, m, along, rows) -> None:
    mm = mq @ R.T
    a = np.einsum("ij,ij->i", n, mm)
    b = np.einsum("ij,ij->i", q @ R.T + shift - p, mm)
    facing = a < -FACING
    with np.errstate(divide="ignore", invalid="ignore"):
        s[rows] = np.where(facing, b / np.where(facing, a, -1.0), MISSED)
    m[rows], along[rows] = mm, a


def _sphere(o, rho, concave, p, n, s, m, along, rows) -> None:
    d = p - o
    beta = np.einsum("ij,ij->i", n, d)
    gamma = np.einsum("ij,ij->i", d, d) - rho**2
    disc = beta**2 - gamma
    root = np.sqrt(np.maximum(disc, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        # The root that cancels least: s1 s2 = gamma (the product of the roots).
        near = np.where(beta <= 0, gamma / (root - beta), -beta - root)  # entering a ball
        far = np.where(beta >= 0, -gamma / (beta + root), root - beta)  # leaving from inside a socket
    gap = np.where(concave, far, near)
    # A ball wholly behind a spring outside it (both roots negative) is no target.
    behind = ~concave & (gamma > 0) & (beta > 0)
    hit = p + gap[:, None] * n
    sign = np.where(concave, -1.0, 1.0)
    normal = sign[:, None] * (hit - o) / rho[:, None]
    a = -root / rho
    ok = (disc >= 0) & ~behind & (root > FACING * rho)
    s[rows] = np.where(ok, gap, MISSED)
    m[rows], along[rows] = np.where(ok[:, None], normal, 0.0), np.where(ok, a, 0.0)
