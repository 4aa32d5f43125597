"""Finite kinematics by IPOPT give the same answer whatever the last digits of their sums.

A ball of radius 25 mm on a flat bed, ``rx, ry`` free about a reference 6.7 mm below its centre
and aside: the moment turns it 75 deg to a stable pose, where Newton converges. IPOPT, started
at rest where no spring touches, moved by steps that all reached the edge of its box; Anderson
acceleration of those steps extrapolated to a rotation of 1e15 degrees, whose residual (no
spring in contact, the whole load unbalanced: 1.0) tied with the plain step's. Which of two
equal residuals was the smaller was decided by their last bit: on some AMD EPYC machines the
leap was taken and IPOPT ended ``unbounded`` with ``Invalid_Number_Detected``, elsewhere it
passed. Here the residuals IPOPT compares are jittered by a few units in the last place (as
another CPU's rounding would), the start is moved by 1e-12, and BLAS runs on one thread or two:
the answer must be Newton's every time (its own equilibrium sums are written here).
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest
from conftest import ball_on_bed

import dea_opt as d
from dea_opt.formulations.finite import ipopt as finite_ipopt
from dea_opt.geometry import sphere_on_bed_layer

REFERENCE, MOMENT, FORCE = (3.6, -1.7, 18.7), (-49.0, 108.0, 23.0), (0.0, 0.0, -25.0)
CENTRE = np.array([0.0, 0.0, 25.0])


@pytest.fixture(scope="module")
def layer():
    return sphere_on_bed_layer(25.0, 2.0, 7.0, 24, 20)


def problem(layer):
    return ball_on_bed(layer, REFERENCE, MOMENT, ("rx", "ry"), FORCE, H=10.0, radius=25.0)


def quiet(*args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return d.solve(*args, **kw)


def net_moment(layer, u):
    """The springs' moment on the ball about its moved reference minus the load's, summed here
    (each spring's ray along +z to the moved sphere, its force ``H (-gap / h) S`` along +z)."""
    theta = u[9:12]
    t = np.linalg.norm(theta)
    W = np.array([[0, -theta[2], theta[1]], [theta[2], 0, -theta[0]], [-theta[1], theta[0], 0]])
    R = np.eye(3) + np.sin(t) / t * W + (1 - np.cos(t)) / t**2 * W @ W
    J = np.eye(3) + (1 - np.cos(t)) / t**2 * W + (t - np.sin(t)) / t**3 * W @ W
    reference = np.asarray(REFERENCE)
    centre = reference + R @ (CENTRE - reference)
    d_ = layer.points - centre
    beta = d_[:, 2]
    disc = beta**2 - (np.einsum("ij,ij->i", d_, d_) - 25.0**2)
    gap = np.where(disc > 0, -beta - np.sqrt(np.maximum(disc, 0)), np.inf)
    push = layer.areas * 10.0 * np.maximum(-gap / layer.thickness, 0.0)  # N along +z
    moment = np.cross(layer.points - reference, np.outer(push, [0.0, 0.0, 1.0])).sum(axis=0)
    return (J.T @ (moment + np.asarray(MOMENT)))[:2]  # the load's moment is -M on the springs' side


@pytest.fixture(scope="module")
def newton(layer):
    solution = quiet(problem(layer), "newton")
    assert solution.success and np.abs(net_moment(layer, solution.u)).max() < 1e-6 * 108.0
    return solution


@pytest.mark.parametrize("seed", [0, 1, *(pytest.param(seed, marks=pytest.mark.slow) for seed in range(2, 6))])
def test_residuals_jittered_in_their_last_digits_leave_ipopt_s_answer_as_it_is(layer, newton, seed, monkeypatch):
    rng = np.random.default_rng(seed)
    real = finite_ipopt._scaled_residual

    def jittered(state, T, energy_scale):  # another CPU's rounding: a few units in the last place
        return real(state, T, energy_scale) * (1.0 + float(rng.integers(-4, 5)) * 2.0**-52)

    monkeypatch.setattr(finite_ipopt, "_scaled_residual", jittered)
    ipopt = quiet(problem(layer), "nlp", x0=np.zeros(2))  # from rest, where the leap was taken
    assert ipopt.success and np.abs(ipopt.pose - newton.pose).max() < 1e-6
    assert np.abs(net_moment(layer, ipopt.u)).max() < 1e-6 * 108.0


@pytest.mark.parametrize(
    "shift",
    [
        (1e-12, 0.0),
        (-3e-12, 2e-12),
        *(pytest.param(s, marks=pytest.mark.slow) for s in ((0.0, -1e-12), (1e-12, 1e-12))),
    ],
)
@pytest.mark.slow
def test_a_start_moved_by_1e_12_gives_the_same_answer(layer, newton, shift):
    for method in ("nlp", "newton"):
        solution = quiet(problem(layer), method, x0=np.asarray(shift))
        assert solution.success and np.abs(solution.pose - newton.pose).max() < 1e-6


@pytest.mark.slow
def test_ipopt_never_takes_a_centre_turned_past_the_range_its_rotation_is_exact_for(layer, monkeypatch):
    """Every centre IPOPT's outer iterations evaluate turns body 2 at most 120 deg (where its
    rotation polynomial is exact), whatever Anderson extrapolates."""
    turns: list = []
    real = finite_ipopt._scaled_residual

    def seen(state, T, energy_scale):
        turns.append(float(np.linalg.norm(state.y[3:6])))
        return real(state, T, energy_scale) * (1.0 - 4 * 2.0**-52)  # ties lean toward the candidate

    monkeypatch.setattr(finite_ipopt, "_scaled_residual", seen)
    ipopt = quiet(problem(layer), "nlp", x0=np.zeros(2))
    assert ipopt.success and turns and max(turns) <= finite_ipopt.ROTATION_RANGE


@pytest.mark.parametrize("threads", ["1", "2"])
@pytest.mark.slow
def test_the_same_answer_with_blas_on_one_thread_or_two(layer, newton, threads, tmp_path):
    script = textwrap.dedent(f"""
        import sys, warnings
        import numpy as np
        sys.path[:0] = [{str(Path(__file__).resolve().parent)!r}, {str(Path(__file__).resolve().parents[1])!r}]
        from test_finite_rounding import problem
        import dea_opt as d
        from dea_opt.geometry import sphere_on_bed_layer
        warnings.simplefilter("ignore")
        solution = d.solve(problem(sphere_on_bed_layer(25.0, 2.0, 7.0, 24, 20)), "nlp", x0=np.zeros(2))
        np.save({str(tmp_path / "pose.npy")!r}, solution.pose if solution.success else np.full((4, 4), np.nan))
    """)
    names = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
    env = {**os.environ, **dict.fromkeys(names, threads)}
    subprocess.run([sys.executable, "-c", script], env=env, check=True, timeout=600)
    pose = np.load(tmp_path / "pose.npy")
    assert np.isfinite(pose).all() and np.abs(pose - newton.pose).max() < 1e-6
