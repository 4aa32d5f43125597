"""The linear-law DEA problem as a convex QP, modelled in cvxpy and solved by Clarabel.

Written math: ``formulations/qp.md``. Variables: the free dofs ``x`` and the compressive
strain ``c``; ``min 1/2 sum V_i H c_i^2 - r . x`` s.t. ``c >= 0``, ``c + e0 + A x >= 0``.
The load is the only cvxpy Parameter, so a new load re-solves without recompiling; spring
forces come from the duals of ``c + e0 + A x >= 0`` (``lambda_i = V_i H c_i``).
"""

from __future__ import annotations

import time
import warnings
from functools import lru_cache

import numpy as np

from ..errors import InputError, MissingDependencyError, SolverError
from .energy import (
    FormulationResult,
    SpringSystem,
    check_options,
    require_finite,
    scaling,
    trivial_result,
)

PAGE = "formulations/qp.md"
LINEAR_ONLY = True

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


class QPModel:
    """A compiled cvxpy model of one spring system, re-solvable for new loads.

    Parameters
    ----------
    system : SpringSystem
    law : LinearLaw
    solver : str
        A QP solver cvxpy has installed (``"CLARABEL"`` by default).
    """

    def __init__(self, system: SpringSystem, law, solver: str = "CLARABEL"):
        if not law.is_linear:
            raise InputError(
                f"method 'qp' needs a LinearLaw, got {law.describe()}: use method='nlp' or "
                f"method='newton' for nonlinear laws"
            )
        try:
            import cvxpy as cp
        except ImportError as exc:  # pragma: no cover - cvxpy is a core dependency
            raise MissingDependencyError("method 'qp' needs cvxpy: pip install cvxpy") from exc
        solver = str(solver).upper()
        if solver not in _installed_solvers():
            raise InputError(
                f"solver must be one of the QP solvers cvxpy has installed {sorted(_installed_solvers())}, "
                f"got {solver!r}"
            )
        start = time.perf_counter()
        self.solver = solver
        self.system, self.law = system, law
        # Solved in the scaled variables xi (x = T xi) and c = strain * c_hat, so that the
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
        weight = np.sqrt(sc.volume * law.H) * sc.strain
        require_finite("the QP's data", weight, sc.AT, system.e0)
        objective = 0.5 * cp.sum_squares(cp.multiply(weight, self.c)) - self.load @ self.xi
        self.contact = self.c + (sc.AT.T / sc.strain) @ self.xi >= -system.e0 / sc.strain
        self.problem = cp.Problem(cp.Minimize(objective), [self.contact])
        self.build_time = time.perf_counter() - start

    def solve(self, load=None, *, tol: float = 1e-10, warm_start: bool = True, **solver_options) -> FormulationResult:
        """Solve for ``load`` (default: the system's own load)."""
        import cvxpy as cp

        check_options(tol=tol)
        load = self.system.load if load is None else np.asarray(load, dtype=float)
        trivial = trivial_result(self.system, self.law, load)
        if trivial is not None:
            return trivial
        scaled = self.scale.load(load)
        require_finite("the load", scaled)
        self.load.value = scaled
        options = {**TOLERANCE_OPTIONS.get(self.solver, lambda t: {})(tol), **solver_options}
        start = time.perf_counter()
        try:
            with warnings.catch_warnings():
                # dea_opt certifies every answer itself; cvxpy's own doubt adds nothing.
                warnings.filterwarnings("ignore", message="Solution may be inaccurate")
                self.problem.solve(solver=self.solver, warm_start=warm_start, **options)
        except (cp.error.SolverError, TypeError, ValueError, KeyError) as exc:
            # An option the solver does not know is the caller's input (Clarabel and PIQP raise
            # TypeError, SCS a TypeError of its own, OSQP a SolverError naming the setting).
            named = any(str(key) in str(exc) for key in solver_options)
            if solver_options and (named or not isinstance(exc, cp.error.SolverError)):
                raise InputError(
                    f"{self.solver} rejected the options {sorted(solver_options)}: {exc} (dea_opt's own qp "
                    f"options are solver, tol and warm_start; the rest go to the solver)") from None
            raise SolverError(f"{self.solver} failed: {exc}", status="solver_error") from exc
        elapsed = time.perf_counter() - start
        stats = self.problem.solver_stats
        status = self.problem.status
        first = not self.compiled
        self.compiled = True
        xi = self.xi.value
        mu = self.contact.dual_value
        n = self.system.n_springs
        if xi is None or mu is None:
            x, mu = np.full(self.system.n_dofs, np.nan), np.full(n, np.nan)
        else:
            x = self.scale.to_x(np.asarray(xi, dtype=float).reshape(-1))
        # mu = V' H strain^2 c_hat = V' H strain c, so sigma = -H c = -mu / (V' strain)
        stress = -np.asarray(mu, dtype=float).reshape(n) / (self.scale.volume * self.scale.strain)
        solver_time = stats.solve_time if stats and stats.solve_time is not None else float("nan")
        return FormulationResult(
            x=np.asarray(x, dtype=float).reshape(-1),
            stress=stress,
            success=status == cp.OPTIMAL,
            status=status,
            message=f"{self.solver}: {status}",
            iterations=int(stats.num_iters or 0) if stats else 0,
            build_time=self.build_time if first else 0.0,
            solve_time=elapsed,
            info={"solver": self.solver, "solver_time": solver_time, "compile_and_solve": first},
        )


def solve(system: SpringSystem, law, *, solver: str = "CLARABEL", tol: float = 1e-10, x0=None, **solver_options):
    """Build and solve the QP once (``x0`` is ignored: interior-point solvers start cold)."""
    check_options(tol=tol)
    model = QPModel(system, law, solver=solver)
    result = model.solve(tol=tol, **solver_options)
    result.build_time = model.build_time
    return result
