"""Scale and conditioning: correct answers or named errors, and no warnings.

Areas from 1e-6 to 1e2 mm^2, thicknesses from 1e-2 to 10 mm, H from 1e-2 to 1e3 MPa, lever
arms (the distance from the body's reference point to the layer) from 1e-3 to 1e3 mm, one
spring to a million, duplicate springs, all springs or none in contact. Each answer is
checked against a closed form (a plate under a centred load carries the uniform pressure
``F / total area`` at the approach ``h eps`` with ``sigma(-eps) = -p``; a scaled problem
gives the scaled answer), and every solve runs with warnings recorded: any warning but a
:class:`dea_opt.ValidityWarning` fails the test (these sizes are outside a joint's on purpose;
tests/core/test_validity.py tests that warning).
"""

from __future__ import annotations

import warnings
from contextlib import contextmanager

import numpy as np
import pytest
from conftest import TIGHT, method_law_pairs
from scipy.optimize import brentq

import dea_opt as d
from dea_opt.geometry import plate_layer, socket_layer

METHODS = ("newton", "qp", "nlp", "auto")
#: A linear and a nonlinear law, each with every method that takes it.
LAW_PAIRS = method_law_pairs(METHODS, [d.LinearLaw(10.0), d.AteshianLaw(0.6, 0.3)])


@contextmanager
def no_warnings(allowed=()):
    """Record every warning; fail on any whose category is not in ``allowed``."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield caught
    bad = [w for w in caught if not (allowed and issubclass(w.category, allowed))]
    assert not bad, "unexpected warnings: " + "; ".join(
        f"{w.category.__name__}: {w.message} ({w.filename}:{w.lineno})" for w in bad
    )


def solve(problem, method, *, allowed=(d.ValidityWarning,), **options):
    """``dea_opt.solve`` with the tight test options and no warning but ``allowed``."""
    opts = {} if method == "auto" else dict(TIGHT[method])
    opts.update(options)
    with no_warnings(allowed):
        solution = d.solve(problem, method, **opts)
    assert solution.success and solution.certificate.passed
    return solution


def grid_layer(cell_area, thickness, nx=8, ny=5, gap=0.0):
    """An ``nx`` x ``ny`` plate of square cells of ``cell_area`` centred at the origin."""
    a = float(np.sqrt(cell_area))
    xs = a * (np.arange(nx) - (nx - 1) / 2)
    ys = a * (np.arange(ny) - (ny - 1) / 2)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    points = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    return d.SpringLayer(points, np.tile([0.0, 0.0, 1.0], (X.size, 1)), cell_area, thickness, gap)


def reference_at(lever):
    direction = np.array([1.0, 0.6, 0.3])
    return tuple(lever * direction / np.linalg.norm(direction))


def strain_for_pressure(law, p):
    """The compressive strain ``eps > 0`` with ``-sigma(-eps) = p`` (a 1-D root)."""

    def f(e):
        return -law.stress(np.array([-e]))[0] - p

    hi = 0.999999 if law.bounded_strain else 10.0
    return brentq(f, 0.0, hi, xtol=1e-300, rtol=1e-15)


def check_centred_plate(solution, problem, pressure, strain, rtol=1e-6):
    """Uniform pressure, uniform strain, the approach at the reference, no rotation."""
    layer = problem.layer
    h = layer.thickness
    np.testing.assert_allclose(solution.pressure, pressure, rtol=rtol, atol=0, err_msg="pressure")
    np.testing.assert_allclose(solution.strain, -strain, rtol=rtol, atol=0, err_msg="strain")
    assert solution.contact_area == pytest.approx(layer.areas.sum(), rel=1e-12)
    approach = float(np.mean(h)) * strain
    # The approach where the springs are: at a reference far from a small layer, the
    # rotation (and so the motion of the reference itself) is ill-conditioned by (L/size)^2,
    # while the motion of the layer is not.
    centroid = layer.points.mean(axis=0)
    at_layer = solution.u[6:9] + np.cross(solution.u[9:12], centroid - np.asarray(problem.body2.reference))
    assert at_layer[2] == pytest.approx(-approach, rel=rtol)
    # rotations: their largest displacement over the layer stays within rtol of the approach
    arm = np.abs(layer.points - centroid).max()
    assert np.abs(solution.u[9:12]).max() * arm <= rtol * approach
    load = problem.body2.load_vector
    np.testing.assert_allclose(solution.contact_force, -load[:3], rtol=0, atol=rtol * abs(load[2]))


# --- a plate under a centred load, over the decades -------------------------------------

BASE = dict(area=1.0, thickness=1.0, H=1.0, lever=1.0)
SWEEP = (
    [dict(BASE, area=a) for a in (1e-6, 1e-4, 1e-2, 1.0, 1e2)]
    + [dict(BASE, thickness=h) for h in (1e-2, 1e-1, 10.0)]
    + [dict(BASE, H=H) for H in (1e-2, 1e3)]
    + [dict(BASE, lever=L) for L in (1e-3, 1e3)]
    + [  # corners of the box
        dict(area=1e-6, thickness=1e-2, H=1e-2, lever=1e-3),
        dict(area=1e2, thickness=10.0, H=1e3, lever=1e-3),
        dict(area=1e-6, thickness=10.0, H=1e3, lever=1e3),
        dict(area=1e2, thickness=1e-2, H=1e-2, lever=1e3),
    ]
)


def _sweep_id(p):
    return "-".join(f"{k}={v:g}" for k, v in p.items())


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("params", SWEEP, ids=_sweep_id)
def test_plate_under_centred_load_carries_uniform_pressure(params, method):
    """Linear law, 40 springs, strain 0.1: ``p = F / total area``, approach ``h p / H``."""
    layer = grid_layer(params["area"], params["thickness"])
    H, strain = params["H"], 0.1
    pressure = H * strain
    force = pressure * layer.areas.sum()
    problem = d.ContactProblem(
        layer,
        d.LinearLaw(H),
        load=d.Load((0, 0, -force), point=(0, 0, 0)),
        reference=reference_at(params["lever"]),
        free=("uz", "rx", "ry"),
    )
    check_centred_plate(solve(problem, method), problem, pressure, strain)


NONLINEAR = [
    d.AteshianLaw(0.6, 0.3),
    d.AteshianLaw(2.0, 0.0),
    d.BlankevoortLaw(0.5),
    d.CubicLaw(0.6, 0.3),
    d.PolynomialLaw(0.6, 0.3, 5),
]


@pytest.mark.parametrize("method", ("newton", "nlp", "auto"))
@pytest.mark.parametrize("strain", (1e-6, 1e-3, 0.3))
@pytest.mark.parametrize("law", NONLINEAR, ids=lambda law: law.describe())
def test_nonlinear_law_plate_closed_form(law, strain, method):
    """An off-centre reference and a tilt-free answer: pressure ``-sigma(-eps)`` everywhere,
    from small strains (where the energies cancel digits) to large ones."""
    layer = grid_layer(1.0, 2.0)
    pressure = -law.stress(np.array([-strain]))[0]
    force = pressure * layer.areas.sum()
    problem = d.ContactProblem(
        layer, law, load=d.Load((0, 0, -force), point=(0, 0, 0)), reference=reference_at(3.0), free=("uz", "rx", "ry")
    )
    check_centred_plate(solve(problem, method), problem, pressure, strain_for_pressure(law, pressure))


@pytest.mark.parametrize("method", ("newton", "auto"))
@pytest.mark.parametrize("strain", np.geomspace(1e-7, 1e-5, 7).tolist(), ids=lambda e: f"{e:.2g}")
@pytest.mark.parametrize("law", [d.BlankevoortLaw(1.0), d.AteshianLaw(1.0, 0.3)], ids=lambda law: law.describe())
def test_nonlinear_laws_at_small_strains_off_centre(law, strain, method):
    """A light eccentric load (strains of 1e-7 to 1e-5, where ``w(eps)`` is a difference of
    nearly equal numbers): certified, and the springs balance the load to 1e-8."""
    layer = plate_layer(10.0, 10.0, 4, 4, thickness=1.0)
    force = -law.stress(np.array([-strain]))[0] * 100.0
    problem = d.ContactProblem(layer, law, load=d.Load((0, 0, -force), point=(1.0, 0.5, 0)), free=("uz", "rx", "ry"))
    s = solve(problem, method)
    resultant = np.concatenate([s.contact_force, s.contact_moment])
    load = problem.body2.load_vector
    np.testing.assert_allclose(resultant[[2, 3, 4]], -load[[2, 3, 4]], rtol=0, atol=1e-8 * force * 5.0)


# --- scaled problems give scaled answers ------------------------------------------------


def _eccentric(law):
    layer = plate_layer(40.0, 10.0, 40, 5, thickness=2.0)
    gap = 0.02 * np.sin(layer.points[:, 0])  # some overlap, some opening
    layer = layer.with_gap(gap)
    return d.ContactProblem(
        layer,
        law,
        load=d.Load((0, 0, -150.0), point=(8.0, 1.5, 0)),
        moment=None,
        reference=(2.0, -1.0, 3.0),
        free=("uz", "rx", "ry"),
    )


def _scaled(problem, s, k):
    """Lengths times ``s``, stresses times ``k``: forces ``k s^2``, moments ``k s^3``."""
    layer = problem.layer
    scaled_layer = d.SpringLayer(
        layer.points * s, layer.normals, layer.areas * s * s, layer.thickness * s, layer.gap * s
    )
    law = problem.law
    H = law.H * k
    new_law = {d.LinearLaw: lambda: d.LinearLaw(H), d.AteshianLaw: lambda: d.AteshianLaw(H, law.beta)}[type(law)]()
    body = problem.body2
    return d.ContactProblem(
        scaled_layer,
        new_law,
        body2=d.Body(
            reference=tuple(np.multiply(body.reference, s)),
            free=body.free,
            force=tuple(np.multiply(body.force, k * s * s)),
            moment=tuple(np.multiply(body.moment, k * s**3)),
        ),
    )


SCALES = [(1e-2, 1.0), (1e2, 1.0), (1.0, 1e-3), (1.0, 1e3), (1e-2, 1e-2), (10.0, 1e2), (1e-1, 1e3)]


@pytest.mark.parametrize("s, k", SCALES, ids=[f"length{s:g}-stress{k:g}" for s, k in SCALES])
@pytest.mark.parametrize("method, law", LAW_PAIRS)
def test_scaled_problems_give_scaled_answers(law, s, k, method):
    """Same strains, pressures times ``k``, translations times ``s``, rotations unchanged."""
    base = _eccentric(law)
    reference = solve(base, "newton")
    assert 0 < reference.contact_area < base.layer.areas.sum()  # lift-off: a real contact problem
    scaled = solve(_scaled(base, s, k), method)
    peak = reference.peak_pressure
    np.testing.assert_allclose(scaled.pressure / k, reference.pressure, rtol=0, atol=1e-6 * peak)
    np.testing.assert_allclose(scaled.strain, reference.strain, rtol=0, atol=1e-6 * np.abs(reference.strain).max())
    np.testing.assert_allclose(scaled.u[6:9] / s, reference.u[6:9], rtol=0, atol=1e-6 * np.abs(reference.u[6:9]).max())
    np.testing.assert_allclose(scaled.u[9:12], reference.u[9:12], rtol=0, atol=1e-6 * np.abs(reference.u[9:12]).max())


# --- lever arms: a reference point far from, or at, the layer ----------------------------


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("lever", (1e-3, 1.0, 1e2, 1e3))
def test_eccentric_plate_with_far_reference(lever, method):
    """The same lift-off problem with the reference moved ``lever`` mm away: the pressures
    do not depend on where moments are taken (the load is the same force at the same point)."""
    law = d.LinearLaw(10.0)
    layer = plate_layer(40.0, 10.0, 40, 5, thickness=2.0)
    load = d.Load((0, 0, -150.0), point=(8.0, 1.5, 0))
    near = d.ContactProblem(layer, law, load=load, reference=(0.0, 0.0, 0.0), free=("uz", "rx", "ry"))
    far = d.ContactProblem(layer, law, load=load, reference=reference_at(lever), free=("uz", "rx", "ry"))
    a, b = solve(near, "newton"), solve(far, method)
    np.testing.assert_allclose(b.pressure, a.pressure, rtol=0, atol=1e-6 * a.peak_pressure)
    np.testing.assert_allclose(b.strain, a.strain, rtol=0, atol=1e-6 * np.abs(a.strain).max())


# --- one spring, and a million ----------------------------------------------------------


@pytest.mark.parametrize("method", METHODS)
def test_one_spring(method):
    layer = d.SpringLayer([[0.3, -0.2, 0.0]], [[0.0, 0.0, 1.0]], 0.5, 2.0)
    law = d.LinearLaw(4.0)
    pressure = 0.2
    one_dof = d.ContactProblem(layer, law, force=(0, 0, -pressure * 0.5), free=("uz",))
    s = solve(one_dof, method)
    assert s.pressure[0] == pytest.approx(pressure, rel=1e-9)
    assert s.u[8] == pytest.approx(-2.0 * pressure / 4.0, rel=1e-9)
    # all six dofs free, pushed through the spring: only uz is resisted (and determined)
    six = d.ContactProblem(
        layer,
        law,
        load=d.Load((0, 0, -pressure * 0.5), point=(0.3, -0.2, 0.0)),
        reference=(0.3, -0.2, 0.0),
        free=d.DOFS,
    )
    s = solve(six, method)
    assert s.pressure[0] == pytest.approx(pressure, rel=1e-9)
    assert s.strain[0] == pytest.approx(-pressure / 4.0, rel=1e-9)
    if method == "newton":  # the minimum-norm answer: nothing moves that nothing resists
        np.testing.assert_allclose(s.u[6:], [0, 0, -0.1, 0, 0, 0], rtol=0, atol=1e-15)


@pytest.mark.parametrize("method", METHODS)
def test_one_spring_cannot_carry_a_sideways_load(method):
    layer = d.SpringLayer([[0.0, 0.0, 0.0]], [[0.0, 0.0, 1.0]], 1.0, 1.0)
    problem = d.ContactProblem(layer, d.LinearLaw(1.0), force=(1.0, 0, -1.0), free=d.DOFS)
    with no_warnings(), pytest.raises(d.LoadNotSupportedError):
        d.solve(problem, method)


@pytest.mark.parametrize("n", [100_000, pytest.param(1_000_000, marks=pytest.mark.slow)], ids=["1e5", "1e6"])
def test_many_springs_newton(n):
    """Newton on 1e5 and 1e6 springs: the centred load exactly, lift-off to the closed form."""
    nx, ny = (1000, 100) if n == 100_000 else (1000, 1000)
    layer = plate_layer(40.0, 10.0, nx, ny, thickness=2.0)
    law = d.LinearLaw(20.0)
    centred = d.ContactProblem(layer, law, load=d.Load((0, 0, -400.0), point=(0, 0, 0)), free=("uz", "rx", "ry"))
    s = solve(centred, "newton")
    np.testing.assert_allclose(s.pressure, 1.0, rtol=1e-9)
    assert s.u[8] == pytest.approx(-0.1, rel=1e-9)
    if n == 100_000:
        P, e, B, L = 500.0, 10.0, 40.0, 10.0
        lifted = d.ContactProblem(layer, law, load=d.Load((0, 0, -P), point=(e, 0, 0)), free=("uz", "rx", "ry"))
        s = solve(lifted, "newton")
        assert s.peak_pressure == pytest.approx(2 * P / (3 * L * (B / 2 - e)), rel=5e-3)
        assert abs(s.contact_area / L - 3 * (B / 2 - e)) <= B / nx + 1e-9


# --- duplicate springs ------------------------------------------------------------------


@pytest.mark.parametrize("method", METHODS)
def test_duplicate_springs_act_as_one_with_the_summed_area(method):
    layer = plate_layer(20.0, 6.0, 10, 3, thickness=1.5)
    gap = 0.01 * np.cos(layer.points[:, 0])
    shares = (0.2, 0.3, 0.5)
    split = d.SpringLayer(
        np.tile(layer.points, (3, 1)),
        np.tile(layer.normals, (3, 1)),
        np.concatenate([layer.areas * f for f in shares]),
        np.tile(layer.thickness, 3),
        np.tile(gap, 3),
    )
    law = d.LinearLaw(5.0)
    load = d.Load((0, 0, -60.0), point=(4.0, 0.7, 0))
    one = d.ContactProblem(layer.with_gap(gap), law, load=load, free=("uz", "rx", "ry"))
    three = d.ContactProblem(split, law, load=load, free=("uz", "rx", "ry"))
    a, b = solve(one, "newton"), solve(three, method)
    assert 0 < a.contact_area < layer.areas.sum()
    np.testing.assert_allclose(b.u, a.u, rtol=0, atol=1e-6 * np.abs(a.u).max())
    np.testing.assert_allclose(b.pressure, np.tile(a.pressure, 3), rtol=0, atol=1e-6 * a.peak_pressure)


@pytest.mark.parametrize("method", METHODS)
def test_fifty_springs_at_one_point(method):
    n = 50
    layer = d.SpringLayer(np.zeros((n, 3)), np.tile([0.0, 0.0, 1.0], (n, 1)), np.linspace(0.1, 1.0, n), 1.0)
    problem = d.ContactProblem(layer, d.LinearLaw(2.0), force=(0, 0, -0.2 * layer.areas.sum()), free=("uz",))
    s = solve(problem, method)
    np.testing.assert_allclose(s.pressure, 0.2, rtol=1e-7)
    assert s.u[8] == pytest.approx(-0.1, rel=1e-7)


# --- all springs or none in contact -----------------------------------------------------


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("gap", ["open", "bonded", "overlap"])
def test_zero_load(gap, method):
    """No load: nothing presses. Open gaps stay open, a bonded layer stays put, and an
    overlapping (pre-compressed) layer pushes the free body off until it is unloaded."""
    layer = plate_layer(10.0, 10.0, 5, 5, thickness=1.0)
    layer = layer.with_gap({"open": 0.05, "bonded": 0.0, "overlap": -0.05}[gap] * (1 + 0.1 * layer.points[:, 0]))
    problem = d.ContactProblem(layer, d.LinearLaw(3.0), free=("uz", "rx", "ry"))
    s = solve(problem, method)
    np.testing.assert_allclose(s.pressure, 0.0, atol=1e-9 * 3.0)
    assert (s.strain >= -1e-9).all()
    with no_warnings():
        summary = s.summary()
    assert summary["peak_pressure_MPa"] < 1e-9 and summary["mean_pressure_MPa"] < 1e-9
    if gap == "bonded":
        np.testing.assert_allclose(s.u, 0.0, atol=1e-9)
    if gap != "overlap":
        assert s.contact_area == 0.0 and np.isnan(s.center_of_pressure).all()


@pytest.mark.parametrize("method", METHODS)
def test_all_springs_open_then_pushed_into_full_contact(method):
    layer = plate_layer(12.0, 8.0, 6, 4, thickness=1.5).with_gap(0.2)
    H, strain = 4.0, 0.05
    area = layer.areas.sum()
    problem = d.ContactProblem(
        layer, d.LinearLaw(H), load=d.Load((0, 0, -H * strain * area), point=(0, 0, 0)), free=("uz", "rx", "ry")
    )
    s = solve(problem, method)
    assert s.contact_area == pytest.approx(area)
    np.testing.assert_allclose(s.pressure, H * strain, rtol=1e-6)
    assert s.u[8] == pytest.approx(-(0.2 + 1.5 * strain), rel=1e-6)


@pytest.mark.parametrize("method", ("newton", "auto"))
@pytest.mark.parametrize("ratio", (10.0, 300.0, 3000.0))
def test_wide_open_gap_and_a_small_load(ratio, method):
    """Every spring open by ``ratio`` times the final compression: the body must travel
    the whole gap before anything resists. Newton's first (extended-range) step only
    moves it by about the final compression, so it must take long steps through the gap."""
    layer = plate_layer(8.0, 8.0, 4, 4, thickness=1.0)
    H, strain = 10.0, 1e-3
    layer = layer.with_gap(ratio * strain)
    area = layer.areas.sum()
    problem = d.ContactProblem(layer, d.LinearLaw(H), force=(0, 0, -H * strain * area), free=("uz",))
    s = solve(problem, method)
    assert s.u[8] == pytest.approx(-(ratio + 1) * strain, rel=1e-9)
    np.testing.assert_allclose(s.pressure, H * strain, rtol=1e-6)


# --- degenerate and unresisted directions -----------------------------------------------


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("moment", (1e2, 1e3))
def test_springs_on_the_neutral_axis(moment, method):
    """Pure bending of a bonded plate whose middle row lies on the neutral axis: those
    springs have zero strain and zero force in the exact answer (weakly active)."""
    layer = plate_layer(40.0, 10.0, 40, 5, thickness=2.0)
    H = 10.0
    problem = d.ContactProblem(layer, d.LinearLaw(H), moment=(-moment, 0, 0), free=("rx",))
    y, A = layer.points[:, 1], layer.areas
    rx = -moment * 2.0 / (H * np.sum(A[y > 0] * y[y > 0] ** 2))
    s = solve(problem, method)
    assert s.u[9] == pytest.approx(rx, rel=1e-9)
    np.testing.assert_allclose(s.pressure, np.where(y > 0, -H * rx * y / 2.0, 0.0), rtol=0, atol=1e-9 * s.peak_pressure)


@pytest.mark.parametrize("method, law", LAW_PAIRS)
def test_ball_in_socket_with_every_dof_free(law, method):
    """A hip with all six dofs of the head free: the springs (all through the centre) do not
    resist its rotations about the centre, and the load has no moment about it, so the
    pressures are those of the head free to translate only."""
    layer = socket_layer(radius=25.0, thickness=2.0, coverage=70.0, n_rings=10, n_sectors=24)
    force = (300.0, 200.0, -2400.0)
    translating = d.ContactProblem(layer, law, force=force, free=("ux", "uy", "uz"))
    free = d.ContactProblem(layer, law, force=force, free=d.DOFS)
    a, b = solve(translating, "newton"), solve(free, method)
    np.testing.assert_allclose(b.pressure, a.pressure, rtol=0, atol=1e-6 * a.peak_pressure)
    np.testing.assert_allclose(b.u[6:9], a.u[6:9], rtol=0, atol=1e-6 * np.abs(a.u[6:9]).max())


# --- warnings and laws at the ends of their ranges ---------------------------------------


@pytest.mark.parametrize("method", METHODS)
def test_validity_warning_is_the_only_warning(method):
    layer = plate_layer(10.0, 10.0, 5, 5, thickness=1.0)
    linear = d.ContactProblem(layer, d.LinearLaw(1.0), force=(0, 0, -0.4 * 100.0), free=("uz",))
    with no_warnings(d.ValidityWarning) as caught:
        s = d.solve(linear, method, **({} if method == "auto" else TIGHT[method]))
    assert s.success and s.max_compressive_strain == pytest.approx(0.4, rel=1e-6)
    assert [w.category for w in caught] == [d.ValidityWarning]
    if method == "qp":
        return
    law = d.AteshianLaw(0.5, 0.0)
    pressure = -law.stress(np.array([-0.97]))[0]
    crushing = d.ContactProblem(layer, law, force=(0, 0, -pressure * 100.0), free=("uz",))
    with no_warnings(d.ValidityWarning) as caught:
        s = d.solve(crushing, method, **({} if method == "auto" else TIGHT[method]))
    assert s.success and s.max_compressive_strain == pytest.approx(0.97, rel=1e-6)
    assert [w.category for w in caught] == [d.ValidityWarning]


BETAS = (0.0, 5e-324, 1e-310, 1e-300, 1e-100, 1e-12, 1e-3, 10.0)


@pytest.mark.parametrize("H", (1e-2, 1.0, 1e3))
@pytest.mark.parametrize("beta", BETAS)
def test_ateshian_law_is_finite_for_every_beta(beta, H):
    """``beta -> 0`` is handled without dividing by zero: also for subnormal ``beta``."""
    law = d.AteshianLaw(H, beta)
    eps = np.concatenate([-np.geomspace(1e-8, 0.99, 40), np.geomspace(1e-8, 0.5, 10)])
    with no_warnings():
        w, sigma, k = law.energy(eps), law.stress(eps), law.tangent(eps)
    assert np.isfinite(w).all() and np.isfinite(sigma).all() and np.isfinite(k).all()
    assert (w >= 0).all()
    if beta < 1e-12:  # the beta = 0 limit (to the rounding of subnormal arithmetic)
        limit = d.AteshianLaw(H, 0.0)
        np.testing.assert_allclose(w, limit.energy(eps), rtol=1e-6)


@pytest.mark.parametrize("method", ("newton", "nlp"))
@pytest.mark.parametrize("beta", (5e-324, 1e-310))
def test_subnormal_beta_solves_like_beta_zero(beta, method):
    layer = grid_layer(1.0, 2.0)
    force = 0.05 * layer.areas.sum()
    tiny = d.ContactProblem(layer, d.AteshianLaw(10.0, beta), force=(0, 0, -force), free=("uz",))
    zero = tiny.with_law(d.AteshianLaw(10.0, 0.0))
    np.testing.assert_allclose(solve(tiny, method).pressure, solve(zero, method).pressure, rtol=1e-9)
