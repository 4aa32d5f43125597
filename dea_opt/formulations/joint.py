"""A whole joint as arrays: every element's strain per unit motion of the bodies it couples.

Written math: ``formulations/joint.md``. A joint of several rigid bodies is held together by
*elements*, each coupling two bodies: the springs of a contact layer (compression only) and the
straight-line ligament bundles (tension only). Under small kinematics each element's strain is
affine in the free dofs ``x`` of the whole joint, and only the dofs of its two bodies enter:

    eps_g(x) = e0_g + A_g x[dofs_g]              (one group g of elements, N_g of them)
    Phi(x) = sum_g sum_i V_gi w_g(clip_g(eps_gi)) - r . x

with ``clip`` ``min(eps, 0)`` for springs and ``max(eps, 0)`` for ligaments. A group holds its
rows over its own dofs only (at most 12), so every pass over the elements costs what the
springs cost, however many bodies the joint has: the joint's ``m x m`` gradient and tangent are
assembled block by block (:func:`assemble`). This module sees arrays and laws, never bodies,
meshes or files: :mod:`dea_opt.joint` builds the groups from a :class:`~dea_opt.joint.Joint`.

Also here: the ligaments' tension-only laws (:class:`TensionLaw`: Blankevoort 1991 as OpenSim's
``Blankevoort1991Ligament`` writes it, and linear), the joint's resisted directions and scaling
(the one test of :func:`~dea_opt.formulations._parts.resistance.unresisted`, on the factors of its groups)
and the joint as one compression-only spring system (:meth:`JointSystem.flat`, every ligament a
spring in reverse) for the QP.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np

from ..errors import InputError
from ..status import Status
from ._parts.resistance import Resistance, factor_resistance, require_finite
from ._parts.system import SpringSystem

PAGE = "formulations/joint.md"

#: The tension-only laws of a ligament bundle.
TENSION_LAWS = ("blankevoort", "linear")


@dataclass(frozen=True, eq=False)
class TensionLaw:
    """The tension-only force of ligament bundles per unit stiffness, ``phi(eps) = f / k``.

    ``"blankevoort"`` (Blankevoort et al. 1991, as OpenSim's ``Blankevoort1991Ligament``): with
    the transition strain ``eps_t``, ``phi = 0`` for ``eps <= 0``, ``eps^2 / (2 eps_t)`` below
    ``eps_t`` (the toe region) and ``eps - eps_t / 2`` beyond. ``"linear"``: ``phi = max(eps, 0)``.
    OpenSim's damping term needs speeds: a quasi-static solve has none and leaves it out.

    Parameters
    ----------
    kind : {"blankevoort", "linear"}
    transition : ndarray, shape (N,)
        ``eps_t`` per bundle (ignored by ``"linear"``).

    The methods take strains (any sign) and return ``phi`` (strain units: the force over ``k``),
    its derivative and its integral ``int_0^eps phi`` (the energy over ``k L0``), all zero for
    ``eps <= 0``. They work on NumPy arrays; :meth:`casadi_energy` builds the CasADi expression.
    """

    kind: str
    transition: np.ndarray

    def __post_init__(self):
        if self.kind not in TENSION_LAWS:
            raise InputError(f"a ligament's law must be one of {TENSION_LAWS}, got {self.kind!r}")

    def _parts(self, eps):
        e = np.maximum(np.asarray(eps, dtype=float), 0.0)
        if self.kind == "linear":
            return e, None, None
        et = self.transition if self.transition.shape == e.shape else np.broadcast_to(self.transition, e.shape)
        return e, et, e < et

    def force(self, eps) -> np.ndarray:
        e, et, toe = self._parts(eps)
        if et is None:
            return e
        return np.where(toe, e * e / (2.0 * et), e - 0.5 * et)

    def tangent(self, eps) -> np.ndarray:
        e, et, toe = self._parts(eps)
        positive = np.asarray(eps, dtype=float) > 0
        if et is None:
            return positive.astype(float)
        return np.where(positive, np.where(toe, e / et, 1.0), 0.0)

    def energy(self, eps) -> np.ndarray:
        e, et, toe = self._parts(eps)
        if et is None:
            return 0.5 * e * e
        return np.where(toe, e**3 / (6.0 * et), 0.5 * e * e - 0.5 * et * e + et * et / 6.0)

    def casadi_energy(self, eps, transition):
        """``int_0^eps phi`` for CasADi symbols ``eps`` (N,) and the numbers ``transition`` (N,)."""
        import casadi as ca

        e = ca.fmax(eps, 0)
        if self.kind == "linear":
            return 0.5 * e * e
        et = ca.DM(np.asarray(transition, dtype=float))
        return ca.if_else(e < et, e**3 / (6.0 * et), 0.5 * e * e - 0.5 * et * e + et * et / 6.0)


@dataclass(frozen=True, eq=False)
class ElementGroup:
    """Elements of one kind and law between two bodies, over the free dofs of those bodies.

    Attributes
    ----------
    name : str
        For messages (``"contact 0"``, ``"ligaments femur-tibia"``).
    kind : {"contact", "ligament", "bilateral"}
        Compression-only springs, tension-only bundles, or linear two-sided rows (finite
        kinematics: the sideways stiffness ``f / L`` of bundles in tension at the pose).
    law : Law, TensionLaw or None
        A spring law (stress in MPa), the bundles' :class:`TensionLaw`, or None (bilateral: linear).
    dofs : ndarray of int, shape (m_g,)
        Indices of the group's free dofs in the joint's free vector ``x``.
    AT : ndarray, shape (m_g, N_g)
        Strain per unit free dof (1/mm, 1/rad), tension positive: ``n . B / h`` for springs,
        ``dL / dx / L0`` for bundles.
    e0 : ndarray, shape (N_g,)
        Strain at ``x = 0`` (gaps, prescribed motion; a bundle's ``L / L0 - 1`` at the start).
    volume : ndarray, shape (N_g,)
        ``V = S h`` (mm^3) for springs; ``L0 k`` (N mm) for bundles: ``V * phi`` is then the
        generalized force per unit strain rate and ``V * w`` the energy (N mm).
    force_scale : ndarray, shape (N_g,)
        Element force (N, tension positive) per unit of the law's output: the area ``S`` (mm^2)
        of a spring, the stiffness ``k`` (N) of a bundle.
    modulus : float
        The law's stiffness scale: ``H`` of a spring law, 1 for bundles (``k`` is in ``V``).
    factor : ndarray, shape (r_g, m_g)
        ``F`` with ``F^T F = A^T diag(V modulus) A``, the group's bonded stiffness.
    stiffness : float
        Its own stiffness scale (N/mm): ``H sum S / h`` for springs, ``sum k / L0`` for bundles.
    basis : (ndarray (k, m_g), ndarray (k, N_g)), optional
        ``(C, E)`` with ``AT = C^T E``: a layer's rows in its own basis (``k = 6``: each spring's
        translation and rotation about the layer's centroid, over ``h``) and how the two bodies'
        free dofs move it. Then every pass over the springs reads 6 rows, however many dofs the
        two bodies have (``formulations/joint.md``, "Gradient and tangent"); ``AT`` is formed only
        where a solver needs the whole matrix (IPOPT, the QP).
    """

    name: str
    kind: str
    law: Any
    dofs: np.ndarray
    AT: np.ndarray | None
    e0: np.ndarray
    volume: np.ndarray
    force_scale: np.ndarray
    modulus: float
    factor: np.ndarray
    stiffness: float
    basis: tuple | None = None

    @property
    def matrix(self) -> np.ndarray:
        """``AT`` (m_g, N_g), formed from the basis the first time it is asked for."""
        if self.AT is not None:
            return self.AT
        if "_matrix" not in self.__dict__:
            assert self.basis is not None
            C, E = self.basis
            self.__dict__["_matrix"] = np.ascontiguousarray(C.T @ E)
        return self.__dict__["_matrix"]

    def rate(self, dx) -> np.ndarray:
        """``A dx[dofs]``, shape (N_g,): the strain per unit step ``dx`` of the joint's free dofs."""
        v = np.asarray(dx, dtype=float)[self.dofs]
        if self.basis is not None:
            C, E = self.basis
            return (C @ v) @ E
        assert self.AT is not None
        return v @ self.AT

    def pull(self, v) -> np.ndarray:
        """``A^T v``, shape (m_g,): the generalized force of element values ``v`` (N,)."""
        if self.basis is not None:
            C, E = self.basis
            return C.T @ (E @ v)
        assert self.AT is not None
        return self.AT @ v

    def gram(self, w) -> np.ndarray:
        """``A^T diag(w) A`` (m_g, m_g) over the elements where ``w`` is nonzero (the last one kept:
        a Newton iteration whose active set and tangents did not change asks for the same again)."""
        last = self.__dict__.get("_last_gram")
        if last is not None and last[0].shape == np.shape(w) and np.array_equal(last[0], w):
            return last[1]
        out = self._gram(w)
        self.__dict__["_last_gram"] = (np.array(w, dtype=float), out)
        return out

    def _gram(self, w) -> np.ndarray:
        rows = np.flatnonzero(w)
        if self.basis is not None:
            C, E = self.basis
            if 3 * rows.size < E.shape[1]:  # few active rows: gathering them is cheaper than the zeros
                E, w = E[:, rows], w[rows]
            return C.T @ ((E * w) @ E.T) @ C
        assert self.AT is not None
        AT = self.AT[:, rows]
        return (AT * w[rows]) @ AT.T

    @property
    def size(self) -> int:
        return int(self.e0.size)

    @property
    def contact(self) -> bool:
        return self.kind == "contact"

    @property
    def bounded(self) -> bool:
        """Springs of a law defined only for ``eps > -1``."""
        return self.contact and bool(getattr(self.law, "bounded_strain", False))

    def strain(self, x) -> np.ndarray:
        """``e0 + A x[dofs]``, shape (N_g,), for the joint's free vector ``x``."""
        return self.e0 + self.rate(x)

    @property
    def two_sided(self) -> bool:
        return self.kind == "bilateral"

    def active(self, eps) -> np.ndarray:
        """Springs in compression, bundles in tension, two-sided rows always."""
        if self.two_sided:
            return np.ones(eps.shape, dtype=bool)
        return eps < 0 if self.contact else eps > 0

    def stress(self, eps) -> np.ndarray:
        """The law's output at the clipped strain: a spring's stress (MPa, <= 0), a bundle's
        ``phi`` (>= 0); ``V * stress`` is the generalized force per unit strain rate."""
        if self.contact:
            return self.law.stress(np.minimum(eps, 0.0))
        if self.two_sided:
            return np.asarray(eps, dtype=float)
        return self.law.force(eps)

    def tangent(self, eps) -> np.ndarray:
        """The derivative of :meth:`stress` in ``eps``: 0 where the element is inactive."""
        if self.contact:
            compressed = eps < 0
            out = np.zeros(eps.shape)
            if compressed.any():
                out[compressed] = self.law.tangent(eps[compressed])
            return out
        if self.two_sided:
            return np.ones(eps.shape)
        return self.law.tangent(eps)

    def every_tangent(self, eps) -> np.ndarray:
        """The stiffness of every element, active or not (a spring's law at ``min(eps, 0)``, a
        bundle's linear slope 1): the safe step's stiffness along directions the active
        elements miss (``formulations/joint.md``, "Newton")."""
        if self.contact:
            return self.law.tangent(np.minimum(eps, 0.0))
        return np.ones(eps.shape)

    def bilateral(self, eps) -> tuple[np.ndarray, np.ndarray]:
        """``(stress, tangent)`` of the elements made two-sided (the paper's extended range): a
        spring's law in tension too, a bundle linear in compression too."""
        if self.contact:
            return self.law.stress(eps), self.law.tangent(eps)
        return np.asarray(eps, dtype=float), np.ones(eps.shape)

    def energy(self, eps) -> np.ndarray:
        """``w`` at the clipped strain (MPa for springs, strain^2 units for bundles)."""
        if self.contact:
            return self.law.energy(np.minimum(eps, 0.0))
        if self.two_sided:
            return 0.5 * np.asarray(eps, dtype=float) ** 2
        return self.law.energy(eps)

    def forces(self, stress) -> np.ndarray:
        """Element forces (N, tension positive) from the law's output."""
        return self.force_scale * np.asarray(stress, dtype=float)


@dataclass(frozen=True, eq=False)
class JointSystem:
    """The small-kinematics joint over its ``m`` free dofs: element groups, load and lengths.

    Attributes
    ----------
    groups : tuple of ElementGroup
    load : ndarray, shape (m,)
        Generalized load on the free dofs (N, N mm).
    lengths : ndarray, shape (m,)
        Per-dof length (mm): 1 for a translation, the RMS distance of the elements' points from
        the body's reference for a rotation (as :attr:`SpringSystem.lengths`).
    """

    groups: tuple
    load: np.ndarray
    lengths: np.ndarray
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def n_dofs(self) -> int:
        return int(self.load.size)

    @property
    def n_elements(self) -> int:
        return sum(g.size for g in self.groups)

    @property
    def stiffness(self) -> float:
        """The joint's own stiffness scale (N/mm): the sum of its groups'."""
        return float(sum(g.stiffness for g in self.groups))

    def with_load(self, load) -> JointSystem:
        """The same elements under another load (the resisted directions are shared)."""
        return JointSystem(self.groups, np.asarray(load, dtype=float), self.lengths, self._cache)

    @cached_property
    def resistance(self) -> Resistance:
        """Which free directions the elements resist, bonded (springs two-sided, bundles too), by
        the one test of :func:`~dea_opt.formulations._parts.resistance.unresisted` on the stacked factors."""
        if "resistance" not in self._cache:
            m = self.n_dofs
            rows = []
            for g in self.groups:
                block = np.zeros((g.factor.shape[0], m))
                block[:, g.dofs] = g.factor
                rows.append(block)
            factor = np.vstack(rows) if rows else np.zeros((0, m))
            require_finite("the joint's bonded stiffness", factor)
            self._cache["resistance"] = factor_resistance(factor, self.lengths, self.stiffness)
        return self._cache["resistance"]

    def strains(self, x) -> list[np.ndarray]:
        """Every group's strains at ``x`` (mm, rad)."""
        return [g.strain(x) for g in self.groups]

    def e0_overlap(self) -> float:
        """``sqrt(sum V modulus clip(e0)^2)`` (the square root of N mm): the energy the start
        stores, the scale of a press fit, of bundles stretched or of springs and bushings
        deflected at the start (two-sided: unclipped)."""
        total = 0.0
        for g in self.groups:
            clipped = g.e0 if g.two_sided else np.minimum(g.e0, 0.0) if g.contact else np.maximum(g.e0, 0.0)
            top = float(np.abs(clipped).max(initial=0.0))
            if top > 0:
                total += top * top * float((g.volume * g.modulus) @ (clipped / top) ** 2)
        return float(np.sqrt(total))

    def flat(self) -> tuple[SpringSystem, list]:
        """The joint as one compression-only spring system of unit modulus, for the QP.

        Every spring keeps its row with its volume times its modulus; every bundle becomes a
        spring in reverse (row ``-A``, strain ``-e0``): a tension-only linear bundle is a
        compressive linear spring of ``V = L0 k``; every two-sided row (a linear spring or
        bushing between bodies) is both, a spring each way, whose energies add to ``V e^2 / 2``.
        Only the linear laws make this a QP.

        Returns
        -------
        system : SpringSystem
            Over the joint's free dofs (dense ``AT``, shape (m, n) with n the elements plus the
            two-sided rows once more).
        convert : list of (slice, sign, scale, slice or None)
            Per group, its rows in the flat system and how a flat stress ``s`` turns into the
            group's law output: ``sign * scale * s`` (a spring's stress ``H s``, a bundle's
            ``phi = -s``), minus ``scale * s`` of the second slice for a two-sided row (its
            reverse spring).
        """
        m = self.n_dofs
        n = self.n_elements + sum(g.size for g in self.groups if g.two_sided)
        AT, e0, volume = np.zeros((m, n)), np.empty(n), np.empty(n)
        convert, at = [], 0
        for g in self.groups:
            sign = 1.0 if g.contact or g.two_sided else -1.0
            part = slice(at, at + g.size)
            AT[g.dofs, part] = sign * g.matrix
            e0[part] = sign * g.e0
            volume[part] = g.volume * g.modulus
            at += g.size
            minus = None
            if g.two_sided:
                minus = slice(at, at + g.size)
                AT[g.dofs, minus] = -g.matrix
                e0[minus] = -g.e0
                volume[minus] = g.volume * g.modulus
                at += g.size
            convert.append((part, sign, g.modulus, minus))
        factor = self.resistance  # shared below, never recomputed from the dense rows
        system = SpringSystem(np.ascontiguousarray(AT), e0, volume, self.load, self.lengths, None, self.stiffness)
        system.__dict__["resistance"] = factor
        return system, convert


def assemble(system: JointSystem, weights, transform=None) -> np.ndarray:
    """``sum_g A_g^T diag(weights_g) A_g`` scattered into the joint's ``m x m`` (or ``T^T . T``).

    Parameters
    ----------
    weights : list of ndarray
        Per group, ``V_gi sigma'_gi`` (zeros allowed; only the nonzero rows are summed).
    transform : ndarray, shape (m, k), optional
        ``T``: returns ``T^T K T`` (k x k).
    """
    m = system.n_dofs
    K = np.zeros((m, m))
    for g, w in zip(system.groups, weights):
        if not np.any(w):
            continue
        K[np.ix_(g.dofs, g.dofs)] += g.gram(w)
    return K if transform is None else transform.T @ K @ transform


def internal_force(system: JointSystem, stresses) -> np.ndarray:
    """``q = sum_g A_g^T (V_g stress_g)`` scattered over the joint's free dofs (N, N mm)."""
    q = np.zeros(system.n_dofs)
    for g, s in zip(system.groups, stresses):
        q[g.dofs] += g.pull(g.volume * s)
    return q


def energy(system: JointSystem, strains) -> float:
    """``sum_g V_g . w_g(clip(eps_g))`` (N mm)."""
    return float(sum(float(g.volume @ g.energy(e)) for g, e in zip(system.groups, strains)))


@dataclass(frozen=True, eq=False)
class JointScaling:
    """``x = T xi`` with ``T = T1 s`` (``T1^T K0 T1 = I`` over the resisted directions, ``K0`` the
    joint's bonded stiffness at its moduli) and energies over ``E0 = s^2``, as
    :class:`~dea_opt.formulations._parts.scaling.Scaling` for one spring system."""

    T: np.ndarray
    energy_scale: float

    @property
    def n_dofs(self) -> int:
        return self.T.shape[1]

    def to_x(self, xi) -> np.ndarray:
        return self.T @ np.asarray(xi, dtype=float)

    def to_xi(self, x) -> np.ndarray:
        return np.linalg.lstsq(self.T, np.asarray(x, dtype=float), rcond=None)[0]


def joint_scaling(system: JointSystem, reference_load=None) -> JointScaling:
    """The scaled variables of ``system`` (``formulations/joint.md``, "Scaling"): ``s`` the larger
    of the load's size ``|T1^T r|`` and the start's stored energy's square root."""
    T1 = system.resistance.T1  # the moduli are in the factors: unit modulus here
    r = system.load if reference_load is None else np.asarray(reference_load, dtype=float)
    s_load = float(np.linalg.norm(T1.T @ r)) if r.size and T1.size else 0.0
    s = max(s_load, system.e0_overlap())
    if not (s > 0.0 and np.isfinite(s)):
        s = 1.0
    return JointScaling(T1 * s, s * s)


@dataclass
class JointResult:
    """A joint formulation's raw answer, before dea_opt certifies it.

    Attributes
    ----------
    x : ndarray, shape (m,)
        The free dofs (mm, rad).
    stresses : list of ndarray
        Per group, the law's output as the formulation sees it (a spring's stress in MPa, a
        bundle's ``phi``; from the duals for the QP), for the certificate to compare with the law.
    success : bool
        The solver's own claim (the certificate decides).
    status : Status
    """

    x: np.ndarray
    stresses: list
    success: bool
    status: Status
    message: str = ""
    iterations: int = 0
    solve_time: float = 0.0
    info: dict = field(default_factory=dict)


def law_stresses(system: JointSystem, x) -> list[np.ndarray]:
    """Every group's law output at ``x``."""
    return [g.stress(e) for g, e in zip(system.groups, system.strains(x))]
