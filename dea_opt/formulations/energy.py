"""What every formulation receives and returns: plain arrays and a law, nothing else.

The reduced problem over the ``m`` free degrees of freedom ``x`` (``formulations/energy.md``):

    eps(x) = e0 + A x                                   (N,)
    Phi(x) = sum_i V_i w(min(eps_i, 0)) - r . x         V_i = S_i h_i

``A`` holds the rows ``n_i^T B_i / h_i`` of Eq. (11) restricted to the free dofs and ``e0``
the strain at ``x = 0`` (gap and prescribed motion). Spring stress is ``sigma_i`` (MPa,
tension positive); the spring force is ``S_i sigma_i``.

Names in the code: the page's ``x`` is ``u_free`` (the free entries of the 12-vector ``u``,
mm and rad; ``Solution.x`` too, as scipy names it), its scaled form ``xi``; ``eps`` is a
strain array, ``strain_scale`` and ``energy_scale`` the sizes of :class:`Scaling`; ``energy``
alone is a law's energy density ``w``.

Also here: the one test of "no spring resists this direction" (:func:`unresisted`,
:func:`resistance`), the guards every formulation runs before compiled code
(:func:`require_finite`, :func:`start_vector`), the answers that need no solver
(:func:`trivial_result`) and the one test of a crushed layer (:func:`crushed`).
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
from functools import cached_property, lru_cache

import numpy as np

from ..errors import InputError, SolverError
from ..status import Status


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
        basis (rotations about the layer's centroid); lets :func:`resistance` skip a singular
        value decomposition of an N x m matrix.
    stiffness : float, optional
        The layer's own stiffness scale per unit modulus, ``k = sum_i S_i / h_i`` (mm): the sum
        of every spring's stiffness along its normal, independent of which dofs are free.
        Directions are judged unresisted against it (:func:`unresisted`). Without it (a system
        built by hand) the largest stiffness among the free dofs stands in, which cannot tell
        a layer that resists none of its free dofs from one that resists them all.
    """

    AT: np.ndarray
    e0: np.ndarray
    volume: np.ndarray
    load: np.ndarray
    dof_length: np.ndarray | None = None
    factor: np.ndarray | None = None
    stiffness: float | None = None

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

    def strain_at(self, u_free) -> np.ndarray:
        """``eps = e0 + A u_free``, shape (N,), for a free-dof motion ``u_free`` (mm, rad)."""
        return self.e0 + np.asarray(u_free, dtype=float) @ self.AT

    def with_load(self, load) -> SpringSystem:
        new = SpringSystem(
            self.AT, self.e0, self.volume, np.asarray(load, dtype=float), self.dof_length, self.factor, self.stiffness
        )
        for name in ("resistance", "motion"):  # the same geometry: the same decisions
            if name in self.__dict__:
                new.__dict__[name] = self.__dict__[name]
        return new

    def recentred(self, u_free) -> SpringSystem:
        """The same springs and load with the origin of the free dofs moved to ``u_free`` (mm, rad):
        ``e0`` becomes the strains there, computed afresh from this system's (never accumulated
        step by step), so that a formulation can solve on in the scale of what is in equilibrium
        there (:func:`scaling`)."""
        new = SpringSystem(
            self.AT, self.strain_at(u_free), self.volume, self.load, self.dof_length, self.factor, self.stiffness
        )
        for name in ("resistance", "motion"):  # the same geometry: the same decisions
            if name in self.__dict__:
                new.__dict__[name] = self.__dict__[name]
        return new

    @cached_property
    def resistance(self) -> Resistance:
        """Which free-dof directions the springs resist (:func:`resistance`), computed once."""
        return resistance(self)


@dataclass
class FormulationResult:
    """A formulation's raw answer, before dea_opt certifies it.

    Attributes
    ----------
    u_free : ndarray, shape (m,)
        The motion of the free dofs (mm, rad): ``x`` of ``formulations/energy.md``.
    stress : ndarray, shape (N,)
        The spring stress as the formulation itself sees it (MPa, from the duals for the
        constrained formulations), so that the certificate can compare it with the law.
    success : bool
        The solver's own claim (the certificate decides ``Solution.success``).
    status : Status
        The solver's status in dea-opt's vocabulary; ``info["native_status"]`` keeps the
        solver's own.
    build_time : float
        Seconds spent building the model, on its first solve only (0 on re-solves).
    """

    u_free: np.ndarray
    stress: np.ndarray
    success: bool
    status: Status
    message: str = ""
    iterations: int = 0
    build_time: float = 0.0
    solve_time: float = 0.0
    info: dict = field(default_factory=dict)


@dataclass(frozen=True, eq=False)
class Scaling:
    """A change of variables that makes every formulation see a well-conditioned problem.

    ``u_free = T xi`` with ``T = T1 s`` and ``T1 = D^-1 Rk Sigma_k^-1 / sqrt(H)`` from the
    singular value decomposition of the factor ``W = U Sigma R^T`` of the bonded stiffness
    (:func:`resistance`; never an eigendecomposition of ``K0 = A^T diag(V H) A``, which would
    square its condition number), so that ``T1^T K0 T1 = I`` (``formulations/energy.md``,
    "Scaling"): directions no spring resists are dropped, the remaining ones are made
    K0-orthonormal (so units, lever arms and far reference points no longer matter), and
    ``s`` makes ``xi = O(1)`` for the larger of the reference load and the overlap. Energies
    are divided by ``E0 = s^2`` and strain variables by ``s0``.

    Attributes
    ----------
    T : ndarray, shape (m, k)
    AT : ndarray, shape (k, N)
        ``T^T A^T``: the strain per unit ``xi``.
    volume : ndarray, shape (N,)
        ``V / E0`` (mm^3 per energy unit).
    energy_scale : float
        ``E0 = s^2`` (N mm).
    strain_scale : float
        ``s0 = s / sqrt(sum_i V_i H)``: a typical strain of the reference load (for scaling
        strain variables).
    """

    T: np.ndarray
    AT: np.ndarray
    volume: np.ndarray
    energy_scale: float
    strain_scale: float

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


#: Ulps of the sizes of its terms that bound the rounding of a computed strain (a sum of a dozen
#: products and a division: 16 is the standard bound ``n eps`` of such a sum, with room): the
#: certificate's (``ContactProblem.strain_rounding``) and Newton's judge of a residual that only the
#: rounding keeps from zero (formulations/energy.md, "The certificate").
ROUNDING = 16.0


#: A direction of motion is *unresisted* when the springs' stiffness along it is at most this
#: fraction of the layer's own stiffness scale (formulations/energy.md, "Unresisted
#: directions"). It is 100 times the rounding of a Gram matrix (about 1e-16 of its largest
#: eigenvalue), and a singular value of 1e-7 of the scale: far below the stiffness of any real
#: direction (the tilt of a layer seen from a reference 1e6 layer radii away is about 1e-12).
UNRESISTED = 1e-14


def unresisted(stiffness, scale: float) -> np.ndarray:
    """The one test of "no spring resists this direction": ``stiffness <= UNRESISTED * scale``.

    Parameters
    ----------
    stiffness : array_like
        Stiffnesses along orthonormal directions: eigenvalues of a stiffness matrix, or
        squared singular values of its factor.
    scale : float
        The stiffness the directions are judged against, in the same units: the layer's own
        (:attr:`SpringSystem.stiffness` times the modulus), or the largest stiffness of the
        same matrix where that is larger (rounding in a matrix is relative to its largest
        entry, so nothing below ``UNRESISTED`` of it can be told from noise).

    Returns
    -------
    ndarray of bool
    """
    return np.asarray(stiffness, dtype=float) <= UNRESISTED * scale


def require_finite(what: str, *arrays) -> None:
    """Raise :class:`SolverError` (status :attr:`Status.NON_FINITE`) before compiled code
    (LAPACK, NNLS, Clarabel, IPOPT) meets a NaN or an infinity, which some of them answer by
    aborting the process rather than by an error."""
    for arr in arrays:
        if not np.isfinite(arr).all():
            raise SolverError(
                f"{what} holds NaN or infinite values (an input near the limits of float64?); "
                f"nothing was passed to the solver",
                status=Status.NON_FINITE,
            )


@dataclass(frozen=True, eq=False)
class Resistance:
    """Which directions of the free dofs the springs resist, decided once by :func:`unresisted`.

    Directions are measured in arc lengths: ``D x`` with ``D`` (:attr:`SpringSystem.lengths`)
    1 for a translation and the layer's radius about the reference for a rotation, and loads
    as ``r / D`` (moments over that radius), so translations and rotations compare like with
    like.

    Attributes
    ----------
    T1 : ndarray, shape (m, k)
        ``T1^T K0 T1 = I`` for the bonded stiffness ``K0 = A^T diag(V) A`` at unit modulus,
        over the ``k`` resisted directions; no part of its columns lies along ``null`` (in
        arc lengths), so ``x = T1 xi`` is the minimum-norm motion.
    null : ndarray, shape (m, m - k)
        Orthonormal basis (in arc lengths) of the unresisted directions.
    lengths : ndarray, shape (m,)
        ``D``.
    range : ndarray, shape (m, k)
        Orthonormal basis (in arc lengths) of the resisted directions.
    scale : float
        The stiffness they were judged against (:attr:`SpringSystem.stiffness`, mm).
    """

    T1: np.ndarray
    null: np.ndarray
    lengths: np.ndarray
    range: np.ndarray
    scale: float

    @property
    def n_resisted(self) -> int:
        return self.T1.shape[1]

    def basis(self, modulus: float = 1.0) -> np.ndarray:
        """``T1`` for a law of small-strain stiffness ``modulus``: ``T1^T K0 T1 = I`` with
        ``K0 = A^T diag(V modulus) A``."""
        return self.T1 / np.sqrt(modulus_scale(modulus))

    def load_part(self, r) -> np.ndarray:
        """The part of the generalized load ``r`` (N, N mm) along unresisted directions, in
        the same units: what no spring force can balance."""
        r = np.asarray(r, dtype=float)
        if not self.n_resisted:
            return r.copy()  # all of it, exactly
        D = self.lengths
        return D * (self.null @ (self.null.T @ (r / D)))

    def load_fraction(self, r) -> float:
        """``|P r / D| / |r / D|``: the fraction of the load (moments over the layer radius)
        that acts along unresisted directions; 0 for no load."""
        rD = np.asarray(r, dtype=float) / self.lengths
        top = float(np.abs(rD).max(initial=0.0))
        if top == 0.0 or not self.null.shape[1]:
            return 0.0
        rD = rD / top  # scaled first, so that neither square under- nor overflows
        return float(np.linalg.norm(self.null.T @ rD) / np.linalg.norm(rD))

    def motion_part(self, u_free) -> np.ndarray:
        """The part of the free-dof motion ``u_free`` (mm, rad) along unresisted directions."""
        D = self.lengths
        return (self.null @ (self.null.T @ (np.asarray(u_free, dtype=float) * D))) / D

    def describe(self, names) -> list[str]:
        """The unresisted directions in words: each free dof that lies wholly among them by its
        name (``"body2.rx"``), then any further direction as a combination
        (``"0.707 body2.ux + 0.707 body2.rz"``, in arc lengths)."""
        p = self.null.shape[1]
        if not p:
            return []
        whole = [j for j in range(len(names)) if float(self.null[j] @ self.null[j]) > 1.0 - 1e-9]
        out = [names[j] for j in whole]
        if len(whole) < p:
            rest = self.null.copy()
            rest[whole] = 0.0  # what is left once the whole dofs are named
            u = np.linalg.svd(rest, full_matrices=False)[0]
            for v in u[:, : p - len(whole)].T:
                v = v / v[np.argmax(np.abs(v))]
                big = np.flatnonzero(np.abs(v) >= 1e-6)
                out.append(" + ".join(f"{v[i]:.3g} {names[i]}" for i in big).replace("+ -", "- "))
        return out


def modulus_scale(modulus) -> float:
    """The law's small-strain stiffness, or 1 for a law without one (it only sets a scale)."""
    modulus = float(modulus)
    return modulus if modulus > 0 and np.isfinite(modulus) else 1.0


def resistance(system: SpringSystem) -> Resistance:
    """The :class:`Resistance` of ``system``: the one place that decides which directions the
    springs resist (``formulations/energy.md``, "Unresisted directions").

    From the singular value decomposition of ``W D^-1``, ``W^T W = K0`` (unit modulus), rather
    than an eigendecomposition of ``K0``, which would square the condition number: a reference
    point far from the layer makes the dofs nearly dependent, and the tilt of the layer must
    survive that. ``W`` is the system's small ``factor`` when it has one, else the N x m matrix
    ``diag(sqrt(V)) A``. A direction is unresisted when its squared singular value passes
    :func:`unresisted` against the layer's stiffness :attr:`SpringSystem.stiffness`, which does
    not depend on which dofs are free: when every free dof is unresisted, rounding noise is
    not mistaken for stiffness.
    """
    rows = system.factor if system.factor is not None else (system.AT * np.sqrt(system.volume)).T
    return factor_resistance(rows, system.lengths, system.stiffness)


def factor_resistance(factor, lengths, stiffness: float | None) -> Resistance:
    """The :class:`Resistance` of the bonded stiffness ``factor^T factor`` (at unit modulus) over
    dofs of ``lengths`` (:attr:`SpringSystem.lengths`), judged against ``stiffness``
    (:attr:`SpringSystem.stiffness`): :func:`resistance` for a system given by its factor alone
    (a joint's, stacked from its elements' factors: ``formulations/joint.md``)."""
    D = np.asarray(lengths, dtype=float)
    m = D.size
    k_layer = 0.0 if stiffness is None else float(stiffness)
    if not m:
        return Resistance(np.zeros((0, 0)), np.zeros((0, 0)), D, np.zeros((0, 0)), k_layer)
    W = np.asarray(factor, dtype=float) / D
    if not W.size:
        return Resistance(np.zeros((m, 0)), np.eye(m), D, np.zeros((m, 0)), k_layer)
    require_finite("the bonded stiffness of the springs", W)
    _, sigma, vt = np.linalg.svd(W, full_matrices=True)
    values = np.concatenate([sigma**2, np.zeros(m - sigma.size)])
    scale = max(k_layer, float(values.max(initial=0.0)))
    keep = ~unresisted(values, scale) if scale > 0 else np.zeros(m, dtype=bool)
    T1 = vt[keep].T / np.sqrt(values[keep]) / D[:, None]
    return Resistance(T1, vt[~keep].T, D, vt[keep].T, scale)


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
    s_load = _norm(T1.T @ r) if r.size else 0.0
    overlap = system.e0.min(initial=0.0) < 0
    s_overlap = _norm(np.sqrt(stiffness) * np.minimum(system.e0, 0.0)) if overlap else 0.0
    s = max(s_load, s_overlap)
    if not (s > 0.0 and np.isfinite(s)):
        s = 1.0
    T = T1 * s
    total = float(stiffness.sum())
    s0 = s / np.sqrt(total) if total > 0 else 1.0
    return Scaling(T=T, AT=np.ascontiguousarray(T.T @ AT), volume=V / s**2, energy_scale=s**2, strain_scale=s0)


def _norm(v) -> float:
    """Euclidean norm scaled by the largest entry first (no overflow or underflow of squares)."""
    v = np.asarray(v, dtype=float)
    top = float(np.abs(v).max(initial=0.0))
    return top * float(np.linalg.norm(v / top)) if top > 0 and np.isfinite(top) else top


def trivial_result(system: SpringSystem, law, load=None) -> FormulationResult | None:
    """The answer without a solver, or ``None`` when a solver is needed.

    * :attr:`Status.HELD`: no free direction is resisted (:class:`Resistance`), and so none can
      carry a load (:func:`dea_opt.check_load_supported` rejects one): every free dof is held at
      zero motion, the minimum-norm answer, and the springs keep the strain of the gap and the
      prescribed motion;
    * :attr:`Status.UNLOADED`: no load and no overlap: nothing moves and no spring carries
      anything.

    Each formulation asks this first, so that no compiled solver sees an empty problem.
    """
    m, n = system.n_dofs, system.n_springs
    load = system.load if load is None else np.asarray(load, dtype=float)
    if m and system.resistance.n_resisted == 0:
        with np.errstate(invalid="ignore", over="ignore"):
            stress = law.stress(np.minimum(system.e0, 0.0))
        return FormulationResult(
            u_free=np.zeros(m),
            stress=stress,
            success=True,
            status=Status.HELD,
            message="no spring resists any free dof: every free dof is held at zero motion (the minimum-norm answer)",
            info={"native_status": None},
        )
    if not load.any() and system.e0.min(initial=0.0) >= 0:
        return FormulationResult(
            u_free=np.zeros(m),
            stress=np.zeros(n),
            success=True,
            status=Status.UNLOADED,
            message="no load and no overlap: nothing to carry",
            info={"native_status": None},
        )
    return None


def failed_result(system: SpringSystem, exc: SolverError) -> FormulationResult:
    """A failed answer (NaN motion and stress) for a solver that raised ``exc``, so that
    ``auto`` can fall back and ``strict=False`` and load paths can report it like any other."""
    status = Status(exc.status) if exc.status else Status.SOLVER_ERROR
    return FormulationResult(
        u_free=np.full(system.n_dofs, np.nan),
        stress=np.full(system.n_springs, np.nan),
        success=False,
        status=status,
        message=str(exc),
        info={"native_status": exc.native_status or exc.status},
    )


#: A failed solve whose most compressed spring is within this of ``eps = -1`` ran into a
#: bounded law's crushing (formulations/energy.md, "Statuses").
CRUSH_WINDOW = 1e-4


def crushed(law, eps) -> bool:
    """Whether a failed solve ended with springs crushed through their thickness: a law
    defined only for ``eps > -1`` whose most compressed spring is within
    :data:`CRUSH_WINDOW` of -1. The one test every formulation uses for
    :attr:`Status.CRUSHED`."""
    eps = np.asarray(eps, dtype=float)
    eps = eps[np.isfinite(eps)]
    return bool(law.bounded_strain and eps.size and eps.min() < -1 + CRUSH_WINDOW)


CRUSHED_MESSAGE = (
    "springs reach eps = {eps:.6f}, crushed through their thickness before the load is carried: "
    "the load is beyond what this layer can bear"
)


def start_vector(system: SpringSystem, x0) -> np.ndarray | None:
    """``x0`` as a finite float vector of shape ``(m,)`` (one value per free dof, mm and rad),
    or ``None``; an :class:`InputError` otherwise."""
    if x0 is None:
        return None
    try:
        start = np.array(x0, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"x0 must be numeric with one value per free dof ({system.n_dofs}), got {x0!r}") from None
    if start.shape != (system.n_dofs,):
        raise InputError(f"x0 must have shape ({system.n_dofs},), one value per free dof, got shape {start.shape}")
    if not np.isfinite(start).all():
        raise InputError(f"x0 must be finite, got {start.tolist()}")
    return start


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
