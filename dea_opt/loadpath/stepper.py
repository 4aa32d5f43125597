"""Solving the frames of a load path one after another with one method, carrying the warm start.

Each formulation's model (:mod:`dea_opt.formulations`) is built once and re-solved with each
frame's load; it is rebuilt when the geometry changes, as it does with poses. A model that
warm-starts (``Capabilities.warm_start``) starts each re-solve from its own last answer, and a
new model from the last certified frame. ``auto`` runs the default formulation so and solves
a frame whose answer fails its certificate again cold, as :func:`dea_opt.solve` does (with its
fallback). A frame under no load gets the answer and the status every method gives it
(:func:`dea_opt.solver.formulation_result`). After a failed frame, :meth:`Stepper.reset` makes
the next one start cold.
"""

from __future__ import annotations

import time

from .. import formulations
from ..problem import ContactProblem
from ..solution import Solution
from ..solver import certified_solution, formulation_plan, formulation_result

__all__ = ["Stepper"]


class Stepper:
    """Solves frame after frame with one method, carrying the warm start.

    Parameters
    ----------
    method : str
        ``"auto"`` or a registered formulation.
    options : dict
        The formulation's options (under ``auto``, routed as :func:`dea_opt.solve` does).
    certificate_tol : float
    """

    def __init__(self, method: str, options: dict, certificate_tol: float):
        self.method = method
        self.options = options
        self.certificate_tol = certificate_tol
        self.u_free = None  # the free-dof motion of the last certified frame (mm, rad)
        self.model = None
        self._plan: list | None = None

    def solve(self, problem: ContactProblem, new_geometry: bool, setup: float = 0.0) -> Solution:
        """Solve one frame; ``setup`` (s) is geometry building to charge to this frame."""
        from ..solver import solve

        if self._plan is None:
            self._plan = formulation_plan(self.method, problem.law, self.options)
        name, options, _ = self._plan[0]  # under auto, the default formulation
        start = time.perf_counter()
        system = problem.system()
        build = setup + (time.perf_counter() - start if new_geometry else 0.0)
        if new_geometry:
            self.model = None
        warm = self.u_free if self.model is None and formulations.capabilities(name).warm_start else None
        if warm is not None and warm.shape != (system.n_dofs,):
            warm = None

        def model():
            if self.model is None:
                self.model = formulations.build(name, system, problem.law, **options)
            return self.model

        # The cone test runs only after a failure (solve_path): a frame's cost is the solve.
        result = formulation_result(problem, system, name, model, x0=warm, check_cone=False)
        solution = certified_solution(problem, result, name, self.certificate_tol, build + result.build_time)
        if not solution.success and self.method == "auto":
            # The previous frame's start may be poor (a jump in the load): solve cold,
            # falling back to the constrained formulation as dea_opt.solve does.
            solution = solve(problem, "auto", certificate_tol=self.certificate_tol, strict=False, **self.options)
        if solution.success:
            self.u_free = solution.u[problem.free_indices]
        return solution

    def reset(self) -> None:
        """Forget the warm start and the model: the next frame starts cold (after a failed frame)."""
        self.u_free = None
        self.model = None
