"""A whole joint under finite kinematics: exact poses, gaps at the pose, exact ligament lengths.

Closed forms (crossed ligaments with exact lengths, a body hanging on a bundle pulled sideways),
the two-body finite problems reproduced, and a knee of two condyles on a plateau held by
collateral and cruciate bundles with all six dofs free: stable, certified, and mirror-symmetric as
its geometry is. Equilibrium is checked by sums written in ``tests/joint_checks.py`` and here
(the springs' gaps to their spheres and the bundles' lengths recomputed from the poses), never by
calling the certificate.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from joint_checks import assert_balanced_at_pose

import dea_opt as d
from dea_opt.formulations.finite import Targets
from dea_opt.geometry import plate_layer, sphere_on_bed_layer

GROUND = d.Body(free=())
HALF, HEIGHT, K, EPS_T = 10.0, 20.0, 1000.0, 0.06
LENGTH = float(np.hypot(2 * HALF, HEIGHT))


def _pose(u, c):
    """The pose of a body moved by ``u`` (translation, rotation vector) about ``c``, by Rodrigues
    written here."""
    theta = np.asarray(u[3:], dtype=float)
    angle = float(np.linalg.norm(theta))
    W = np.array([[0, -theta[2], theta[1]], [theta[2], 0, -theta[0]], [-theta[1], theta[0], 0]])
    if angle == 0.0:
        R = np.eye(3)
    else:
        R = np.eye(3) + np.sin(angle) / angle * W + (1 - np.cos(angle)) / angle**2 * W @ W
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = np.asarray(c) + np.asarray(u[:3]) - R @ np.asarray(c)
    return T


# --- closed forms -----------------------------------------------------------------------------


@pytest.mark.parametrize("shear", [3.0, 40.0], ids=["toe", "linear"])
def test_crossed_ligaments_take_their_exact_length(shear):
    bodies = {"ground": GROUND, "block": d.Body(reference=(0.0, 0.0, HEIGHT), free=("ux",), force=(shear, 0.0, 0.0))}
    ligaments = [
        d.Ligament("ground", (-HALF, 0, 0), "block", (HALF, 0, HEIGHT), stiffness=K, slack_length=LENGTH),
        d.Ligament("ground", (HALF, 0, 0), "block", (-HALF, 0, HEIGHT), stiffness=K, slack_length=LENGTH),
    ]
    s = d.solve(d.Joint(bodies, ligaments=ligaments, kinematics="finite"))
    ux = s.bodies["block"].u[0]
    # bundle "a" runs from (-10, 0, 0) to (10 + ux, 0, 20): its exact length and its pull along x
    length = np.hypot(2 * HALF + ux, HEIGHT)
    eps = length / LENGTH - 1
    force = K * (eps * eps / (2 * EPS_T) if eps < EPS_T else eps - EPS_T / 2)
    assert s.success and s.status == "converged"
    assert force * (2 * HALF + ux) / length == pytest.approx(shear, rel=1e-10)
    assert (eps < EPS_T) == (shear == 3.0)
    assert s.ligaments.length[0] == pytest.approx(length, rel=1e-12)
    assert s.ligaments.force[0] == pytest.approx(force, rel=1e-10) and s.ligaments.force[1] == 0.0
    np.testing.assert_allclose(s.ligaments.point2[0], [HALF + ux, 0, HEIGHT], atol=1e-12)
    assert s.validity.valid and s.validity["stability"].passed


def test_a_body_hanging_on_a_bundle_is_held_sideways_only_by_finite_kinematics():
    W, F, L0, k = 100.0, 30.0, 50.0, 2000.0
    bodies = {"ground": GROUND, "bob": d.Body(reference=(0.0, 0.0, -L0), free=("ux", "uz"), force=(F, 0.0, -W))}
    bundle = [d.Ligament("ground", (0, 0, 0), "bob", (0, 0, -L0), stiffness=k, slack_length=L0, law="linear")]
    small = d.Joint(bodies, ligaments=bundle)
    # a straight line resists no sideways motion to first order: the small kinematics cannot carry F
    with pytest.raises(d.LoadNotSupportedError, match="bob.ux"):
        d.solve(small)
    s = d.solve(d.Joint(bodies, ligaments=bundle, kinematics="finite"))
    tension = np.hypot(F, W)
    length = L0 * (1 + tension / k)
    ux, uz = s.bodies["bob"].u[[0, 2]]
    assert s.success
    assert s.ligaments.force[0] == pytest.approx(tension, rel=1e-10)
    assert ux == pytest.approx(length * F / tension, rel=1e-10)
    assert uz == pytest.approx(L0 - length * W / tension, rel=1e-10)
    assert s.validity["stability"].passed  # a pendulum hangs stably
    assert_balanced_at_pose(s, 1e-10)


# --- the two-body finite problems through the joint -------------------------------------------


def _finite_cases():
    layer = plate_layer(nx=20, ny=6)
    yield (
        "punch",
        d.ContactProblem(
            layer,
            d.LinearLaw(10.0),
            force=(0, 0, -200.0),
            moment=(0, 300.0, 0),
            reference=(0, 0, 5.0),
            free=("uz", "ry"),
            kinematics="finite",
        ),
    )
    bed = sphere_on_bed_layer(radius=25.0, thickness=2.0, n_rings=24, n_sectors=24)
    yield (
        "ball",
        d.ContactProblem(
            bed,
            d.AteshianLaw(2.0, 0.2),
            force=(0, 0, -30.0),
            moment=(40.0, -20.0, 0),
            reference=(0, 0, 20.0),
            free=("uz", "rx", "ry"),
            kinematics="finite",
            targets=Targets.spheres((0, 0, 25.0), 25.0, n=len(bed)),
        ),
    )


FINITE = dict(_finite_cases())


@pytest.mark.parametrize("case", sorted(FINITE))
def test_a_two_body_finite_problem_through_the_joint_is_reproduced(case):
    problem = FINITE[case]
    two = d.solve(problem)
    contact = d.Contact(problem.layer, problem.law, body1="one", body2="two", targets=problem.targets)
    many = d.solve(d.Joint({"one": problem.body1, "two": problem.body2}, [contact], kinematics="finite"))
    assert many.success and two.success
    scale = float(np.abs(two.u).max())
    np.testing.assert_allclose(many.bodies["two"].u, two.u[6:], rtol=0, atol=1e-10 * scale)
    assert many.contacts[0].peak_pressure == pytest.approx(two.peak_pressure, rel=1e-9)
    np.testing.assert_allclose(many.bodies["two"].pose, two.pose, atol=1e-10)
    assert_balanced_at_pose(many, 1e-9)


def test_the_qp_is_a_small_kinematics_method():
    joint = d.Joint(
        {"g": GROUND, "b": d.Body(free=("uz",), force=(0, 0, -1.0))},
        [d.Contact(plate_layer(nx=3, ny=3), d.LinearLaw(1.0), body1="g", body2="b")],
        kinematics="finite",
    )
    with pytest.raises(d.InputError, match="small-kinematics method"):
        d.solve(joint, "qp")
    with pytest.raises(d.InputError, match="max_steps"):
        d.solve(joint, max_steps=0)


# --- a knee of two condyles held by collateral and cruciate bundles ---------------------------

R, SPACING = 30.0, 20.0


def _condyles():
    """Springs on a plateau of two 24 mm squares, mirror images across x = 0 (medial +x), under two
    spherical condyles of radius 30 mm centred 30 mm above them: their gaps the spheres' heights."""
    n = 20
    xs = (np.arange(n) + 0.5) / n * 24 - 12
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    medial = np.column_stack([SPACING + X.ravel(), Y.ravel(), np.zeros(X.size)])
    points = np.vstack([medial, medial * [-1, 1, 1]])
    rho2 = (np.abs(points[:, 0]) - SPACING) ** 2 + points[:, 1] ** 2
    N = len(points)
    layer = d.SpringLayer(
        points,
        np.tile([0, 0, 1.0], (N, 1)),
        1.0,
        5.0,
        R - np.sqrt(R * R - rho2),
        labels=np.repeat(["medial", "lateral"], N // 2),
    )
    centres = np.column_stack([np.sign(points[:, 0]) * SPACING, np.zeros(N), np.full(N, R)])
    return layer, centres


def _knee_ligaments():
    """A collateral on each side and two bundles of each cruciate, mirror images across x = 0 (y
    posterior: the ACL from the posterior femur to the anterior tibia, the PCL the other way)."""
    out = []
    for side in (1.0, -1.0):
        out.append(
            d.Ligament(
                "femur", (26 * side, 2, 30), "tibia", (28 * side, -2, -25), stiffness=2000.0, reference_strain=0.08
            )
        )
        out.append(
            d.Ligament(
                "femur", (3 * side, 10, 22), "tibia", (-3 * side, -10, 0), stiffness=1500.0, reference_strain=0.06
            )
        )
        out.append(
            d.Ligament(
                "femur", (3 * side, -10, 22), "tibia", (-3 * side, 12, -5), stiffness=1500.0, reference_strain=0.05
            )
        )
    return out


def _knee(kinematics, moment=(0.0, 0.0, 0.0)):
    layer, centres = _condyles()
    targets = Targets.spheres(centres, R, n=len(layer)) if kinematics == "finite" else None
    bodies = {"tibia": GROUND, "femur": d.Body(reference=(0, 0, R), force=(0, 0, -400.0), moment=moment)}
    contact = d.Contact(layer, d.LinearLaw(20.0), body1="tibia", body2="femur", targets=targets)
    return d.Joint(bodies, [contact], _knee_ligaments(), kinematics=kinematics)


MIRROR = np.array([-1, 1, 1, 1, -1, -1.0])  # x -> -x: ux, ry, rz change sign


@pytest.mark.parametrize("kinematics", ["small", "finite"])
def test_a_knee_with_six_free_dofs_is_held_stable_certified_and_symmetric(kinematics):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        plain = d.solve(_knee(kinematics))
        varus = d.solve(_knee(kinematics, moment=(0, 3000.0, 0)))
        valgus = d.solve(_knee(kinematics, moment=(0, -3000.0, 0)))
    for s in (plain, varus, valgus):
        assert s.success and s.status == "converged"
        assert (s.ligaments.force > 0).all()  # every bundle holds
        if kinematics == "finite":
            assert s.validity.valid and s.validity["stability"].value < 0  # every direction resists
            assert_balanced_at_pose(s, 1e-9)
    u = plain.bodies["femur"].u
    scale = float(np.abs(u).max())
    # the geometry is its own mirror image: so is the answer to a load on the mirror plane
    np.testing.assert_allclose(u * MIRROR, u, atol=1e-12 * scale)
    layer = plain.contacts[0].problem.layer
    share = [
        float((plain.contacts[0].pressure * layer.areas)[layer.labels == side].sum()) for side in ("medial", "lateral")
    ]
    assert share[0] == pytest.approx(share[1], rel=1e-12)
    # and mirrored moments give mirrored answers, the medial load moving to the lateral side
    np.testing.assert_allclose(varus.bodies["femur"].u, valgus.bodies["femur"].u * MIRROR, atol=1e-12 * scale)
    np.testing.assert_allclose(varus.ligaments.force[[3, 4, 5, 0, 1, 2]], valgus.ligaments.force, rtol=1e-10)
    # the answer does not hinge on rounding: a start perturbed by 1e-12 finds it again
    again = d.solve(_knee(kinematics), x0=plain.x + 1e-12 * np.arange(1, 7))
    np.testing.assert_allclose(again.x, plain.x, rtol=0, atol=1e-10 * scale)


def test_the_finite_knee_s_springs_and_bundles_are_where_its_pose_puts_them():
    s = d.solve(_knee("finite", moment=(0, 3000.0, 0)))
    u = s.bodies["femur"].u
    T = _pose(u, (0, 0, R))
    np.testing.assert_allclose(s.bodies["femur"].pose, T, atol=1e-12)
    # each spring's gap: its ray up from the plateau to its condyle where the femur is
    layer0, centres = _condyles()
    moved = centres @ T[:3, :3].T + T[:3, 3]
    d0 = layer0.points - moved
    beta = d0[:, 2]  # n = +z
    gap = -beta - np.sqrt(beta**2 - (np.einsum("ij,ij->i", d0, d0) - R * R))
    pressure = -20.0 * np.minimum(gap / 5.0, 0.0)
    np.testing.assert_allclose(s.contacts[0].pressure, pressure, rtol=1e-10, atol=1e-12)
    # each bundle's length between its insertions where the poses put them
    for i, lig in enumerate(s.joint.ligaments):
        p1 = np.asarray(lig.point1) @ T[:3, :3].T + T[:3, 3]
        assert s.ligaments.length[i] == pytest.approx(np.linalg.norm(np.asarray(lig.point2) - p1), rel=1e-12)


def test_ipopt_takes_the_finite_steps_too():
    bodies = {
        "ground": GROUND,
        "block": d.Body(reference=(0.0, 0.0, HEIGHT), free=("ux", "uz"), force=(40.0, 0.0, -5.0)),
    }
    ligaments = [
        d.Ligament("ground", (-HALF, 0, 0), "block", (HALF, 0, HEIGHT), stiffness=K, slack_length=LENGTH, law="linear"),
        d.Ligament("ground", (HALF, 0, 0), "block", (-HALF, 0, HEIGHT), stiffness=K, slack_length=LENGTH, law="linear"),
    ]
    joint = d.Joint(bodies, ligaments=ligaments, kinematics="finite")
    newton, ipopt = d.solve(joint, "newton"), d.solve(joint, "nlp")
    assert newton.success and ipopt.success
    np.testing.assert_allclose(ipopt.x, newton.x, rtol=1e-9)
    assert_balanced_at_pose(ipopt, 1e-9)
