"""One result type for every formulation, carrying the certificate dea_opt computes itself.

The certificate (:func:`certify`) is a check a reader can redo with the problem's arrays and
``u``; ``formulations/energy.md`` ("The certificate") and the user guide's concepts page state
the same definitions. With ``f_i = S_i sigma(min(eps_i, 0))`` the law's spring forces at ``u`` (N,
tension positive), ``f^rep_i`` the forces the formulation reported, ``q = G_free^T f`` the
generalized spring force on the free dofs and ``r`` the load there (N; N mm for rotations),
``L_j`` 1 for a translation and the layer's radius about the body's reference for a
rotation (mm), and ``H`` the law's small-strain modulus, every force residual is relative
to one force scale::

    F = max( max_j |r_j| / L_j,  sum_i |f_i|,  H sum_i S_i max(-e0_i, 0) )

(the load, the springs' total force, and the force of the initial overlap of gaps and
prescribed motion), none of which is rounding noise when the others vanish. A residual whose
numerator is exactly 0 is 0 (also when ``F = 0``).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from .formulations.energy import (
    modulus_scale,
    require_finite,
    single_threaded_blas,
    unresisted,
)
from .kinematics import DOF_NAMES
from .status import Status
from .validity import Validity, assess

if TYPE_CHECKING:
    from .problem import ContactProblem

__all__ = ["Certificate", "Solution", "certify"]


@dataclass(frozen=True)
class Certificate:
    """Residuals computed by dea_opt from ``u``, never taken from a solver.

    Notation as in the module docstring (``F`` the force scale, ``L_j`` the dof lengths).

    Attributes
    ----------
    equilibrium : float
        The largest of three parts. (1) Per free dof: ``max_j |q_j - r_j| / L_j / F``.
        (2) The fraction of the load that acts along directions no spring resists
        (:class:`~dea_opt.formulations.energy.Resistance`): ``|P r / L| / |r / L|`` with
        ``P`` the orthogonal projector onto those directions (in arc lengths), so a load no
        spring can carry counts in full whatever its size. (3) The spring forces that the
        answer's motion along those directions produces (motion no spring resists changes no
        strain except through rounding): ``sum_i |f_i - f'_i| / F`` with ``f'`` the forces
        with that motion removed.
    tension : float
        ``sum_i max(f^rep_i, 0) / F``: tensile force the formulation reported.
    complementarity : float
        ``sum_i |f^rep_i| max(eps_i, 0) / F``: open springs carry nothing.
    consistency : float
        ``sum_i`` of how far ``f^rep_i`` lies outside ``S_i [sigma(eps_i - d), sigma(eps_i + d)]``
        (strains clipped at 0), over ``F``, with ``d = tolerance * max(max_i -min(eps_i, 0),
        max_i -min(e0_i, 0))``: the formulation's forces are what the law gives at a strain
        within the certified precision of the compression.
    energy : float
        Energy a further Newton step could still release, ``g^T K^+ g / 2`` with ``g = q - r``
        and ``K`` the tangent of the compressed springs, over the resisted directions (its
        pseudo-inverse drops what :func:`~dea_opt.formulations.energy.unresisted` calls no
        stiffness), relative to ``max(stored energy + |r . x|, H sum_i V_i min(e0_i, 0)^2 / 2)``.
    tolerance : float
        The bound every residual must meet.
    """

    equilibrium: float
    tension: float
    complementarity: float
    consistency: float
    energy: float
    tolerance: float = 1e-6

    @property
    def passed(self) -> bool:
        values = (self.equilibrium, self.tension, self.complementarity, self.consistency, self.energy)
        return all(np.isfinite(v) and v <= self.tolerance for v in values)

    def worst(self) -> tuple[str, float]:
        """The name and value of the largest residual."""
        items = self.as_dict()
        items.pop("tolerance")
        items.pop("passed")
        name = max(items, key=lambda k: items[k] if np.isfinite(items[k]) else np.inf)
        return name, items[name]

    def as_dict(self) -> dict:
        return {
            "equilibrium": self.equilibrium,
            "tension": self.tension,
            "complementarity": self.complementarity,
            "consistency": self.consistency,
            "energy": self.energy,
            "tolerance": self.tolerance,
            "passed": self.passed,
        }


def _ratio(numerator: float, scale: float) -> float:
    """``numerator / scale``, 0 when the numerator is exactly 0 (nothing to measure)."""
    if numerator == 0.0:
        return 0.0
    return numerator / scale if scale > 0 else float("inf")


def certify(problem, u, reported_stress, tolerance: float = 1e-6) -> Certificate:
    """Check ``u`` against the law: equilibrium, sign, complementarity, optimality.

    Every residual is defined in :class:`Certificate`; they use dea_opt's own arrays and
    ``u``, nothing the solver computed except ``reported_stress``.

    Parameters
    ----------
    problem : ContactProblem
    u : ndarray, shape (12,)
    reported_stress : ndarray, shape (N,)
        Spring stress as the formulation reported it (MPa, tension positive).
    tolerance : float
    """
    with single_threaded_blas():
        return _certify(problem, u, reported_stress, tolerance)


def _certify(problem, u, reported_stress, tolerance: float) -> Certificate:
    layer, law = problem.layer, problem.law
    system = problem.system()
    res = system.resistance
    free = problem.free_indices
    u_free = np.asarray(u, dtype=float)[free]
    eps = problem.strain(u)
    compressed = np.minimum(eps, 0.0)
    with np.errstate(invalid="ignore", over="ignore"):
        sigma = law.stress(compressed)
        force = layer.areas * sigma
        reported = layer.areas * np.asarray(reported_stress, dtype=float)
        # A^T (V sigma) = G_free^T (S sigma): the generalized spring force on the free dofs.
        q = system.AT @ (system.volume * sigma)
    if not (np.isfinite(sigma).all() and np.isfinite(reported).all() and np.isfinite(q).all()):
        nan = float("nan")
        return Certificate(nan, nan, nan, nan, nan, tolerance)
    r, L = system.load, system.lengths
    H = modulus_scale(law.modulus)
    # The initial overlap (gaps and prescribed motion): usually none, and then no pass over it.
    overlap = np.maximum(-system.e0, 0.0) if system.e0.min(initial=0.0) < 0 else None
    preload = 0.0 if overlap is None else H * float(layer.areas @ overlap)
    F = max(float(np.abs(r / L).max(initial=0.0)), float(np.abs(force).sum()), preload)
    g = q - r
    equilibrium = _ratio(float(np.abs(g / L).max(initial=0.0)), F)
    if res.null.shape[1]:
        equilibrium = max(equilibrium, res.load_fraction(r))
        z = res.motion_part(u_free)
        if z.any():
            with np.errstate(invalid="ignore", over="ignore"):
                held = layer.areas * law.stress(np.minimum(eps - z @ system.AT, 0.0))
            equilibrium = max(equilibrium, _ratio(float(np.nan_to_num(np.abs(force - held), nan=np.inf).sum()), F))
    tension = _ratio(float(np.maximum(reported, 0.0).sum()), F)
    complementarity = _ratio(float(np.abs(reported) @ np.maximum(eps, 0.0)), F)
    # A reported force is consistent when the law gives it at a strain within the certified
    # precision of the compression: springs on the edge of the contact, where interior-point
    # duals are of order sqrt(mu), are judged on what the strain allows.
    delta = tolerance * max(float(-compressed.min(initial=0.0)), float(-system.e0.min(initial=0.0)))
    with np.errstate(invalid="ignore", over="ignore"):
        low = layer.areas * law.stress(np.minimum(eps - delta, 0.0))
        high = layer.areas * law.stress(np.minimum(eps + delta, 0.0))
    excess = np.maximum(low - reported, 0.0) + np.maximum(reported - high, 0.0)
    consistency = _ratio(float(np.nan_to_num(excess, nan=np.inf).sum()), F)
    decrement = _energy_residual(system, res, law, eps, g, u_free, H, overlap) if free.size else 0.0
    return Certificate(equilibrium, tension, complementarity, consistency, decrement, tolerance)


def _energy_residual(system, res, law, eps, g, u_free, H, overlap) -> float:
    """``g^T K^+ g / 2`` over the resisted directions, relative to the energy scale."""
    rows = np.flatnonzero(eps < 0)
    if not rows.size or not res.n_resisted:
        return 0.0
    compressed = eps[rows]
    with np.errstate(invalid="ignore", over="ignore"):
        weight = system.volume[rows] * law.tangent(compressed)
        stored = float(system.volume[rows] @ law.energy(compressed))
    AT = system.AT[:, rows]
    K = (AT * weight) @ AT.T
    if not (np.isfinite(K).all() and np.isfinite(stored)):
        return float("nan")
    # In the resisted basis (T1^T K0 T1 = I at the law's modulus) the bonded layer's
    # stiffness is the identity: the scale the one test of "unresisted" judges against.
    T1 = res.basis(H)
    Kt = T1.T @ K @ T1
    gt = T1.T @ g
    require_finite("the certificate's tangent", Kt, gt)
    vals, vecs = np.linalg.eigh(Kt)
    keep = ~unresisted(vals, max(float(vals[-1]), 1.0))
    coeff = vecs[:, keep].T @ gt
    decrement = float(coeff @ (coeff / vals[keep]))
    preload = 0.0 if overlap is None else 0.5 * H * float(system.volume @ overlap**2)
    scale = max(stored + abs(float(system.load @ u_free)), preload)
    return _ratio(0.5 * abs(decrement), scale)


@dataclass(frozen=True, eq=False)
class Solution:
    """The equilibrium of a :class:`~dea_opt.problem.ContactProblem`, from any formulation.

    Spring quantities have shape (N,), in the layer's spring order. ``stress`` and
    ``spring_force`` are tension positive (so ``<= 0``); ``pressure = -stress >= 0``.
    ``certificate`` says the answer solves the equations; ``validity`` says whether the
    equations still describe cartilage there (:mod:`dea_opt.validity`,
    ``formulations/validity.md``). ``status`` is a
    :class:`~dea_opt.status.Status` (a ``str``: ``"converged"``, ``"unloaded"``, ...), the
    solver's own in ``info["native_status"]``.

    ``u`` is the 12-vector of Eq. (7) (mm, rad); ``x`` is its scipy-like alias (not the
    free-dof vector ``x`` of ``formulations/energy.md``, which is ``u[problem.free_indices]``).
    """

    problem: ContactProblem
    u: np.ndarray
    strain: np.ndarray
    pressure: np.ndarray
    method: str
    success: bool
    status: Status
    message: str
    iterations: int
    build_time: float
    solve_time: float
    certificate: Certificate
    info: dict = field(default_factory=dict)
    #: A validity report evaluated beyond the defaults (:meth:`with_validity`); None: the default.
    assessed_validity: Validity | None = field(default=None, repr=False)

    # scipy.optimize names
    @property
    def x(self) -> np.ndarray:
        """Alias of ``u`` (the 12-vector of Eq. 7), as in ``scipy.optimize.OptimizeResult``."""
        return self.u

    @property
    def nit(self) -> int:
        return self.iterations

    @property
    def failure(self) -> str:
        """Why this answer is not a success, in one clause ("" when it is): its certificate's worst
        residual when the certificate failed, else what the solve said (``info["failure"]``: a
        finite-kinematics answer whose springs were not confirmed at its pose, or a crushed layer)."""
        if self.success:
            return ""
        if not self.certificate.passed:
            name, value = self.certificate.worst()
            return f"certificate residual {name} = {value:.3g} > {self.certificate.tolerance:g}"
        return self.info.get("failure") or f"status {self.status!r}: {self.status.description}"

    @property
    def body1_displacement(self) -> np.ndarray:
        """``(ux, uy, uz, rx, ry, rz)`` of body 1 (mm, rad)."""
        return self.u[:6]

    @property
    def body2_displacement(self) -> np.ndarray:
        return self.u[6:]

    @property
    def pose(self) -> np.ndarray:
        """Body 2's 4x4 pose relative to body 1 that ``u`` implies: each body's rotation vector taken as
        an exact rotation about its reference, ``T1^-1 T2`` (for ``kinematics="small"`` the rigid
        motion with the linearised motion's rotation vector and translation; for ``"finite"`` the
        solved pose itself, composed with the pose the targets were cast at)."""
        from .formulations._parts.finite_geometry import pose_matrix

        c1, c2 = self.problem.body1.reference, self.problem.body2.reference
        return np.linalg.inv(pose_matrix(self.u[:6], c1)) @ pose_matrix(self.u[6:], c2)

    @property
    def in_contact(self) -> np.ndarray:
        return self.strain < 0

    @property
    def stress(self) -> np.ndarray:
        return -self.pressure

    @property
    def spring_force(self) -> np.ndarray:
        """``S_i sigma_i`` in N (tension positive, so <= 0)."""
        return -self.pressure * self.problem.layer.areas

    @property
    def _normal_forces(self) -> np.ndarray:
        return (self.pressure * self.problem.layer.areas)[:, None] * self.problem.layer.normals

    @property
    def contact_force(self) -> np.ndarray:
        """Resultant force the springs exert on body 2 (N); minus its load at equilibrium."""
        return self._normal_forces.sum(axis=0)

    @property
    def contact_moment(self) -> np.ndarray:
        """Resultant moment the springs exert on body 2 about :attr:`moment_point` (N mm)."""
        arm = self.problem.layer.points - self.moment_point
        return np.cross(arm, self._normal_forces).sum(axis=0)

    @property
    def moment_point(self) -> np.ndarray:
        """The point :attr:`contact_moment` is taken about (mm, body 1's frame): body 2's reference
        (for finite kinematics, where the motion took it: ``reference + u[6:9]``)."""
        return np.asarray(self.problem.body2.reference, dtype=float)

    @property
    def peak_pressure(self) -> float:
        """Largest pressure (MPa)."""
        return float(self.pressure.max(initial=0.0))

    @property
    def contact_area(self) -> float:
        """Area of the springs in contact (mm^2)."""
        return float(self.problem.layer.areas[self.in_contact].sum())

    @property
    def mean_pressure(self) -> float:
        """Area-weighted mean pressure over the contact (MPa); 0 without contact."""
        area = self.contact_area
        return float(np.sum(self.pressure * self.problem.layer.areas) / area) if area > 0 else 0.0

    @property
    def total_normal_force(self) -> float:
        """Sum of the spring force magnitudes (N)."""
        return float(np.sum(self.pressure * self.problem.layer.areas))

    @property
    def center_of_pressure(self) -> np.ndarray:
        """Pressure-weighted centroid of the contact (mm); NaN without contact."""
        weight = self.pressure * self.problem.layer.areas
        total = weight.sum()
        if total <= 0:
            return np.full(3, np.nan)
        return weight @ self.problem.layer.points / total

    @property
    def max_compressive_strain(self) -> float:
        """``-min(eps)`` over the springs in contact (0 without contact)."""
        return float(max(-self.strain.min(initial=0.0), 0.0))

    @cached_property
    def validity(self) -> Validity:
        """The :class:`~dea_opt.validity.Validity` report of this answer: the one given to
        :meth:`with_validity`, else the default limits with ``dropped_springs`` not evaluated.

        For other limits, or a count of springs dropped at the solved pose, use
        :meth:`with_validity`, or call :func:`dea_opt.validity.assess` ``(solution.problem,
        solution.u, solution.strain, solution.pressure, limits=..., dropped=...)``.
        """
        validity = self.assessed_validity
        if validity is None:
            validity = assess(self.problem, self.u, self.strain, self.pressure, **self._counts())
        return _ran_away(validity) if self.status == Status.UNBOUNDED else validity

    def _counts(self) -> dict:
        """The counts of springs this answer knows for :func:`~dea_opt.validity.assess` (none; a
        finite-kinematics answer knows what its updates dropped and lost)."""
        return {}

    def with_validity(self, validity: Validity | None = None, *, dropped: int | None = None, limits=None) -> Solution:
        """A copy of this solution whose :attr:`validity` is ``validity``, or is assessed with
        ``dropped`` and ``limits`` (this solution is frozen and stays as it is).

        Parameters
        ----------
        validity : Validity, optional
            A report of this answer (from :func:`dea_opt.validity.assess`).
        dropped : int, optional
            Springs the proximity window drops at the solved pose, e.g.
            ``dea_opt.mesh.recast_at_solution(solution, cast).dropped``: evaluates the
            ``dropped_springs`` check (a finite-kinematics answer counts its own: this replaces it).
        limits : ValidityLimits, optional
            Default :data:`dea_opt.validity.DEFAULT_LIMITS`.

        Returns
        -------
        Solution
            Everything else shared with this one (``info`` copied).
        """
        from .errors import InputError
        from .validity import DEFAULT_LIMITS

        if validity is not None:
            if not isinstance(validity, Validity):
                raise InputError(f"validity must be a dea_opt.validity.Validity, got {type(validity).__name__}")
            if dropped is not None or limits is not None:
                raise InputError("give validity, or dropped and limits to assess it, not both")
        else:
            counts = self._counts()
            if dropped is not None:
                counts["dropped"] = dropped
            validity = assess(
                self.problem,
                self.u,
                self.strain,
                self.pressure,
                limits=DEFAULT_LIMITS if limits is None else limits,
                **counts,
            )
        return replace(self, info=dict(self.info), assessed_validity=validity)

    @property
    def reactions(self) -> dict:
        """Generalized force the supports apply at every dof that is not free (N, N mm)."""
        layer = self.problem.layer
        q = self.problem.normal_operator.T @ (-self.pressure * layer.areas)
        reaction = q - self.problem.load_vector
        held = np.setdiff1d(np.arange(12), self.problem.free_indices)
        return {DOF_NAMES[i]: float(reaction[i]) for i in held}

    def summary(self) -> dict:
        """The headline numbers as plain Python values (for tables and JSON), each name ending with
        its unit (:mod:`dea_opt.units`): ``peak_pressure_MPa``, ``contact_area_mm2``, ...; ``u`` the
        motion of every dof (``body2_uz_mm``, ``body2_rx_rad``), ``reactions`` the generalized force
        of every held dof (``body1_ux_N``, ``body1_rx_Nmm``)."""
        from .units import dof_name

        return {
            "method": self.method,
            "success": self.success,
            "status": self.status,
            "law": self.problem.law.describe(),
            "n_springs": len(self.pressure),
            "peak_pressure_MPa": self.peak_pressure,
            "mean_pressure_MPa": self.mean_pressure,
            "contact_area_mm2": self.contact_area,
            "center_of_pressure_mm": self.center_of_pressure.tolist(),
            "contact_force_N": self.contact_force.tolist(),
            "contact_moment_Nmm": self.contact_moment.tolist(),
            "max_compressive_strain": self.max_compressive_strain,
            "u": {dof_name(name): float(value) for name, value in zip(DOF_NAMES, self.u)},
            "iterations": self.iterations,
            "build_time_s": self.build_time,
            "solve_time_s": self.solve_time,
            "certificate": self.certificate.as_dict(),
            "validity": self.validity.as_dict(),
            "reactions": {dof_name(name, "force"): value for name, value in self.reactions.items()},
        }

    def __repr__(self) -> str:
        return (
            f"Solution(method={self.method!r}, success={self.success}, peak={self.peak_pressure:.6g} MPa, "
            f"area={self.contact_area:.6g} mm^2, nit={self.iterations}, valid={self.validity.valid})"
        )

    # --- output files (dea_opt.io) ----------------------------------------------------
    def to_vtk(self, path, **kw):
        """Write the contact surface with cell data (``.vtu``/``.vtp``); see :func:`dea_opt.io.to_vtk`."""
        from .io import to_vtk

        return to_vtk(self, path, **kw)

    def to_csv(self, path):
        """Write one row per spring; see :func:`dea_opt.io.to_csv` for the columns."""
        from .io import to_csv

        return to_csv(self, path)

    def to_json(self, path, **kw):
        """Write the summary as JSON; see :func:`dea_opt.io.to_json`."""
        from .io import to_json

        return to_json(self, path, **kw)

    def plot_pressure(self, path, **kw):
        """Draw a pressure map to a PNG; see :func:`dea_opt.io.plot_pressure`."""
        from .io import plot_pressure

        return plot_pressure(self, path, **kw)

    def regions(self, labels=None, planes=None):
        """Statistics per region; see :func:`dea_opt.anatomy.regions.regional_statistics`."""
        from .anatomy.regions import regional_statistics

        return regional_statistics(self, labels=labels, planes=planes)


#: The checks that measure the answer itself (not the layer's sizes).
_OF_THE_ANSWER = ("strain", "rotation", "gap_error", "peak_pressure", "dropped_springs", "lost_through_layer")


def _ran_away(validity: Validity) -> Validity:
    """``validity`` of an answer whose iterates ran away (``Status.UNBOUNDED``): the failed checks of
    the answer say that it is no equilibrium, not what a failure would mean at one (a crushed
    layer, a load in the wrong unit)."""
    why = (
        "the answer is where the solver's iterates ran away (status 'unbounded'), no equilibrium: its strains, "
        "pressures and motion mean nothing (the message says which load no spring resists)"
    )
    checks = tuple(
        replace(c, advice=why) if c.passed is False and c.name in _OF_THE_ANSWER else c for c in validity.checks
    )
    return replace(validity, checks=checks)
