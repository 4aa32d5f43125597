"""How far apart answers of one problem are: the measure ``dea_opt.compare`` and comparison
studies (:mod:`dea_opt.study`) share, and :class:`Comparison`, what ``dea_opt.compare`` returns.

Finite kinematics re-cast the springs at each answer's pose, so two answers of one problem may
stand on different springs: their pressures are matched by the mesh face each spring stands on.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["Comparison", "disagreement", "pressure_difference"]


@dataclass(frozen=True)
class Comparison:
    """One problem solved by several methods (:func:`dea_opt.compare`), and how far apart they lie.

    Attributes
    ----------
    solutions : dict
        ``{method: Solution}`` (``{method: JointSolution}`` for a joint), in the order run.
    displacement : float
        The largest pairwise difference of the displacement ``u`` (of a joint: its free dofs)
        relative to the pair's largest magnitude (:func:`disagreement`; dimensionless).
    pressure : float
        The largest pairwise difference of the springs' pressures relative to the pair's larger
        peak pressure (dimensionless; finite answers matched by mesh face).
    skipped : dict
        ``{method: why}`` for the methods named that do not solve the problem.
    notes : tuple of str
        The method names that stood for another formulation (finite kinematics).
    ligament_force : float or None
        For a joint with ligaments, the largest pairwise difference of the bundles' forces
        relative to the largest (dimensionless); None for two bodies.
    """

    solutions: dict
    displacement: float
    pressure: float
    skipped: dict = field(default_factory=dict)
    notes: tuple = ()
    ligament_force: float | None = None

    @property
    def methods(self) -> tuple:
        """The methods that ran, in order."""
        return tuple(self.solutions)

    @property
    def success(self) -> bool:
        """Whether every method gave a certified answer."""
        return all(s.success for s in self.solutions.values())


def pressure_difference(solution, reference) -> float:
    """The largest difference (MPa) of the springs' pressures of two answers of one problem.

    Springs cast from meshes (``layer.source_face``) are matched by the face they stand on, a
    spring of one answer only counting with its whole pressure; springs of one layer are compared
    one by one. NaN when the answers hold different numbers of springs that cannot be matched.
    """
    a, b = np.asarray(solution.pressure), np.asarray(reference.pressure)
    fa = getattr(solution.problem.layer, "source_face", None)
    fb = getattr(reference.problem.layer, "source_face", None)
    if fa is None or fb is None or np.array_equal(fa, fb):
        return float(np.abs(a - b).max(initial=0.0)) if a.shape == b.shape else float("nan")
    union = np.union1d(fa, fb)
    on_a, on_b = np.zeros(len(union)), np.zeros(len(union))
    on_a[np.searchsorted(union, fa)] = a
    on_b[np.searchsorted(union, fb)] = b
    return float(np.abs(on_a - on_b).max(initial=0.0))


def disagreement(solutions) -> tuple[float, float]:
    """``(displacement, pressure)``: the largest pairwise difference of ``u`` relative to the
    pair's largest ``|u|``, and of the pressures (:func:`pressure_difference`) relative to the
    pair's larger peak pressure; ``(0, 0)`` for fewer than two answers, NaN where a pair cannot
    be compared (a non-finite answer, springs that cannot be matched)."""
    du, dp = [0.0], [0.0]
    items = list(solutions)
    for i, a in enumerate(items):
        for b in items[i + 1 :]:
            su = max(float(np.abs(a.u).max()), float(np.abs(b.u).max()), 1e-300)
            sp = max(a.peak_pressure, b.peak_pressure, 1e-300)
            du.append(float(np.abs(a.u - b.u).max() / su))
            dp.append(pressure_difference(a, b) / sp)
    # np.max, not max: a NaN (a pair that cannot be compared) must not read as agreement
    return float(np.max(du)), float(np.max(dp))
