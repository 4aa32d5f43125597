"""What every formulation receives and returns: plain arrays and a law, nothing else.

The reduced problem over the ``m`` free degrees of freedom ``x`` (``formulations/energy.md``):

    eps(x) = e0 + A x                                   (N,)
    Phi(x) = sum_i V_i w(min(eps_i, 0)) - r . x         V_i = S_i h_i

``A`` holds the rows ``n_i^T B_i / h_i`` of Eq. (11) restricted to the free dofs and ``e0``
the strain at ``x = 0`` (gap and prescribed motion). Spring stress is ``sigma_i`` (MPa,
tension positive); the spring force is ``S_i sigma_i``.

Names in the code: the page's ``x`` is ``u_free`` (the free entries of the 12-vector ``u``,
mm and rad; ``Solution.x`` too, as scipy names it), its scaled form ``xi``; ``eps`` is a
strain array; ``energy`` alone is a law's energy density ``w``.

Here: the system (:class:`SpringSystem`) and the raw answer (:class:`FormulationResult`), the
rounding bound of a computed strain (:data:`ROUNDING`), the check of a start (:func:`start_vector`)
and the answers that need no solver (:func:`trivial_result`, and :func:`failed_result` for a solver
that raised). Beside it: which directions the springs resist and the guard before compiled code
(:mod:`~dea_opt.formulations._parts.resistance`), the variables the
formulations solve in (:mod:`~dea_opt.formulations._parts.scaling`), the one test of a crushed layer
(:mod:`~dea_opt.formulations._parts.crush`) and BLAS on one thread (``dea_opt._checks.threads``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from ...errors import InputError, SolverError
from ...status import Status
from .resistance import Resistance, resistance

__all__ = [
    "ROUNDING",
    "FormulationResult",
    "SpringSystem",
    "failed_result",
    "start_vector",
    "trivial_result",
]


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
        basis (rotations about the layer's centroid); lets :func:`~dea_opt.formulations._parts.resistance.resistance` skip a singular
        value decomposition of an N x m matrix.
    stiffness : float, optional
        The layer's own stiffness scale per unit modulus, ``k = sum_i S_i / h_i`` (mm): the sum
        of every spring's stiffness along its normal, independent of which dofs are free.
        Directions are judged unresisted against it (:func:`~dea_opt.formulations._parts.resistance.unresisted`). Without it (a system
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
        there (:func:`~dea_opt.formulations._parts.scaling.scaling`)."""
        new = SpringSystem(
            self.AT, self.strain_at(u_free), self.volume, self.load, self.dof_length, self.factor, self.stiffness
        )
        for name in ("resistance", "motion"):  # the same geometry: the same decisions
            if name in self.__dict__:
                new.__dict__[name] = self.__dict__[name]
        return new

    @cached_property
    def resistance(self) -> Resistance:
        """Which free-dof directions the springs resist (:func:`~dea_opt.formulations._parts.resistance.resistance`), computed once."""
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


#: Ulps of the sizes of its terms that bound the rounding of a computed strain (a sum of a dozen
#: products and a division: 16 is the standard bound ``n eps`` of such a sum, with room): the
#: certificate's (``ContactProblem.strain_rounding``) and Newton's judge of a residual that only the
#: rounding keeps from zero (formulations/energy.md, "The certificate").
ROUNDING = 16.0


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


def trivial_result(system: SpringSystem, law, load=None) -> FormulationResult | None:
    """The answer without a solver, or ``None`` when a solver is needed.

    * :attr:`Status.HELD`: no free direction is resisted (:class:`~dea_opt.formulations._parts.resistance.Resistance`), and so none can
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
