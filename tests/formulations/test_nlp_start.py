"""The constrained NLP's start from Newton's answer: the block ties' multipliers against a plain
sum written here, and IPOPT's answer from that start against the cubic law and equilibrium by this
file's own sums, the same as from a cold start, and unmoved by a start perturbed by 1e-12."""

from __future__ import annotations

import numpy as np
import pytest

import dea_opt as d
from dea_opt.formulations import SpringSystem
from dea_opt.formulations._parts.nlp_start import block_tie_duals
from dea_opt.formulations.nlp import NLPModel


def cubic_stress(H: float, beta: float, eps):
    """Eq. (3), written here: ``sigma = H/2 (2 e - e^2 + (1 + 4 beta) e^3)`` for ``e = min(eps, 0)``."""
    e = np.minimum(eps, 0.0)
    return 0.5 * H * (2 * e - e**2 + (1 + 4 * beta) * e**3)


def random_system(seed: int, m: int = 3, n: int = 400) -> SpringSystem:
    """Springs facing a body from below and its sides, a load inside what they carry."""
    rng = np.random.default_rng(seed)
    AT = rng.normal(size=(m, n))
    AT[0] = np.abs(AT[0]) + 0.2  # every spring resists the first dof's push
    e0 = rng.uniform(-0.005, 0.02, n)
    volume = rng.uniform(0.5, 5.0, n)
    sigma = -rng.uniform(0.1, 1.0, n) * (rng.random(n) < 0.5)
    return SpringSystem(AT, e0, volume, AT @ (volume * sigma), stiffness=float(volume.sum()))


@pytest.mark.parametrize("seed", range(3))
def test_block_tie_duals_are_minus_each_block_s_force(seed):
    rng = np.random.default_rng(seed)
    k, n, nb = 4, 103, 11
    AT = rng.normal(size=(k, n))
    lam = rng.normal(size=n)
    block = np.sort(rng.integers(0, nb, n))
    s0 = rng.uniform(0.1, 3.0)
    got = block_tie_duals(AT, s0, lam, block, nb)
    expected = []
    for b in range(1, nb):  # CasADi's vec of the (k, nb - 1) ties: column b - 1, then its k rows
        for j in range(k):
            expected.append(-sum(AT[j, i] / s0 * lam[i] for i in range(n) if block[i] == b))
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12 * np.abs(expected).max())


@pytest.mark.parametrize("seed", range(3))
def test_ipopt_from_newton_s_answer_is_the_nlp_s_own_answer(seed):
    system = random_system(seed)
    law = d.CubicLaw(4.0, 0.3)
    warm = NLPModel(system, law).solve()
    assert warm.info["start"] == "Newton's answer" and warm.success
    eps = system.e0 + system.AT.T @ warm.u_free
    stress = cubic_stress(4.0, 0.3, eps)
    scale = np.abs(stress).max()
    np.testing.assert_allclose(warm.stress, stress, rtol=0, atol=1e-7 * scale)
    balance = system.AT @ (system.volume * stress)
    np.testing.assert_allclose(balance, system.load, rtol=0, atol=1e-7 * np.abs(system.load).max())
    cold = NLPModel(system, law).solve(x0=np.zeros(system.n_dofs))
    assert cold.info["start"] == "cold" and cold.success
    np.testing.assert_allclose(warm.u_free, cold.u_free, rtol=1e-8, atol=1e-10)
    # A start 1e-12 away (another CPU's rounding of Newton's answer) gives the same answer.
    nudged = NLPModel(system, law).solve(x0=warm.u_free * (1 + 1e-12) + 1e-12)
    np.testing.assert_allclose(nudged.u_free, warm.u_free, rtol=1e-8, atol=1e-10)


def test_a_start_newton_cannot_give_is_a_cold_start():
    """A load no spring can carry (every spring resists only a push along the first dof, the load
    pulls): Newton does not converge, and IPOPT starts cold and does not claim an answer."""
    system = random_system(0, n=40)
    law = d.CubicLaw(4.0, 0.3)
    pull = np.array([10.0 * np.abs(system.load).max(), 0.0, 0.0])
    away = SpringSystem(system.AT, system.e0, system.volume, pull, stiffness=system.stiffness)
    result = NLPModel(away, law).solve()
    assert result.info["start"] == "cold" and not result.success
