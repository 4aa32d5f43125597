"""Newton's fused sweeps over the springs against plain whole-array NumPy written here.

Sizes cross several blocks and end in a partial one; the laws include a nonlinear and a bounded one,
and strains that open, close and (for the bounded law) cross eps = -1.
"""

import numpy as np
import pytest

import dea_opt as dea
from dea_opt.formulations._parts import sweeps

LAWS = [dea.LinearLaw(7.0), dea.CubicLaw(5.0, 0.3), dea.AteshianLaw(4.0, 0.2)]
N = 3 * sweeps.BLOCK + 1234


def _arrays(seed, k=5, n=N):
    rng = np.random.default_rng(seed)
    AT = np.ascontiguousarray(rng.normal(size=(k, n)))
    V = rng.uniform(0.1, 2.0, n)
    eps = rng.uniform(-0.4, 0.3, n)
    return AT, V, eps


def _close(a, b):
    np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12 * float(np.abs(b).max(initial=1.0)))


@pytest.mark.parametrize("law", LAWS, ids=lambda law: type(law).__name__)
@pytest.mark.parametrize("seed", [0, 1])
def test_state_is_the_whole_array_sums(law, seed):
    AT, V, eps = _arrays(seed)
    got = sweeps.state(AT, V, eps, law, extended=True)
    c = np.minimum(eps, 0.0)
    _close(got.internal, AT @ (V * law.stress(c)))
    assert got.compression == pytest.approx(float(V @ (c * c)), rel=1e-12)
    act = eps < 0
    A = AT[:, act]
    _close(got.K, (A * (V[act] * law.tangent(eps[act]))) @ A.T)
    _close(got.bilateral, AT @ (V * law.stress(eps)))
    _close(got.K_all, (AT * (V * law.tangent(eps))) @ AT.T)
    bare = sweeps.state(AT, V, eps, law, tangent=False)
    assert bare.K is None and bare.bilateral is None and bare.K_all is None
    _close(bare.internal, got.internal)


def test_state_with_every_spring_open_or_closed():
    AT, V, eps = _arrays(2)
    law = dea.LinearLaw(3.0)
    open_ = sweeps.state(AT, V, np.abs(eps) + 0.01, law)
    assert not open_.internal.any() and not open_.K.any() and open_.compression == 0.0
    closed = -np.abs(eps) - 0.01
    got = sweeps.state(AT, V, closed, law)
    _close(got.K, (AT * (3.0 * V)) @ AT.T)
    _close(got.internal, AT @ (V * 3.0 * closed))


@pytest.mark.parametrize("law", LAWS, ids=lambda law: type(law).__name__)
def test_tangent_slope_and_energy(law):
    AT, V, eps = _arrays(3)
    w = V * law.tangent(np.minimum(eps, 0.0))
    _close(sweeps.tangent(AT, w), (AT * w) @ AT.T)
    Ad = np.random.default_rng(4).normal(size=eps.size) * 0.1
    for alpha in (0.0, 0.5, 1.0, 3.0):
        trial = eps + alpha * Ad
        out = np.empty_like(eps)
        value = sweeps.slope(law, V, eps, Ad, alpha, out)
        np.testing.assert_array_equal(out, trial)
        if law.bounded_strain and trial.min() <= -1.0:
            assert value == np.inf
        else:
            expected = float((V * law.stress(np.minimum(trial, 0.0))) @ Ad)
            assert value == pytest.approx(expected, rel=1e-11, abs=1e-11)
            energy = float(V @ law.energy(np.minimum(trial, 0.0)))
            assert sweeps.energy(law, V, eps, Ad, alpha) == pytest.approx(energy, rel=1e-11)


def test_slope_beyond_a_bounded_law():
    AT, V, eps = _arrays(5)
    law = dea.AteshianLaw(4.0, 0.2)
    Ad = -np.ones_like(eps)
    out = np.empty_like(eps)
    assert sweeps.slope(law, V, eps, Ad, 2.0, out) == np.inf
    np.testing.assert_array_equal(out, eps - 2.0)


def _plate(n_side=300, free=("uz", "rx", "ry")):
    from dea_opt.geometry import plate_layer

    layer = plate_layer(40.0, 10.0, n_side, n_side // 2, thickness=2.0)
    return dea.ContactProblem(
        layer, dea.CubicLaw(10.0, 0.3), load=dea.Load((0, 0, -500.0), point=(8.0, 2.0, 0)), free=free
    )


def test_certificate_sums_are_the_whole_array_sums():
    from dea_opt.certificate_sums import sums

    p = _plate()
    assert len(p.layer) > 2 * sweeps.BLOCK
    rng = np.random.default_rng(6)
    u = np.zeros(12)
    u[p.free_indices] = (-0.05, 0.004, -0.003)
    u[:3] = (0.001, -0.002, 0.0005)
    eps = p.strain(u)
    reported = p.law.stress(np.minimum(eps, 0.0)) * (1 + 1e-3 * rng.normal(size=eps.size))
    got = sums(p, u, eps, reported, 1e-6)
    system, layer, law = p.system(), p.layer, p.law
    AT, V, S = system.AT, system.volume, layer.areas
    c = np.minimum(eps, 0.0)
    sigma = law.stress(c)
    _close(got.q, AT @ (V * sigma))
    assert got.force == pytest.approx(float(np.abs(S * sigma).sum()), rel=1e-12)
    # the strains' rounding, as ContactProblem.strain_rounding states it
    rounding = p.strain_rounding(u)
    near = eps - rounding < 0
    moved = np.maximum(
        np.abs(law.stress(np.minimum(eps - rounding, 0.0)) - sigma),
        np.abs(law.stress(np.minimum(eps + rounding, 0.0)) - sigma),
    )
    _close(got.spread, np.abs(AT[:, near]) @ (V[near] * moved[near]))
    rep = S * reported
    assert got.tension == pytest.approx(float(np.maximum(rep, 0.0).sum()), rel=1e-12, abs=1e-300)
    assert got.complementarity == pytest.approx(float(np.abs(rep) @ np.maximum(eps, 0.0)), rel=1e-12)
    delta = 1e-6 * float(-c.min()) + rounding
    low, high = S * law.stress(np.minimum(eps - delta, 0.0)), S * law.stress(np.minimum(eps + delta, 0.0))
    excess = np.maximum(low - rep, 0.0) + np.maximum(rep - high, 0.0)
    assert got.consistency == pytest.approx(float(excess.sum()), rel=1e-10)
    act = eps < 0
    A = AT[:, act]
    _close(got.K, (A * (V[act] * law.tangent(eps[act]))) @ A.T)
    assert got.stored == pytest.approx(float(V[act] @ law.energy(eps[act])), rel=1e-12)
    assert got.compressed == int(act.sum()) and got.finite


def test_gap_error_is_the_exact_rotation_minus_the_linear_one():
    from scipy.spatial.transform import Rotation

    from dea_opt.validity import rotation_gap_error

    p = _plate(free=dea.DOFS)
    u = np.zeros(12)
    u[3:6] = (0.02, -0.01, 0.03)
    u[9:12] = (-0.04, 0.05, 0.01)
    got = rotation_gap_error(p, u)
    x, n = p.layer.points, p.layer.normals
    expected = np.zeros(len(x))
    for sign, body, k in ((-1.0, p.body1, 3), (1.0, p.body2, 9)):
        theta = u[k : k + 3]
        r = x - np.asarray(body.reference)
        exact = r @ (Rotation.from_rotvec(theta).as_matrix() - np.eye(3)).T
        linear = np.cross(theta, r)
        expected += sign * np.einsum("ij,ij->i", n, exact - linear)
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-12 * float(np.abs(expected).max()))


@pytest.mark.parametrize("law", LAWS, ids=lambda law: type(law).__name__)
def test_scaled_state_is_the_sums_over_the_scaled_copy(law):
    # Newton sums over A^T and V and scales the sums (sweeps.scaled): the numbers of summing over
    # the scaled copy T^T A^T and V / E0 that it no longer makes.
    AT, V, eps = _arrays(4, k=4)
    rng = np.random.default_rng(5)
    T, E0 = rng.normal(size=(4, 3)) * 1e-3, 2.5e-6
    got = sweeps.scaled(sweeps.state(AT, V, eps, law, extended=True), T, E0)
    want = sweeps.state(np.ascontiguousarray(T.T @ AT), V / E0, eps, law, extended=True)
    for name in ("internal", "K", "bilateral", "K_all"):
        _close(getattr(got, name), getattr(want, name))
    assert got.compression == pytest.approx(want.compression, rel=1e-12)
    assert sweeps.scaled(sweeps.state(AT, V, eps, law, tangent=False), T, E0).K is None
