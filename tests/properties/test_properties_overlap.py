"""Property test: layers that start in overlap, loads over fourteen decades, every method.

The family that once certified answers missing up to half the load (``tests/core/test_certificate_scale.py``
has its fixed reproducers): a random layer (a plate, a spherical cap, a cylindrical trough or an
ellipsoidal bowl from ``tests/properties/test_attack_small.py``'s generator) whose gaps mostly overlap, by up to
0.6 of the thickness, any law, a random body and subset of dofs free about a random reference, and a
load of 1e-11 to 1e3 N the springs can push. The properties, for every method that takes the law:

* a certified answer balances the load: the springs' forces and moments on every free dof, summed
  here with the normal operator written here (``rows``), plus the load, are at most 1e-6 of the
  load (moments over the layer's RMS radius about the body's reference);
* ``auto`` returns a certified answer unless the problem says why it cannot: the load is not
  supported (``LoadNotSupportedError``), float64 does not resolve it against the overlap (the
  certificate's rounding above its tolerance, the residual within that rounding), or the layer is
  crushed.

Profiles as in ``tests/properties/test_properties.py`` (``DEA_HYPOTHESIS_PROFILE``: ``ci`` 40 problems,
``thorough`` 400; ``DEA_HYPOTHESIS_SEED`` for a seeded draw instead of the derandomized one).
"""

from __future__ import annotations

import warnings

import numpy as np
from hypothesis import given, note, settings
from hypothesis import strategies as st
from test_attack_small import draw, rows
from test_properties import _BASE, PROFILE, SEEDED

import dea_opt as d
from dea_opt.solver import beyond_resolution

EXAMPLES = {"ci": 40, "thorough": 400}[PROFILE]


def imbalance(problem: d.ContactProblem, u) -> tuple[float, float]:
    """``(residual, load)`` on the free dofs: ``G^T f + r`` with ``G`` (:func:`rows`) the springs'
    closing per unit ``u`` and ``f`` their push (N) from strains ``(gap + G u) / h`` (a push ``f_i``
    along ``n_i`` on body 2 is ``f_i`` times spring ``i``'s row on every dof), moments over the RMS
    radius about each body's reference; and the load's largest component in that measure."""
    layer, law = problem.layer, problem.law
    c1, c2 = (np.asarray(b.reference, dtype=float) for b in (problem.body1, problem.body2))
    G = rows(layer.points, layer.normals, c1, c2)
    eps = (layer.gap + G @ u) / layer.thickness
    with np.errstate(invalid="ignore", over="ignore"):
        sigma = law.H * np.minimum(eps, 0.0) if isinstance(law, d.LinearLaw) else law.stress(np.minimum(eps, 0.0))
    push = -sigma * layer.areas  # >= 0, on body 2 along +n and on body 1 along -n
    spring = G.T @ push  # the springs' forces and moments on both bodies about their references
    radius = [np.sqrt(np.mean(np.sum((layer.points - c) ** 2, axis=1))) for c in (c1, c2)]
    length = np.concatenate([np.ones(3), np.full(3, radius[0]), np.ones(3), np.full(3, radius[1])])
    free = problem.free_indices
    load = problem.load_vector
    return float(np.abs((spring + load)[free] / length[free]).max()), float(np.abs(load[free] / length[free]).max())


@settings(_BASE, max_examples=EXAMPLES)
@SEEDED
@given(seed=st.integers(0, 2**32 - 1))
def test_a_certified_answer_of_a_layer_in_overlap_balances_its_load(seed):
    drawn = draw(np.random.default_rng(seed))
    problem = drawn.problem
    note(f"{drawn.label}; {problem!r}")
    methods = ["auto"] + [m for m in ("newton", "qp", "nlp") if d.formulations.takes(m, problem.law)]
    for method in methods:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                solution = d.solve(problem, method, strict=False)
        except d.LoadNotSupportedError:
            continue
        note(f"{method}: {solution.status} {solution.certificate}")
        if solution.success:
            residual, load = imbalance(problem, solution.u)
            assert residual <= 1e-6 * load, f"{method}: certified, but {residual / load:.3g} of the load unbalanced"
        elif method == "auto":
            assert beyond_resolution(solution) or solution.status is d.Status.CRUSHED, solution.message
