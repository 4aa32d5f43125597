"""The variables every formulation solves in: a change of variables that makes units, lever arms
and far reference points not matter (``formulations/energy.md``, "Scaling").

``u_free = T xi`` over the resisted directions (:class:`~dea_opt.formulations._parts.resistance.Resistance`),
sized so that ``xi = O(1)`` for the larger of the load and the overlap; energies divided by
``E0 = s^2``, strain variables by ``s0`` (:class:`Scaling`, built by :func:`~dea_opt.formulations._parts.scaling.scaling`). Tolerances
then mean the same for every unit and load. Units: mm, rad, N, N mm.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .resistance import modulus_scale
from .system import SpringSystem

__all__ = ["Scaling", "norm", "scaling"]


@dataclass(frozen=True, eq=False)
class Scaling:
    """A change of variables that makes every formulation see a well-conditioned problem.

    ``u_free = T xi`` with ``T = T1 s`` and ``T1 = D^-1 Rk Sigma_k^-1 / sqrt(H)`` from the
    singular value decomposition of the factor ``W = U Sigma R^T`` of the bonded stiffness
    (:func:`~dea_opt.formulations._parts.resistance.resistance`; never an eigendecomposition of ``K0 = A^T diag(V H) A``, which would
    square its condition number), so that ``T1^T K0 T1 = I`` (``formulations/energy.md``,
    "Scaling"): directions no spring resists are dropped, the remaining ones are made
    K0-orthonormal (so units, lever arms and far reference points no longer matter), and
    ``s`` makes ``xi = O(1)`` for the larger of the reference load and the overlap. Energies
    are divided by ``E0 = s^2`` and strain variables by ``s0``.

    Attributes
    ----------
    T : ndarray, shape (m, k)
    system_AT, system_volume : ndarray, shape (m, N) and (N,)
        The unscaled system's ``A^T`` and ``V`` (the system's own arrays, not copies).
    AT : ndarray, shape (k, N)
        ``T^T A^T``: the strain per unit ``xi``, computed on first use (a copy of ``8 k N``
        bytes, which the formulations that build matrices need; Newton never asks for it: it
        folds ``T`` into its ``k``-vectors and ``k x k`` matrices, ``formulations/energy.md``, "Scaling").
    volume : ndarray, shape (N,)
        ``V / E0`` (mm^3 per energy unit), computed on first use.
    energy_scale : float
        ``E0 = s^2`` (N mm).
    strain_scale : float
        ``s0 = s / sqrt(sum_i V_i H)``: a typical strain of the reference load (for scaling
        strain variables).
    """

    T: np.ndarray
    system_AT: np.ndarray
    system_volume: np.ndarray
    energy_scale: float
    strain_scale: float

    @cached_property
    def AT(self) -> np.ndarray:
        return np.ascontiguousarray(self.T.T @ self.system_AT)

    @cached_property
    def volume(self) -> np.ndarray:
        return self.system_volume / self.energy_scale

    @property
    def n_dofs(self) -> int:
        return self.T.shape[1]

    def load(self, r) -> np.ndarray:
        """The scaled load ``T^T r / E0`` for a load ``r`` on the free dofs."""
        return self.T.T @ np.asarray(r, dtype=float) / self.energy_scale

    def to_u_free(self, xi) -> np.ndarray:
        """The free-dof motion ``T xi`` (mm, rad)."""
        return self.T @ np.asarray(xi, dtype=float)

    def to_xi(self, u_free) -> np.ndarray:
        """Least-squares ``xi`` for a free-dof motion ``u_free`` (its resisted part)."""
        return np.linalg.lstsq(self.T, np.asarray(u_free, dtype=float), rcond=None)[0]

    def system(self, e0, load) -> SpringSystem:
        """The scaled system, for a formulation that knows nothing of the scaling."""
        return SpringSystem(self.AT, e0, self.volume, self.load(load))


def scaling(system: SpringSystem, modulus: float, reference_load=None) -> Scaling:
    """The :class:`Scaling` of ``system`` for a law of small-strain stiffness ``modulus``.

    ``s`` is the larger of the load's size ``|T1^T r|`` and the overlap's
    ``sqrt(sum V H min(e0, 0)^2)`` (both the square root of an energy), so that a tiny load on
    a press-fitted layer is not solved in units where the press fit is enormous.
    """
    AT, V = system.AT, system.volume
    stiffness = V * modulus_scale(modulus)
    T1 = system.resistance.basis(modulus)
    r = system.load if reference_load is None else np.asarray(reference_load, dtype=float)
    s_load = norm(T1.T @ r) if r.size else 0.0
    overlap = system.e0.min(initial=0.0) < 0
    s_overlap = norm(np.sqrt(stiffness) * np.minimum(system.e0, 0.0)) if overlap else 0.0
    s = max(s_load, s_overlap)
    if not (s > 0.0 and np.isfinite(s)):
        s = 1.0
    T = T1 * s
    total = float(stiffness.sum())
    s0 = s / np.sqrt(total) if total > 0 else 1.0
    return Scaling(T=T, system_AT=AT, system_volume=V, energy_scale=s**2, strain_scale=s0)


def norm(v) -> float:
    """Euclidean norm scaled by the largest entry first (no overflow or underflow of squares)."""
    v = np.asarray(v, dtype=float)
    top = float(np.abs(v).max(initial=0.0))
    return top * float(np.linalg.norm(v / top)) if top > 0 and np.isfinite(top) else top
