"""Solving the frames of a load path one after another with one method, carrying the warm start.

``newton`` (and ``auto``) start every frame from the previous frame's displacement; ``qp``
and ``nlp`` build one model and re-solve it with the new load (rebuilt when the geometry
changes, as it does with poses).
"""

from __future__ import annotations

import time

import numpy as np

from ..errors import SolverError
from ..problem import ContactProblem
from ..solution import Solution
from ..solver import certified_solution

__all__ = ["Stepper"]


class Stepper:
    """Solves frame after frame with one method, carrying the warm start."""

    def __init__(self, method: str, options: dict, certificate_tol: float):
        self.method = method
        self.options = options
        self.certificate_tol = certificate_tol
        self.x = None
        self.model = None

    def solve(self, problem: ContactProblem, new_geometry: bool, setup: float = 0.0) -> Solution:
        """Solve one frame; ``setup`` (s) is geometry building to charge to this frame."""
        from ..solver import solve

        if problem.free_indices.size == 0:
            return solve(problem, "newton", certificate_tol=self.certificate_tol, strict=False)
        start = time.perf_counter()
        system = problem.system()
        build = setup + (time.perf_counter() - start if new_geometry else 0.0)
        if new_geometry:
            self.model = None
        if not system.load.any():
            # No load: dea_opt.solve's own answer, so that the frame gets the status and the
            # certificate of that situation that every method shares.
            newton = ("gtol", "xtol", "max_iter")
            if self.method == "newton":
                options = {k: v for k, v in self.options.items() if k in newton}
            elif self.method == "auto":
                options = {}
            else:
                options = {k: v for k, v in self.options.items() if k not in newton}
            return solve(problem, self.method, certificate_tol=self.certificate_tol, strict=False, **options)
        if self.method in ("newton", "auto"):
            solution = self._newton(problem, system, build)
        else:
            solution = self._model(problem, system, build)
        if solution.success:
            self.x = solution.u[problem.free_indices]
        return solution

    def reset(self) -> None:
        """Forget the warm start and the model: the next frame starts cold (after a failed frame)."""
        self.x = None
        self.model = None

    def _newton(self, problem, system, build) -> Solution:
        from ..formulations import newton
        from ..solver import solve

        options = {k: v for k, v in self.options.items() if k in ("gtol", "xtol", "max_iter")}
        result = newton.solve(system, problem.law, x0=self.x, **options)
        solution = certified_solution(problem, result, "newton", self.certificate_tol, build)
        if not solution.success and self.method == "auto":
            # The previous frame's start may be poor (a jump in the load): solve cold,
            # falling back to the constrained formulation as dea_opt.solve does.
            fallback = {k: v for k, v in self.options.items() if k not in ("gtol", "xtol", "max_iter")}
            solution = solve(problem, "auto", certificate_tol=self.certificate_tol, strict=False, **fallback)
        return solution

    def _model(self, problem, system, build) -> Solution:
        from ..formulations import FormulationResult
        from ..formulations.nlp import NLPModel
        from ..formulations.qp import QPModel

        options = dict(self.options)
        if self.model is None:
            if self.method == "qp":
                self.model = QPModel(system, problem.law, solver=options.pop("solver", "CLARABEL"))
            else:
                names = ("form", "tol", "max_iter", "ipopt_options")
                nlp_options = {k: options.pop(k) for k in names if k in options}
                self.model = NLPModel(system, problem.law, **nlp_options)
            build += self.model.build_time
        else:
            options.pop("solver", None)
        try:
            if self.method == "qp":
                result = self.model.solve(system.load, **{k: v for k, v in options.items() if k == "tol"})
            else:
                result = self.model.solve(system.load, warm_start=True)
        except SolverError as exc:
            # As dea_opt.solve does: a solver that raised gives a failed frame, not an abort.
            result = FormulationResult(x=np.full(system.n_dofs, np.nan), stress=np.full(system.n_springs, np.nan),
                                       success=False, status=exc.status or "solver_error", message=str(exc))
        return certified_solution(problem, result, self.method, self.certificate_tol, build)
