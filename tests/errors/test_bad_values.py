"""Bad values in a problem's data (its layer, law, bodies and loads): a named InputError, the same
from every method, raised where the value is given; and the range rule for values whose products
overflow or underflow, the same for every field rather than case by case."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import METHODS, invoke, one_paragraph_error

import dea_opt as d
from dea_opt._checks.inputs import LARGEST, SMALLEST
from dea_opt.geometry import plate_layer, sphere_on_bed_layer

N = 4
GOOD = dict(points=np.zeros((N, 3)), normals=np.tile([0, 0, 1.0], (N, 1)), areas=1.0, thickness=2.0)


def layer_with(**changes):
    return d.SpringLayer(**{**GOOD, **changes})


def _nan_points():
    p = np.zeros((N, 3))
    p[2, 1] = np.nan
    return p


def _zero_normal():
    n = np.tile([0, 0, 1.0], (N, 1))
    n[1] = 0
    return n


@pytest.fixture(scope="module")
def small_bed():
    return sphere_on_bed_layer(radius=25.0, thickness=2.0, extent=7.0, n_rings=10, n_sectors=16)


# --- the layer ----------------------------------------------------------------------------------


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize(
    "changes, message",
    [
        ({"points": _nan_points()}, r"points must be finite, got nan at index \(2, 1\)"),
        ({"normals": _zero_normal()}, r"normals must be nonzero vectors, got \[0.0, 0.0, 0.0\] at index 1"),
        ({"areas": np.array([1.0, -1.0, 1.0, 1.0])}, r"areas must be > 0 everywhere, got -1.0 at index 1"),
        ({"thickness": -2.0}, r"thickness must be > 0 everywhere, got -2.0"),
        ({"areas": np.ones(3)}, r"areas must have shape \(4,\), got shape \(3,\)"),
        ({"normals": np.ones((3, 3))}, r"normals must have shape \(4, 3\), got shape \(3, 3\)"),
        ({"points": np.ones((4, 2))}, r"points must have shape \(N, 3\), got shape \(4, 2\)"),
        ({"gap": "wide"}, r"gap must be numeric"),
    ],
)
def test_bad_layer(method, changes, message):
    # The layer is checked once, at the boundary, before any method sees it.
    with pytest.raises(d.InputError, match=message):
        d.solve(d.ContactProblem(layer_with(**changes), d.LinearLaw(1.0), force=(0, 0, -1)), method)


@pytest.mark.parametrize(
    "field, value",
    [
        ("thickness", 1e-320),
        ("thickness", 1e-40),
        ("areas", 1e-320),
        ("areas", 1e300),
        ("thickness", 1e200),
        ("gap", 1e300),
        ("points", 1e200),
    ],
)
def test_layer_values_out_of_range(small_bed, field, value):
    arrays = {
        "points": small_bed.points,
        "normals": small_bed.normals,
        "areas": small_bed.areas,
        "thickness": small_bed.thickness,
        "gap": small_bed.gap,
    }
    arrays[field] = np.full_like(arrays[field], value)
    with pytest.raises(d.InputError, match=f"{field} must be at (most|least)"):
        d.SpringLayer(**arrays)


@pytest.mark.parametrize("scale", [1e200, 1e155, 1e-200, 1e-310])
def test_normals_of_any_finite_length_are_normalised_and_never_dropped(scale):
    layer = plate_layer(10.0, 10.0, 4, 4, thickness=1.0)
    unit = layer.normals
    big = d.SpringLayer(layer.points, unit * scale, layer.areas, layer.thickness)
    np.testing.assert_allclose(big.normals, unit, rtol=1e-15, atol=0)
    tilted = np.array([[3.0, 4.0, 0.0]]) * scale
    np.testing.assert_allclose(d.SpringLayer([[0, 0, 0]], tilted, 1.0, 1.0).normals, [[0.6, 0.8, 0.0]], rtol=1e-15)
    H, p = 2.0, 0.1
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        s = d.solve(d.ContactProblem(big, d.LinearLaw(H), force=(0, 0, -p * layer.areas.sum()), free=("uz",)))
    np.testing.assert_allclose(s.pressure, p, rtol=1e-9)  # every spring carries its share


# --- the law ------------------------------------------------------------------------------------


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize(
    "make, message",
    [
        (lambda: d.LinearLaw(0.0), "H must be a finite number > 0, got 0.0"),
        (lambda: d.LinearLaw(-0.5), "H must be a finite number > 0, got -0.5"),
        (lambda: d.AteshianLaw(0.6, -0.05), "beta must be a finite number >= 0, got -0.05"),
    ],
)
def test_bad_law(method, make, message):
    with pytest.raises(d.InputError, match=message):
        d.solve(d.ContactProblem(layer_with(), make(), force=(0, 0, -1)), method)


@pytest.mark.parametrize(
    "make",
    [
        lambda: d.LinearLaw(1e308),
        lambda: d.LinearLaw(1e-320),
        lambda: d.LinearLaw(2 * LARGEST),
        lambda: d.LinearLaw(SMALLEST / 2),
        lambda: d.AteshianLaw(1e308, 0.1),
        lambda: d.BlankevoortLaw(1e-310),
        lambda: d.CubicLaw(1.0, 1e300),
        lambda: d.PolynomialLaw(1e29, 1e29, 5),  # its Taylor coefficients overflow
    ],
    ids=["H=1e308", "H=1e-320", "H>largest", "H<smallest", "ateshian", "blankevoort", "cubic-beta", "polynomial"],
)
def test_law_parameters_out_of_range(make):
    with pytest.raises(d.InputError):
        make()


def test_law_h_1e308_through_a_scenario_is_a_clean_cli_error(tmp_path):
    """The reported reproducer went through auto's qp fallback into cvxpy ('Problem data contains
    NaN or Inf'); now the law is rejected when it is built, and the CLI says so."""
    scenario = tmp_path / "huge.toml"
    scenario.write_text(
        '[geometry]\nkind = "sphere_on_bed"\n[law]\nkind = "linear"\nH = 1e308\n'
        '[load]\nforce = [0, 0, -10]\n[body2]\nreference = [0, 0, 25]\nfree = ["uz"]\n'
    )
    assert "1e+30" in one_paragraph_error(invoke("run", scenario, "-o", tmp_path / "out"))


@pytest.mark.parametrize("H", [LARGEST, SMALLEST, 1.0])
@pytest.mark.parametrize("method", ("newton", "qp", "nlp"))
def test_the_largest_and_smallest_modulus_solve_exactly(H, method):
    """A bonded plate under a central force: pressure F / A and approach F h / (H A) at either
    end of the range (nothing overflows or underflows on the way)."""
    layer = plate_layer(10.0, 10.0, 5, 5, thickness=2.0)
    area = layer.areas.sum()
    F = min(max(1e-3 * H * area, 10 * SMALLEST), 1e-3)  # strains of 0.1 or less, loads within the range
    s = d.solve(d.ContactProblem(layer, d.LinearLaw(H), force=(0, 0, -F), free=("uz", "rx", "ry")), method)
    assert s.success
    np.testing.assert_allclose(s.pressure, F / area, rtol=1e-6)
    assert s.u[8] == pytest.approx(-F * 2.0 / (H * area), rel=1e-6)


# --- bodies, loads and the problem's arguments ------------------------------------------------------


@pytest.mark.parametrize(
    "body, message",
    [
        (lambda: d.Body(free=("uz", "spin")), r"free must hold dof names .* got 'spin'"),
        (lambda: d.Body(force=(0, 1)), r"force must have shape \(3,\), got shape \(2,\)"),
        (lambda: d.Body(reference=(0, 0, np.inf)), r"reference must be finite"),
        (lambda: d.Body(prescribed={"uz": "down"}), r"prescribed\['uz'\] must be a number"),
        (lambda: d.Body(prescribed={"wz": 1.0}), r"prescribed must use dof names"),
    ],
)
def test_bad_body(body, message):
    with pytest.raises(d.InputError, match=message):
        body()


def test_bad_problem_arguments():
    with pytest.raises(d.InputError, match="layer must be a SpringLayer, got ndarray"):
        d.ContactProblem(np.zeros((3, 3)), d.LinearLaw(1.0))
    with pytest.raises(d.InputError, match="law must be a dea_opt Law"):
        d.ContactProblem(layer_with(), "linear")
    with pytest.raises(d.InputError, match="either body2"):
        d.ContactProblem(layer_with(), d.LinearLaw(1.0), body2=d.Body(), force=(0, 0, 1))


@pytest.mark.parametrize(
    "make",
    [
        lambda: d.Load(force=(0, 0, 1e300)),
        lambda: d.Load(moment=(1e31, 0, 0)),
        lambda: d.Load(force=(0, 0, -1.0), point=(1e200, 0, 0)),
        lambda: d.Body(reference=(0, 0, 1e300)),
        lambda: d.Body(prescribed={"uz": 1e300}),
        lambda: d.Body(force=(0, 0, 1e31)),
    ],
    ids=["force", "moment", "point", "reference", "prescribed", "body-force"],
)
def test_loads_and_bodies_out_of_range(make):
    with pytest.raises(d.InputError, match="must be at most 1e\\+30"):
        make()


def test_a_point_load_whose_moment_overflows_the_range(small_bed):
    """Force and point each within range, their moment about the reference not."""
    with pytest.raises(d.InputError, match="moment must be at most"):
        d.ContactProblem(small_bed, d.LinearLaw(1.0), load=d.Load((0, 0, -1e20), point=(1e20, 0, 0)), free=("uz",))


@pytest.mark.parametrize("size", [1e-200, 1e-31])
def test_a_nonzero_load_below_the_smallest_scale(small_bed, size):
    with pytest.raises(d.InputError, match="a nonzero load must reach at least 1e-30"):
        d.ContactProblem(small_bed, d.LinearLaw(1.0), force=(0, 0, -size), reference=(0, 0, 25.0), free=("uz",))


@pytest.mark.parametrize("method", ("newton", "qp", "nlp", "auto"))
def test_tiny_loads_within_the_range_are_solved(method):
    """1e-12 N and 1e-12 N mm on a unit modulus: far inside the range, solved exactly."""
    layer = plate_layer(10.0, 10.0, 5, 5, thickness=2.0)
    problem = d.ContactProblem(
        layer, d.LinearLaw(1.0), force=(0, 0, -1e-12), moment=(1e-13, 0, 0), free=("uz", "rx", "ry")
    )
    s = d.solve(problem, method)
    assert s.success
    f = (s.pressure * layer.areas)[:, None] * layer.normals
    np.testing.assert_allclose(f.sum(axis=0), [0, 0, 1e-12], rtol=0, atol=1e-18)
    np.testing.assert_allclose(np.cross(layer.points, f).sum(axis=0), [-1e-13, 0, 0], rtol=0, atol=1e-18)
