"""A joint solved by several methods, and how far their answers lie apart (``dea.compare`` for a Joint).

The math of each method: ``formulations/joint.md``. The disagreement is measured as for two bodies
(:func:`dea_opt.compare`): the largest pairwise difference of the free dofs relative to their
largest magnitude, of every layer's pressures relative to the largest peak, and of the bundles'
forces relative to the largest.
"""

from __future__ import annotations

import numpy as np

from ..agreement import Comparison
from ..errors import InputError
from ..formulations._parts.joint_ipopt import linear
from .solve import solve_joint

__all__ = ["compare_joint", "joint_methods"]


def joint_methods(joint, methods=None) -> tuple[list[str], dict]:
    """``(methods to run, {skipped method: why})`` for ``joint``: every method that solves it by default
    (``newton``, ``nlp``, and ``qp`` for linear elements under small kinematics)."""
    asked = ["newton", "qp", "nlp"] if methods is None else list(methods)
    run, skipped = [], {}
    for method in asked:
        if method not in ("newton", "qp", "nlp"):
            raise InputError(f"methods for a joint must be taken from newton, qp, nlp, got {method!r}")
        if method == "qp" and joint.kinematics == "finite":
            skipped[method] = "qp is a small-kinematics method"
        elif method == "qp" and not linear(joint.system()):
            skipped[method] = "qp needs linear elements only (LinearLaw springs, law='linear' ligaments)"
        else:
            run.append(method)
    if not run:
        raise InputError(f"no method in {asked} solves this joint: {skipped}")
    return run, skipped


def _spread(values) -> float:
    values = [np.asarray(v, dtype=float) for v in values]
    if len(values) < 2:
        return 0.0
    scale = max(float(np.abs(v).max(initial=0.0)) for v in values)
    worst = max(float(np.abs(a - b).max(initial=0.0)) for i, a in enumerate(values) for b in values[i + 1 :])
    return worst / scale if scale > 0 else worst


def compare_joint(joint, methods=None, *, certificate_tol: float = 1e-6, **options) -> Comparison:
    """Solve ``joint`` by each method (options per method: ``compare(joint, nlp={"tol": 1e-12})``).

    Returns
    -------
    Comparison
        ``solutions`` ``{method: JointSolution}``, the ``displacement``, ``pressure`` and
        ``ligament_force`` differences (relative) and the methods ``skipped``.
    """
    run, skipped = joint_methods(joint, methods)
    solutions = {m: solve_joint(joint, m, certificate_tol=certificate_tol, **options.get(m, {})) for m in run}
    answers = list(solutions.values())
    pressure = 0.0
    for i in range(len(joint.contacts)):
        pressure = max(pressure, _spread([s.contacts[i].pressure for s in answers]))
    return Comparison(
        solutions,
        displacement=_spread([s.x for s in answers]),
        pressure=pressure,
        skipped=skipped,
        ligament_force=_spread([s.ligaments.force for s in answers]) if len(joint.ligaments) else 0.0,
    )
