"""One result type for every formulation, carrying the certificate dea_opt computes itself."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .formulations.energy import bonded_basis, single_threaded_blas
from .kinematics import DOF_NAMES
from .validity import Validity, assess

__all__ = ["Certificate", "Solution", "certify"]


@dataclass(frozen=True)
class Certificate:
    """Residuals computed by dea_opt from ``u``, never taken from a solver.

    Attributes
    ----------
    equilibrium : float
        The residual ``g = q - r`` over the free dofs (``q`` the generalized force of the
        law's spring forces at ``u``), the larger of two measures: in the norm of the bonded
        stiffness ``K0``, ``sqrt(g K0^+ g / r K0^+ r)`` (free of units and of where the
        reference points are), and per dof relative to ``max(|r|, sum |f_i|)`` with moments
        divided by the layer's radius. Any load along a direction no spring resists counts
        in full.
    tension : float
        Tensile spring force the formulation reported, as a fraction of the total force.
    complementarity : float
        ``sum_i |f_i| max(eps_i, 0)`` over the total force: open springs carry nothing.
    consistency : float
        The formulation's own spring forces (the duals, for the constrained formulations)
        against the law's: ``sum_i`` of how far ``f_i^rep`` lies outside the forces the law
        gives for strains within ``tolerance * max |eps|`` of ``eps_i``, over the total force.
    energy : float
        Energy a further Newton step could still release, ``g^T K^+ g / 2``, relative to
        the strain energy plus the work of the load.
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


def _stiffness_norm_ratio(system, modulus, g, q) -> float:
    """``sqrt(g K0^+ g / max(r K0^+ r, q K0^+ q))`` plus the part of ``g`` nothing resists."""
    T1, null = bonded_basis(system, modulus)
    r = system.load

    def norm(v):
        return float(np.linalg.norm(T1.T @ v))

    scale = max(norm(r), norm(q), 1e-300)
    rnorm = max(np.linalg.norm(r), np.linalg.norm(q), 1e-300)
    return max(norm(g) / scale, float(np.linalg.norm(null.T @ g) / rnorm))


def certify(problem, u, reported_stress, tolerance: float = 1e-6) -> Certificate:
    """Check ``u`` against the law: equilibrium, sign, complementarity, optimality.

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
    free = problem.free_indices
    x = np.asarray(u, dtype=float)[free]
    eps = problem.strain(u)
    compressed = np.minimum(eps, 0.0)
    with np.errstate(invalid="ignore", over="ignore"):
        sigma = law.stress(compressed)
        force = layer.areas * sigma
        reported = layer.areas * np.asarray(reported_stress, dtype=float)
        # A^T (V sigma) = G_free^T (S sigma): the generalized spring force on the free dofs.
        q = system.AT @ (system.volume * sigma)
    g = q - system.load
    if not (np.isfinite(sigma).all() and np.isfinite(reported).all()):
        nan = float("nan")
        return Certificate(nan, nan, nan, nan, nan, tolerance)
    # Forces below a strain of 1e-12 everywhere are rounding noise, not a scale.
    floor = 1e-12 * float(layer.areas.sum()) * (law.modulus if law.modulus > 0 else 1.0)
    total = max(np.abs(force).sum(), np.abs(reported).sum(), floor, 1e-300)
    tension = float(np.maximum(reported, 0.0).sum() / total)
    complementarity = float(np.abs(reported) @ np.maximum(eps, 0.0) / total)
    # A reported force is consistent when the law gives it at a strain within the certified
    # precision (tolerance x the largest strain): springs on the edge of the contact, where
    # interior-point duals are of order sqrt(mu), are judged on what the strain allows.
    delta = tolerance * max(float(np.abs(eps).max(initial=0.0)), 1e-300)
    with np.errstate(invalid="ignore", over="ignore"):
        low = layer.areas * law.stress(np.minimum(eps - delta, 0.0))
        high = layer.areas * law.stress(np.minimum(eps + delta, 0.0))
    excess = np.maximum(low - reported, 0.0) + np.maximum(reported - high, 0.0)
    consistency = float(np.nan_to_num(excess, nan=np.inf).sum() / total)
    equilibrium = energy = 0.0
    if free.size:
        length = np.repeat(problem.layer_radius, 6)[free]
        length[free % 6 < 3] = 1.0
        per_dof = np.linalg.norm(g / length) / max(np.linalg.norm(system.load / length), np.abs(force).sum(), 1e-300)
        equilibrium = max(float(per_dof), _stiffness_norm_ratio(system, law.modulus, g, q))
        rows = np.flatnonzero(eps < 0)
        if rows.size:
            with np.errstate(invalid="ignore", over="ignore"):
                weight = system.volume[rows] * law.tangent(compressed[rows])
                stored = float(system.volume[rows] @ law.energy(compressed[rows]))
            AT = system.AT[:, rows]
            K = (AT * weight) @ AT.T
            if np.isfinite(K).all():
                decrement = float(g @ np.linalg.lstsq(K, g, rcond=1e-12)[0])
                energy = 0.5 * abs(decrement) / max(stored + abs(float(system.load @ x)), 1e-300)
            else:
                energy = float("nan")
    return Certificate(equilibrium, tension, complementarity, consistency, energy, tolerance)


@dataclass(frozen=True, eq=False)
class Solution:
    """The equilibrium of a :class:`~dea_opt.problem.ContactProblem`, from any formulation.

    Spring quantities have shape (N,), in the layer's spring order. ``stress`` and
    ``spring_force`` are tension positive (so ``<= 0``); ``pressure = -stress >= 0``.
    ``certificate`` says the answer solves the equations; ``validity`` says whether the
    equations still describe cartilage there (:mod:`dea_opt.validity`).
    """

    problem: object
    u: np.ndarray
    strain: np.ndarray
    pressure: np.ndarray
    method: str
    success: bool
    status: str
    message: str
    iterations: int
    build_time: float
    solve_time: float
    certificate: Certificate
    info: dict = field(default_factory=dict)

    # scipy.optimize names
    @property
    def x(self) -> np.ndarray:
        """Alias of ``u`` (the 12-vector of Eq. 7)."""
        return self.u

    @property
    def nit(self) -> int:
        return self.iterations

    @property
    def body1_displacement(self) -> np.ndarray:
        """``(ux, uy, uz, rx, ry, rz)`` of body 1 (mm, rad)."""
        return self.u[:6]

    @property
    def body2_displacement(self) -> np.ndarray:
        return self.u[6:]

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
        """Resultant moment the springs exert on body 2 about its reference (N mm)."""
        arm = self.problem.layer.points - np.asarray(self.problem.body2.reference)
        return np.cross(arm, self._normal_forces).sum(axis=0)

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
        """The :class:`~dea_opt.validity.Validity` report of this answer with the default limits.

        For other limits, or a count of springs dropped at the solved pose, call
        :func:`dea_opt.validity.assess` ``(solution.problem, solution.u, solution.strain,
        solution.pressure, limits=..., dropped=...)``.
        """
        return assess(self.problem, self.u, self.strain, self.pressure)

    @property
    def reactions(self) -> dict:
        """Generalized force the supports apply at every dof that is not free (N, N mm)."""
        layer = self.problem.layer
        q = self.problem.normal_operator.T @ (-self.pressure * layer.areas)
        reaction = q - self.problem.load_vector
        held = np.setdiff1d(np.arange(12), self.problem.free_indices)
        return {DOF_NAMES[i]: float(reaction[i]) for i in held}

    def summary(self) -> dict:
        """The headline numbers as plain Python values (for tables and JSON)."""
        return {
            "method": self.method,
            "success": self.success,
            "status": self.status,
            "law": self.problem.law.describe(),
            "n_springs": len(self.pressure),
            "peak_pressure": self.peak_pressure,
            "mean_pressure": self.mean_pressure,
            "contact_area": self.contact_area,
            "center_of_pressure": self.center_of_pressure.tolist(),
            "contact_force": self.contact_force.tolist(),
            "contact_moment": self.contact_moment.tolist(),
            "max_compressive_strain": self.max_compressive_strain,
            "u": self.u.tolist(),
            "iterations": self.iterations,
            "build_time": self.build_time,
            "solve_time": self.solve_time,
            "certificate": self.certificate.as_dict(),
            "validity": self.validity.as_dict(),
            "reactions": self.reactions,
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
        """Statistics per region; see :func:`dea_opt.regions.regional_statistics`."""
        from .regions import regional_statistics

        return regional_statistics(self, labels=labels, planes=planes)
