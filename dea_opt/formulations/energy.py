"""What every formulation receives and returns: plain arrays and a law, nothing else.

The reduced problem over the ``m`` free degrees of freedom ``x`` (``formulations/energy.md``):

    eps(x) = e0 + A x                                   (N,)
    Phi(x) = sum_i V_i w(min(eps_i, 0)) - r . x         V_i = S_i h_i

``A`` holds the rows ``n_i^T B_i / h_i`` of Eq. (11) restricted to the free dofs and ``e0``
the strain at ``x = 0`` (gap and prescribed motion). Spring stress is ``sigma_i`` (MPa,
tension positive); the spring force is ``S_i sigma_i``.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
from functools import lru_cache

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
    dof_length : ndarray, shape (m,), optional
        See :attr:`lengths`.
    factor : ndarray, shape (r, m), optional
        ``F`` with ``F^T F = A^T diag(V) A``, computed from the geometry in a well-conditioned
        basis (rotations about the layer's centroid); lets :func:`bonded_basis` skip a QR
        factorization of an N x m matrix.
    """

    AT: np.ndarray
    e0: np.ndarray
    volume: np.ndarray
    load: np.ndarray
    dof_length: np.ndarray | None = None
    factor: np.ndarray | None = None

    @property
    def lengths(self) -> np.ndarray:
        """Per-dof length (mm) that makes the dofs commensurate: 1 for a translation, the
        layer's radius about the reference for a rotation (``dof_length``, default ones)."""
        return np.ones(self.AT.shape[0]) if self.dof_length is None else self.dof_length

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
        return SpringSystem(self.AT, self.e0, self.volume, np.asarray(load, dtype=float), self.dof_length,
                            self.factor)


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


#: Ratio of a direction's stiffness "singular value" to the largest below which no spring
#: resists it (rounding noise in the spring directions is about 1e-15).
UNRESISTED = 1e-10


@dataclass(frozen=True, eq=False)
class Scaling:
    """A change of variables that makes every formulation see a well-conditioned problem.

    ``x = T xi`` with ``T = Q Lambda^(-1/2) s`` from the bonded stiffness
    ``K0 = A^T diag(V H) A = Q Lambda Q^T`` (``formulations/energy.md``, "Scaling"):
    directions no spring resists are dropped, the remaining ones are made K0-orthonormal
    (so units, lever arms and far reference points no longer matter), and ``s`` makes
    ``xi = O(1)`` for the reference load. Energies are divided by ``E0 = s^2`` and strains
    are of order ``strain``.

    Attributes
    ----------
    T : ndarray, shape (m, k)
    AT : ndarray, shape (k, N)
        ``T^T A^T``: the strain per unit ``xi``.
    volume : ndarray, shape (N,)
        ``V / E0``.
    energy : float
        ``E0``.
    strain : float
        A typical strain magnitude of the reference load (for scaling strain variables).
    """

    T: np.ndarray
    AT: np.ndarray
    volume: np.ndarray
    energy: float
    strain: float

    @property
    def n_dofs(self) -> int:
        return self.T.shape[1]

    def load(self, r) -> np.ndarray:
        """The scaled load ``T^T r / E0`` for a load ``r`` on the free dofs."""
        return self.T.T @ np.asarray(r, dtype=float) / self.energy

    def to_x(self, xi) -> np.ndarray:
        return self.T @ np.asarray(xi, dtype=float)

    def to_xi(self, x) -> np.ndarray:
        """Least-squares ``xi`` for a free-dof vector ``x`` (its resisted part)."""
        return np.linalg.lstsq(self.T, np.asarray(x, dtype=float), rcond=None)[0]

    def system(self, e0, load) -> SpringSystem:
        """The scaled system, for a formulation that knows nothing of the scaling."""
        return SpringSystem(self.AT, e0, self.volume, self.load(load))


def bonded_basis(system: SpringSystem, modulus: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """``(T1, null)``: ``T1`` (m, k) with ``T1^T K0 T1 = I`` over the resisted directions of
    ``K0 = A^T diag(V modulus) A``, and an orthonormal basis ``null`` (m, m - k) of the rest.

    From the singular value decomposition of ``W D^-1``, ``W^T W = K0``, rather than an
    eigendecomposition of ``K0``, which would square the condition number: a reference point
    far from the layer makes the dofs nearly dependent, and the tilt of the layer must survive
    that. ``W`` is the system's small ``factor`` when it has one, else the N x m matrix
    ``diag(sqrt(V modulus)) A``. ``D`` (``lengths``) measures rotations as arc lengths, so that
    the test for "no spring resists this direction" compares like with like, and ``T1`` has
    no part along ``null`` (in those units), so that ``x = T1 xi`` is the minimum-norm motion,
    the same whichever way the problem is turned.
    """
    m = system.n_dofs
    if not m:
        return np.zeros((0, 0)), np.zeros((0, 0))
    D = system.lengths
    modulus = modulus if modulus > 0 and np.isfinite(modulus) else 1.0
    if system.factor is not None:
        W = np.sqrt(modulus) * system.factor / D
    else:
        W = (system.AT * np.sqrt(system.volume * modulus)).T / D
    if not W.size:
        return np.zeros((m, 0)), np.linalg.qr(np.diag(1.0 / D))[0]
    _, sigma, vt = np.linalg.svd(W, full_matrices=True)
    sigma = np.concatenate([sigma, np.zeros(m - sigma.size)])
    keep = sigma > UNRESISTED * max(sigma[0], 0.0) if sigma[0] > 0 else np.zeros(m, dtype=bool)
    T1 = vt[keep].T / sigma[keep] / D[:, None]
    null = vt[~keep].T
    if null.shape[1]:
        null = np.linalg.qr(null / D[:, None])[0]
    return T1, null


def scaling(system: SpringSystem, modulus: float, reference_load=None) -> Scaling:
    """The :class:`Scaling` of ``system`` for a law of small-strain stiffness ``modulus``."""
    AT, V = system.AT, system.volume
    stiffness = V * (modulus if modulus > 0 and np.isfinite(modulus) else 1.0)
    T1, _ = bonded_basis(system, modulus)
    r = system.load if reference_load is None else np.asarray(reference_load, dtype=float)
    s = float(np.linalg.norm(T1.T @ r)) if r.size else 0.0
    if s == 0.0:
        # No load: the overlap the springs must push out sets the scale.
        s = float(np.sqrt(stiffness @ np.minimum(system.e0, 0.0) ** 2))
    if s == 0.0:
        s = 1.0
    T = T1 * s
    total = float(stiffness.sum())
    strain = s / np.sqrt(total) if total > 0 else 1.0
    return Scaling(T=T, AT=np.ascontiguousarray(T.T @ AT), volume=V / s**2, energy=s**2, strain=strain)


@lru_cache(maxsize=1)
def _blas_controller():
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:  # pragma: no cover - threadpoolctl is a dependency
        return None
    return ThreadpoolController()


def single_threaded_blas():
    """A context in which BLAS runs on one thread.

    The passes over the springs are matrix-vector products bound by memory bandwidth: a second
    BLAS thread does not make them faster, and its start-up costs more than the product itself
    at 1e4 springs (a 101-frame load path ran 4x faster on one thread).
    """
    controller = _blas_controller()
    if controller is None:
        return contextlib.nullcontext()
    return controller.limit(limits=1, user_api="blas")
