"""Springs re-cast at another pose, with a proximity window that follows the pose.

A layer cast at one pose (:func:`~dea_opt.mesh.cast_springs`) is re-cast at another
(:func:`recast`), e.g. at the pose a solution reached (:func:`recast_at_solution`). The
overlap a ray may take moves with mesh 2: every ray may overlap ``max_overlap`` more than
mesh 2's motion along it brings, and a spring of the start pose keeps ``max_overlap`` of
slack below the gap its target's tangent plane predicts (:func:`tangent_plane_gap`). So a
spring of the start pose whose face still faces mesh 2 is never dropped because the overlap
grew; rays that went back through mesh 1's own layer are rejected; every spring lost, dropped
or rejected is counted. Lengths in mm, forces in N, moments in N mm.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import InputError
from .springs import LOST_REASONS, SpringCast, _cast, check_pose

__all__ = ["Recast", "body_pose", "recast", "recast_at_solution", "relative_pose", "tangent_plane_gap"]


def _rotation(theta) -> np.ndarray:
    """The rotation matrix of the rotation vector ``theta`` (rad), exactly (Rodrigues)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(np.asarray(theta, dtype=float)).as_matrix()


def body_pose(u6, reference) -> np.ndarray:
    """The 4x4 pose of a body displaced by ``u6 = (ux, uy, uz, rx, ry, rz)`` about ``reference``.

    The rotation vector ``(rx, ry, rz)`` is taken as an exact rotation about the reference
    point: ``x' = c + t + R(theta) (x - c)``.
    """
    u6 = np.asarray(u6, dtype=float)
    c = np.asarray(reference, dtype=float)
    R = _rotation(u6[3:6])
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = c + u6[:3] - R @ c
    return T


def relative_pose(u, reference1, reference2) -> np.ndarray:
    """Body 2's motion seen from body 1, ``T1^-1 T2``, for the 12-vector ``u`` (mm, rad)."""
    u = np.asarray(u, dtype=float)
    return np.linalg.inv(body_pose(u[:6], reference1)) @ body_pose(u[6:], reference2)


def tangent_plane_gap(layer, pose) -> np.ndarray:
    """Each spring's gap at another pose of mesh 2, on its target's tangent plane (mm).

    The spring's ray ``p + s n`` (body 1 held still) meets the plane through the target
    point ``q`` with normal ``m``, both moved by ``pose`` (mesh 2's pose in mesh 1's frame,
    as in :func:`cast_springs`): ``s = (R q + t - p) . R m / (n . R m)``. At the pose the
    layer was cast at this is ``layer.gap``; it equals a fresh cast's gap wherever the hit
    stays on the same face of mesh 2.

    Parameters
    ----------
    layer : SpringLayer
        A layer with targets (cast from meshes: ``layer.has_targets``).
    pose : array_like, shape (4, 4)
        Rigid transform of mesh 2.

    Returns
    -------
    ndarray, shape (N,)
        The gaps (mm); NaN where a ray runs parallel to its target plane.
    """
    if not getattr(layer, "has_targets", False):
        raise InputError(
            "layer has no targets (target_points, target_normals, target_faces): only springs "
            "cast from meshes have them"
        )
    T = check_pose(pose)
    if T is None:
        raise InputError("pose must be a 4x4 rigid transform, got None")
    R, shift = T[:3, :3], T[:3, 3]
    q = layer.target_points @ R.T + shift
    m = layer.target_normals @ R.T
    along = np.einsum("ij,ij->i", layer.normals, m)
    ahead = np.einsum("ij,ij->i", q - layer.points, m)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(np.abs(along) > 1e-12, ahead / along, np.nan)


@dataclass(frozen=True, eq=False)
class Recast:
    """Springs re-cast at a new pose, compared with the springs of the start pose.

    Attributes
    ----------
    cast : SpringCast
        The springs at the new pose; ``cast.dropped`` counts what its window dropped.
    start : SpringCast
        The springs of the start pose.
    lost : dict {reason: ndarray of int}
        The faces of mesh 1 that carried a spring at the start pose and carry none at the new
        pose, by reason (:data:`~dea_opt.mesh.springs.LOST_REASONS`): ``gap`` (separated
        beyond ``max_gap``) and ``no_hit`` (the ray no longer meets a face of mesh 2 that faces
        it) are motion; ``overlap``, ``through_layer``, ``angle`` and ``thickness`` as in
        :class:`~dea_opt.mesh.springs.Dropped`.
    gained : ndarray of int
        The faces of mesh 1 that carry a spring at the new pose only.
    force, moment : ndarray, shape (3,), or None
        From :func:`recast_at_solution`: the force (N) the re-cast springs exert on body 2 at
        the solved pose, and its moment (N mm) about body 2's reference point there, in the
        world frame, under the problem's law.
    solution_force, solution_moment : ndarray, shape (3,), or None
        The same of the solution's own springs (equal to the load's when certified).
    """

    cast: SpringCast
    start: SpringCast
    lost: dict
    gained: np.ndarray
    force: np.ndarray | None = None
    moment: np.ndarray | None = None
    solution_force: np.ndarray | None = None
    solution_moment: np.ndarray | None = None
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))

    @property
    def dropped(self) -> int:
        """Springs that would carry load at the new pose but lie outside the window (its
        ``overlap`` drops): the count for :func:`dea_opt.validity.assess` ``(dropped=...)``."""
        return self.cast.dropped["overlap"]

    @property
    def rejected(self) -> int:
        """Rays rejected because they went back through mesh 1's own layer."""
        return self.cast.dropped["through_layer"]

    @property
    def kept(self) -> int:
        """Springs of the start pose that carry a spring at the new pose too."""
        return len(self.start.layer) - sum(len(f) for f in self.lost.values())

    @property
    def counts(self) -> dict:
        """Every count: ``kept``, ``gained``, ``lost_<reason>``, ``dropped_<reason>``."""
        out = {"kept": self.kept, "gained": len(self.gained)}
        out.update({f"lost_{r}": len(f) for r, f in self.lost.items()})
        out.update({f"dropped_{r}": c for r, c in self.cast.dropped.counts.items()})
        return out

    @property
    def force_error(self) -> float:
        """``|force - solution_force| / |solution_force|``: how far the re-cast springs are
        from carrying the load the solution's springs carry (NaN without a solution)."""
        if self.force is None or self.solution_force is None:
            return float("nan")
        scale = float(np.linalg.norm(self.solution_force))
        return float(np.linalg.norm(self.force - self.solution_force) / scale) if scale > 0 else float("nan")

    def describe(self) -> str:
        lost = ", ".join(f"{r} {len(f)}" for r, f in self.lost.items() if len(f)) or "none"
        text = (
            f"{len(self.cast.layer)} springs at the new pose: {self.kept} of {len(self.start.layer)} "
            f"kept, {len(self.gained)} gained, lost: {lost}; dropped by the window: "
            f"{self.cast.dropped.describe()}"
        )
        if self.force is not None:
            error = self.force_error  # NaN when the solution carries no force: no relative error to give
            text += (
                f"; force {np.array2string(self.force, precision=4)} N against "
                f"{np.array2string(np.asarray(self.solution_force), precision=4)} N"
                + (f" ({error:.2%})" if np.isfinite(error) else " (-: the solution carries no force)")
            )
        return text

    def __repr__(self) -> str:
        return f"Recast({self.describe()})"


def recast(cast: SpringCast, pose) -> Recast:
    """Re-cast the springs of ``cast`` with mesh 2 at ``pose``, the window following the pose.

    Parameters
    ----------
    cast : SpringCast
        Springs cast at a start pose (:func:`~dea_opt.mesh.cast_springs`); its options
        (thickness, window, labels, engine) are used again.
    pose : array_like, shape (4, 4)
        The new pose of mesh 2 in mesh 1's frame (replacing ``cast.pose``).

    Returns
    -------
    Recast
        The new springs and what became of the old ones. Each ray may overlap
        ``max_overlap`` plus how far the motion from ``cast.pose`` to ``pose`` brings mesh 2
        toward it along the ray; a spring of the start pose may overlap ``max_overlap`` more
        than its target's tangent plane predicts. Rays that go back through mesh 1's own
        layer are rejected.
    """
    if not isinstance(cast, SpringCast):
        raise InputError(f"cast must be a SpringCast (from dea_opt.mesh.cast_springs), got {type(cast).__name__}")
    T = check_pose(pose)
    if T is None:
        raise InputError("pose must be a 4x4 rigid transform, got None")
    options, m1 = cast.options, cast.mesh1  # a trimesh.Trimesh
    m1_: Any = m1
    if not options:
        raise InputError("cast has no options to repeat: make it with dea_opt.mesh.cast_springs")
    motion = T @ np.linalg.inv(cast.pose)  # mesh 2's motion, in mesh 1's frame
    normals = -m1_.face_normals if options["flip"] else m1_.face_normals
    start_faces = np.asarray(cast.layer.source_face)
    point = np.array(m1_.triangles_center)
    point[start_faces] = cast.hit_point  # where mesh 2 was met: its motion there counts
    toward = -np.einsum("ij,ij->i", normals, point @ motion[:3, :3].T + motion[:3, 3] - point)
    allowed = options["max_overlap"] + np.maximum(toward, 0.0)
    predicted = tangent_plane_gap(cast.layer, T)
    slack = np.where(np.isfinite(predicted), options["max_overlap"] - predicted, -np.inf)
    allowed[start_faces] = np.maximum(allowed[start_faces], slack)
    new = _cast(m1, cast.mesh2, T, options, allowed)
    codes = np.asarray(new.outcome)[start_faces]
    lost = {reason: start_faces[codes == i] for i, reason in enumerate(LOST_REASONS)}
    gained = np.setdiff1d(np.asarray(new.layer.source_face), start_faces)
    return Recast(new, cast, lost, gained, pose=T)


def _check_finite_cast(solution, cast: SpringCast) -> None:
    """A finite-kinematics answer's springs were kept up to date from a cast: it must be ``cast``
    (its tracker says so; a pickled answer has none, and its springs' faces must be faces of
    ``cast``'s mesh 1 at least)."""
    tracker = getattr(solution, "tracker", None)
    faces = solution.problem.layer.source_face
    if tracker is not None:  # the cast it started from, or its last whole re-cast
        ok = tracker.origin is cast or tracker.cast is cast
    else:
        ok = faces is None or not len(faces) or int(np.max(faces)) < len(getattr(cast.mesh1, "faces", ()))
    if not ok:
        raise InputError(
            "the finite-kinematics solution's springs were not kept up to date from this cast: pass the "
            "SpringCast the problem's targets came from (ContactProblem(cast.layer, ..., targets=cast))"
        )


def recast_at_solution(solution, cast: SpringCast) -> Recast:
    """Re-cast a solution's springs at the pose it solved, and the force they carry there.

    Parameters
    ----------
    solution : Solution
        A solution whose layer is ``cast.layer`` (the springs cast from meshes), or a
        finite-kinematics solution whose targets are ``cast`` (its springs, kept up to date as
        body 2 moved, are then compared with a fresh cast at ``solution.pose``).
    cast : SpringCast
        The cast that made the solution's layer (or its targets).

    Returns
    -------
    Recast
        At the relative pose ``u`` implies (exact rotations by the rotation vectors, body 1's
        motion removed): the counts (``dropped`` for :func:`dea_opt.validity.assess`,
        ``rejected``, ``lost``, ``gained``), and ``force``/``moment``: what the re-cast springs
        carry at that pose with no further motion, in the world frame, to compare with
        ``solution_force``/``solution_moment`` (the load, when certified). The difference is
        the error of the small-kinematics model of Eq. (9)-(11).
    """
    problem = getattr(solution, "problem", None)
    if problem is None or not hasattr(solution, "u"):
        raise InputError(f"solution must be a dea_opt Solution, got {type(solution).__name__}")
    if not isinstance(cast, SpringCast):
        raise InputError(f"cast must be a SpringCast (from dea_opt.mesh.cast_springs), got {type(cast).__name__}")
    layer = problem.layer
    finite = getattr(problem, "kinematics", "small") == "finite"
    if finite:
        _check_finite_cast(solution, cast)
    elif layer is not cast.layer and not (
        len(layer) == len(cast.layer)
        and layer.source_face is not None
        and np.array_equal(layer.source_face, np.asarray(cast.layer.source_face))
        and np.array_equal(layer.gap, cast.layer.gap)
    ):
        raise InputError(
            f"the solution's layer ({len(layer)} springs) is not the layer of this cast "
            f"({len(cast.layer)} springs): pass the SpringCast its layer came from"
        )
    u = np.asarray(solution.u, dtype=float)
    if u.shape != (12,) or not np.isfinite(u).all():
        raise InputError(f"the solution's u must be 12 finite numbers, got {u!r}")
    c1, c2 = problem.body1.reference, problem.body2.reference
    T1 = body_pose(u[:6], c1)
    # Finite kinematics solved the pose itself (body 1 fixed), composed with the pose its targets
    # were cast at (a load path's frame); the springs it kept up to date are compared with a
    # fresh cast there: formulations/finite.md, "Checked against a fresh cast".
    solved = np.asarray(solution.pose, dtype=float) if finite else np.linalg.inv(T1) @ body_pose(u[6:], c2) @ cast.pose
    out = recast(cast, solved)
    new = out.cast.layer
    strain = np.minimum(new.gap / new.thickness, 0.0)
    pressure = -np.asarray(problem.law.stress(strain), dtype=float)
    spring = (pressure * new.areas)[:, None] * new.normals  # on body 2, in body 1's frame
    centre = np.linalg.inv(T1) @ np.append(np.asarray(c2) + u[6:9], 1.0)  # body 2's reference now
    R1 = T1[:3, :3]
    force = R1 @ spring.sum(axis=0)
    moment = R1 @ np.cross(new.points - centre[:3], spring).sum(axis=0)
    return Recast(
        out.cast,
        cast,
        out.lost,
        out.gained,
        force,
        moment,
        np.asarray(solution.contact_force, dtype=float),
        np.asarray(solution.contact_moment, dtype=float),
        out.pose,
    )
