"""Linear springs between points, bushings between body frames, and loads at points of a body in the
ground or body frame: closed forms by every method, small and finite kinematics.

Each closed form is written here from the statics of the case (springs in series share their
force; a torsion bushing's moment balances the load's; a follower force keeps its lever arm, a
force fixed in space loses it as the body turns), never taken from dea-opt.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.optimize import brentq
from scipy.spatial.transform import Rotation

import dea_opt as d
from dea_opt.errors import InputError
from dea_opt.joint import BodyLoad, Bushing, Spring

GROUND = d.Body(free=())
METHODS = {"small": ("newton", "qp", "nlp"), "finite": ("newton", "nlp")}
CASES = [(k, m) for k, methods in METHODS.items() for m in methods]


def _solve(joint, method):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        return d.solve(joint, method)


@pytest.mark.parametrize(("kinematics", "method"), CASES)
def test_springs_in_series_share_their_force(kinematics, method):
    k1, k2, P, rest2 = 50.0, 80.0, 12.0, 9.0
    bodies = {
        "g": GROUND,
        "a": d.Body(reference=(10, 0, 0), free=("ux",)),
        "b": d.Body(reference=(20, 0, 0), free=("ux",), force=(P, 0, 0)),
    }
    springs = [
        Spring("g", (0, 0, 0), "a", (10, 0, 0), stiffness=k1, name="first"),
        Spring("a", (10, 0, 0), "b", (20, 0, 0), stiffness=k2, rest_length=rest2),
    ]
    s = _solve(d.Joint(bodies, springs=springs, kinematics=kinematics), method)
    assert s.success
    # the first spring carries P: a moves P/k1; the second carries P at length rest2 + P/k2
    xa = P / k1
    xb = 10.0 + xa + rest2 + P / k2 - 20.0
    tol = 1e-8 if method == "qp" else 1e-11
    assert s.bodies["a"].u[0] == pytest.approx(xa, abs=tol * 10)
    assert s.bodies["b"].u[0] == pytest.approx(xb, abs=tol * 10)
    rows = s.elastic
    assert [r["name"] for r in rows] == ["first", "spring 1"]
    for row in rows:
        assert row["force_N"] == pytest.approx(P, rel=tol)
    assert rows[1]["length_mm"] == pytest.approx(rest2 + P / k2, rel=tol)
    # the ground holds the chain: its reaction balances the load
    assert s.bodies["g"].reactions["ux"] == pytest.approx(-P, rel=tol)


@pytest.mark.parametrize(("kinematics", "method"), CASES)
@pytest.mark.parametrize("frame", ["body", "ground"])
def test_a_torsion_bushing_balances_a_force_at_a_point(kinematics, method, frame):
    c, r, F = 2000.0, 10.0, 30.0
    bodies = {"g": GROUND, "b": d.Body(reference=(0, 0, 0), free=("rz",))}
    joint = d.Joint(
        bodies,
        bushings=[Bushing("g", "b", rotational_stiffness=(0, 0, c))],
        loads=[BodyLoad("b", force=(0, F, 0), point=(r, 0, 0), frame=frame)],
        kinematics=kinematics,
    )
    s = _solve(joint, method)
    assert s.success
    if kinematics == "small" or frame == "body":
        exact = r * F / c  # a follower force keeps its lever arm (and the small kinematics do not turn it)
    else:
        exact = brentq(lambda t: c * t - r * F * np.cos(t), 0.0, 1.0)  # a force fixed in space loses it
    tol = 1e-8 if method == "qp" else 1e-12
    assert s.bodies["b"].u[5] == pytest.approx(exact, rel=tol)
    assert s.elastic[0]["moment_z_Nmm"] == pytest.approx(c * exact, rel=tol)
    assert s.elastic[0]["rotation_z_rad"] == pytest.approx(exact, rel=tol)


@pytest.mark.parametrize(("kinematics", "method"), CASES)
def test_a_bushing_deflects_along_its_own_axes(kinematics, method):
    """A body held only by a bushing whose frame is turned: the deflection is the force in the
    bushing's axes over each axis's stiffness (the body does not turn: no moment about the origin)."""
    R = Rotation.from_rotvec([0.3, -0.5, 0.8]).as_matrix()
    frame = np.eye(4)
    frame[:3, :3], frame[:3, 3] = R, (5.0, -2.0, 7.0)
    k = np.array([100.0, 250.0, 40.0])
    force = np.array([3.0, -4.0, 2.0])
    bodies = {"g": GROUND, "b": d.Body(reference=(5.0, -2.0, 7.0), force=force)}
    joint = d.Joint(
        bodies,
        bushings=[Bushing("g", "b", frame, translational_stiffness=k, rotational_stiffness=(1e4, 2e4, 3e4))],
        kinematics=kinematics,
    )
    s = _solve(joint, method)
    assert s.success
    local = R.T @ force / k  # the deflection along each of the bushing's axes
    tol = 1e-8 if method == "qp" else 1e-11
    np.testing.assert_allclose(s.bodies["b"].u[:3], R @ local, rtol=0, atol=tol * 10)
    np.testing.assert_allclose(s.bodies["b"].u[3:], 0.0, atol=tol)
    row = s.elastic[0]
    np.testing.assert_allclose([row[f"deflection_{a}_mm"] for a in "xyz"], local, rtol=tol, atol=1e-14)
    np.testing.assert_allclose([row[f"force_{a}_N"] for a in "xyz"], R.T @ force, rtol=tol, atol=1e-12)


def test_a_bushing_axis_of_no_stiffness_is_no_element():
    """A bushing stiff about z only: the other dofs are held by nothing, and a load along them is refused."""
    bodies = {"g": GROUND, "b": d.Body(free=("rz", "ux"), force=(1.0, 0, 0))}
    joint = d.Joint(bodies, bushings=[Bushing("g", "b", rotational_stiffness=(0, 0, 10.0))])
    with pytest.raises(d.LoadNotSupportedError, match="b.ux"):
        d.solve(joint)


def test_a_point_load_in_the_ground_frame_is_its_moment_about_the_reference():
    """Small kinematics: a force at a point is that force at the reference and its moment, in either frame."""
    bodies = {"g": GROUND, "b": d.Body(reference=(1, 2, 3))}
    at = np.eye(4)
    at[:3, 3] = (1, 2, 3)  # the bushing's origin at the reference: its forces and moments decouple there
    bushing = Bushing("g", "b", at, translational_stiffness=(50, 60, 70), rotational_stiffness=(800, 900, 1000))
    F, P, M = np.array([2.0, -1.0, 3.0]), np.array([6.0, -4.0, 5.0]), np.array([10.0, 0.0, -20.0])
    moment = M + np.cross(P - (1, 2, 3), F)
    a = _solve(d.Joint(bodies, bushings=[bushing], loads=[BodyLoad("b", F, M, P, "body")]), "newton")
    b = _solve(
        d.Joint({"g": GROUND, "b": d.Body(reference=(1, 2, 3), force=F, moment=moment)}, bushings=[bushing]), "newton"
    )
    np.testing.assert_allclose(a.bodies["b"].u, b.bodies["b"].u, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(a.bodies["b"].u[3:], moment / (800, 900, 1000), rtol=1e-12)
    np.testing.assert_allclose(a.bodies["b"].u[:3], F / (50, 60, 70), rtol=1e-12)


def test_a_follower_load_turns_with_a_body_on_free_coordinates():
    """Finite kinematics, six free dofs: a body on three collinear-free springs and a torsion bushing under a
    follower moment and force. The answer's pose turns the load's components with the body; summed here,
    the elements' wrench balances it."""
    bodies = {"g": GROUND, "b": d.Body(reference=(0, 0, 0))}
    springs = [
        Spring("g", p, "b", q, stiffness=30.0)
        for p, q in (
            ((-20, 0, 0), (-5, 0, 0)),
            ((20, 0, 0), (5, 0, 0)),
            ((0, -20, 0), (0, -5, 0)),
            ((0, 20, 0), (0, 5, 0)),
            ((0, 0, -20), (0, 0, -5)),
            ((0, 0, 20), (0, 0, 5)),
        )
    ]
    bushing = Bushing("g", "b", rotational_stiffness=(500.0, 700.0, 900.0))
    load = BodyLoad("b", force=(4.0, 1.0, -2.0), moment=(50.0, -80.0, 120.0), point=(3.0, 1.0, 0.0), frame="body")
    s = _solve(d.Joint(bodies, springs=springs, bushings=[bushing], loads=[load], kinematics="finite"), "newton")
    assert s.success and s.status == "converged"
    T = s.bodies["b"].pose
    R, t = T[:3, :3], T[:3, 3]
    c = t  # the reference (the origin) where the motion took it
    net_f = R @ np.array(load.force)
    net_m = R @ np.array(load.moment) + np.cross(R @ np.array(load.point) + t - c, R @ np.array(load.force))
    for spring, row in zip(springs, s.elastic[: len(springs)]):
        p1, p2 = np.array(spring.point1), R @ np.array(spring.point2) + t
        e = (p2 - p1) / np.linalg.norm(p2 - p1)
        assert row["length_mm"] == pytest.approx(np.linalg.norm(p2 - p1), rel=1e-12)
        assert row["force_N"] == pytest.approx(30.0 * (np.linalg.norm(p2 - p1) - 15.0), rel=1e-9, abs=1e-12)
        net_f -= row["force_N"] * e  # tension pulls the body's end back toward the ground's
        net_m -= np.cross(p2 - c, row["force_N"] * e)
    # the bushing: the moment conjugate to the rotation vector theta of R, M = J(theta)^-T C theta
    theta = Rotation.from_matrix(R).as_rotvec()
    angle = np.linalg.norm(theta)
    W = np.array([[0, -theta[2], theta[1]], [theta[2], 0, -theta[0]], [-theta[1], theta[0], 0]])
    J = np.eye(3) + (1 - np.cos(angle)) / angle**2 * W + (angle - np.sin(angle)) / angle**3 * W @ W
    net_m -= np.linalg.solve(J.T, np.array([500.0, 700.0, 900.0]) * theta)
    scale = 4.0 + np.abs([r["force_N"] for r in s.elastic[:6]]).sum()
    assert np.abs(net_f).max() <= 1e-9 * scale
    assert np.abs(net_m).max() <= 1e-9 * scale * 20.0
    assert angle > 0.05  # the body turned enough for the follower load to differ from a fixed one


def test_springs_and_bushings_in_a_scenario(tmp_path):
    from dea_opt.scenario import load_scenario
    from dea_opt.scenario.joint_build import build_joint

    text = """
[[bodies]]
name = "ground"

[[bodies]]
name = "block"
reference = [0, 0, 10]
free = ["ux", "rz"]
force = [2, 0, 0]
point = [0, 5, 10]

[[springs]]
name = "s"
body1 = "ground"
point1 = [-20, 0, 10]
body2 = "block"
point2 = [0, 0, 10]
stiffness = 4.0

[[bushings]]
name = "torsion"
body1 = "ground"
body2 = "block"
frame = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 10], [0, 0, 0, 1]]
rotational_stiffness = [0, 0, 1000.0]
"""
    path = tmp_path / "s.toml"
    path.write_text(text)
    joint, _ = build_joint(load_scenario(path))
    s = d.solve(joint)
    # the spring takes the force (2 N over 4 N/mm), the bushing the moment 2 N x 5 mm (about -z)
    assert s.bodies["block"].u[0] == pytest.approx(0.5, rel=1e-12)
    assert s.bodies["block"].u[5] == pytest.approx(-10.0 / 1000.0, rel=1e-12)
    assert [r["name"] for r in s.elastic] == ["s", "torsion"]


@pytest.mark.parametrize(
    ("make", "words"),
    [
        (lambda: Spring("a", (0, 0, 0), "b", (0, 0, 0), stiffness=1.0), "two different points"),
        (lambda: Spring("a", (0, 0, 0), "a", (1, 0, 0), stiffness=1.0), "two different bodies"),
        (lambda: Spring("a", (0, 0, 0), "b", (1, 0, 0), stiffness=-1.0), "Spring.stiffness"),
        (lambda: Spring("a", (0, 0, 0), "b", (1, 0, 0), stiffness=1.0, rest_length=-1.0), "Spring.rest_length"),
        (lambda: Bushing("a", "b", np.diag([1, 1, 2, 1.0]), (1, 1, 1)), "rigid transform"),
        (lambda: Bushing("a", "b", translational_stiffness=(0, 0, 0)), "at least one axis"),
        (lambda: Bushing("a", "b", translational_stiffness=(1, -1, 0)), "translational_stiffness"),
        (lambda: BodyLoad("a", frame="femur"), "BodyLoad.frame"),
        (lambda: BodyLoad("", force=(1, 0, 0)), "BodyLoad.body"),
        (lambda: d.Joint({"g": GROUND}, loads=[BodyLoad("x")]), "not a body"),
        (
            lambda: d.Joint({"g": GROUND, "b": d.Body()}, springs=[Spring("g", (0, 0, 0), "c", (1, 0, 0), 1.0)]),
            "not a body",
        ),
        (lambda: d.Joint({"g": GROUND, "b": d.Body()}, loads=[BodyLoad("b", (1, 0, 0))]), "nothing holds"),
    ],
)
def test_bad_elements_and_loads_are_input_errors(make, words):
    with pytest.raises(InputError, match=words):
        make()
