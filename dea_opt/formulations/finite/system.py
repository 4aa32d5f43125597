"""Finite kinematics, equilibrium: a problem's arrays, and the forces, residual and tangent at a pose of body 2.

Written math: ``formulations/finite.md`` ("Forces and the residual", "Tangent"). Units: mm, rad,
N, N mm, MPa.

:class:`FiniteSystem` holds the arrays of one problem: the springs on body 1 (points and unit
normals (N, 3), areas ``S_i`` (N,) mm^2, thicknesses ``h_i`` (N,) mm), their
:class:`~dea_opt.formulations.finite.geometry.Targets` on body 2, body 2's reference point ``c``
(3,), its free coordinates and prescribed values, and the load (a force ``F`` (3,) N at the
reference and a moment ``M`` (3,) N mm, constant in space). Body 2's coordinates are
``y = (t, theta)`` (6,): the translation of its reference point and its rotation vector
(``u[6:12]`` of the 12-vector, taken exactly). :meth:`FiniteSystem.state` gives the
:class:`State` at ``y``: the springs' gaps, strains and forces, the residual, and on demand its
tangent.

Spring ``i`` pushes body 2 along its own direction ``n_i`` (body 1 is fixed) with
``f_i = S_i sigma(min(s_i / h_i, 0))`` (N, tension positive), ``s_i`` the gap to its target at
the pose. On the six coordinates the net generalized force is

    r(y) = [rho_F; J(theta)^T rho_M],   rho_F = sum_i f_i n_i - F,
    rho_M = sum_i f_i (p_i - c') x n_i - M,   c' = c + t

zero on the free coordinates at equilibrium; on the others it is minus the reaction. Its exact
Jacobian is the tangent (:meth:`State.tangent`), whose sum over the springs is one pass
(:func:`stiffness_sum`: compiled where the install built ``_finite.c``, else its numpy twin).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .geometry import (
    Gaps,
    PlaneRows,
    Targets,
    _as_rows,
    compiled_system,
    evaluate,
    plane_gaps,
)
from .rotations import jacobian_transpose_derivative, rotation_and_jacobian

__all__ = ["FiniteSystem", "State", "arms_of", "generalized", "stiffness_sum"]


@dataclass(frozen=True, eq=False)
class FiniteSystem:
    """The arrays of a finite-kinematics problem: springs, targets, body 2's coordinates and load.

    Attributes
    ----------
    points, normals : ndarray (N, 3)
        The springs on body 1 (mm, unit), fixed.
    areas, thickness : ndarray (N,)
        ``S_i`` (mm^2), ``h_i`` (mm).
    targets : Targets
    reference : ndarray (3,)
        ``c``: body 2's reference point at zero displacement (mm).
    free : ndarray of int (m,)
        Body 2's free coordinates among ``(ux, uy, uz, rx, ry, rz)`` = ``(t, theta)``.
    base : ndarray (6,)
        Body 2's coordinates with the free ones at zero (prescribed values, zeros).
    force, moment : ndarray (3,)
        The load on body 2: ``F`` (N) at its reference, ``M`` (N mm), constant in space.
    """

    points: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    thickness: np.ndarray
    targets: Targets
    reference: np.ndarray
    free: np.ndarray
    base: np.ndarray
    force: np.ndarray
    moment: np.ndarray
    #: ``a_i`` about the origin as rows (6, N): ``[n_i; p_i x n_i]``, one matrix-vector product
    #: gives the springs' resultant and moment.
    arms: np.ndarray = field(init=False, repr=False)
    #: The springs and their plane targets as rows (None when some target is a sphere).
    planes: PlaneRows | None = field(init=False, repr=False)

    def __post_init__(self):
        pT = np.ascontiguousarray(np.asarray(self.points, dtype=float).T)
        nT = np.ascontiguousarray(np.asarray(self.normals, dtype=float).T)
        planes = PlaneRows(self.targets, self.points, self.normals, pT, nT) if self.targets.is_plane.all() else None
        object.__setattr__(self, "arms", arms_of(pT, nT))
        object.__setattr__(self, "planes", planes)

    @classmethod
    def of_rows(
        cls, points, normals, areas, thickness, targets, pT, nT, arms, mT, qm, reference, free, base, force, moment
    ) -> FiniteSystem:
        """A system whose springs' rows are already at hand: ``pT, nT`` (3, N), ``arms`` (6, N,
        :func:`arms_of`), and their plane targets' ``mT`` (3, N) and ``qm`` (N,)
        (:class:`PlaneRows`), kept up to date by whoever holds them (a tracker's springs change by
        a few a step), not built again."""
        system = object.__new__(cls)
        values = {
            "points": points,
            "normals": normals,
            "areas": areas,
            "thickness": thickness,
            "targets": targets,
            "reference": reference,
            "free": free,
            "base": base,
            "force": force,
            "moment": moment,
            "arms": arms,
            "planes": PlaneRows.of_rows(points, normals, pT, nT, mT, qm),
        }
        for name, value in values.items():
            object.__setattr__(system, name, value)
        return system

    def __len__(self) -> int:
        return len(self.points)

    def coordinates(self, u_free) -> np.ndarray:
        """Body 2's six coordinates ``y`` for the free values ``u_free`` (mm, rad)."""
        y = self.base.copy()
        y[self.free] = u_free
        return y

    def transform(self, y, R=None) -> np.ndarray:
        """Body 2's own frame to the world at ``y``: the displacement composed with ``targets.frame``
        (``R``, the rotation of ``y[3:6]``, when already known)."""
        if R is None:
            R, _ = rotation_and_jacobian(y[3:6])
        D = np.eye(4)
        D[:3, :3] = R
        D[:3, 3] = self.reference + y[:3] - R @ self.reference
        return D @ self.targets.frame

    def gaps(self, transform) -> Gaps:
        """The springs' gaps to their targets moved by ``transform`` (:meth:`transform`)."""
        if self.planes is not None:
            return plane_gaps(self.planes, transform)
        return evaluate(self.targets, self.points, self.normals, transform)

    def with_load(self, force, moment) -> FiniteSystem:
        """The same springs and body 2 under another load: ``force`` (3,) N, ``moment`` (3,) N mm."""
        return FiniteSystem(
            self.points,
            self.normals,
            self.areas,
            self.thickness,
            self.targets,
            self.reference,
            self.free,
            self.base,
            np.asarray(force, float),
            np.asarray(moment, float),
        )

    def with_springs(self, points, normals, areas, thickness, targets, rows: tuple | None = None) -> FiniteSystem:
        """This body 2 and load with other springs; ``rows`` their rows when at hand (:meth:`of_rows`)."""
        if rows is not None:
            pT, nT, arms, mT, qm = rows
            return FiniteSystem.of_rows(
                points,
                normals,
                areas,
                thickness,
                targets,
                pT,
                nT,
                arms,
                mT,
                qm,
                self.reference,
                self.free,
                self.base,
                self.force,
                self.moment,
            )
        return FiniteSystem(
            points, normals, areas, thickness, targets, self.reference, self.free, self.base, self.force, self.moment
        )

    def state(self, y, law, bilateral: bool = False) -> State:
        """Everything at ``y`` that the residual needs (one pass over the springs). The last one is
        kept: a solve starts where the update of its springs evaluated them."""
        y = np.array(y, dtype=float)  # a copy: the state keeps it
        last = self.__dict__.get("_last")
        if last is not None and last.law is law and last.bilateral == bilateral and np.array_equal(last.y, y):
            return last
        state = State(self, y, law, bilateral)
        object.__setattr__(self, "_last", state)
        return state


class State:
    """The springs' gaps, strains and forces at one pose, the residual there, and (on demand) its tangent.

    Made by :meth:`FiniteSystem.state`. ``bilateral`` evaluates the law in tension too (the
    extended range of a cold start).

    Attributes
    ----------
    y : ndarray (6,)
        Body 2's coordinates ``(t, theta)`` (mm, rad).
    J : ndarray (3, 3)
        ``J(theta)``, the left Jacobian of the rotation.
    centre : ndarray (3,)
        ``c' = c + t``, body 2's reference point at the pose (mm).
    gaps : Gaps
        Each spring's gap to its target at the pose.
    eps, sigma : ndarray (N,)
        Strains ``s_i / h_i`` and stresses (MPa; zero in tension unless ``bilateral``).
    residual6 : ndarray (6,)
        ``r(y)`` on all six coordinates (N, N mm); :meth:`residual` is its free part.
    load6, internal6 : ndarray (6,)
        The load on the six coordinates and the springs' part of the residual
        (``residual6 = internal6 - load6``).
    """

    def __init__(self, system: FiniteSystem, y, law, bilateral: bool = False):
        self.system, self.y, self.law, self.bilateral = system, y, law, bilateral
        R, self.J = rotation_and_jacobian(y[3:6])
        self.centre = system.reference + y[:3]
        self.gaps = system.gaps(system.transform(y, R))
        self.eps = self.gaps.s / system.thickness
        with np.errstate(over="ignore", invalid="ignore"):
            self.sigma = law.stress(self.eps if bilateral else np.minimum(self.eps, 0.0))
        if bilateral:
            self.sigma = np.where(self.gaps.valid, self.sigma, 0.0)
        with np.errstate(invalid="ignore"):  # a law's NaN past its domain: the residual shows it (finite)
            spring = system.arms @ (system.areas * self.sigma)  # sum f a_i about the origin
            self.force_sum = spring[:3]
            spring[3:] -= _hat(self.centre) @ self.force_sum
            self.spring = spring  # sum f a_i, spatial, about c'
            self.net = self.spring - np.concatenate([system.force, system.moment])
            self.residual6 = np.concatenate([self.net[:3], self.J.T @ self.net[3:]])
        self.load6 = np.concatenate([system.force, self.J.T @ system.moment])
        self.internal6 = self.residual6 + self.load6

    @property
    def finite(self) -> bool:
        return bool(np.isfinite(self.residual6).all())

    @property
    def crushed(self) -> bool:
        """Beyond a bounded law's domain (a spring at ``eps <= -1``)."""
        return bool(self.law.bounded_strain and self.eps[self.gaps.valid].min(initial=0.0) <= -1.0)

    def residual(self) -> np.ndarray:
        """``r(y)`` on the free coordinates (N, N mm)."""
        return self.residual6[self.system.free]

    def _shift(self) -> np.ndarray:
        """``L`` (6, 6): the rows ``[n; p x n]`` about the origin to ``[n; (p - c') x n]`` about ``c'``."""
        L = np.eye(6)
        L[3:, :3] = -_hat(self.centre)
        return L

    def force_rows(self) -> np.ndarray:
        """``a_i = [n_i; (p_i - c') x n_i]`` (6, N): spring ``i``'s force direction and moment arm."""
        return self._shift() @ self.system.arms

    def tangent(self, rows=None, weights=None) -> np.ndarray:
        """``dr/dy`` on the free coordinates (m, m): the consistent tangent.

        ``sum_i k_i a_i b_i^T`` over the compressed springs (``k_i = S_i sigma'(eps_i) / h_i``,
        ``b_i`` the gap's derivative), the lever arm moving with the reference, mapped by
        ``blockdiag(I, J)``, plus the derivative of ``J^T`` against the net moment. With
        ``a_i = L [n_i; p_i x n_i]`` and ``b_i = L [m_i; z_i x m_i] / (n_i . m_i)`` (``L`` moving
        moments from the origin to ``c'``) the sum is ``L G L^T``, ``G`` one 6 x 6 product.
        """
        s, gaps = self.system, self.gaps
        # Every spring in one pass, those outside ``rows`` with weight 0 (no gathers of rows).
        if rows is None and weights is None:
            active = gaps.valid & ((self.eps < 0) | self.bilateral)
            eps = self.eps if self.bilateral else np.minimum(self.eps, 0.0)
            with np.errstate(invalid="ignore", divide="ignore", over="ignore"):  # open springs: masked
                k = s.areas * self.law.tangent(np.where(active, eps, 0.0)) / (s.thickness * gaps.along)
            w = np.where(active, k, 0.0)
        else:
            if rows is None:
                rows = np.flatnonzero(gaps.valid & ((self.eps < 0) | self.bilateral))
            if weights is None:
                eps = self.eps[rows] if self.bilateral else np.minimum(self.eps[rows], 0.0)
                weights = s.areas[rows] * self.law.tangent(eps) / s.thickness[rows]
            w = np.zeros(len(s))
            w[rows] = weights / gaps.along[rows]
        planes = s.planes
        pT, nT = (planes.pT, planes.nT) if planes is not None else (s.points.T, s.normals.T)
        G = stiffness_sum(w, gaps.s, pT, nT, gaps.mT, s.arms)
        L = self._shift()
        K = L @ G @ L.T
        K[3:, :3] += _hat(self.force_sum)  # the lever arm p - c' shortens as the reference moves
        M = np.eye(6)
        M[3:, 3:] = self.J
        Kc = np.zeros((6, 6))
        Kc[:3] = K[:3] @ M
        Kc[3:] = self.J.T @ K[3:] @ M
        Kc[3:, 3:] += jacobian_transpose_derivative(self.y[3:6], self.net[3:])
        free = s.free
        return Kc[np.ix_(free, free)]

    def material(self) -> np.ndarray:
        """``sum_i k_i a_i a_i^T`` over every spring with a valid target, at the small-strain
        modulus where open: symmetric positive (semi)definite, for safe steps."""
        s, gaps = self.system, self.gaps
        rows = np.flatnonzero(gaps.valid)
        eps = np.minimum(self.eps[rows], 0.0)
        weights = s.areas[rows] * self.law.tangent(eps) / s.thickness[rows]
        U = s.arms[:, rows]
        M = np.eye(6)
        M[3:, 3:] = self.J
        ML = (M.T @ self._shift())[s.free]
        return ML @ ((U * weights) @ U.T) @ ML.T


def stiffness_sum(w, s, pT, nT, mT, arms, compiled: bool | None = None) -> np.ndarray:
    """``G = sum_i w_i a_i v_i^T`` (6, 6) over the springs with ``w_i != 0``: ``a_i`` = ``arms[:, i]``,
    ``v_i = [m_i; h_i x m_i]`` with the hit ``h_i = p_i + s_i n_i`` (rows (3, N): ``pT``, ``nT``,
    ``mT``; gaps ``s`` (N,), inf where missed). One compiled pass (``_finite.c``) unless
    ``compiled`` is False or it was not built, else numpy (its matrix product adds in blocks: the
    same sum to rounding)."""
    kernel = compiled_system() if compiled is None or compiled else None
    if kernel is not None:
        G = np.empty((6, 6))
        kernel.tangent_sum(len(w), *(_as_rows(a) for a in (w, s, pT, nT, mT, arms)), G)
        return G
    gap = np.where(w != 0.0, s, 0.0)
    hit = pT + gap * nT
    V = np.empty((6, len(w)))
    V[:3] = mT
    V[3] = hit[1] * mT[2] - hit[2] * mT[1]
    V[4] = hit[2] * mT[0] - hit[0] * mT[2]
    V[5] = hit[0] * mT[1] - hit[1] * mT[0]
    return (arms * w) @ V.T


def arms_of(pT, nT, out=None) -> np.ndarray:
    """``a_i = [n_i; p_i x n_i]`` (6, K) of springs at ``pT``, along ``nT`` (3, K): the moment about
    ``c'`` is then ``sum f (p x n) - c' x sum f n`` (the cross products once)."""
    arms = np.empty((6, pT.shape[1])) if out is None else out
    arms[:3] = nT
    arms[3] = pT[1] * nT[2] - pT[2] * nT[1]
    arms[4] = pT[2] * nT[0] - pT[0] * nT[2]
    arms[5] = pT[0] * nT[1] - pT[1] * nT[0]
    return arms


def generalized(state) -> np.ndarray:
    """Each spring's force direction on body 2's six coordinates, ``blockdiag(I, J)^T a_i`` (6, N)."""
    M = np.eye(6)
    M[3:, 3:] = state.J.T
    return (M @ state._shift()) @ state.system.arms


def _hat(v) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
