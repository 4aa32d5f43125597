"""Inputs that used to raise raw tracebacks or
were silently mangled now raise a named InputError, and their neighbours (other products that
overflow, subnormal scales) are handled by the same range rule, not case by case."""

from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest

import dea_opt as d
from dea_opt._checks.inputs import LARGEST, SMALLEST
from dea_opt.geometry import plate_layer, sphere_on_bed_layer


@pytest.fixture(scope="module")
def bed():
    return sphere_on_bed_layer(radius=25.0, thickness=2.0, extent=7.0, n_rings=10, n_sectors=16)


def pressed(layer, law=None, **kw):
    return d.ContactProblem(
        layer, law or d.LinearLaw(1.0), force=(0, 0, -10.0), reference=(0, 0, 25.0), free=kw.pop("free", ("uz",)), **kw
    )


# --- solver options ------------------------------------------------------------------------


@pytest.mark.parametrize("method", ("newton", "nlp", "auto"))
@pytest.mark.parametrize("x0", [np.zeros(3), [[0.0]], [np.nan], "zero"])
def test_x0_must_be_one_finite_value_per_free_dof(bed, method, x0):
    with pytest.raises(d.InputError, match="x0 must"):
        d.solve(pressed(bed), method, x0=x0)


@pytest.mark.parametrize("method", ("newton", "nlp", "auto"))
@pytest.mark.parametrize("max_iter", [2.5, 0, -3, True, "10"])
def test_max_iter_must_be_a_positive_integer(bed, method, max_iter):
    with pytest.raises(d.InputError, match="max_iter must be an integer >= 1"):
        d.solve(pressed(bed), method, max_iter=max_iter)


@pytest.mark.parametrize(
    "method, name", [("nlp", "tol"), ("qp", "tol"), ("newton", "gtol"), ("newton", "xtol"), ("auto", "tol")]
)
@pytest.mark.parametrize("value", [-1, 0, 1.5, float("nan"), float("inf"), "1e-8"])
def test_tolerances_must_lie_in_zero_one(bed, method, name, value):
    with pytest.raises(d.InputError, match=f"{name} must be a number in \\(0, 1\\)"):
        d.solve(pressed(bed), method, **{name: value})


def test_options_are_checked_even_when_no_solver_runs(bed):
    """A problem answered without a solver (no load, no overlap) still rejects a bad option."""
    unloaded = d.ContactProblem(bed, d.LinearLaw(1.0), reference=(0, 0, 25.0), free=("uz",))
    with pytest.raises(d.InputError, match="x0 must"):
        d.solve(unloaded, "newton", x0=[1.0, 2.0])


@pytest.mark.parametrize(
    "options, reason",
    [
        ({"bogus_key": 1}, "No such IPOPT option: bogus_key"),
        ({"tol": -1.0}, "Invalid options"),
    ],
)
def test_ipopt_options_ipopt_rejects_are_input_errors(bed, options, reason):
    with pytest.raises(d.InputError, match=f"ipopt_options .* were rejected by IPOPT: {reason}"):
        d.solve(pressed(bed), "nlp", ipopt_options=options)


@pytest.mark.parametrize("options", [["tol", 1e-8], {1: 2}])
def test_ipopt_options_must_be_a_dict_of_names(bed, options):
    with pytest.raises(d.InputError, match="ipopt_options must be a dict"):
        d.solve(pressed(bed), "nlp", ipopt_options=options)


@pytest.mark.parametrize("solver", ["CLARABEL", "OSQP", "SCS", "PIQP"])
def test_an_unknown_qp_solver_setting_is_an_input_error(bed, solver):
    with pytest.raises(d.InputError, match=f"{solver} rejected the options \\['bogus'\\]"):
        d.solve(pressed(bed), "qp", solver=solver, bogus=1)


# --- values whose products overflow or underflow -----------------------------------------------


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
def test_layer_values_out_of_range(bed, field, value):
    arrays = {
        "points": bed.points,
        "normals": bed.normals,
        "areas": bed.areas,
        "thickness": bed.thickness,
        "gap": bed.gap,
    }
    arrays[field] = np.full_like(arrays[field], value)
    with pytest.raises(d.InputError, match=f"{field} must be at (most|least)"):
        d.SpringLayer(**arrays)


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


def test_a_point_load_whose_moment_overflows_the_range(bed):
    """Force and point each within range, their moment about the reference not."""
    with pytest.raises(d.InputError, match="moment must be at most"):
        d.ContactProblem(bed, d.LinearLaw(1.0), load=d.Load((0, 0, -1e20), point=(1e20, 0, 0)), free=("uz",))


@pytest.mark.parametrize("size", [1e-200, 1e-31])
def test_a_nonzero_load_below_the_smallest_scale(bed, size):
    with pytest.raises(d.InputError, match="a nonzero load must reach at least 1e-30"):
        d.ContactProblem(bed, d.LinearLaw(1.0), force=(0, 0, -size), reference=(0, 0, 25.0), free=("uz",))


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


def test_law_h_1e308_through_a_scenario_is_a_clean_cli_error(tmp_path):
    """The reported reproducer went through auto's qp fallback into cvxpy ('Problem data contains
    NaN or Inf'); now the law is rejected when it is built, and the CLI says so."""
    scenario = tmp_path / "huge.toml"
    scenario.write_text(
        '[geometry]\nkind = "sphere_on_bed"\n[law]\nkind = "linear"\nH = 1e308\n'
        '[load]\nforce = [0, 0, -10]\n[body2]\nreference = [0, 0, 25]\nfree = ["uz"]\n'
    )
    done = subprocess.run(
        [sys.executable, "-m", "dea_opt.cli", "run", str(scenario), "-o", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert done.returncode == 2, done.stderr[-2000:]
    assert done.stderr.startswith("dea-opt: error:") and "Traceback" not in done.stderr
    assert "1e+30" in done.stderr


# --- normals normalised without overflow -----------------------------------------------


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


def test_a_zero_normal_is_still_an_error():
    with pytest.raises(d.InputError, match="normals must be nonzero vectors, got \\[0.0, 0.0, 0.0\\] at index 1"):
        d.SpringLayer([[0, 0, 0], [1, 0, 0]], [[0, 0, 1], [0, 0, 0]], 1.0, 1.0)
