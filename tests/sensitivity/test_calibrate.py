"""Calibration (formulations/sensitivity.md, "Calibration"): synthetic recovery on the real knee and
the hip, the censored residuals, the exact Jacobian, standard errors in closed form, the readers."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import KNEE
from scipy.special import log_ndtr

import dea_opt as d
from dea_opt.geometry import plate_layer, socket_layer, sphere_on_bed_layer
from dea_opt.sensitivity.calibrate import (
    FILMS,
    ContactData,
    Film,
    ForceDisplacement,
    PressureMap,
    _Model,
    apply_parameters,
    calibrate,
)

KNEE_FILES = ("femoral_cartilage.stl", "medial_tibial_cartilage.stl", "lateral_tibial_cartilage.stl")
TRUE = {"H": 5.0, "beta": 0.6}


def solve(problem):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        return d.solve(problem, "newton")


def film_reading(solution, seed, film="LLW"):
    """The solution's pressures with 5 % multiplicative noise, read through a film."""
    rng = np.random.default_rng(seed)
    measured = np.maximum(solution.pressure * (1 + 0.05 * rng.standard_normal(len(solution.pressure))), 0.0)
    return PressureMap(solution.problem.layer.points, measured, film=film)


def check_recovery(problem):
    truth = solve(problem.with_law(d.AteshianLaw(**TRUE)))
    data = film_reading(truth, seed=0)
    # a real film reading: some points below its range, a few saturated, most within
    assert (data.state == -1).sum() > 100 and (data.state == 1).sum() > 0 and (data.state == 0).sum() > 1000
    start = problem.with_law(d.AteshianLaw(2 * TRUE["H"], 2 * TRUE["beta"]))
    fit = calibrate(start, data, ("H", "beta"))
    assert fit.success
    assert fit.start == {"H": 10.0, "beta": 1.2}
    assert abs(fit.values["H"] / TRUE["H"] - 1) < 0.02
    assert abs(fit.values["beta"] / TRUE["beta"] - 1) < 0.10
    for name, value in TRUE.items():
        assert abs(fit.values[name] - value) < 3 * fit.standard_errors[name], (name, fit.values, fit.standard_errors)
    assert fit.correlation.shape == (2, 2) and fit.correlation[0, 0] == pytest.approx(1.0)
    assert -1 <= fit.correlation[0, 1] <= 1
    return fit


@pytest.fixture(scope="module")
def knee_problem():
    if not all((KNEE / name).is_file() for name in KNEE_FILES):
        pytest.skip(f"the knee meshes are not in {KNEE}")
    from dea_opt import mesh as M

    femur, medial, lateral = (M.load_mesh(KNEE / name) for name in KNEE_FILES)
    tibia, labels = M.concatenate_meshes({"medial": medial, "lateral": lateral})
    layer = M.springs_from_meshes(tibia, femur, labels=labels, max_gap=2.0)
    centre = 0.5 * sum((m.area_faces @ m.triangles_center) / m.area for m in (medial, lateral))
    return d.ContactProblem(
        layer, d.AteshianLaw(**TRUE), force=(0.0, 0.0, -1000.0), reference=tuple(centre), free=("uz", "ry")
    )


def test_synthetic_recovery_on_the_real_knee(knee_problem, tmp_path):
    fit = check_recovery(knee_problem)
    table = fit.residual_map()
    assert set(table.columns) >= {"x_mm", "y_mm", "z_mm", "measured_MPa", "predicted_MPa", "state", "residual"}
    assert set(table.state) == {"below", "measured", "saturated"}
    # censored points the model agrees with add nothing
    agree = (table.state == "below") & (table.predicted_MPa < 0.5 * FILMS["LLW"].lower)
    assert np.abs(table.residual[agree]).max() < 1e-6
    path = fit.plot(tmp_path / "knee_fit.png")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_synthetic_recovery_on_the_hip():
    """The demo's hip socket (meshed finer), 2.4 kN tilted 20 degrees from its axis."""
    layer = socket_layer(radius=25.0, thickness=3.0, coverage=80.0, n_rings=90, n_sectors=240, gap=0.3)
    tilt = np.radians(20.0)
    problem = d.ContactProblem(
        layer,
        d.AteshianLaw(**TRUE),
        force=2400.0 * np.array([np.sin(tilt), 0, -np.cos(tilt)]),
        reference=(0, 0, 0),
        free=("ux", "uy", "uz"),
    )
    check_recovery(problem)


def small_problem(law=None):
    law = law or d.AteshianLaw(0.6, 0.3)
    layer = sphere_on_bed_layer(radius=25.0, thickness=2.0, extent=7.0, n_rings=30, n_sectors=24)
    return d.ContactProblem(
        layer, law, force=(0, 0, -10.0), moment=(3.0, 0, 0), reference=(0, 0, 25.0), free=("uz", "rx", "ry")
    )


def test_the_jacobian_is_the_derivative_of_the_residuals():
    problem = small_problem()
    truth = solve(problem)
    rng = np.random.default_rng(3)
    data = (
        PressureMap(
            problem.layer.points,
            truth.pressure * np.exp(0.05 * rng.standard_normal(len(truth.pressure))),
            film=(0.05, 0.3),
        ),
        ContactData(area=90.0, center=(0.2, 0.1, 0.0)),
    )
    model = _Model(problem, data, ("H", "beta"), np.array([True, True]), "newton")
    z = np.log([0.7, 0.25])
    r, J, _ = model.evaluate(z)
    assert r.size == len(problem.layer) + 4
    for k in range(2):
        t = 1e-6
        step = np.eye(2)[k] * t
        fd = (model.evaluate(z + step)[0] - model.evaluate(z - step)[0]) / (2 * t)
        rows = slice(0, len(problem.layer))  # the area rate is a smoothed step, not a difference
        np.testing.assert_allclose(J[rows, k], fd[rows], rtol=1e-5, atol=1e-6 * np.abs(fd[rows]).max())
        np.testing.assert_allclose(J[-3:, k], fd[-3:], rtol=1e-5, atol=1e-8)  # centre of pressure


def test_censored_residuals_in_closed_form():
    """A plate under a uniform pressure of 1 MPa, read at three points through films."""
    layer = plate_layer(10.0, 10.0, 10, 10, thickness=2.0)
    s = solve(d.ContactProblem(layer, d.LinearLaw(1.0), force=(0, 0, -100.0), reference=(0, 0, 0), free=("uz",)))
    np.testing.assert_allclose(s.pressure, 1.0)
    points = layer.points[:3]

    def residual(reading, film):
        data = PressureMap(points[:1], [reading], film=film, noise=0.1)
        return data.residuals(s, None, (), {})[0][0]

    assert residual(1.2, None) == pytest.approx(np.log(1.0 / 1.2) / 0.1, rel=1e-5)  # log of hypot(m, floor)
    assert residual(0.5, "LLW") == pytest.approx(np.sqrt(-2 * log_ndtr(-np.log(1.0 / 0.5) / 0.1)), rel=1e-5)  # "below"
    assert residual(0.1, "LLLW") == pytest.approx(np.sqrt(-2 * log_ndtr(-np.log(1.0 / 0.2) / 0.1)), rel=1e-5)  # far off
    assert residual(0.6, "LLLW") == pytest.approx(
        np.sqrt(-2 * log_ndtr(np.log(1.0 / 0.6) / 0.1)), rel=1e-5
    )  # saturated
    assert residual(2.5, "LW") < 1e-6  # "below" 2.5 and the model says 1: it agrees
    assert residual(10.0, "LW") > 10.0  # "saturated" while the model says 1
    assert PressureMap(points, [0.5, 1.0, 2.5], film="LLW").state.tolist() == [-1, 0, 1]


def test_standard_error_in_closed_form():
    """Uniform pressure p = -Fz / S read with relative noise s at n points: se(Fz) = |Fz| s / sqrt(n)."""
    layer = plate_layer(10.0, 10.0, 20, 20, thickness=2.0)
    problem = d.ContactProblem(layer, d.LinearLaw(2.0), force=(0, 0, -100.0), reference=(0, 0, 0), free=("uz",))
    truth = solve(problem)
    rng = np.random.default_rng(5)
    data = PressureMap(layer.points, truth.pressure * np.exp(0.05 * rng.standard_normal(400)), noise=0.05)
    fit = calibrate(apply_parameters(problem, {"Fz": -60.0}), data, ("Fz",))
    assert fit.errors == "stated"  # the noise is stated: carried through the Jacobian
    assert fit.standard_errors["Fz"] == pytest.approx(abs(fit.values["Fz"]) * 0.05 / np.sqrt(400), rel=1e-6)
    # the fitted load is the geometric mean of the readings times the area
    expected = -np.exp(np.mean(np.log(data.pressure))) * layer.areas.sum()
    assert fit.values["Fz"] == pytest.approx(expected, rel=1e-8)


def test_force_displacement_curve_recovers_the_modulus():
    """A bonded plate pushed down by d: the layer pushes back with H S d / h."""
    layer = plate_layer(10.0, 10.0, 10, 10, thickness=2.0)
    problem = d.ContactProblem(layer, d.LinearLaw(3.0), force=(0, 0, 0), reference=(0, 0, 0), free=("rx", "ry"))
    approach = np.array([0.05, 0.1, 0.2])
    force = 7.5 * 100.0 * approach / 2.0  # the true H is 7.5 MPa
    fit = calibrate(problem, ForceDisplacement("uz", -approach, force, noise=0.1), ("H",))
    assert fit.values["H"] == pytest.approx(7.5, rel=1e-8)
    assert fit.nfev >= 3 * 2  # three prescribed solves per evaluation


def test_contact_area_and_centre_of_pressure():
    problem = small_problem()
    truth = solve(problem)
    data = ContactData(area=truth.contact_area, center=truth.center_of_pressure, area_std=1.0, center_std=0.01)
    fit = calibrate(problem.with_law(d.AteshianLaw(1.2, 0.3)), data, ("H",))
    assert fit.values["H"] == pytest.approx(0.6, rel=0.03)


def test_readers_and_placement(tmp_path):
    csv = tmp_path / "film.csv"
    csv.write_text("x,y,z,p,note\n0,0,0,1.5,a\n1,0,0,0.2,b\n")
    data = PressureMap.from_csv(csv, film="LLW")
    assert data.points.shape == (2, 3) and data.state.tolist() == [0, -1] and data.film is FILMS["LLW"]
    (tmp_path / "bad.csv").write_text("x,y,p\n0,0,1\n")
    with pytest.raises(d.InputError, match="missing z"):
        PressureMap.from_csv(tmp_path / "bad.csv")
    (tmp_path / "text.csv").write_text("x,y,z,p\n0,0,0,high\n")
    with pytest.raises(d.InputError, match="numbers"):
        PressureMap.from_csv(tmp_path / "text.csv")
    with pytest.raises(d.InputError, match="no such file"):
        PressureMap.from_csv(tmp_path / "none.csv")
    values = np.array([[1.0, 2.0, np.nan], [3.0, 4.0, 5.0]])
    grid = PressureMap.from_grid(values, origin=(10, 0, 5), axis_u=(0, 2, 0), axis_v=(0, 0, 1), spacing=(0.5, 2.0))
    np.testing.assert_allclose(grid.points[0], [10, 0.25, 6.0])  # cell (0, 0)
    np.testing.assert_allclose(grid.points[-1], [10, 1.25, 8.0])  # cell (2, 1)
    assert grid.pressure.tolist() == [1.0, 2.0, 3.0, 4.0, 5.0]
    with pytest.raises(d.InputError, match="parallel"):
        PressureMap.from_grid(values, (0, 0, 0), (1, 0, 0), (2, 0, 0), 1.0)
    with pytest.raises(d.InputError, match="film"):
        PressureMap(np.zeros((1, 3)), [1.0], film="XYZ")
    with pytest.raises(d.InputError, match="lower < upper"):
        Film(2.0, 1.0)
    with pytest.raises(d.InputError, match=">= 0"):
        PressureMap(np.zeros((1, 3)), [-1.0])


def test_bad_calibration_requests_are_named_errors():
    problem = small_problem()
    data = ContactData(area=90.0)
    with pytest.raises(d.InputError, match="parameters"):
        calibrate(problem, data, ("E",))
    with pytest.raises(d.InputError, match="start"):
        calibrate(problem, data, ("H",), start={"beta": 0.1})
    with pytest.raises(d.InputError, match="> 0"):
        calibrate(problem, data, ("H",), start={"H": -1.0})
    with pytest.raises(d.InputError, match="data"):
        calibrate(problem, [1, 2], ("H",))
    far = PressureMap(np.full((3, 3), 500.0), [1.0, 1.0, 1.0])
    with pytest.raises(d.InputError, match="within"):
        calibrate(problem, far, ("H",))
    with pytest.raises(d.InputError, match="translation"):
        ForceDisplacement("rx", [0.1], [1.0])
