"""What each solver sees: Clarabel through its own API gets exactly the minimal QP, a
solver reached through cvxpy gets no auxiliary variable or row, IPOPT gets the block copies of
the dofs and nothing more; and each answers random systems whose equilibrium and law this file
checks with its own sums."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import scipy.sparse as sp

import dea_opt as d
from dea_opt.formulations import SpringSystem
from dea_opt.formulations.nlp import NLPModel
from dea_opt.formulations.qp import QPModel, _contact_rows
from dea_opt.study import installed_qp_solvers

#: QP solvers reached through cvxpy that are installed here (OSQP and PIQP are in [dev]).
THROUGH_CVXPY = [s for s in ("OSQP", "PIQP") if s in installed_qp_solvers()]


def random_system(seed: int, m: int = 3, n: int = 60) -> tuple[SpringSystem, np.ndarray]:
    """A random system whose load lies inside the cone the springs carry: ``r = A^T (V sigma)``
    for a stress ``sigma <= 0`` on a random third of the springs. Returns it and a second load
    built the same way."""
    rng = np.random.default_rng(seed)
    AT = rng.normal(size=(m, n))
    e0 = rng.uniform(-0.01, 0.05, n)
    volume = rng.uniform(0.5, 5.0, n)

    def load():
        sigma = -rng.uniform(0.1, 2.0, n) * (rng.random(n) < 0.35)
        return AT @ (volume * sigma)

    return SpringSystem(AT, e0, volume, load(), stiffness=float(volume.sum())), load()


def own_check(system: SpringSystem, H: float, load, u, stress) -> None:
    """The law and equilibrium by this test's own sums: ``sigma_i = H min(e0_i + a_i . u, 0)``
    and ``sum_i V_i sigma_i a_i = r`` (the stationarity of ``sum V w(eps) - r . u``)."""
    eps = system.e0 + system.AT.T @ u
    np.testing.assert_allclose(stress, H * np.minimum(eps, 0.0), rtol=0, atol=1e-7 * np.abs(stress).max())
    balance = system.AT @ (system.volume * stress)
    np.testing.assert_allclose(balance, load, rtol=0, atol=1e-7 * np.abs(load).max())


def test_clarabel_sees_the_minimal_qp():
    """k + N variables, a diagonal P with the N springs' weights, and 2N rows of the
    nonnegative cone: the same matrices as the reported QP built here with scipy's blocks."""
    system, _ = random_system(0)
    H = 2.0
    model = QPModel(system, d.LinearLaw(H))
    sc, n = model.scale, system.n_springs
    k, s0 = sc.n_dofs, sc.strain_scale
    G, P, b = model.backend.G, model.backend.P, model.backend.b
    expected_G = sp.block_array([[None, -sp.eye_array(n)], [sp.csc_array(-sc.AT.T / s0), -sp.eye_array(n)]])
    expected_P = sp.diags_array(np.concatenate([np.zeros(k), sc.volume * H * s0**2]))
    assert G.shape == (2 * n, k + n) and G.nnz == k * n + 2 * n
    assert P.shape == (k + n, k + n) and P.nnz == n
    assert abs(G - expected_G).max() == 0 and abs(P - expected_P).max() == 0
    np.testing.assert_array_equal(b, np.concatenate([np.zeros(n), system.e0 / s0]))


@pytest.mark.parametrize("seed", range(4))
def test_clarabel_s_contact_rows_leave_out_the_dofs_a_spring_does_not_feel(seed):
    """``G`` of an ``A T`` with a dof some springs do not feel (zeros), one no spring feels and one
    every spring feels: the issue's QP built with scipy's blocks and ``eliminate_zeros``, entry for
    entry and in the same order, with int32 indices; and the model's ``P``, likewise."""
    rng = np.random.default_rng(seed)
    k, n = 4, 50
    AT = rng.normal(size=(k, n))
    AT[0, rng.random(n) < 0.4] = 0.0
    AT[2] = 0.0
    s0 = rng.uniform(0.1, 10.0)
    G = sp.csc_array(_contact_rows(AT, s0), shape=(2 * n, k + n))
    expected = sp.csc_array(sp.block_array([[None, -sp.eye_array(n)], [sp.csc_array(-AT.T / s0), -sp.eye_array(n)]]))
    expected.eliminate_zeros()
    expected.sort_indices()
    assert G.indices.dtype == np.int32 and G.indptr.dtype == np.int32
    assert G.has_sorted_indices and G.shape == expected.shape
    np.testing.assert_array_equal(G.indptr, expected.indptr)
    np.testing.assert_array_equal(G.indices, expected.indices)
    np.testing.assert_array_equal(G.data, expected.data)
    system, _ = random_system(seed)
    H = 3.0
    model = QPModel(system, d.LinearLaw(H))
    sc = model.scale
    expected_P = sp.csc_array(sp.diags_array(np.concatenate([np.zeros(sc.n_dofs), sc.volume * H * sc.strain_scale**2])))
    expected_P.eliminate_zeros()
    P = model.backend.P
    np.testing.assert_array_equal(P.indptr, expected_P.indptr)
    np.testing.assert_array_equal(P.indices, expected_P.indices)
    np.testing.assert_array_equal(P.data, expected_P.data)


@pytest.mark.parametrize("solver", THROUGH_CVXPY)
def test_a_solver_through_cvxpy_sees_no_auxiliary_variable_or_row(solver):
    """``sum_squares`` of a variable (not of ``multiply(w, c)``): cvxpy hands the solver k + N
    variables, N springs' weights in P, and only the contact rows besides the bounds."""
    system, _ = random_system(1)
    model = QPModel(system, d.LinearLaw(1.0), solver=solver)
    data, _, _ = model.backend.problem.get_problem_data(solver)
    k, n = model.scale.n_dofs, system.n_springs
    assert data["P"].shape == (k + n, k + n) and data["P"].nnz == n
    assert data["A"].shape[0] == 0  # no equality rows
    assert data["F"].shape[1] == k + n and data["F"].shape[0] in (n, 2 * n)  # contact rows (+ c >= 0)


@pytest.mark.parametrize("solver", ["CLARABEL", *THROUGH_CVXPY])
@pytest.mark.parametrize("seed", range(4))
def test_random_systems_by_our_own_sums(solver, seed):
    system, other = random_system(seed)
    H = 3.0
    model = QPModel(system, d.LinearLaw(H), solver=solver, tol=1e-12)
    for load in (system.load, other, 0.5 * system.load):
        result = model.solve(load)
        assert result.success, result.message
        own_check(system, H, load, result.u_free, result.stress)


@pytest.mark.parametrize("seed", range(3))
def test_a_re_solve_with_a_new_load_is_a_fresh_solve(seed):
    """Only q changes in Clarabel's update: the answer is that of a model built for the new load."""
    system, other = random_system(seed, m=6, n=200)
    law = d.LinearLaw(1.5)
    model = QPModel(system, law, tol=1e-12)
    model.solve()
    again = model.solve(other)
    fresh = QPModel(
        SpringSystem(system.AT, system.e0, system.volume, other, stiffness=system.stiffness), law, tol=1e-12
    ).solve()
    assert again.build_time == 0.0 and fresh.build_time > 0.0
    np.testing.assert_allclose(again.u_free, fresh.u_free, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(again.stress, fresh.stress, rtol=0, atol=1e-8 * np.abs(fresh.stress).max())


def test_a_load_the_springs_cannot_carry_is_clarabel_s_dual_infeasibility():
    """Called directly (no cone test before it), a load pulling body 2 away from every spring
    leaves the QP unbounded: Clarabel's DualInfeasible, reported as 'unbounded' with no answer."""
    AT = np.ones((1, 5))  # every spring stretches when body 2 moves along +x
    system = SpringSystem(AT, np.zeros(5), np.ones(5), np.array([1.0]), stiffness=5.0)
    result = QPModel(system, d.LinearLaw(1.0)).solve()
    assert not result.success and result.status is d.Status.UNBOUNDED
    assert result.info["native_status"] in ("DualInfeasible", "AlmostDualInfeasible")
    assert np.isnan(result.u_free).all() and np.isnan(result.stress).all()


def test_a_setting_clarabel_does_not_know_is_named_when_the_model_is_built():
    system, _ = random_system(2)
    with pytest.raises(d.InputError, match=r"CLARABEL rejected the options \['tol_gap'\]"):
        QPModel(system, d.LinearLaw(1.0), tol_gap=1e-9)
    with pytest.raises(d.InputError, match=r"CLARABEL rejected the options \['max_iter'\]"):
        QPModel(system, d.LinearLaw(1.0), max_iter="many")


def test_the_default_qp_imports_no_cvxpy():
    """cvxpy costs most of a second to import: a qp solve with the default solver (its name
    given, as a scenario gives it) never loads it."""
    code = (
        "import sys, dea_opt as d; from dea_opt.geometry import plate_layer; "
        "p = d.ContactProblem(plate_layer(10.0, 10.0, 8, 8, thickness=2.0), d.LinearLaw(5.0), "
        "force=(0, 0, -50.0), free=('uz',)); s = d.solve(p, 'qp', solver='clarabel'); "
        "print(s.success, s.info['native_status'], 'cvxpy' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False)
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["True", "Solved", "False"]


@pytest.mark.parametrize("n", [1, 7, 60, 401])
def test_ipopt_sees_the_block_copies_and_nothing_more(n):
    """The constrained NLP: k dofs per block of about sqrt(N) springs (the first block's copy
    is x itself) and N compressive strains; N contact rows and k ties per further block."""
    system, _ = random_system(3, m=4, n=n)
    model = NLPModel(system, d.CubicLaw(2.0, 0.3))
    k, nb = model.scale.n_dofs, model.n_blocks
    assert nb == int(np.ceil(n / np.ceil(np.sqrt(n))))
    assert model.solver.size1_in("x0") == k * nb + n
    assert model.solver.size1_in("lbg") == n + k * (nb - 1)
    result = model.solve()
    assert result.success, result.message
    law = d.CubicLaw(2.0, 0.3)
    eps = system.e0 + system.AT.T @ result.u_free
    np.testing.assert_allclose(
        result.stress, law.stress(np.minimum(eps, 0.0)), rtol=0, atol=1e-6 * np.abs(result.stress).max()
    )
    np.testing.assert_allclose(
        system.AT @ (system.volume * result.stress), system.load, rtol=0, atol=1e-6 * np.abs(system.load).max()
    )
