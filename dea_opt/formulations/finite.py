"""Finite kinematics by Newton: the registry's entry ``"finite"`` (exact rotation, gaps at the current pose).

Written math: ``formulations/finite.md``. ``ContactProblem(..., kinematics="finite")`` is solved
by :func:`solve` (``dea_opt.solve`` sends it there): body 2's coordinates are its reference's
translation and its rotation vector taken as an exact rotation (``u[6:12]``); each spring pushes
body 2 along its own direction with the force the law gives at its gap to its target at that
pose (the tangent plane of a face of mesh 2, or a plane or sphere given by :class:`Targets`);
Newton with the consistent tangent solves the equilibrium of the free coordinates
(:mod:`~dea_opt.formulations._finite_newton`), springs cast from meshes follow body 2
(:mod:`~dea_opt.formulations._finite_recast`), and the answer is certified at the solved pose
(:mod:`~dea_opt.formulations._finite_solution`). The independent cross-check by IPOPT is
:mod:`~dea_opt.formulations.finite_nlp`; the QP is a small-kinematics method only.
"""

from __future__ import annotations

from ._finite_driver import ALIASES, plan, solve
from ._finite_geometry import Targets
from ._finite_solution import FiniteSolution
from ._options import Capabilities, Option

__all__ = [
    "ALIASES",
    "CAPABILITIES",
    "OPTIONS",
    "RECAST_OPTIONS",
    "FiniteModel",
    "FiniteSolution",
    "Model",
    "Targets",
    "plan",
    "solve",
]

PAGE = "formulations/finite.md"

#: The re-casting options of both finite formulations (formulations/finite.md, "Re-casting").
RECAST_OPTIONS = (
    Option("recast", bool, True, "keep springs cast from meshes (targets= a SpringCast) up to date as body 2 moves"),
    Option("recast_shift", float, 0.01, "mm a spring's hit may move before its thickness is measured again",
           range=(0, float("inf"))),
    Option("full_shift", float, 5.0, "mm the hits may move before the whole of mesh 1 is cast again",
           range=(0, float("inf"))),
    Option("max_recasts", int, 10, "updates of the springs after converged solves, at most", range=(0, None)),
)
#: The options of :func:`solve` with ``method="finite"``.
OPTIONS = (
    Option("xtol", float, 1e-12, "relative step that counts as converged once the contact set is unchanged",
           range=(0, 1), tolerance=True),
    Option("gtol", float, 1e-12, "equilibrium residual in the scaled variables that counts as converged",
           range=(0, 1), tolerance=True),
    Option("max_iter", int, 100, "Newton iterations per solve, at most", range=(1, None)),
    Option("extended_start", bool, True, "treat every spring as active, tension included, in the first "
           "iteration of a cold start"),
    *RECAST_OPTIONS,
)
CAPABILITIES = Capabilities(laws="any", warm_start=True, kinematics=("finite",), duals=False,
                            checks_load_first=False)
EXTRA_OPTIONS = None
VARIANT = None


class FiniteModel:
    """A finite-kinematics problem, re-solvable for new loads, warm-started from its last answer.

    The finite formulations solve a :class:`~dea_opt.problem.ContactProblem` (its targets, body
    2's reference, the re-casting of its springs), not a small
    :class:`~dea_opt.formulations.energy.SpringSystem`: ``FiniteModel(problem, **options)``;
    ``solve(load=None, *, x0=None, frame=None)`` returns a certified
    :class:`FiniteSolution` (``load`` a :class:`~dea_opt.problem.Load` on body 2).
    """

    method = "finite"

    def __init__(self, problem, law=None, **options):
        from ..errors import InputError
        from ..problem import ContactProblem

        if not isinstance(problem, ContactProblem) or problem.kinematics != "finite":
            raise InputError(f"the {self.method} formulation solves a ContactProblem with kinematics='finite' (built "
                             f"by dea_opt.solve), not {type(problem).__name__}")
        self.problem = problem if law is None else problem.with_law(law)
        self.options = options
        self.build_time = 0.0
        self._x, self._tracker = None, None

    def solve(self, load=None, *, x0=None, frame=None) -> FiniteSolution:
        problem = self.problem if load is None else self.problem.with_load(load)
        start = self._x if x0 is None else x0
        solution = solve(problem, self.method, strict=False, frame=frame, tracker=self._tracker, x0=start,
                         **self.options)
        if solution.success:
            self._x, self._tracker = solution.u[problem.free_indices], solution.tracker
        return solution


Model = FiniteModel
