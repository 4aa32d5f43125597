"""Finite kinematics, the answer: the solution at the solved pose and its certificate there.

Written math: ``formulations/finite.md`` ("Certificate in the deformed configuration"). The
certificate is the one of :func:`dea_opt.certificate.certify`, with every quantity taken at the
solved pose: the forces the springs exert along their directions ``n_i`` about body 2's current
reference point ``c' = c + t``, mapped to the free coordinates by ``blockdiag(I, J(theta))``,
against the load mapped the same way; the strains are the gaps at that pose over the thickness.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np

from ..certificate import certify
from ..formulations._parts.system import ROUNDING, SpringSystem
from ..formulations.finite import Targets, generalized, left_jacobian, pose_matrix
from ..kinematics import DOF_NAMES
from ..mesh.walk import dot
from ..solution import Solution

#: The checks of the answer's own values, whose advice is void where it is no equilibrium.
_OF_THE_ANSWER = ("strain", "rotation", "gap_error", "peak_pressure", "dropped_springs", "lost_through_layer")


def plane_error(cast, layer, eps, pose) -> tuple[float, float]:
    """``(relative, mm)``: how far the tangent planes of ``cast`` (springs not re-cast as body 2
    moved) misplace the springs' compression at ``pose`` (mesh 2's, 4x4), against mesh 2 there.

    Each spring's ray is cast afresh at ``pose`` by the cast's rules (:func:`~dea_opt.mesh.cast_faces`,
    followed from the face its plane came from); the error is ``|min(g, 0) - min(s, 0)|`` with ``s``
    the plane's gap and ``g`` the mesh's (``+inf``, open, where the ray meets no face: a plane that
    carries load there carries it off the mesh), the largest of all springs in mm, and as a strain
    (each gap over its own thickness, the mesh's measured afresh): the finite kinematics'
    ``gap_error`` (``formulations/validity.md``, section 2).
    """
    from ..mesh import Mesh1, Mesh2, cast_faces

    s = np.where(np.isfinite(eps), eps, 0.0) * layer.thickness
    if not len(s):
        return 0.0, 0.0
    allowed = cast.options["max_overlap"] + np.maximum(-s, 0.0)  # the window reaches the planes' overlap
    fresh = cast_faces(cast, pose, layer.source_face, allowed, Mesh1.of(cast), Mesh2.of(cast), met=layer.target_faces)
    gap = np.where(fresh.spring, fresh.gap, np.inf)
    with np.errstate(invalid="ignore"):
        strain = np.where(fresh.spring, gap / (fresh.h1 + fresh.h2), np.inf)
    mm = np.abs(np.minimum(gap, 0.0) - np.minimum(s, 0.0))
    relative = np.abs(np.minimum(strain, 0.0) - np.minimum(s / layer.thickness, 0.0))
    return float(np.max(relative)), float(np.max(mm))


class _Deformed:
    """What :func:`~dea_opt.certificate.certify` reads of a problem, at the solved pose."""

    def __init__(self, layer, law, system: SpringSystem, free_indices, eps, rounding):
        self.layer, self.law, self._system, self.free_indices = layer, law, system, free_indices
        self._eps, self._rounding = eps, rounding

    def system(self) -> SpringSystem:
        return self._system

    def strain(self, u) -> np.ndarray:
        return self._eps

    def strain_rounding(self, u) -> np.ndarray:
        return self._rounding


def strain_rounding(state) -> np.ndarray:
    """A bound on the rounding of the springs' strains at ``state``'s pose, shape (N,): ``ROUNDING``
    ulps of the sizes the gaps are computed from (the springs' points, their targets' points and
    radii, the pose's translation), over ``|dot(n_i, m_i)|`` (the ray's incidence on its target) and the
    thickness; 0 where the ray misses its target (open, no force). Far from the origin, or where
    a deep start and the motion cancel to a small gap, the strain keeps only the digits these leave
    (``formulations/energy.md``, "The certificate")."""
    system, gaps = state.system, state.gaps
    targets = system.targets
    shift = float(np.linalg.norm(system.transform(state.y)[:3, 3]))
    # (row norms as a product: np.linalg.norm(axis=1) takes ten times as long on (N, 3))
    size = np.sqrt(dot(system.points, system.points)) + np.sqrt(dot(targets.points, targets.points))
    size += targets.radius + shift
    along = np.abs(gaps.along)
    valid = gaps.valid & (along > 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = ROUNDING * np.finfo(float).eps * size / (along * system.thickness)
    return np.where(valid, bound, 0.0)


def certificate(state, law, layer, lengths, stiffness, u, reported_stress, tolerance):
    """The :class:`~dea_opt.certificate.Certificate` of a finite-kinematics answer at its solved pose.

    Everything it measures is at that pose: the springs' forces there, the load mapped there, the
    strains' rounding there (:func:`strain_rounding`); nothing of the start.

    Parameters
    ----------
    state : State
        The springs at the solved pose.
    layer : SpringLayer
        The springs (for their areas).
    lengths : ndarray (m,)
        The free coordinates' lengths (1 mm; the layer's radius for a rotation).
    stiffness : float
        ``sum_i S_i / h_i`` (mm).
    u : ndarray (12,)
    reported_stress : ndarray (N,)
        The formulation's spring stress (MPa).
    """
    system = state.system
    free = system.free
    eps = _finite(state.eps)
    AT = np.ascontiguousarray(generalized(state)[free] / system.thickness)
    load = state.load6[free]
    volume = system.areas * system.thickness
    # A small factor R (R^T R = A^T diag(V) A) spares the decision of the resisted directions an
    # SVD of the N x m matrix.
    factor = np.linalg.qr((AT * np.sqrt(volume)).T, mode="r") if AT.size else np.zeros((0, len(free)))
    small = SpringSystem(AT, eps, volume, load, lengths, factor, stiffness)
    deformed = _Deformed(layer, law, small, 6 + free, eps, strain_rounding(state))
    return certify(deformed, u, reported_stress, tolerance)


def _finite(eps) -> np.ndarray:
    """Strains of springs whose ray misses its target (``inf``) as open ones: the largest finite
    strain, at least 1 (a stress reported there then weighs in the residuals as it is, not
    times 1e300)."""
    finite = np.isfinite(eps)
    return np.where(finite, eps, max(1.0, float(np.max(eps, where=finite, initial=1.0))))


@dataclass(frozen=True, eq=False)
class FiniteSolution(Solution):
    """A :class:`~dea_opt.solution.Solution` of finite kinematics: every quantity at the solved pose.

    ``problem.layer`` holds the springs of the solved pose (after any re-casts); ``strain`` is
    each spring's gap at that pose over its thickness. ``targets`` are the springs' targets
    (:class:`~dea_opt.formulations.finite.Targets`); ``info`` counts the re-casts and
    the springs they gained, lost and dropped (``info["recast"]``); ``lost_through_layer`` the
    loaded springs lost through the layer that still lie behind mesh 1's far side at the solved
    pose (a validity check); ``stability`` how far the answer is from a stable equilibrium
    (:func:`~dea_opt.finite.stability.softest`: above 0 when a disturbance along
    ``info["softest_direction"]`` grows; the ``stability`` validity check); ``tracker`` is the
    re-casting state a load path's next frame continues from.
    """

    targets: Targets | None = None
    dropped: int | None = None
    lost_through_layer: int | None = None
    stability: float | None = None
    tracker: object = field(default=None, repr=False)

    def __getstate__(self) -> dict:
        # Pickled (sent to another process, saved), the answer leaves its tracker behind: the
        # meshes and casts a load path's next frame would continue from, tens of MB.
        return {**self.__dict__, "tracker": None}

    @property
    def pose(self) -> np.ndarray:
        """Body 2's mesh pose in body 1's frame (4x4): the exact motion of ``u`` composed with the pose
        the springs' targets were cast at; ``dea_opt.mesh.springs_from_meshes(..., pose=solution.pose)``
        casts the springs afresh there."""
        frame = np.eye(4) if self.targets is None else self.targets.frame
        return pose_matrix(self.u[6:], self.problem.body2.reference) @ frame

    @property
    def moment_point(self) -> np.ndarray:
        """Body 2's reference point at the solved pose (mm): what :attr:`contact_moment` is taken about."""
        return np.asarray(self.problem.body2.reference, dtype=float) + self.u[6:9]

    @property
    def reactions(self) -> dict:
        """Generalized force the supports apply at every coordinate that is not free (N, N mm): body 1's
        six about its reference, body 2's on its translation and rotation vector at the solved pose."""
        problem, layer = self.problem, self.problem.layer
        f = -self.pressure * layer.areas
        c1 = np.asarray(problem.body1.reference)
        q1 = -np.concatenate([f @ layer.normals, f @ np.cross(layer.points - c1, layer.normals)])
        c2 = np.asarray(problem.body2.reference) + self.u[6:9]
        J = left_jacobian(self.u[9:12])
        spring2 = np.concatenate([f @ layer.normals, J.T @ (f @ np.cross(layer.points - c2, layer.normals))])
        load = problem.load_vector
        load2 = np.concatenate([load[6:9], J.T @ load[9:12]])
        reaction = np.concatenate([q1 - load[:6], spring2 - load2])
        held = np.setdiff1d(np.arange(12), problem.free_indices)
        return {DOF_NAMES[i]: float(reaction[i]) for i in held}

    @property
    def validity(self):
        """As :attr:`Solution.validity <dea_opt.solution.Solution.validity>`; for a solve that did not
        converge where its iterates met a verdict they could not prove (``info["unproved"]``:
        crushed springs, a runaway), the failed checks of the answer say that it is no equilibrium,
        not what a failure would mean at one (a crushed layer, a load in the wrong unit)."""
        validity = super().validity
        was = self.info.get("unproved")
        if self.success or not was:
            return validity
        met = "ran away" if was == "unbounded" else "crushed springs or lost them through the layer"
        why = (
            f"the answer is where the solver's iterates stopped without converging (they {met}, which proves nothing "
            f"about the load), no equilibrium: its strains, pressures and motion mean nothing (the message says "
            f"what the iterates did)"
        )
        checks = tuple(
            replace(c, advice=why) if c.passed is False and c.name in _OF_THE_ANSWER else c for c in validity.checks
        )
        return replace(validity, checks=checks)

    def _counts(self) -> dict:
        """The validity report at the solved pose counts the springs the window dropped there and
        those lost through the layer (when the springs were re-cast from meshes), and says whether
        the equilibrium is stable."""
        return {
            "plane_error": self._plane_error,
            "dropped": self.dropped,
            "lost_through_layer": self.lost_through_layer,
            "stability": self.stability,
            "softest": self.info.get("softest_direction", ""),
        }

    @cached_property
    def _plane_error(self) -> tuple[float, float] | None:
        """:func:`plane_error` where the springs came from a cast and were not re-cast (``recast=False``,
        or a subset of a cast's springs, which knows its meshes: ``SpringLayer.cast``): re-cast
        springs meet mesh 2 on their faces at the solved pose, closed-form targets are the model."""
        from ..mesh import SpringCast

        cast = self.problem.targets
        if cast is None and self.targets is not None and self.targets.faces is not None:
            cast = self.problem.layer.cast  # the tangent planes of the layer's own targets
        if self.tracker is not None or not isinstance(cast, SpringCast) or not np.isfinite(self.u).all():
            return None
        return plane_error(cast, self.problem.layer, self.strain, self.pose)

    def summary(self) -> dict:
        out = super().summary()
        out["kinematics"] = "finite"
        out["pose"] = self.pose.tolist()
        out["recast"] = dict(self.info.get("recast", {}))
        return out
