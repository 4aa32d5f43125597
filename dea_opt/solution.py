"""One result type for every formulation: :class:`Solution`, the answer with the certificate dea_opt
computed for it (:mod:`dea_opt.certificate`) and its validity report (:mod:`dea_opt.validity`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import TYPE_CHECKING

import numpy as np

from .certificate import Certificate
from .kinematics import DOF_NAMES
from .status import Status
from .validity import Validity, assess

if TYPE_CHECKING:
    from .problem import ContactProblem

__all__ = ["Solution"]


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
        """The optimized variables, as ``scipy.optimize.OptimizeResult.x``: ``u`` at the free dofs,
        shape (m,), mm and rad, in the order of ``problem.free_names`` (what ``x0`` takes)."""
        return self.u[self.problem.free_indices]

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
        return self.info.get("failure") or f"status '{self.status}': {self.status.description}"

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
        from .formulations.finite.rotations import pose_matrix

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
