"""Large motion: finite-kinematics problems solved with the springs following body 2.

Written math: ``formulations/finite.md``. ``dea_opt.solve`` sends a
``ContactProblem(..., kinematics="finite")`` to :func:`solve` (:mod:`~dea_opt.finite.driver`):
it turns the problem into the arrays the registry's formulations ``finite`` (Newton) and
``finite_nlp`` (IPOPT) solve (:mod:`dea_opt.formulations.finite`), and after each converged
solve brings springs cast from meshes up to date at the solved pose
(:class:`~dea_opt.finite.tracker.MeshTracker`, with the public casting functions of
:mod:`dea_opt.mesh`), solving again while a loaded spring changed. The answer is a
:class:`~dea_opt.finite.solution.FiniteSolution`, certified at the solved pose. The
formulations see arrays and a law only; everything that knows meshes, casts, problems and poses
is here.
"""

from .driver import plan, solve
from .solution import FiniteSolution
from .tracker import MeshTracker

__all__ = ["FiniteSolution", "MeshTracker", "plan", "solve"]
