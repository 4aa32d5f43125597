"""Finite kinematics: a load no free motion can make the springs carry is a LoadNotSupportedError
that names the load and the reason, not a SolverError after a failed Newton.

Two closed forms. Springs on a flat bed under a ball whose centre is body 2's reference point:
a rotation about the centre maps the ball onto itself, so no spring's gap changes however far
body 2 turns, and a moment about that point is carried by nothing (the springs push along the
bed's normal with lever arms about the point, but no rotation loads them). Flat targets turned
by a prescribed 100 degrees face away from body 1 (``n . m = -cos 100 deg > 0``): every ray
misses, and no translation changes that. Beside each, the resisted problem next to it solves,
and its springs balance the load (summed here)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import ball_on_bed

import dea_opt as d
from dea_opt.formulations.finite import Targets, evaluate, pose_matrix
from dea_opt.geometry import plate_layer, sphere_on_bed_layer

H = 10.0  # MPa
R = 25.0  # mm, the ball's radius; it touches the bed at the origin
CENTRE = (0.0, 0.0, R)


@pytest.fixture(scope="module")
def bed():
    return sphere_on_bed_layer(R, 2.0, 7.0, 40, 32)


def ball_problem(layer, reference, moment, free, force=(0.0, 0.0, 0.0)):
    return ball_on_bed(layer, reference, moment, free, force, H=H, radius=R)


def solve(problem, method="auto", **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        return d.solve(problem, method, **options)


def springs_on_body2(solution):
    """The springs' force (N) on body 2 and its moment (N mm) about body 2's reference at the solved
    pose, summed here from each spring's pressure, area and direction (the bed's normal)."""
    layer = solution.problem.layer
    push = (solution.pressure * layer.areas)[:, None] * layer.normals
    centre = np.asarray(solution.problem.body2.reference) + solution.u[6:9]
    return push.sum(axis=0), np.cross(layer.points - centre, push).sum(axis=0)


def test_turning_a_ball_about_its_centre_changes_no_gap(bed):
    """The premise, checked on the exact gaps: any rotation about the centre, 0.1 to 90 degrees."""
    targets = Targets.spheres(CENTRE, R, n=len(bed))
    start = evaluate(targets, bed.points, bed.normals, np.eye(4)).s
    assert np.isfinite(start).all() and 0.0 < start.min() < 1e-3  # just clear of the bed: none compressed
    rng = np.random.default_rng(5)
    for degrees in (0.1, 5.0, 30.0, 90.0):
        axis = rng.normal(size=3)
        theta = np.radians(degrees) * axis / np.linalg.norm(axis)
        turned = evaluate(targets, bed.points, bed.normals, pose_matrix(np.r_[0.0, 0.0, 0.0, theta], CENTRE)).s
        np.testing.assert_allclose(turned, start, atol=1e-9)


@pytest.mark.parametrize("method", ["auto", "newton", "nlp"])
@pytest.mark.parametrize(
    "free, moment, said",
    [
        (
            ("rx",),
            (500.0, 0.0, 0.0),
            "moment +500 N mm along x on body2 (moment about its reference point (0, 0, 25) mm)",
        ),
        (
            ("rx", "ry", "rz"),
            (500.0, 200.0, 0.0),
            "moment +500 N mm along x on body2, moment +200 N mm along y on body2 (moments about its reference point",
        ),
    ],
    ids=["rx", "rx-ry-rz"],
)
def test_a_moment_about_the_centre_of_ball_targets_is_not_supported(bed, free, moment, said, method):
    problem = ball_problem(bed, CENTRE, moment, free)
    with pytest.raises(d.LoadNotSupportedError) as caught:
        solve(problem, method)
    message = str(caught.value)
    names = tuple(f"body2.{dof}" for dof in free)
    assert f"no motion of the free dofs {names} changes any spring's gap at the start pose" in message
    assert f"Unresisted: {said}" in message  # which component
    assert f"{len(bed)} of the {len(bed)} springs' targets have their normal at the hit through body 2's " in message
    assert "reference point (0, 0, 25) mm (spheres centred there)" in message  # and why
    assert "take a reference point the targets' normals do not pass through" in message
    assert caught.value.direction == {f"body2.{dof}": moment["xyz".index(dof[1])] for dof in free}


def test_the_ball_turned_about_a_point_off_its_centre_carries_the_moment(bed):
    """Reference 3 mm off the centre along y: turning by theta about x lowers the ball onto the bed
    below its centre, at lever arm -3 cos(theta) mm, so the springs push with 200 / (3 cos theta) N."""
    reference = (0.0, 3.0, R)
    for free in (("rx",), ("rx", "ry", "rz")):
        solution = solve(ball_problem(bed, reference, (200.0, 0.0, 0.0), free))
        assert solution.success
        force, moment = springs_on_body2(solution)
        # equilibrium, summed here: the springs balance the load along every resisted free dof
        np.testing.assert_allclose(moment[:2], [-200.0, 0.0], atol=1e-6)
        np.testing.assert_allclose(force[:2], 0.0, atol=1e-9)
        theta = solution.u[9]
        assert 0.05 < theta < 0.3 and abs(solution.u[10]) < 1e-9
        assert force[2] == pytest.approx(200.0 / (3.0 * np.cos(theta)), rel=5e-3)
        if "rz" in free:  # turning about the bed's normal changes no gap here either: held, and said
            assert solution.info["held"] and "body2.rz" in solution.info["held"][0]


# --- targets facing away from body 1 -----------------------------------------------------------------


def plate_problem(degrees, free=("uz",)):
    layer = plate_layer(6.0, 6.0, 30, 30, thickness=10.0)
    return d.ContactProblem(
        layer,
        d.LinearLaw(H),
        body2=d.Body(
            reference=(0.0, 0.0, 4.0), free=free, force=(0, 0, -400.0), prescribed={"rx": np.radians(degrees)}
        ),
        kinematics="finite",
        targets=Targets.facing(layer),
    )


@pytest.mark.parametrize("method", ["auto", "newton", "nlp"])
@pytest.mark.parametrize("free", [("uz",), ("uz", "ry")], ids=["uz", "uz-ry"])
def test_targets_turned_to_face_away_from_body_1_support_no_load(free, method):
    problem = plate_problem(100.0, free)
    # the closed form: each target's normal -z turned 100 deg about x, against the springs' +z
    turned = pose_matrix([0, 0, 0, np.radians(100.0), 0, 0], (0, 0, 4.0))[:3, :3] @ [0.0, 0.0, -1.0]
    assert turned[2] == pytest.approx(-np.cos(np.radians(100.0))) and turned[2] > 0
    with pytest.raises(d.LoadNotSupportedError) as caught:
        solve(problem, method)
    message = str(caught.value)
    n = len(problem.layer)
    names = tuple(f"body2.{dof}" for dof in free)
    assert f"no motion of the free dofs {names} changes any spring's gap at the start pose" in message
    assert f"{n} of the {n} springs' rays miss their targets ({n} of them face away from body 1" in message
    assert "Unresisted: force -400 N along z on body2" in message
    assert "give targets that face the springs at the start pose" in message
    assert caught.value.direction["body2.uz"] == -400.0


def test_targets_turned_20_degrees_still_face_the_springs_and_carry_the_load():
    solution = solve(plate_problem(20.0))
    assert solution.success
    force, _ = springs_on_body2(solution)
    assert force[2] == pytest.approx(400.0, rel=1e-9)  # along uz, the one free dof
    # the tilted planes press on the springs at each spring's own gap: p = -H eps
    assert np.allclose(solution.pressure, -H * np.minimum(solution.strain, 0.0), rtol=1e-12)


# --- a moment the springs resist only past a whole turn: the energy is unbounded -----------------------

OFF_CENTRE = (2.0, 3.0, R)  # the reference, beside the centre at the same height
SPIN = (200.0, -100.0, 0.0)  # N mm: a component along the line from the centre to the reference


def test_a_moment_along_the_line_through_the_centre_turns_the_ball_without_bound(bed):
    """Turning about the line through the reference and the centre maps the ball onto itself (no gap
    changes: the springs' energy stays what it is) while the moment's component along that line does
    work ``M . a theta`` growing without bound: Phi has no minimum along it, and Newton says so. With
    two rotations free the balances that hold at every pose say nothing of it, so nothing is proved
    about the load: the answer is a solve that did not converge, saying what Newton found."""
    axis = np.subtract(OFF_CENTRE, CENTRE) / np.linalg.norm(np.subtract(OFF_CENTRE, CENTRE))
    targets = Targets.spheres(CENTRE, R, n=len(bed))
    start = evaluate(targets, bed.points, bed.normals, np.eye(4)).s
    for degrees in (10.0, 90.0, 270.0):
        pose = pose_matrix(np.r_[0.0, 0.0, 0.0, np.radians(degrees) * axis], OFF_CENTRE)
        np.testing.assert_allclose(evaluate(targets, bed.points, bed.normals, pose).s, start, atol=1e-9)
    assert np.dot(SPIN, axis) == pytest.approx(100.0 / np.sqrt(13.0))  # the work per radian, N mm
    problem = ball_problem(bed, OFF_CENTRE, SPIN, ("rx", "ry"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        solution = d.solve(problem, "newton", strict=False)
        with pytest.raises(d.SolverError) as caught:
            d.solve(problem, "newton")
    assert solution.status is d.Status.MAX_ITERATIONS and not solution.success
    assert solution.info["unproved"] == "unbounded" and solution.message.startswith("did not converge: ")
    assert "the energy decreases without bound along the search direction (rx " in solution.message
    assert "a sphere turning about its own centre" in solution.message
    assert caught.value.status is d.Status.MAX_ITERATIONS


@pytest.mark.slow
def test_auto_tries_the_other_means_before_it_says_newton_found_no_equilibrium(bed):
    """No pose is an equilibrium (the turn about that line changes nothing but the moment's work),
    but that is not proved from the problem: ``auto`` tries the other start, a load continuation
    and IPOPT (here given 1 s, ``max_time``) before it fails, and says what each found."""
    problem = ball_problem(bed, OFF_CENTRE, SPIN, ("rx", "ry"))
    solution = solve_loose(problem, max_time=1.0)
    assert not solution.success and solution.status not in (d.Status.CRUSHED, d.Status.UNBOUNDED)
    story = solution.info["fallback"]
    assert story.startswith("finite ended with status 'unbounded' (the energy decreases without bound")
    assert "finite_nlp from" in story and "a continuation" in story
    with pytest.raises(d.SolverError, match="the energy decreases without bound") as caught:
        solve(problem, "auto", max_time=1.0)
    assert caught.value.status not in (d.Status.CRUSHED, d.Status.UNBOUNDED)


def solve_loose(problem, method="auto", **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        return d.solve(problem, method, strict=False, **options)


class _Line:
    """A manufactured line: ``phi'(a)`` given, body 2 turned one radian a unit step (free uz, rx)."""

    def __init__(self, slope, d=(0.0, 1.0)):
        self.d, self._slope = np.asarray(d, dtype=float), slope

    def slope(self, a):
        return self._slope(a), ("state at", a)


def _basin(a):
    """Descending steeply (``phi' = -1``) but on a contact from 0.20 to 0.50 rad that resists past the
    load: ``phi'`` rises through the Wolfe band to +1 at 0.25 rad."""
    return 1.0 if 0.30 <= a <= 0.50 else -1.0 + 2.0 * max(0.0, 1.0 - abs(a - 0.25) / 0.05) * (a < 0.30)


def test_the_line_search_leaps_a_contact_that_resists_over_a_few_degrees_and_the_scan_finds_it():
    from dea_opt.formulations.finite.newton import _scan
    from dea_opt.formulations.newton import _line_search

    line = _Line(_basin)
    alpha, _, _ = _line_search(line, -1.0, 0.9)
    assert alpha == np.inf  # fourfold steps from 1 never land on 0.2-0.5
    alpha, state, used = _scan(line, np.array([2, 3]), -1.0, 0.9)
    assert 0.2 <= alpha <= 0.25 and state == ("state at", alpha)
    assert -0.9 <= _basin(alpha) <= -1e-4  # the Wolfe band of phi'(0) = -1
    assert used < 360


def test_the_scan_finds_nothing_on_a_turn_no_spring_resists_nor_on_a_line_that_only_slides():
    from dea_opt.formulations.finite.newton import _scan

    alpha, state, used = _scan(_Line(lambda a: -1.0), np.array([2, 3]), -1.0, 0.9)
    assert alpha is None and state is None and used == 360  # one a degree over a whole turn
    alpha, _, used = _scan(_Line(_basin, d=(1.0, 0.0)), np.array([2, 3]), -1.0, 0.9)
    assert alpha is None and used == 0  # uz alone: no turn to look over
