"""A tiny load on the real knee (small kinematics): the meshes start 0.075 mm apart, and a load of
1e-4 to 1e-8 N brings the femur down onto one spring and tips it onto three.

Newton's safe step once moved the spring in contact as it turned the femur toward the next: the
femur rocked from one spring to another and back, 100 iterations without converging (and
``auto`` fell back to the QP, which Clarabel called dual infeasible below 1e-6 N: 'unbounded').
The safe step now turns body 2 about the springs in contact (``formulations/newton.md``, "Safe
step"). Each load is carried, its springs balancing it (summed here, with the held ``ux, uy``
taking their reactions), at nearly the touching pose. Reads ``../shared/data/knee``; skips
without it."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import real_knee

import dea_opt as d


@pytest.fixture(scope="module")
def knee():
    return real_knee()


def _problem(knee, load):
    return d.ContactProblem(
        knee["cast"].layer,
        d.LinearLaw(10.0),
        force=(0.0, 0.0, -load),
        reference=tuple(knee["reference"]),
        free=("uz", "rx", "ry"),
    )


def _balance(solution, load):
    """The springs' force along z (N) and their moment about x and y (N mm) at the reference."""
    layer = solution.problem.layer
    push = (solution.pressure * layer.areas)[:, None] * layer.normals
    arms = layer.points - np.asarray(solution.problem.body2.reference)
    return push.sum(axis=0)[2], np.cross(arms, push).sum(axis=0)[:2]


@pytest.mark.parametrize("method", ["newton", "auto"])
@pytest.mark.parametrize("load", [1e-4, 1e-6, 1e-8])
def test_a_tiny_load_tips_the_femur_onto_its_contact_in_a_few_newton_iterations(knee, load, method):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        solution = d.solve(_problem(knee, load), method)
        touching = d.solve(_problem(knee, 1e-2), method)
    assert solution.success and solution.method == "newton" and solution.iterations <= 30
    fz, moment = _balance(solution, load)
    radius = np.sqrt(((solution.problem.layer.points - knee["reference"]) ** 2).sum(axis=1).mean())
    assert fz == pytest.approx(load, rel=1e-6) and np.abs(moment).max() < 1e-6 * load * radius
    assert np.abs(solution.u[8:11] - touching.u[8:11]).max() < 0.02  # mm and rad: the same contact


def test_the_qp_does_not_take_clarabels_false_ray_for_an_unbounded_load(knee):
    """Below 1e-6 N the QP's gaps are 1e6 strain units of the load's scale, and Clarabel calls it
    dual infeasible. Its ray compresses the springs (their strains along it, from the layer's
    points and normals, here), so it is no direction of unbounded decrease: the answer is
    ``inaccurate``, not ``unbounded``."""
    from dea_opt.formulations.qp import QPModel

    problem = _problem(knee, 1e-6)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        solution = d.solve(problem, "qp", strict=False)
    assert not solution.success and solution.status is not d.Status.UNBOUNDED
    model = QPModel(problem.system(), problem.law)
    model.solve()
    if "DualInfeasible" not in solution.message:  # another Clarabel may solve it: nothing to check
        return
    assert solution.status is d.Status.INACCURATE and "ray compresses springs" in solution.message
    uz, rx, ry = model.scale.to_u_free(model.backend.ray)
    layer = problem.layer
    moved = np.array([0.0, 0.0, uz]) + np.cross([rx, ry, 0.0], layer.points - knee["reference"])
    strain = np.einsum("ij,ij->i", layer.normals, moved) / layer.thickness
    assert strain.max() < 0  # every spring compressed along it: the energy grows, it does not fall


@pytest.mark.parametrize(
    ("force", "moment"),
    [
        ((-1.34e-11, -9.506e-10, -1.0226e-08), (5.223e-09, -3.7654e-08, -1.3389e-09)),
        ((1.3752e-09, 3.1304e-09, -1.5437e-08), (-7.6764e-08, 1.6051e-09, 1.715e-08)),
    ],
)
def test_a_spring_reached_only_far_along_a_safe_step_is_no_unbounded_load(knee, force, moment):
    """At 1e-8 N the gaps are 1e9 strain units of the load's scale: the next spring to touch lies
    beyond 1e12 steps along a safe step, where the line search once declared the energy unbounded
    (``line_search_failed``). A spring whose strain falls along the line bounds it; the search goes
    on past it, and the load, which the springs carry, is balanced (summed here)."""
    problem = d.ContactProblem(
        knee["cast"].layer,
        d.LinearLaw(10.0),
        force=force,
        moment=moment,
        reference=tuple(knee["reference"]),
        free=("uz", "rx", "ry"),
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        solution = d.solve(problem, "newton")
    assert solution.success
    layer = problem.layer
    push = (solution.pressure * layer.areas)[:, None] * layer.normals
    arms = layer.points - knee["reference"]
    radius = np.sqrt((arms**2).sum(axis=1).mean())
    size = float(np.linalg.norm(force))
    assert abs(push.sum(axis=0)[2] + force[2]) < 1e-6 * size
    assert np.abs(np.cross(arms, push).sum(axis=0)[:2] + moment[:2]).max() < 1e-6 * size * radius


@pytest.mark.slow
def test_newton_and_the_qp_agree_on_random_loads_of_every_size_on_the_knee(knee):
    """60 loads from 1e-8 to 3000 N (mostly along -z, with shear and moments of their size) on
    random sets of free dofs: each one the springs can carry (``LoadNotSupportedError`` otherwise,
    skipped) is solved by Newton, balanced by its springs (summed here), and where the QP solves
    it too, both give the same motion. (The safe step that moved the springs in contact left one
    such load in five unsolved after 100 iterations.)"""
    rng = np.random.default_rng(7)
    sets = [("uz",), ("uz", "ry"), ("uz", "rx", "ry"), ("uz", "rx"), ("uz", "rx", "ry", "rz")]
    solved = 0
    for _ in range(60):
        size = 10 ** rng.uniform(-8, 3.5)
        free = sets[rng.integers(len(sets))]
        force = np.array([rng.normal(0, 0.1), rng.normal(0, 0.1), -1.0]) * size
        moment = rng.normal(0, 2, 3) * size
        problem = d.ContactProblem(
            knee["cast"].layer,
            d.LinearLaw(10.0),
            force=tuple(force),
            moment=tuple(moment),
            reference=tuple(knee["reference"]),
            free=free,
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                newton = d.solve(problem, "newton", strict=False)
            except d.LoadNotSupportedError:
                continue
            qp = d.solve(problem, "qp", strict=False)
        assert newton.success, (size, free, newton.message)
        layer = problem.layer
        push = (newton.pressure * layer.areas)[:, None] * layer.normals
        arms = layer.points - knee["reference"]
        total = np.concatenate([push.sum(axis=0) + force, np.cross(arms, push).sum(axis=0) + moment])
        radius = np.sqrt((arms**2).sum(axis=1).mean())
        index = [("ux", "uy", "uz", "rx", "ry", "rz").index(name) for name in free]
        scale = np.where(np.array(index) < 3, 1.0, radius) * max(np.abs(force).max(), 1e-300)
        assert np.abs(total[index] / scale).max() < 1e-6, (size, free)
        if qp.success:
            assert np.abs(newton.u - qp.u).max() < 1e-5 * max(1.0, np.abs(newton.u).max())
        solved += 1
    assert solved >= 30
