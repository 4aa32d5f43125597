"""No input makes compiled code (NNLS, LAPACK, Clarabel, IPOPT) abort the
process. The reproducers run in a subprocess, which must exit cleanly with a named error."""

from __future__ import annotations

import subprocess
import sys
import textwrap

import numpy as np
import pytest

import dea_opt as d
from dea_opt.formulations import FormulationResult, SpringSystem
from dea_opt.formulations import get as formulation

METHODS = ("newton", "qp", "nlp", "auto")

#: Two springs on a sphere around the reference, only ``rx`` free: both lever arms are exactly
#: zero, so NNLS used to get an m x 0 matrix and the process died with "double free".
TWO_SPRINGS = """
import numpy as np
import dea_opt as d
points = np.array([[0.0, 0.0, -10.0], [0.0, -10.0, 0.0]])
layer = d.SpringLayer(points, -points / 10.0, 1.0, 1.0)
problem = d.ContactProblem(layer, d.LinearLaw(1.0), moment=(1e-3, 0, 0), reference=(0, 0, 0), free=("rx",))
"""


def _run(code: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(code)], capture_output=True, text=True, timeout=120, check=False
    )


@pytest.mark.parametrize("call", [f"d.solve(problem, {m!r})" for m in METHODS] + ["d.check_load_supported(problem)"])
def test_two_springs_on_a_sphere_with_only_rx_free_exit_cleanly(call):
    code = (
        TWO_SPRINGS
        + f"""
try:
    {call}
except d.LoadNotSupportedError as exc:
    print("named:", type(exc).__name__, exc.direction)
"""
    )
    done = _run(code)
    assert done.returncode == 0, f"exit {done.returncode}: {done.stderr[-2000:]}"
    assert "named: LoadNotSupportedError {'body2.rx': 0.001}" in done.stdout


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


def _system(m=1, n=3, load=None, e0=None):
    AT = np.zeros((m, n))
    AT[0] = 1.0
    return SpringSystem(
        AT, np.zeros(n) if e0 is None else e0, np.ones(n), np.ones(m) if load is None else load, stiffness=float(n)
    )


@pytest.mark.parametrize("method", ("newton", "qp", "nlp"))
@pytest.mark.parametrize("bad", [np.nan, np.inf])
def test_a_non_finite_load_never_reaches_the_solver(method, bad):
    """Formulations called directly (as load paths do) get a SolverError, not a crash or a raw
    error from inside cvxpy or CasADi."""
    system = _system(load=np.array([bad]))
    with pytest.raises(d.SolverError) as info:
        formulation(method).solve(system, d.LinearLaw(1.0))
    assert info.value.status is d.Status.NON_FINITE


@pytest.mark.parametrize("method", ("newton", "qp", "nlp"))
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


@pytest.mark.parametrize("method", METHODS)
def test_a_layer_without_springs_and_no_load_is_held(method):
    empty = d.SpringLayer(np.zeros((0, 3)), np.zeros((0, 3)), 1.0, 1.0)
    s = d.solve(d.ContactProblem(empty, d.LinearLaw(1.0), free=("uz", "rx")), method)
    assert s.success and s.status is d.Status.HELD and not s.u.any()
