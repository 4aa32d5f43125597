"""Acceptance 7 of the core: bad input gets a named DeaError, the same class from every method."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import METHODS

import dea_opt as d
from dea_opt.geometry import socket_layer, sphere_on_bed_layer

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


def test_unknown_method():
    p = d.ContactProblem(layer_with(), d.LinearLaw(1.0), force=(0, 0, -1), free=("uz",))
    with pytest.raises(d.InputError, match=r"method must be one of .* got 'simplex'"):
        d.solve(p, "simplex")


def test_qp_with_a_nonlinear_law_names_the_alternatives():
    p = d.ContactProblem(layer_with(), d.AteshianLaw(0.6, 0.1), force=(0, 0, -1), free=("uz",))
    with pytest.raises(d.InputError, match=r"method 'qp' needs a LinearLaw.*method='newton' or method='nlp'"):
        d.solve(p, "qp")


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


def _bed(law=None, force=(0, 0, -5.0), free=("uz",)):
    layer = sphere_on_bed_layer(radius=25.0, thickness=2.0, extent=6.0, n_rings=30, n_sectors=16)
    return d.ContactProblem(layer, law or d.LinearLaw(0.6), force=force, reference=(0, 0, 25.0), free=free)


@pytest.mark.parametrize("method", METHODS)
def test_load_pulling_the_bodies_apart(method):
    with pytest.raises(d.LoadNotSupportedError, match=r"force \+5 N along z on body2") as info:
        d.solve(_bed(force=(0, 0, 5.0)), method)
    assert info.value.direction["body2.uz"] == pytest.approx(5.0)


@pytest.mark.parametrize("method", [*METHODS, "auto"])
def test_moment_about_the_centre_of_a_ball_in_its_socket(method):
    layer = socket_layer(radius=25.0, thickness=2.0, coverage=80.0, n_rings=12, n_sectors=24)
    p = d.ContactProblem(layer, d.LinearLaw(1.0), force=(0, 0, -100.0), moment=(0, 0, 50.0))
    with pytest.raises(d.LoadNotSupportedError, match=r"moment \+50 N mm along z on body2"):
        d.solve(p, method)


@pytest.mark.parametrize("method", METHODS)
def test_free_body_without_springs(method):
    empty = d.SpringLayer(np.zeros((0, 3)), np.zeros((0, 3)), 1.0, 1.0)
    with pytest.raises(d.LoadNotSupportedError, match="no spring resists"):
        d.solve(d.ContactProblem(empty, d.LinearLaw(1.0), force=(0, 0, -1.0), free=("uz",)), method)


@pytest.mark.parametrize("method", ["newton", "nlp"])
@pytest.mark.parametrize(
    "law, force",
    [(d.AteshianLaw(0.6, 0.05), 400.0), (d.AteshianLaw(0.6, 0.0), 400.0), (d.BlankevoortLaw(0.6), 100.0)],
    ids=["ateshian", "ateshian-0", "log"],
)
def test_bounded_laws_pushed_towards_crushing_never_give_nan(method, law, force):
    # The log law's barrier is weak (finite energy at eps = -1), so it gets a smaller load.
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # no numpy warning
        warnings.simplefilter("ignore", d.ValidityWarning)  # nearly crushed: expected here
        s = d.solve(_bed(law, force=(0, 0, -force)), method)
    assert np.isfinite(s.pressure).all() and np.isfinite(s.u).all()
    assert -1 < s.strain.min() < -0.6
    assert s.certificate.passed


def test_linear_law_beyond_its_validity_warns():
    with pytest.warns(d.ValidityWarning, match="beyond the range"):
        d.solve(_bed(force=(0, 0, -20.0)), "newton")
    with pytest.warns(d.ValidityWarning, match="crushed"):
        d.solve(_bed(force=(0, 0, -400.0)), "newton")


def test_bounded_law_nearly_crushed_warns():
    with pytest.warns(d.ValidityWarning, match="nearly crushed"):
        s = d.solve(_bed(d.AteshianLaw(0.6, 0.0), force=(0, 0, -400.0)), "newton")
    assert -1 < s.strain.min() <= -0.95


def test_unknown_option_names_the_accepted_ones():
    with pytest.raises(d.InputError, match=r"method 'newton' takes the options .*'x0'.* got unknown option 'tolx'"):
        d.solve(_bed(), "newton", tolx=1e-3)
    with pytest.raises(d.InputError, match=r"unknown option 'solver'"):
        d.solve(_bed(), "nlp", solver="CLARABEL")


@pytest.mark.parametrize("tol", [0, -1e-6, 2.0, float("nan"), "tight"])
def test_bad_certificate_tolerance(tol):
    with pytest.raises(d.InputError, match="certificate_tol must be a number in"):
        d.solve(_bed(), "newton", certificate_tol=tol)
