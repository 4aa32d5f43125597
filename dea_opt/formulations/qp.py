"""The linear-law DEA problem as a convex QP, modelled in cvxpy and solved by Clarabel.

Written math: ``formulations/qp.md``. Variables: the free dofs ``x`` (``u_free`` in the
code) and the compressive strain ``c``; ``min 1/2 sum V_i H c_i^2 - r . x`` s.t. ``c >= 0``, ``c + e0 + A x >= 0``.
The load is the only cvxpy Parameter, so a new load re-solves without recompiling; spring
forces come from the duals of ``c + e0 + A x >= 0`` (``lambda_i = V_i H c_i``).
"""

from __future__ import annotations

import time
import warnings
from functools import lru_cache

import numpy as np

from ..errors import InputError, MissingDependencyError, SolverError
from ..status import Status
from ._options import Capabilities, Option, Variant, validate
from .energy import (
    FormulationResult,
    SpringSystem,
    require_finite,
    scaling,
    start_vector,
    trivial_result,
)

PAGE = "formulations/qp.md"

#: Tolerance options of each solver cvxpy knows, as functions of one tolerance.
TOLERANCE_OPTIONS = {
    "CLARABEL": lambda tol: {"tol_gap_abs": tol, "tol_gap_rel": tol, "tol_feas": tol, "tol_ktratio": tol * 1e-2},
    "OSQP": lambda tol: {"eps_abs": tol, "eps_rel": tol, "polishing": True, "max_iter": 200_000},
    "SCS": lambda tol: {"eps_abs": tol, "eps_rel": tol, "max_iters": 200_000},
    "PIQP": lambda tol: {"eps_abs": tol, "eps_rel": tol, "eps_duality_gap_abs": tol, "eps_duality_gap_rel": tol},
    "ECOS": lambda tol: {"abstol": tol, "reltol": tol, "feastol": tol},
}


@lru_cache(maxsize=1)
def _installed_solvers() -> tuple:
    """cvxpy's installed solvers (asking costs milliseconds, which a load path repeats)."""
    import cvxpy as cp

    return tuple(cp.installed_solvers())


OPTIONS = (
    Option("solver", str, "CLARABEL", "a QP solver cvxpy has installed", choices=_installed_solvers,
           normalize=str.upper),
    Option("tol", float, 1e-10, "the solver's own tolerances (TOLERANCE_OPTIONS)", range=(0, 1), tolerance=True,
           build=False),
    Option("warm_start", bool, True, "cvxpy's warm_start (re-solves reuse the compiled problem either way)",
           build=False),
)
CAPABILITIES = Capabilities(laws="linear", warm_start=False, duals=True, checks_load_first=True)
EXTRA_OPTIONS = "passed to the QP solver through cvxpy's solve"
VARIANT = Variant("solver")

#: cvxpy's statuses, as dea-opt's vocabulary (formulations/qp.md, "Statuses"); any other is
#: a solver error.
NATIVE_STATUS = {
    "optimal": Status.CONVERGED,
    "optimal_inaccurate": Status.INACCURATE,
    "infeasible": Status.INFEASIBLE,
    "infeasible_inaccurate": Status.INFEASIBLE,
    "unbounded": Status.UNBOUNDED,
    "unbounded_inaccurate": Status.UNBOUNDED,
    "user_limit": Status.MAX_ITERATIONS,
    "solver_error": Status.SOLVER_ERROR,
}


class QPModel:
    """A compiled cvxpy model of one spring system, re-solvable for new loads.

    Parameters
    ----------
    system : SpringSystem
    law : LinearLaw
    **options
        :data:`OPTIONS` (``solver``, default ``"CLARABEL"``; ``tol``, default 1e-10;
        ``warm_start``); any other option goes to the solver.
    """

    def __init__(self, system: SpringSystem, law, **options):
        known = {option.name for option in OPTIONS}
        checked = validate("qp", OPTIONS, options, EXTRA_OPTIONS)
        self.solver_options = {k: v for k, v in checked.items() if k not in known}
        self.tol, self.warm_start = checked["tol"], checked["warm_start"]
        if not CAPABILITIES.takes(law):
            raise InputError(f"method 'qp' needs a LinearLaw, got {law.describe()}: use another method for this law")
        try:
            import cvxpy as cp
        except ImportError as exc:  # pragma: no cover - cvxpy is a core dependency
            raise MissingDependencyError("method 'qp' needs cvxpy: pip install cvxpy") from exc
        start = time.perf_counter()
        self.solver = checked["solver"]
        self.system, self.law = system, law
        # Solved in the scaled variables xi (u_free = T xi) and c = s0 c_hat, so that the
        # solver's absolute tolerances mean the same for every unit and load size.
        self.scale = sc = scaling(system, law.H)
        k, n = sc.n_dofs, system.n_springs
        self.trivial = k == 0  # nothing resisted: no model (Clarabel must not see an empty one)
        self.build_time = time.perf_counter() - start
        self.compiled = False
        if self.trivial:
            return
        self.xi = cp.Variable(k, name="xi")
        self.c = cp.Variable(n, nonneg=True, name="c")
        self.load = cp.Parameter(k, name="r")
        weight = np.sqrt(sc.volume * law.H) * sc.strain_scale
        require_finite("the QP's data", weight, sc.AT, system.e0)
        objective = 0.5 * cp.sum_squares(cp.multiply(weight, self.c)) - self.load @ self.xi
        self.contact = self.c + (sc.AT.T / sc.strain_scale) @ self.xi >= -system.e0 / sc.strain_scale
        self.problem = cp.Problem(cp.Minimize(objective), [self.contact])
        self.build_time = time.perf_counter() - start

    def solve(self, load=None, *, x0=None) -> FormulationResult:
        """Solve for ``load`` (default: the system's own load); ``x0`` is checked and then
        ignored: interior-point solvers start cold."""
        import cvxpy as cp

        start_vector(self.system, x0)
        load = self.system.load if load is None else np.asarray(load, dtype=float)
        trivial = trivial_result(self.system, self.law, load)
        if trivial is not None:
            return trivial
        scaled = self.scale.load(load)
        require_finite("the load", scaled)
        self.load.value = scaled
        solver_options = self.solver_options
        options = {**TOLERANCE_OPTIONS.get(self.solver, lambda t: {})(self.tol), **solver_options}
        start = time.perf_counter()
        try:
            with warnings.catch_warnings():
                # dea_opt certifies every answer itself; cvxpy's own doubt adds nothing.
                warnings.filterwarnings("ignore", message="Solution may be inaccurate")
                self.problem.solve(solver=self.solver, warm_start=self.warm_start, **options)
        except (cp.error.SolverError, TypeError, ValueError, KeyError) as exc:
            # An option the solver does not know is the caller's input (Clarabel and PIQP raise
            # TypeError, SCS a TypeError of its own, OSQP a SolverError naming the setting).
            named = any(str(key) in str(exc) for key in solver_options)
            if solver_options and (named or not isinstance(exc, cp.error.SolverError)):
                own = ", ".join(option.name for option in OPTIONS)
                raise InputError(
                    f"{self.solver} rejected the options {sorted(solver_options)}: {exc} (dea_opt's own qp "
                    f"options are {own}; the rest go to the solver)") from None
            raise SolverError(f"{self.solver} failed: {exc}", status=Status.SOLVER_ERROR) from exc
        elapsed = time.perf_counter() - start
        stats = self.problem.solver_stats
        native = str(self.problem.status)
        first = not self.compiled
        self.compiled = True
        xi = self.xi.value
        mu = self.contact.dual_value
        n = self.system.n_springs
        if xi is None or mu is None:
            u_free, mu = np.full(self.system.n_dofs, np.nan), np.full(n, np.nan)
        else:
            u_free = self.scale.to_u_free(np.asarray(xi, dtype=float).reshape(-1))
        # mu = V' H s0^2 c_hat = V' H s0 c, so sigma = -H c = -mu / (V' s0)
        stress = -np.asarray(mu, dtype=float).reshape(n) / (self.scale.volume * self.scale.strain_scale)
        solver_time = stats.solve_time if stats and stats.solve_time is not None else float("nan")
        return FormulationResult(
            u_free=np.asarray(u_free, dtype=float).reshape(-1),
            stress=stress,
            success=native == cp.OPTIMAL,
            status=NATIVE_STATUS.get(native, Status.SOLVER_ERROR),
            message=f"{self.solver}: {native}",
            iterations=int(stats.num_iters or 0) if stats else 0,
            build_time=self.build_time if first else 0.0,
            solve_time=elapsed,
            info={"native_status": native, "solver": self.solver, "solver_time": solver_time,
                  "compile_and_solve": first},
        )


Model = QPModel


def solve(system: SpringSystem, law, *, x0=None, **options) -> FormulationResult:
    """Build and solve the QP once (``x0`` is ignored: interior-point solvers start cold)."""
    return QPModel(system, law, **options).solve(x0=x0)
