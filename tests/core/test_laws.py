"""Acceptance 1 of the core: the laws are what the paper says, and self-consistent."""

from __future__ import annotations

import math

import numpy as np
import pytest

import dea_opt as d
from dea_opt.laws import ateshian_taylor_coefficients

LAWS = [
    d.LinearLaw(0.45),
    d.AteshianLaw(0.6, 0.05),
    d.AteshianLaw(0.3, 0.6),
    d.AteshianLaw(0.5, 0.0),
    d.CubicLaw(0.6, 0.3),
    d.PolynomialLaw(0.6, 0.6, 5),
    d.PolynomialLaw(0.4, 0.2, 8),
    d.BlankevoortLaw(0.5),
]
STRAINS = np.linspace(-0.9, 0.6, 61)


def eq2(eps, H, beta):
    """Eq. (2) typed straight from the paper."""
    lam = 1 + eps
    return H * (lam**2 - 1) / (2 * lam ** (2 * beta + 1)) * math.exp(beta * (lam**2 - 1))


@pytest.mark.parametrize("law", LAWS, ids=lambda law: law.describe())
def test_energy_derivative_is_stress_and_stress_derivative_is_tangent(law):
    h = 1e-6
    dw = (law.energy(STRAINS + h) - law.energy(STRAINS - h)) / (2 * h)
    ds = (law.stress(STRAINS + h) - law.stress(STRAINS - h)) / (2 * h)
    scale = law.H
    np.testing.assert_allclose(dw, law.stress(STRAINS), atol=1e-7 * scale * 10)
    np.testing.assert_allclose(ds, law.tangent(STRAINS), rtol=1e-6, atol=1e-6 * scale)
    assert law.energy(np.zeros(1))[0] == 0.0
    assert law.stress(np.zeros(1))[0] == 0.0
    assert law.modulus == pytest.approx(law.H, rel=1e-12)


@pytest.mark.parametrize("beta", [0.0, 0.05, 0.3, 0.6])
def test_ateshian_is_eq2(beta):
    law = d.AteshianLaw(0.6, beta)
    expected = [eq2(e, 0.6, beta) for e in STRAINS]
    np.testing.assert_allclose(law.stress(STRAINS), expected, rtol=1e-13, atol=1e-15)


def test_ateshian_value_at_30_percent_compression():
    # The reported check: |sigma(-0.3)| is about 1.23 H x 0.3 for beta = 0.05.
    law = d.AteshianLaw(1.0, 0.05)
    assert -law.stress(np.array([-0.3]))[0] / 0.3 == pytest.approx(1.2267, abs=1e-4)


def test_beta_to_zero_limit_is_continuous():
    eps = np.linspace(-0.8, 0.5, 27)
    limit = d.AteshianLaw(0.5, 0.0)
    for beta in (1e-6, 1e-9, 1e-12):
        np.testing.assert_allclose(d.AteshianLaw(0.5, beta).energy(eps), limit.energy(eps), rtol=1e-5, atol=1e-14)
        np.testing.assert_allclose(d.AteshianLaw(0.5, beta).stress(eps), limit.stress(eps), rtol=1e-5, atol=1e-14)
    assert np.isfinite(limit.energy(eps)).all()


@pytest.mark.parametrize("beta", [0.05, 0.6])
def test_eq3_is_the_third_order_taylor_series_of_eq2(beta):
    # Checked, not assumed: the cubic's error against Eq. (2) shrinks like eps^4.
    cubic = d.CubicLaw(0.6, beta)
    errors = []
    steps = np.array([1e-1, 5e-2, 2.5e-2, 1.25e-2])
    for e in steps:
        errors.append(abs(cubic.stress(np.array([-e]))[0] - eq2(-e, 0.6, beta)))
    order = np.polyfit(np.log(steps), np.log(errors), 1)[0]
    assert order == pytest.approx(4.0, abs=0.15)
    # and the alphas of Eq. (5)
    np.testing.assert_allclose(cubic.coefficients, [0.6, -0.3, 0.6 * (1 + 4 * beta) / 2])


@pytest.mark.parametrize("beta", [0.0, 0.05, 0.6])
def test_polynomial_order_3_equals_cubic(beta):
    assert d.PolynomialLaw(0.6, beta, 3) == d.CubicLaw(0.6, beta)
    np.testing.assert_allclose(
        d.PolynomialLaw(0.6, beta, 3).coefficients, d.CubicLaw(0.6, beta).coefficients, rtol=1e-14
    )
    np.testing.assert_allclose(
        d.PolynomialLaw(0.6, beta, 3).energy(STRAINS), d.CubicLaw(0.6, beta).energy(STRAINS), rtol=1e-13, atol=1e-16
    )


@pytest.mark.parametrize("order", [2, 5, 7, 9])
def test_taylor_coefficients_match_numerical_derivatives(order):
    # Taylor order n of Eq. (2) approximates it to O(eps^(n+1)).
    H, beta = 0.6, 0.3
    law = d.PolynomialLaw(H, beta, order)
    e = np.array([-0.02, 0.02])
    err = np.abs(law.stress(e) - [eq2(x, H, beta) for x in e])
    assert (err < 5 * 0.02 ** (order + 1) * H * 10).all()


def test_higher_orders_approach_eq2_on_the_papers_range():
    eps = np.linspace(-0.4, 0.4, 41)
    exact = np.array([eq2(x, 0.6, 0.6) for x in eps])
    deviations = [np.max(np.abs(d.PolynomialLaw(0.6, 0.6, n).stress(eps) - exact)) for n in (3, 5, 7, 9)]
    assert all(b < a for a, b in zip(deviations, deviations[1:]))


def test_taylor_coefficients_first_terms():
    c = ateshian_taylor_coefficients(2.0, 0.25, 4)
    np.testing.assert_allclose(c[:3], [2.0, -1.0, 2.0 * (1 + 1.0) / 2])


@pytest.mark.parametrize(
    "law", [d.AteshianLaw(0.6, 0.05), d.AteshianLaw(0.6, 0.0), d.BlankevoortLaw(0.6)], ids=lambda law: law.describe()
)
def test_bounded_laws_are_infinite_not_nan_when_crushed(law):
    eps = np.array([-1.0, -1.5, -0.999999])
    with np.errstate(all="raise"):
        s, t, w = law.stress(eps), law.tangent(eps), law.energy(eps)
    assert not np.isnan(s).any() and not np.isnan(t).any() and not np.isnan(w).any()
    assert s[0] == -np.inf and t[0] == np.inf and w[0] == np.inf
    assert np.isfinite(w[2])


@pytest.mark.parametrize("law", LAWS, ids=lambda law: law.describe())
def test_casadi_expressions_match_numpy(law):
    import casadi as ca

    x = ca.SX.sym("x")
    fns = ca.Function("f", [x], [law.stress(x), law.tangent(x), law.energy(x)])
    for e in (-0.7, -0.2, 0.0, 0.3):
        s, t, w = (float(v) for v in fns(e))
        arr = np.array([e])
        assert s == pytest.approx(law.stress(arr)[0], rel=1e-12, abs=1e-15)
        assert t == pytest.approx(law.tangent(arr)[0], rel=1e-12, abs=1e-15)
        assert w == pytest.approx(law.energy(arr)[0], rel=1e-10, abs=1e-15)


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda: d.LinearLaw(0), "H must be a finite number > 0"),
        (lambda: d.LinearLaw(-1), "H must be a finite number > 0"),
        (lambda: d.LinearLaw(float("nan")), "H must be a finite number > 0"),
        (lambda: d.AteshianLaw(0.6, -0.1), "beta must be a finite number >= 0"),
        (lambda: d.CubicLaw("soft", 0.1), "H must be a number"),
        (lambda: d.PolynomialLaw(0.6, 0.1, 0), "order must be an integer"),
        (lambda: d.PolynomialLaw(0.6, 0.1, 2.5), "order must be an integer"),
    ],
)
def test_bad_law_parameters(make, message):
    with pytest.raises(d.InputError, match=message):
        make()
