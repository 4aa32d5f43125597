"""What every formulation receives and returns: plain arrays and a law, nothing else.

The reduced problem over the ``m`` free degrees of freedom ``x`` (``formulations/energy.md``):

    eps(x) = e0 + A x                                   (N,)
    Phi(x) = sum_i V_i w(min(eps_i, 0)) - r . x         V_i = S_i h_i

``A`` holds the rows ``n_i^T B_i / h_i`` of Eq. (11) restricted to the free dofs and ``e0``
the strain at ``x = 0`` (gap and prescribed motion). Spring stress is ``sigma_i`` (MPa,
tension positive); the spring force is ``S_i sigma_i``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True, eq=False)
class SpringSystem:
    """The reduced DEA problem as arrays.

    Attributes
    ----------
    AT : ndarray, shape (m, N)
        Strain per unit free displacement (1/mm, 1/rad), float64 C-contiguous: one row per
        dof, so every pass over the springs reads memory in order.
    e0 : ndarray, shape (N,)
        Strain at ``x = 0``.
    volume : ndarray, shape (N,)
        Spring volume ``S_i h_i`` in mm^3.
    load : ndarray, shape (m,)
        Generalized load on the free dofs (N, N mm).
    """

    AT: np.ndarray
    e0: np.ndarray
    volume: np.ndarray
    load: np.ndarray

    @property
    def A(self) -> np.ndarray:
        """``AT.T``, shape (N, m): the rows ``n_i^T B_i / h_i`` over the free dofs."""
        return self.AT.T

    @property
    def n_springs(self) -> int:
        return self.AT.shape[1]

    @property
    def n_dofs(self) -> int:
        return self.AT.shape[0]

    def strain(self, x) -> np.ndarray:
        return self.e0 + np.asarray(x, dtype=float) @ self.AT

    def with_load(self, load) -> "SpringSystem":
        return SpringSystem(self.AT, self.e0, self.volume, np.asarray(load, dtype=float))


@dataclass
class FormulationResult:
    """A formulation's raw answer, before dea_opt certifies it.

    ``stress`` is the spring stress as the formulation itself sees it (from the duals for
    the constrained formulations), so that the certificate can compare it with the law.
    """

    x: np.ndarray
    stress: np.ndarray
    success: bool
    status: str
    message: str = ""
    iterations: int = 0
    build_time: float = 0.0
    solve_time: float = 0.0
    info: dict = field(default_factory=dict)
