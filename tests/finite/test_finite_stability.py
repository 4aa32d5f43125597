"""Finite kinematics: an equilibrium body 2 leaves at the smallest disturbance is no answer.

A ball of radius 25 mm on a flat bed of springs, ``uz, rx, ry`` free about a reference 3 mm off
its centre, under 68 N and a moment. The springs push along +z through the ball's centre; a
load applied at a reference above the centre tips the ball as it turns (an inverted pendulum),
one below it rights the ball (a pendulum). Above, with exact rotations the forces balance at a
pose turned 15 deg, but the ball leaves it at the smallest disturbance: IPOPT finds that point and
its certificate passes; Newton, which descends the energy, leaves it (``unbounded``). The
``stability`` validity check tells them apart (``formulations/validity.md``, section 7).

The test's own model: each spring's gap to the moved sphere in closed form (the ray from the
spring along +z meets the sphere's lower half), its force ``H (-gap / h) S`` along +z, summed into
the net force and moment on the ball about its moved reference, mapped to the rotation vector by
the left Jacobian, and differentiated by central differences."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import ball_on_bed

import dea_opt as d
from dea_opt.geometry import sphere_on_bed_layer
from dea_opt.validity import ValidityLimits, assess

RADIUS, H = 25.0, 10.0
CENTRE = np.array([0.0, 0.0, RADIUS])
ABOVE = (1.3, 1.4, 27.6)  # the reference 2.6 mm above the ball's centre, 1.9 mm aside
BELOW = (1.3, 1.4, 22.4)
FREE = ("uz", "rx", "ry")
FORCE = (0.0, 0.0, -68.0)
TIPPING = (57.0, -131.0, -227.0)  # N mm: balanced only where it tips the ball
HELD = (5.0, -10.0, 0.0)  # N mm: the ball settles


@pytest.fixture(scope="module")
def layer():
    return sphere_on_bed_layer(RADIUS, 2.0, 7.0, 24, 20)


def ball(layer, moment, reference, free=FREE, force=FORCE):
    return ball_on_bed(layer, reference, moment, free, force, H=H, radius=RADIUS)


def quiet(function, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return function(*args, **kw)


def _hat(v):
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _rotation(theta):
    t = np.linalg.norm(theta)
    W = _hat(theta)
    if t < 1e-12:
        return np.eye(3) + W
    return np.eye(3) + np.sin(t) / t * W + (1 - np.cos(t)) / t**2 * W @ W


def _left_jacobian(theta):
    t = np.linalg.norm(theta)
    W = _hat(theta)
    if t < 1e-8:
        return np.eye(3) + 0.5 * W
    return np.eye(3) + (1 - np.cos(t)) / t**2 * W + (t - np.sin(t)) / t**3 * W @ W


def net_generalized(layer, moment, reference, y, load=FORCE):
    """The net generalized force on the ball (springs plus load) at body 2's coordinates ``y`` (6,):
    force (N) and the moment about its moved reference mapped to the rotation vector (N mm)."""
    t, theta = y[:3], y[3:]
    reference = np.asarray(reference)
    centre = reference + t + _rotation(theta) @ (CENTRE - reference)
    points, normals = layer.points, layer.normals  # normals +z
    to_centre = centre - points
    along = np.einsum("ij,ij->i", to_centre, normals)
    gap = along - np.sqrt(along**2 - np.einsum("ij,ij->i", to_centre, to_centre) + RADIUS**2)
    pressure = H * np.maximum(-gap / layer.thickness, 0.0)
    push = (pressure * layer.areas)[:, None] * normals
    force = push.sum(axis=0) + np.asarray(load)
    arm = np.cross(points - (reference + t), push).sum(axis=0) + np.asarray(moment)
    return np.concatenate([force, _left_jacobian(theta).T @ arm])


def stiffness_of(layer, moment, reference, solution, step=1e-6):
    """``-d(net)/dy`` on the free coordinates at the solution, by central differences, and the net there."""
    free = [d.DOFS.index(name) - 6 for name in FREE]
    y = np.array(solution.u[6:], dtype=float)
    K = np.zeros((len(free), len(free)))
    for column, index in enumerate(free):
        dy = np.zeros(6)
        dy[index] = step
        plus, minus = (
            net_generalized(layer, moment, reference, y + dy),
            net_generalized(layer, moment, reference, y - dy),
        )
        K[:, column] = -(plus - minus)[free] / (2 * step)
    return K, net_generalized(layer, moment, reference, y)[free]


def scaled(layer, reference, K):
    """``K`` in the springs' motion (mm): a rotation times the springs' RMS radius about the
    reference (the inertia of a body whose mass lies at the springs), ``D^-1 K D^-1``."""
    rho = np.sqrt(np.mean(np.sum((layer.points - np.asarray(reference)) ** 2, axis=1)))
    lengths = np.array([1.0 if name.startswith("u") else rho for name in FREE])
    return K / lengths[:, None] / lengths[None, :]


def instability(layer, reference, K) -> float:
    """``-min Re(lambda) / max |lambda|`` of the scaled tangent: above 0 where a disturbance grows."""
    values = np.linalg.eigvals(scaled(layer, reference, K))
    return float(-values.real.min() / np.abs(values).max())


def test_ipopt_certifies_a_tipping_equilibrium_that_fails_the_stability_check(layer):
    # from rest (IPOPT's own start is the small kinematics' answer, from which it turns past its range)
    solution = quiet(d.solve, ball(layer, TIPPING, ABOVE), "nlp", x0=np.zeros(3))
    assert solution.success  # the forces balance there: the certificate passes
    K, net = stiffness_of(layer, TIPPING, ABOVE, solution)
    assert np.abs(net).max() < 1e-5 * 227.0  # equilibrium, summed here
    assert np.degrees(np.linalg.norm(solution.u[9:])) > 10.0
    eigenvalues = np.linalg.eigvals(K)
    assert eigenvalues.real.min() < -0.01 * np.abs(eigenvalues).max()  # a disturbance grows
    check = solution.validity["stability"]
    assert check.passed is False and not solution.validity.valid
    assert instability(layer, ABOVE, K) > 1e-4
    assert check.value == pytest.approx(instability(layer, ABOVE, K), rel=1e-4)
    along = solution.info["softest_direction"]
    assert "rx" in along and "deg" in along and along in check.advice
    assert "unstable" in check.advice and "ligaments" in check.advice
    # Newton, descending the energy, does not stop there
    newton = quiet(d.solve, ball(layer, TIPPING, ABOVE), "newton", strict=False)
    assert newton.status is d.Status.MAX_ITERATIONS and not newton.success
    assert newton.info["unproved"] == "unbounded" and "the energy decreases without bound" in newton.message
    assert newton.validity["stability"].passed is None  # no equilibrium to test


def test_a_ball_that_settles_passes_the_stability_check_and_newton_and_ipopt_agree(layer):
    solution = quiet(d.solve, ball(layer, HELD, BELOW), "newton")
    assert solution.success
    K, net = stiffness_of(layer, HELD, BELOW, solution)
    assert np.abs(net).max() < 1e-6 * 68.0
    assert np.linalg.eigvals(K).real.min() > 0.0
    check = solution.validity["stability"]
    assert check.passed is True and check.value <= 0.0 and solution.validity.valid
    assert check.value == pytest.approx(instability(layer, BELOW, K), rel=1e-4)
    ipopt = quiet(d.solve, ball(layer, HELD, BELOW), "nlp")
    assert ipopt.success and np.abs(ipopt.u - solution.u).max() < 1e-6
    assert ipopt.validity["stability"].passed is True


def test_the_small_kinematics_do_not_evaluate_stability_their_energy_is_convex(layer):
    small = quiet(d.solve, d.ContactProblem(layer, d.LinearLaw(H), force=FORCE, reference=BELOW, free=FREE))
    check = small.validity["stability"]
    assert check.passed is None and "convex" in check.advice and "stability" not in small.validity.as_dict()["failed"]


def test_assess_takes_a_stability_value_and_its_limit(layer):
    problem = ball(layer, HELD, BELOW)
    u = np.zeros(12)
    unstable = assess(problem, u, stability=0.2, softest="rx +1.5 deg")
    assert unstable["stability"].passed is False and "along rx +1.5 deg" in unstable["stability"].advice
    assert assess(problem, u, stability=-0.3)["stability"].passed is True
    assert assess(problem, u, stability=0.2, limits=ValidityLimits(stability=0.5))["stability"].passed is True
    assert "not finite" in assess(problem, u, stability=float("nan"))["stability"].advice
    assert assess(problem, u)["stability"].passed is None
    with pytest.raises(d.InputError, match="ValidityLimits.stability"):
        ValidityLimits(stability=-1.0)


@pytest.mark.slow
def test_a_line_search_step_grown_past_a_quarter_turn_is_scanned_not_taken(layer):
    """``rx, ry`` free about a reference 6.7 mm below the ball's centre and aside: the moment turns
    the ball 75 deg to a stable pose. The line search once grew its steps fourfold to a point
    1000 turns away where the Wolfe conditions happened to hold, and the iterates ran to 1e15
    degrees (``unbounded``); a grown step that turns the ball past a quarter turn now has the
    turn scanned one degree apart instead."""
    reference, moment, force = (3.6, -1.7, 18.7), (-49.0, 108.0, 23.0), (0.0, 0.0, -25.0)

    newton = quiet(d.solve, ball(layer, moment, reference, ("rx", "ry"), force), "newton")
    rotation = newton.pose[:3, :3]
    turn = np.degrees(np.arccos(np.clip((np.trace(rotation) - 1) / 2, -1, 1)))  # the pose's, however written
    assert newton.success and 60.0 < turn < 90.0
    net = net_generalized(layer, moment, reference, newton.u[6:], force)[[3, 4]]
    assert np.abs(net).max() < 1e-6 * 108.0  # equilibrium about rx, ry, summed here
    assert newton.validity["stability"].passed is True
    ipopt = quiet(d.solve, ball(layer, moment, reference, ("rx", "ry"), force), "nlp")
    assert ipopt.success and np.abs(ipopt.pose - newton.pose).max() < 1e-6  # the same pose


def test_newton_leaves_an_unstable_equilibrium_for_the_stable_one_a_ball_rolled_over(layer):
    """No moment, ``uz, rx, ry`` free about a reference 2.6 mm above the ball's centre: the upright
    ball is balanced but tips (an inverted pendulum: a turn moves the centre aside of the reference,
    and the contact force through it tips the ball further); turned half a turn the centre lies
    2.6 mm above the reference, a pendulum, and the ball rests there. Newton from rest stops upright,
    where the forces balance; it now measures the tangent there, steps down the energy along the
    motion that gives way, and ends rolled over. Closed form: the turn is half a turn and the centre
    rests where the upright ball's does (the same force on the same sphere), 2 x 2.6 mm lower
    in ``uz``; the net force summed here vanishes and the tangent is stable."""
    reference = (0.0, 0.0, 27.6)
    upright = quiet(d.solve, ball(layer, (0.0, 0.0, 0.0), reference, ("uz",)), "newton")
    newton = quiet(d.solve, ball(layer, (0.0, 0.0, 0.0), reference), "newton")
    assert upright.success and newton.success
    turn = np.linalg.norm(newton.u[9:])
    assert turn == pytest.approx(np.pi, abs=1e-6)
    centre = newton.pose[:3, :3] @ CENTRE + newton.pose[:3, 3]
    assert centre == pytest.approx(CENTRE + [0.0, 0.0, upright.u[8]], abs=1e-6)
    assert newton.u[8] == pytest.approx(upright.u[8] - 2 * 2.6, abs=1e-6)
    K, net = stiffness_of(layer, (0.0, 0.0, 0.0), reference, newton)
    assert np.abs(net).max() < 1e-6 * 68.0
    assert instability(layer, reference, K) < 0.0 and newton.validity["stability"].passed is True
    assert newton.validity.valid
    left = newton.info["escapes"]
    assert len(left) == 1 and "left an unstable equilibrium" in left[0] and left[0] in newton.message
    # the upright pose is the equilibrium IPOPT keeps from rest, and the check fails it
    ipopt = quiet(d.solve, ball(layer, (0.0, 0.0, 0.0), reference), "nlp")
    assert ipopt.success and np.linalg.norm(ipopt.u[9:]) < 1e-9 and ipopt.u[8] == pytest.approx(upright.u[8], abs=1e-6)
    assert ipopt.validity["stability"].passed is False
