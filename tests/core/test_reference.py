"""Acceptance 2-5 of the core: closed forms, and the three formulations agreeing.

Every reference problem is solved by every method that applies; the closed form checks
each solution and the agreement test compares them pairwise.
"""

from __future__ import annotations

import math
from functools import cache

import numpy as np
import pytest
from conftest import METHODS, applies, solve_quietly
from scipy.integrate import quad
from scipy.optimize import brentq

import dea_opt as d
from dea_opt.geometry import plate_layer, socket_layer, sphere_on_bed_layer

R, H_BED = 25.0, 2.0  # sphere radius and bed thickness (mm)
P, B, L = 500.0, 40.0, 10.0  # plate load (N) and size (mm)


def _plate(e):
    layer = plate_layer(B, L, 400, 10, thickness=2.0)
    return d.ContactProblem(layer, d.LinearLaw(10.0), load=d.Load((0, 0, -P), point=(e, 0, 0)), free=("uz", "rx", "ry"))


def _socket():
    layer = socket_layer(radius=R, thickness=2.0, coverage=90.0, n_rings=60, n_sectors=120)
    return d.ContactProblem(layer, d.LinearLaw(10.0), force=(0, 0, -1000.0), free=("ux", "uy", "uz"))


def _bed(law, force):
    layer = sphere_on_bed_layer(radius=R, thickness=H_BED, extent=7.0, n_rings=120, n_sectors=64)
    return d.ContactProblem(layer, law, force=(0, 0, -force), reference=(0, 0, R), free=("uz",))


BED_LAWS = {
    "linear": d.LinearLaw(0.6),
    "ateshian-0.05": d.AteshianLaw(0.6, 0.05),
    "ateshian-0.6": d.AteshianLaw(0.6, 0.6),
}
CASES = {
    "plate-e5": lambda: _plate(5.0),
    "plate-e10": lambda: _plate(10.0),
    "socket": _socket,
    **{f"bed-{k}": (lambda law=law: _bed(law, 10.0)) for k, law in BED_LAWS.items()},
}


@cache
def problem(case):
    return CASES[case]()


@cache
def solution(case, method):
    return solve_quietly(problem(case), method)


def pairs():
    for case in CASES:
        for method in METHODS:
            if applies(method, problem(case).law):
                yield case, method


PAIRS = list(pairs())


@pytest.mark.parametrize("e", [5.0, 10.0])
@pytest.mark.parametrize("method", METHODS)
def test_plate_closed_form(method, e):
    s = solution(f"plate-e{e:g}", method)
    if e < B / 6:  # full contact: trapezoidal pressure
        peak = P / (B * L) * (1 + 6 * e / B)
        assert s.contact_area == pytest.approx(B * L)
    else:  # lift-off: triangular pressure over 3 (B/2 - e)
        peak = 2 * P / (3 * L * (B / 2 - e))
        length = s.contact_area / L
        assert abs(length - 3 * (B / 2 - e)) <= B / 400 + 1e-9
    assert s.peak_pressure == pytest.approx(peak, rel=5e-3)


@pytest.mark.parametrize("method", METHODS)
def test_ball_in_socket_closed_form(method):
    s = solution("socket", method)
    assert s.peak_pressure == pytest.approx(3 * 1000.0 / (2 * math.pi * R**2), rel=5e-3)
    assert s.contact_area == pytest.approx(2 * math.pi * R**2, rel=1e-9)  # full hemisphere


def _linear_approach(force, H):
    return brentq(lambda x: math.pi * H * x * x * (R - x / 3) / H_BED - force, 1e-12, 2 * H_BED)


def _quadrature(force, law):
    """Approach and peak pressure from a 1-D quadrature of the law over the contact circle."""

    def carried(approach):
        a = math.sqrt(2 * R * approach - approach**2)

        def strain(rho):
            return (R - math.sqrt(R * R - rho * rho) - approach) / H_BED

        return quad(
            lambda rho: -law.stress(np.array([strain(rho)]))[0] * 2 * math.pi * rho,
            0,
            a,
            epsabs=1e-13,
            epsrel=1e-12,
            limit=200,
        )[0]

    approach = brentq(lambda x: carried(x) - force, 1e-6, 0.999 * H_BED, xtol=1e-14)
    return approach, -law.stress(np.array([-approach / H_BED]))[0]


@pytest.mark.parametrize(
    "name, method", [(name, m) for name, law in BED_LAWS.items() for m in METHODS if applies(m, law)]
)
def test_sphere_on_bed(name, method):
    law = BED_LAWS[name]
    s = solution(f"bed-{name}", method)
    approach = -s.u[8]
    if law.is_linear:
        assert approach == pytest.approx(_linear_approach(10.0, law.H), rel=5e-3)
        assert s.peak_pressure == pytest.approx(law.H * approach / H_BED, rel=5e-3)
    expected_approach, expected_peak = _quadrature(10.0, law)
    assert approach == pytest.approx(expected_approach, rel=5e-3)
    assert s.peak_pressure == pytest.approx(expected_peak, rel=5e-3)
    assert s.max_compressive_strain > 0.25  # the interesting, nonlinear range


@pytest.mark.parametrize("case, method", PAIRS)
def test_contact_force_balances_the_load(case, method):
    s = solution(case, method)
    p = problem(case)
    load = p.body2.load_vector
    resultant = np.concatenate([s.contact_force, s.contact_moment])
    free = [i for i, dof in enumerate(d.DOFS) if dof in p.body2.free]
    scale = np.linalg.norm(load[:3])
    np.testing.assert_allclose(resultant[free], -load[free], rtol=0, atol=1e-8 * scale * max(1.0, R))
    assert s.success and s.certificate.passed
    # scipy's x: the variables solved for, body 2's free dofs (u[6:12]) in the order of DOFS
    np.testing.assert_array_equal(s.x, s.u[6:][free])
    assert s.x.shape == (len(p.body2.free),)


@pytest.mark.parametrize("case", list(CASES))
def test_methods_agree(case):
    sols = [solution(case, m) for m in METHODS if applies(m, problem(case).law)]
    assert len(sols) >= 2
    ref = sols[0]
    for s in sols[1:]:
        np.testing.assert_allclose(s.u, ref.u, rtol=0, atol=1e-6 * np.abs(ref.u).max())
        np.testing.assert_allclose(s.pressure, ref.pressure, rtol=0, atol=1e-6 * ref.peak_pressure)


@pytest.mark.filterwarnings("ignore::dea_opt.ValidityWarning")
def test_compare_reports_disagreement():
    out = d.compare(problem("plate-e10"), qp={"tol": 1e-10}, nlp={"tol": 1e-12})
    assert set(out.solutions) == {"qp", "nlp", "newton"}
    assert out.displacement < 1e-6 and out.pressure < 1e-6
    out = d.compare(problem("bed-ateshian-0.05"), methods=("qp", "newton"))
    assert "qp" in out.skipped and set(out.solutions) == {"newton"}
