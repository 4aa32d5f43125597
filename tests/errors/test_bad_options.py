"""Bad arguments of ``solve`` (the method, its options, the certificate's tolerance): a named
InputError naming the option, what was expected and what came, checked before any solver runs."""

from __future__ import annotations

import numpy as np
import pytest

import dea_opt as d
from dea_opt.geometry import sphere_on_bed_layer


@pytest.fixture(scope="module")
def small_bed():
    return sphere_on_bed_layer(radius=25.0, thickness=2.0, extent=7.0, n_rings=10, n_sectors=16)


def pressed(layer, law=None, **kw):
    return d.ContactProblem(
        layer, law or d.LinearLaw(1.0), force=(0, 0, -10.0), reference=(0, 0, 25.0), free=kw.pop("free", ("uz",)), **kw
    )


# --- the method and the names of its options ------------------------------------------------------


def test_unknown_method(small_bed):
    with pytest.raises(d.InputError, match=r"method must be one of .* got 'simplex'"):
        d.solve(pressed(small_bed), "simplex")


def test_qp_with_a_nonlinear_law_names_the_alternatives(small_bed):
    with pytest.raises(d.InputError, match=r"method 'qp' needs a LinearLaw.*method='newton' or method='nlp'"):
        d.solve(pressed(small_bed, d.AteshianLaw(0.6, 0.1)), "qp")


def test_unknown_option_names_the_accepted_ones(small_bed):
    with pytest.raises(d.InputError, match=r"method 'newton' takes the options .*'x0'.* got unknown option 'tolx'"):
        d.solve(pressed(small_bed), "newton", tolx=1e-3)
    with pytest.raises(d.InputError, match=r"unknown option 'solver'"):
        d.solve(pressed(small_bed), "nlp", solver="CLARABEL")


# --- the values of the options ------------------------------------------------------------------


@pytest.mark.parametrize("method", ("newton", "nlp", "auto"))
@pytest.mark.parametrize("x0", [np.zeros(3), [[0.0]], [np.nan], "zero"])
def test_x0_must_be_one_finite_value_per_free_dof(small_bed, method, x0):
    with pytest.raises(d.InputError, match="x0 must"):
        d.solve(pressed(small_bed), method, x0=x0)


@pytest.mark.parametrize("method", ("newton", "nlp", "auto"))
@pytest.mark.parametrize("max_iter", [2.5, 0, -3, True, "10"])
def test_max_iter_must_be_a_positive_integer(small_bed, method, max_iter):
    with pytest.raises(d.InputError, match="max_iter must be an integer >= 1"):
        d.solve(pressed(small_bed), method, max_iter=max_iter)


@pytest.mark.parametrize(
    "method, name", [("nlp", "tol"), ("qp", "tol"), ("newton", "gtol"), ("newton", "xtol"), ("auto", "tol")]
)
@pytest.mark.parametrize("value", [-1, 0, 1.5, float("nan"), float("inf"), "1e-8"])
def test_tolerances_must_lie_in_zero_one(small_bed, method, name, value):
    with pytest.raises(d.InputError, match=f"{name} must be a number in \\(0, 1\\)"):
        d.solve(pressed(small_bed), method, **{name: value})


@pytest.mark.parametrize("tol", [0, -1e-6, 2.0, float("nan"), "tight"])
def test_bad_certificate_tolerance(small_bed, tol):
    with pytest.raises(d.InputError, match="certificate_tol must be a number in"):
        d.solve(pressed(small_bed), "newton", certificate_tol=tol)


def test_options_are_checked_even_when_no_solver_runs(small_bed):
    """A problem answered without a solver (no load, no overlap) still rejects a bad option."""
    unloaded = d.ContactProblem(small_bed, d.LinearLaw(1.0), reference=(0, 0, 25.0), free=("uz",))
    with pytest.raises(d.InputError, match="x0 must"):
        d.solve(unloaded, "newton", x0=[1.0, 2.0])


# --- options handed to the solvers: what they reject is an input error ----------------------------


@pytest.mark.parametrize(
    "options, reason",
    [
        ({"bogus_key": 1}, "No such IPOPT option: bogus_key"),
        ({"tol": -1.0}, "Invalid options"),
    ],
)
def test_ipopt_options_ipopt_rejects_are_input_errors(small_bed, options, reason):
    with pytest.raises(d.InputError, match=f"ipopt_options .* were rejected by IPOPT: {reason}"):
        d.solve(pressed(small_bed), "nlp", ipopt_options=options)


@pytest.mark.parametrize("options", [["tol", 1e-8], {1: 2}])
def test_ipopt_options_must_be_a_dict_of_names(small_bed, options):
    with pytest.raises(d.InputError, match="ipopt_options must be a dict"):
        d.solve(pressed(small_bed), "nlp", ipopt_options=options)


@pytest.mark.parametrize("solver", ["CLARABEL", "OSQP", "SCS", "PIQP"])
def test_an_unknown_qp_solver_setting_is_an_input_error(small_bed, solver):
    with pytest.raises(d.InputError, match=f"{solver} rejected the options \\['bogus'\\]"):
        d.solve(pressed(small_bed), "qp", solver=solver, bogus=1)


def test_an_option_no_method_of_auto_knows_is_refused_even_where_newton_answers(small_bed):
    """``auto`` hands an option Newton does not declare to the QP's solver, its fallback: an option
    Clarabel does not know either is refused before anything is solved, not only on the day the
    fallback runs (a misspelt option of a load path, such as ``keep_solutions`` given to
    ``solve_path`` instead of in its ``outputs``, was silently dropped)."""
    problem = pressed(small_bed)
    assert d.solve(problem, "auto").method == "newton"  # the fallback would not run
    with pytest.raises(d.InputError, match=r"CLARABEL rejected the options \['keep_solutions'\]"):
        d.solve(problem, "auto", keep_solutions=False)
    loads = np.array([[0.0, 0.0, -10.0], [0.0, 0.0, -20.0]])
    with pytest.raises(d.InputError, match=r"CLARABEL rejected the options \['keep_solutions'\]"):
        d.solve_path(problem, loads, method="auto", keep_solutions=False)
    assert d.solve(problem, "auto", equilibrate_enable=True).success  # a setting Clarabel knows passes
