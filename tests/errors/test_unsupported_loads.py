"""Loads no spring can carry, and problems with nothing to solve: a named LoadNotSupportedError
(with the unbalanced direction), or the answer "held", from every method; never a crash.

No such input makes compiled code (NNLS, LAPACK, Clarabel, IPOPT) abort the process: the
reproducers of the aborts that were run in a subprocess, which must exit cleanly with a named
error."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest
from conftest import METHODS

import dea_opt as d
from dea_opt.formulations import FormulationResult, SpringSystem
from dea_opt.formulations import get as formulation
from dea_opt.geometry import socket_layer, sphere_on_bed_layer


def _bed(force):
    layer = sphere_on_bed_layer(radius=25.0, thickness=2.0, extent=6.0, n_rings=30, n_sectors=16)
    return d.ContactProblem(layer, d.LinearLaw(0.6), force=force, reference=(0, 0, 25.0), free=("uz",))


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


@pytest.mark.parametrize("method", [*METHODS, "auto"])
def test_a_layer_without_springs_and_no_load_is_held(method):
    empty = d.SpringLayer(np.zeros((0, 3)), np.zeros((0, 3)), 1.0, 1.0)
    s = d.solve(d.ContactProblem(empty, d.LinearLaw(1.0), free=("uz", "rx")), method)
    assert s.success and s.status is d.Status.HELD and not s.u.any()


# --- the formulations called directly (as load paths do) --------------------------------------------


def _system(m=1, n=3, load=None, e0=None):
    AT = np.zeros((m, n))
    AT[0] = 1.0
    return SpringSystem(
        AT, np.zeros(n) if e0 is None else e0, np.ones(n), np.ones(m) if load is None else load, stiffness=float(n)
    )


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_a_non_finite_load_never_reaches_the_solver(method, bad):
    """A SolverError, not a crash or a raw error from inside cvxpy or CasADi."""
    system = _system(load=np.array([bad]))
    with pytest.raises(d.SolverError) as info:
        formulation(method).solve(system, d.LinearLaw(1.0))
    assert info.value.status is d.Status.NON_FINITE


@pytest.mark.parametrize("method", METHODS)
def test_no_resisted_direction_builds_no_solver(method):
    """Free dofs that no spring resists: the formulations answer 'held' without building a
    model (Clarabel and IPOPT never see an empty problem)."""
    AT = np.zeros((2, 4))  # no spring resists either dof
    system = SpringSystem(AT, np.full(4, -0.1), np.ones(4), np.zeros(2), stiffness=4.0)
    result = formulation(method).solve(system, d.LinearLaw(2.0))
    assert isinstance(result, FormulationResult)
    assert result.success and result.status is d.Status.HELD
    np.testing.assert_array_equal(result.u_free, 0.0)
    np.testing.assert_allclose(result.stress, -0.2)


# --- compiled code never aborts the process ------------------------------------------------------

#: Two springs on a sphere around the reference, only ``rx`` free: both lever arms are exactly
#: zero, so NNLS used to get an m x 0 matrix and the process died with "double free".
TWO_SPRINGS = """
import numpy as np
import dea_opt as d
points = np.array([[0.0, 0.0, -10.0], [0.0, -10.0, 0.0]])
layer = d.SpringLayer(points, -points / 10.0, 1.0, 1.0)
problem = d.ContactProblem(layer, d.LinearLaw(1.0), moment=(1e-3, 0, 0), reference=(0, 0, 0), free=("rx",))
"""

#: Each call of the two-spring reproducer, in one process: an abort in any of them ends the
#: process, and the calls it printed before say which one it was.
CALLS = [f"d.solve(problem, {m!r})" for m in (*METHODS, "auto")] + ["d.check_load_supported(problem)"]


def _run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, timeout=120, check=False
    )


def test_two_springs_on_a_sphere_with_only_rx_free_exit_cleanly():
    code = TWO_SPRINGS + "".join(
        f"""
try:
    {call}
except d.LoadNotSupportedError as exc:
    print({call!r}, "named:", type(exc).__name__, exc.direction, flush=True)
"""
        for call in CALLS
    )
    done = _run(code)
    assert done.returncode == 0, f"exit {done.returncode}: {done.stdout}{done.stderr[-2000:]}"
    for call in CALLS:
        assert f"{call} named: LoadNotSupportedError {{'body2.rx': 0.001}}" in done.stdout, call


def test_the_cone_test_never_hands_nnls_an_empty_matrix():
    """Springs resist uz, but their lever arms about x are exactly zero (all on the x axis)
    and a moment about y is loaded with uz and ry free: the cone test over the resisted
    directions must name the unbalanced part instead of aborting."""
    code = """
import numpy as np
import dea_opt as d
points = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
layer = d.SpringLayer(points, [[0, 0, 1.0], [0, 0, 1.0]], 1.0, 1.0)
problem = d.ContactProblem(layer, d.LinearLaw(1.0), force=(0, 0, 1.0), reference=(0, 0, 0), free=("uz", "ry"))
try:
    d.solve(problem, "qp")
except d.LoadNotSupportedError as exc:
    print("named:", type(exc).__name__)
"""
    done = _run(code)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "named: LoadNotSupportedError" in done.stdout
