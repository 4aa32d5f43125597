"""Failure paths, each forced: every one ends as a SolverError or a certified success; and loads
that push a layer towards crushing, which end in a finite answer with a ValidityWarning, or a
SolverError that says "crushed".

Also ``method="auto"``: Newton first, then the constrained formulation that fits the law.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import pytest

import dea_opt as d
from dea_opt import Status
from dea_opt.geometry import plate_layer, sphere_on_bed_layer
from dea_opt.study import installed_qp_solvers


def _plate(law=None, e=5.0):
    layer = plate_layer(40.0, 10.0, 80, 4, thickness=2.0)
    return d.ContactProblem(
        layer, law or d.LinearLaw(10.0), load=d.Load((0, 0, -500.0), point=(e, 0, 0)), free=("uz", "rx", "ry")
    )


def _bed(law=None, force=5.0):
    """A ball on a bed pressed down by ``force`` (N), only ``uz`` free (linear law H = 0.6 MPa
    by default)."""
    layer = sphere_on_bed_layer(radius=25.0, thickness=2.0, extent=6.0, n_rings=30, n_sectors=16)
    law = law or d.LinearLaw(0.6)
    return d.ContactProblem(layer, law, force=(0, 0, -force), reference=(0, 0, 25.0), free=("uz",))


def _certified_or_solver_error(problem, method, **options):
    """Run a forced failure; return the solution if certified, None if a SolverError."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", d.ValidityWarning)
            s = d.solve(problem, method, **options)
    except d.SolverError as exc:
        assert exc.status, "a SolverError carries the solver's status"
        if exc.solution is not None:
            assert not exc.solution.success
        return None
    assert s.success and s.certificate.passed
    assert np.isfinite(s.pressure).all()
    return s


@dataclass(frozen=True)
class CubicOnly(d.Law):
    """``sigma = H eps^3``: its tangent is zero at eps = 0, singular at Newton's start."""

    H: float = 1.0
    name = "cubic-only"

    def stress_expr(self, eps, xp):
        return self.H * eps**3

    def tangent_expr(self, eps, xp):
        return 3 * self.H * eps**2

    def energy_expr(self, eps, xp):
        return 0.25 * self.H * eps**4


@dataclass(frozen=True)
class NaNLaw(d.Law):
    """A broken user law: NaN stress beyond 10 % compression."""

    H: float = 10.0
    name = "nan-law"

    def _nan_beyond(self, value, eps):
        return np.where(np.asarray(eps) < -0.1, np.nan, value) if isinstance(eps, np.ndarray) else value

    def stress_expr(self, eps, xp):
        return self._nan_beyond(self.H * eps, eps)

    def tangent_expr(self, eps, xp):
        return self._nan_beyond(self.H + 0 * eps, eps)

    def energy_expr(self, eps, xp):
        return self._nan_beyond(0.5 * self.H * eps * eps, eps)


def test_qp_iteration_limit():
    assert _certified_or_solver_error(_plate(), "qp", max_iter=2) is None


def test_nlp_iteration_limit():
    """From the zero motion (a cold start; from Newton's answer IPOPT can finish in two), two
    iterations are too few."""
    problem = _plate()
    assert _certified_or_solver_error(problem, "nlp", max_iter=2, x0=np.zeros(problem.system().n_dofs)) is None


def test_newton_iteration_limit():
    assert _certified_or_solver_error(_plate(e=10.0), "newton", max_iter=1) is None


#: First-order QP solvers that stop early at a loose tolerance, those installed here.
LOOSE = [
    (solver, options)
    for solver, options in (("SCS", {}), ("OSQP", {"polishing": False}))
    if solver in installed_qp_solvers()
]


@pytest.mark.parametrize("solver, options", LOOSE)
def test_inaccurate_answer_is_not_a_success(solver, options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        s = d.solve(_plate(e=10.0), "qp", solver=solver, tol=1e-1, strict=False, **options)
    assert not s.success
    assert not s.certificate.passed
    assert s.status is Status.INACCURATE and s.info["native_status"] in ("optimal", "optimal_inaccurate")
    with pytest.raises(d.SolverError, match="no certified answer"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            d.solve(_plate(e=10.0), "qp", solver=solver, tol=1e-1, **options)


def test_qp_solver_that_raises(monkeypatch):
    """Clarabel, called through its own API, raising inside its solve (a Rust panic arrives
    as an exception of its own type)."""
    import clarabel

    class Broken:
        def __init__(self, *args):
            pass

        def solve(self):
            raise RuntimeError("forced failure")

    monkeypatch.setattr(clarabel, "DefaultSolver", Broken)
    with pytest.raises(d.SolverError, match="forced failure") as info:
        d.solve(_plate(), "qp")
    assert info.value.status is Status.SOLVER_ERROR


@pytest.mark.parametrize("solver", [s for s in ("OSQP", "PIQP", "SCS") if s in installed_qp_solvers()][:1])
def test_qp_solver_through_cvxpy_that_raises(monkeypatch, solver):
    import cvxpy as cp

    def broken(self, *args, **kwargs):
        raise cp.error.SolverError("forced failure")

    monkeypatch.setattr(cp.Problem, "solve", broken)
    with pytest.raises(d.SolverError, match="forced failure") as info:
        d.solve(_plate(), "qp", solver=solver)
    assert info.value.status is Status.SOLVER_ERROR


def test_nlp_solver_that_raises(monkeypatch):
    from dea_opt.formulations import nlp

    original = nlp.NLPModel.__init__

    def init(self, *args, **kwargs):
        original(self, *args, **kwargs)

        def broken(**_):
            raise RuntimeError("forced IPOPT failure")

        self.solver = broken

    monkeypatch.setattr(nlp.NLPModel, "__init__", init)
    with pytest.raises(d.SolverError, match="forced IPOPT failure") as info:
        d.solve(_plate(), "nlp")
    assert info.value.status is Status.SOLVER_ERROR and info.value.native_status == "exception"


@pytest.mark.parametrize("form", ["constrained", "reduced"])
def test_ipopt_near_the_edge_of_the_ateshian_domain(form):
    # A heavy load drives strains close to -1, where the law is undefined beyond.
    s = _certified_or_solver_error(_bed(d.AteshianLaw(0.6, 0.05), 400.0), "nlp", form=form)
    if s is not None:
        assert -1 < s.strain.min() < -0.7


def test_singular_tangent_at_the_start_fails_newton_and_auto_falls_back():
    problem = _plate(CubicOnly(50.0))
    with pytest.raises(d.SolverError) as info:
        d.solve(problem, "newton")
    assert info.value.status in (Status.STALLED, Status.LINE_SEARCH_FAILED, Status.MAX_ITERATIONS)
    s = d.solve(problem, "auto")
    assert s.success and s.method == "nlp"
    assert "newton ended with status" in s.info["fallback"]
    assert s.info["requested"] == "auto"


def test_auto_uses_newton_when_it_succeeds_and_qp_for_linear_fallback(monkeypatch):
    s = d.solve(_plate())
    assert s.method == "newton" and s.info["fallback"] is None
    from dea_opt.formulations import newton

    def fails(self, load=None, *, x0=None):
        return d.formulations.FormulationResult(
            u_free=np.zeros(self.system.n_dofs),
            stress=np.zeros(self.system.n_springs),
            success=False,
            status=Status.MAX_ITERATIONS,
            message="forced failure",
        )

    monkeypatch.setattr(newton.NewtonModel, "solve", fails)
    s = d.solve(_plate())
    assert s.method == "qp" and "max_iterations" in s.info["fallback"]


def test_auto_is_the_default():
    import inspect

    assert inspect.signature(d.solve).parameters["method"].default == "auto"


@pytest.mark.parametrize("method", ["newton", "nlp", "auto"])
def test_nan_from_a_user_law_is_never_a_success(method):
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        assert _certified_or_solver_error(_plate(NaNLaw(), e=10.0), method) is None


def test_log_law_beyond_its_capacity_says_crushed():
    with pytest.raises(d.SolverError, match="crushed"):
        d.solve(_bed(d.BlankevoortLaw(0.6), 400.0), "newton")


def test_strict_false_returns_the_uncertified_solution():
    s = d.solve(_plate(e=10.0), "newton", max_iter=1, strict=False)
    assert not s.success and s.status is Status.MAX_ITERATIONS and s.info["native_status"] == "max_iter"


# --- towards crushing ---------------------------------------------------------------------------


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
        s = d.solve(_bed(law, force), method)
    assert np.isfinite(s.pressure).all() and np.isfinite(s.u).all()
    assert -1 < s.strain.min() < -0.6
    assert s.certificate.passed


def test_linear_law_beyond_its_validity_warns():
    with pytest.warns(d.ValidityWarning, match="beyond the range"):
        d.solve(_bed(force=20.0), "newton")
    with pytest.warns(d.ValidityWarning, match="crushed"):
        d.solve(_bed(force=400.0), "newton")


def test_bounded_law_nearly_crushed_warns():
    with pytest.warns(d.ValidityWarning, match="nearly crushed"):
        s = d.solve(_bed(d.AteshianLaw(0.6, 0.0), 400.0), "newton")
    assert -1 < s.strain.min() <= -0.95
