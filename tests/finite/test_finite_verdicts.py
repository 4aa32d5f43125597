"""Finite kinematics: no verdict on the load without a proof, and none that depends on the start.

A failed solve proves nothing about the load: Newton's iterates may crush springs or run away
from one start while another start, a load continuation or IPOPT reaches an equilibrium.
``crushed`` stands where the springs the layer can have, each crushed to strain -1, carry less
than the load along a balance of body 2 that holds at every pose (``formulations/finite.md``,
"What the layer can carry"); otherwise the answer is a solve that did not converge, and
``method="auto"`` tries the other means first. Every equilibrium here is checked with sums
written here: the springs' forces along their normals at their gaps to the targets moved by the
solved pose (computed here), and their moments about body 2's moved reference.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import real_knee

import dea_opt as d
from dea_opt import mesh as M
from dea_opt.formulations.finite import pose_matrix
from dea_opt.geometry import plate_layer
from dea_opt.mesh import springs_from_meshes


def quiet(function, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return function(*args, **kw)


def ateshian(law, eps):
    """Ateshian's stress (MPa), written here: ``H (lam^2 - 1) / (2 lam^(2 beta + 1)) exp(beta (lam^2 - 1))``."""
    lam = 1.0 + np.minimum(eps, 0.0)
    return law.H * (lam**2 - 1) / (2 * lam ** (2 * law.beta + 1)) * np.exp(law.beta * (lam**2 - 1))


def left_jacobian(theta):
    t = np.linalg.norm(theta)
    W = np.array([[0, -theta[2], theta[1]], [theta[2], 0, -theta[0]], [-theta[1], theta[0], 0]])
    if t < 1e-8:
        return np.eye(3) + 0.5 * W
    return np.eye(3) + (1 - np.cos(t)) / t**2 * W + (t - np.sin(t)) / t**3 * W @ W


# --- a punch lifted off an Ateshian layer --------------------------------------------------------

PUNCH = plate_layer(6.0, 6.0, 60, 6, thickness=10.0)
LIFTED = [  # (H, beta, F, M): a lever of 2.2 to 2.8 mm on a punch 3 mm to its edge
    (13.4, 0.548, 66.1, 148.0),
    (1.25, 0.403, 3.97, 10.8),
    (18.0, 0.0521, 133.0, 317.0),
]


def punch(H, beta, F, M):
    return d.ContactProblem(
        PUNCH,
        d.AteshianLaw(H, beta),
        force=(0, 0, -F),
        moment=(0, M, 0),
        reference=(0, 0, 0),
        free=("uz", "ry"),
        kinematics="finite",
    )


def punch_balance(problem, solution):
    """The net force along z and moment about y on the punch (springs minus load), summed here:
    each spring's own plane (through its point at its gap, normal -z) moved by the pose."""
    layer, y = PUNCH, solution.u[6:]
    R = pose_matrix(y, (0.0, 0.0, 0.0))[:3, :3]
    q = (layer.points + layer.gap[:, None] * layer.normals) @ R.T + y[:3]
    m = -layer.normals @ R.T
    gap = np.einsum("ij,ij->i", q - layer.points, m) / np.einsum("ij,ij->i", layer.normals, m)
    push = -ateshian(problem.law, gap / layer.thickness) * layer.areas  # N along +z
    centre = y[:3]
    moment = np.cross(layer.points - centre, np.outer(push, [0, 0, 1.0])).sum(axis=0)
    net_z = push.sum() + problem.body2.force[2]
    net_ry = (left_jacobian(y[3:]).T @ (moment + np.asarray(problem.body2.moment)))[1]
    return net_z, net_ry, gap / layer.thickness


@pytest.mark.parametrize("case", LIFTED)
def test_a_punch_lifted_off_an_ateshian_layer_is_carried_not_crushed(case):
    """Newton from rest crushes the edge springs to strain -1 and runs out of iterations; Ateshian's
    law stiffens without bound there, so nothing proves the load too large. ``auto`` goes on: a load
    continuation from a fraction of the load finds the punch tilted 60-80 deg, balanced (summed
    here), springs short of -1; IPOPT by name finds the same pose."""
    from dea_opt.finite import verdict

    problem = punch(*case)
    newton = quiet(d.solve, problem, "newton", strict=False)
    assert not newton.success and newton.status is d.Status.MAX_ITERATIONS
    assert newton.info["unproved"] == "crushed" and "crushed" in newton.info["native_status"]
    assert verdict.prove(problem) is None
    solution = quiet(d.solve, problem, "auto")
    assert solution.success and solution.status is d.Status.CONVERGED
    net_z, net_ry, eps = punch_balance(problem, solution)
    assert abs(net_z) < 1e-6 * case[2] and abs(net_ry) < 1e-6 * case[3]
    assert -1.0 < eps.min() < -0.4 and 55.0 < np.degrees(solution.u[10]) < 85.0
    assert solution.validity["stability"].passed is not False
    assert "a continuation from" in solution.info["fallback"]


def test_ipopt_by_name_finds_the_lifted_punch_that_newton_from_rest_does_not():
    problem = punch(*LIFTED[0])
    ipopt = quiet(d.solve, problem, "nlp")
    auto = quiet(d.solve, problem, "auto")
    assert ipopt.success and np.abs(ipopt.u - auto.u).max() < 1e-6
    net_z, net_ry, eps = punch_balance(problem, ipopt)
    assert abs(net_z) < 1e-6 * 66.1 and abs(net_ry) < 1e-6 * 148.0 and eps.min() > -0.6


# --- crushed, proved: the layer's capacity at strain -1 ------------------------------------------


def test_what_the_punch_s_springs_carry_at_strain_minus_one_is_the_bound_of_the_proof():
    """A linear law carries at most H per unit area inside the model (strain -1: crushed through the
    thickness, body 2 on body 1): 36 mm^2 of 10 MPa carry 360 N along z. Past it the load is proved
    beyond what the layer bears (the bound and the load in words); the equations still have a
    solution past strain -1, which every method certifies and the validity report rejects."""
    from dea_opt.finite import verdict

    def problem(force):
        return d.ContactProblem(PUNCH, d.LinearLaw(10.0), force=(0, 0, -force), free=("uz", "ry"), kinematics="finite")

    assert PUNCH.areas.sum() == pytest.approx(36.0)
    proof = verdict.prove(problem(400.0))
    assert proof.kind == "crushed" and proof.demand == pytest.approx(400.0) and proof.capacity == pytest.approx(360.0)
    assert "the load asks 400 N, more than the 360 springs the layer can have carry there" in proof.message()
    assert verdict.prove(problem(350.0)) is None
    for method in ("newton", "nlp", "auto"):
        solution = quiet(d.solve, problem(400.0), method)
        assert solution.success and solution.strain.min() == pytest.approx(-400.0 / 360.0, rel=1e-9)
        assert solution.validity["strain"].passed is False


def test_a_load_that_pulls_the_punch_off_its_bed_is_not_supported_at_any_pose():
    """Springs along +z push the punch up whatever its pose: a force pulling it up is carried by
    no compression of them, proved along the balance of the force along z."""
    problem = d.ContactProblem(
        PUNCH, d.LinearLaw(10.0), force=(0, 0, 10.0), moment=(0, 5.0, 0), free=("uz", "ry"), kinematics="finite"
    )
    for method in ("newton", "nlp", "auto"):
        with pytest.raises(
            d.LoadNotSupportedError, match="none of the 360 springs the layer can have pushes"
        ) as caught:
            quiet(d.solve, problem, method)
        assert caught.value.direction["body2.uz"] == pytest.approx(10.0)


# --- the knee, flexed: one verdict from every start -------------------------------------------------


@pytest.fixture(scope="module")
def flexed():
    """The real knee with the femur flexed 15 deg about a medial-lateral axis 25 mm above the plateau,
    springs cast there (``uz, rx, ry`` free, 1000 N and a moment of 2000 N mm about x, H = 40 MPa)."""
    knee = real_knee()
    reference = np.asarray(knee["reference"])
    pose = pose_matrix([0, 0, 0, np.radians(15.0), 0, 0], reference + [0.0, 0.0, 25.0])
    cast = quiet(M.cast_springs, knee["mesh1"], knee["mesh2"], pose=pose, **knee["options"])
    problem = d.ContactProblem(
        cast.layer,
        d.LinearLaw(40.0),
        force=(0, 0, -1000.0),
        moment=(2000.0, 0, 0),
        reference=tuple(reference),
        free=("uz", "rx", "ry"),
        kinematics="finite",
        targets=cast,
    )
    return problem


def test_the_flexed_knee_gives_the_same_answer_from_starts_above_and_deep_in_the_cartilage(flexed):
    """Started 1 mm above the cast pose Newton's springs did not settle within max_recasts
    (``max_iterations``); started 4 mm into the cartilage its iterates lost loaded springs through
    the tibial layer and it said ``crushed``, a verdict on a load the layer carries thirty times
    over. Now every start gives the same certified pose, its springs balancing the load (summed
    here from each spring's gap to the face of the femur it met, moved by the pose)."""
    poses = []
    for start in (1.0, -0.3, -4.0):
        solution = quiet(d.solve, flexed, "auto", strict=False, x0=np.array([start, 0.0, 0.0]))
        assert solution.success, (start, solution.status, solution.message[:300])
        layer, t = solution.problem.layer, solution.targets
        P = solution.pose
        q, m = t.points @ P[:3, :3].T + P[:3, 3], t.normals @ P[:3, :3].T
        gap = np.einsum("ij,ij->i", q - layer.points, m) / np.einsum("ij,ij->i", layer.normals, m)
        push = 40.0 * np.maximum(-gap / layer.thickness, 0.0) * layer.areas
        force = push @ layer.normals
        centre = np.asarray(flexed.body2.reference) + solution.u[6:9]
        moment = np.cross(layer.points - centre, push[:, None] * layer.normals).sum(axis=0)
        net = left_jacobian(solution.u[9:12]).T @ (moment + np.asarray(flexed.body2.moment))
        assert abs(force[2] - 1000.0) < 1e-6 * 1000.0 and np.abs(net[:2]).max() < 1e-6 * 2000.0
        poses.append(solution.pose)
    assert max(np.abs(p - poses[0]).max() for p in poses) < 1e-6


# --- a layer cast from meshes, solved with finite kinematics without targets= ------------------------


def test_a_layer_from_meshes_is_re_cast_by_default_and_a_fresh_cast_carries_the_load():
    """``springs_from_meshes`` then ``kinematics="finite"`` without ``targets=``: the layer
    remembers its cast, so the springs follow the femur. A fresh cast of the meshes at the solved
    pose (no state of the solve) carries the load to 1e-4 (summed here); on the start hits' tangent
    planes it carried 1.0 % less, while the answer read valid."""
    knee = real_knee()
    layer = quiet(springs_from_meshes, knee["mesh1"], knee["mesh2"], **knee["options"])
    problem = d.ContactProblem(
        layer,
        d.LinearLaw(10.0),
        force=(0, 0, -1000.0),
        moment=(5000.0, 0, 0),
        reference=tuple(knee["reference"]),
        free=("uz", "rx", "ry"),
        kinematics="finite",
    )
    solution = quiet(d.solve, problem)
    assert solution.success
    fresh = quiet(springs_from_meshes, knee["mesh1"], knee["mesh2"], pose=solution.pose, max_gap=2.0, max_overlap=10.0)
    carried = float((10.0 * np.maximum(-fresh.gap / fresh.thickness, 0.0) * fresh.areas) @ fresh.normals[:, 2])
    assert carried == pytest.approx(1000.0, rel=1e-4)
    assert layer.cast is not None and layer.cast.layer is layer
    assert solution.info["recast"]["updates"] + solution.info["recast"]["recasts"] >= 1
    # a part of the cast's springs is no cast's own layer: on its tangent planes, said and measured
    part = layer.subset(np.arange(len(layer)))
    planes = quiet(d.solve, d.ContactProblem(part, problem.law, body2=problem.body2, kinematics="finite"))
    assert "stayed on the tangent planes" in planes.message
    check = planes.validity["gap_error"]
    assert check.passed is not None and np.isfinite(check.value)


# --- tiny loads on the knee: a warm start from a larger load ------------------------------------------


@pytest.mark.parametrize(
    ("force", "lever", "law"),
    [
        (0.00558, (-2.653, -1.003, -2.763), d.LinearLaw(10.0)),
        (0.000187, (-2.731, 2.502, 0.397), d.AteshianLaw(2.0, 0.3)),
    ],
    ids=["5.6mN-linear", "0.19mN-ateshian"],
)
def test_a_tiny_load_on_the_knee_is_carried_from_a_larger_one(force, lever, law):
    """Milli- and micro-newtons with moments of a few mm's lever, ``uz, rx, ry`` free: on the few
    springs that touch, Newton from the small kinematics' answer runs out of iterations, tipping
    the femur to and fro. The same load ten or a thousand times larger is carried from a cold
    start, and from its pose the load scaled back is carried at every step: ``auto`` does that,
    and its answer is balanced (summed here from each spring's gap to the face it met) and stable.
    Newton alone is auto's first solve (the same formulation, options and start): its failure is
    read from the story auto's answer tells, rather than solved a second time."""
    from dea_opt.finite.arrays import plan

    knee = real_knee()
    problem = d.ContactProblem(
        knee["cast"].layer,
        law,
        force=(0, 0, -force),
        moment=tuple(force * np.asarray(lever)),
        reference=tuple(knee["reference"]),
        free=("uz", "rx", "ry"),
        kinematics="finite",
        targets=knee["cast"],
    )
    solution = quiet(d.solve, problem, "auto")
    assert solution.success and solution.validity["stability"].passed is True
    assert plan("auto", law, {})[0] == plan("newton", law, {})[0]  # Newton alone is auto's first solve
    # auto goes on only after a first Newton without a certified answer, and its story starts with
    # how that ended (its raw status: out of iterations, or springs crushed on the way, unproved)
    story = solution.info["fallback"]
    assert story.startswith("finite ended with status '") and "a continuation from" in story
    layer, t, P = solution.problem.layer, solution.targets, solution.pose
    q, m = t.points @ P[:3, :3].T + P[:3, 3], t.normals @ P[:3, :3].T
    gap = np.einsum("ij,ij->i", q - layer.points, m) / np.einsum("ij,ij->i", layer.normals, m)
    eps = np.minimum(gap / layer.thickness, 0.0)
    stress = law.H * eps if isinstance(law, d.LinearLaw) else ateshian(law, eps)
    push = -stress * layer.areas
    centre = np.asarray(problem.body2.reference) + solution.u[6:9]
    moment = np.cross(layer.points - centre, push[:, None] * layer.normals).sum(axis=0)
    net = left_jacobian(solution.u[9:12]).T @ (moment + np.asarray(problem.body2.moment))
    scale = force * max(1.0, np.linalg.norm(lever))
    assert abs(push @ layer.normals[:, 2] - force) < 1e-6 * force and np.abs(net[:2]).max() < 1e-6 * scale


def test_a_sliding_runaway_with_a_bounded_law_is_not_called_crushed():
    """Ateshian's law, five dofs free, 4 mN: nothing holds the femur's slide, and Newton's iterates
    drive springs to strain -1 on the way. A law that stiffens without bound there cannot be
    crushed by a finite load (nothing is proved): the answer did not converge, and says what the
    iterates did."""
    knee = real_knee()
    problem = d.ContactProblem(
        knee["cast"].layer,
        d.AteshianLaw(2.0, 0.3),
        force=(0, 0, -0.00417),
        moment=tuple(0.00417 * np.array([-0.535, -0.807, -0.581])),
        reference=tuple(knee["reference"]),
        free=("ux", "uy", "uz", "rx", "ry"),
        kinematics="finite",
        targets=knee["cast"],
    )
    solution = quiet(d.solve, problem, "newton", strict=False)
    assert not solution.success and solution.status is d.Status.MAX_ITERATIONS
    assert solution.info["unproved"] == "crushed" and "beyond what this layer can bear" not in solution.message
