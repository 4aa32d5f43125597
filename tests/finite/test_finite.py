"""Finite kinematics against closed forms, finite differences and IPOPT.

Every equilibrium is checked with sums written here (forces along the springs' normals, moments
about body 2's reference where it is at the solved pose), never with the certificate. Geometry:
a rigid flat punch on a bed of springs normal to it (each spring's target its own plane), a
ball in a socket and a sphere on a bed (sphere targets), and random tilted planes.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import dea_opt as d
from dea_opt import finite
from dea_opt.formulations.finite import Targets
from dea_opt.formulations.finite import geometry as G
from dea_opt.formulations.finite import rotations as Rot
from dea_opt.formulations.finite.system import FiniteSystem
from dea_opt.geometry import plate_layer, socket_layer, sphere_on_bed_layer

H = 10.0  # MPa
THICK = 10.0  # mm: a thick layer keeps a 25-degree tilt in full contact below 30 % strain
PUNCH = 6.0  # mm: the punch is PUNCH x PUNCH


def solve(problem, method="newton", **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        return d.solve(problem, method, **options)


def punch(nx=60, ny=6, length=PUNCH):
    return plate_layer(length, PUNCH, nx, ny, thickness=THICK)


def punch_problem(layer, force, moment, reference=(0.0, 0.0, 0.0), free=("uz", "ry"), law=None, **kw):
    return d.ContactProblem(
        layer,
        law or d.LinearLaw(H),
        force=(0.0, 0.0, -force),
        moment=(0.0, moment, 0.0),
        reference=reference,
        free=free,
        kinematics="finite",
        **kw,
    )


def springs_on_body2(solution):
    """Force and moment (about body 2's reference at the solved pose) the springs exert, summed here."""
    layer = solution.problem.layer
    push = (solution.pressure * layer.areas)[:, None] * layer.normals
    centre = np.asarray(solution.problem.body2.reference) + solution.u[6:9]
    return push.sum(axis=0), np.cross(layer.points - centre, push).sum(axis=0)


# --- geometry --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "theta", [np.zeros(3), np.array([1e-5, -2e-5, 3e-6]), np.array([0.3, -0.2, 0.5]), np.array([1.5, 0.4, -2.0])]
)
def test_rotation_and_its_jacobian(theta):
    assert np.abs(Rot.rotation(theta) - Rotation.from_rotvec(theta).as_matrix()).max() < 1e-14
    R, J = Rot.rotation(theta), Rot.left_jacobian(theta)
    for j in range(3):
        step = np.zeros(3)
        step[j] = 1e-6
        dR = (Rot.rotation(theta + step) - Rot.rotation(theta - step)) / 2e-6
        spin = dR @ R.T  # [J e_j]x
        assert np.allclose([spin[2, 1], spin[0, 2], spin[1, 0]], J[:, j], atol=1e-8)
    moment = np.array([3.0, -1.0, 2.0])
    fd = np.column_stack(
        [
            (Rot.left_jacobian(theta + e).T @ moment - Rot.left_jacobian(theta - e).T @ moment) / 2e-6
            for e in np.eye(3) * 1e-6
        ]
    )
    assert np.allclose(Rot.jacobian_transpose_derivative(theta, moment), fd, atol=1e-7)


@pytest.mark.parametrize("tau", [0.0, 1e-8, 0.0999999, 0.1, 0.1000001, 0.5, 4.0])
def test_the_derivative_of_j_transpose_m_is_smooth_where_its_series_meets_its_closed_form(tau):
    # complex steps on J itself (no subtraction) as the reference, on both sides of tau = 0.1
    theta = np.sqrt(tau) * np.array([0.6, -0.48, 0.64])
    moment = np.array([3.0, -1.0, 2.0])
    reference = np.empty((3, 3))
    for j in range(3):
        step = theta.astype(complex)
        step[j] += 1e-30j
        reference[:, j] = (Rot.left_jacobian(step).T @ moment).imag / 1e-30
    assert np.abs(Rot.jacobian_transpose_derivative(theta, moment) - reference).max() < 1e-13


def _random_springs(rng, n=80):
    p = np.column_stack([rng.uniform(-8, 8, n), rng.uniform(-8, 8, n), rng.normal(0, 0.2, n)])
    normal = np.array([0.0, 0.0, 1.0]) + rng.normal(0, 0.1, (n, 3))
    return p, normal / np.linalg.norm(normal, axis=1)[:, None]


def _targets(kind, rng, p, n):
    if kind == "planes":
        m = -n + rng.normal(0, 0.25, n.shape)
        return Targets.planes(p + 0.1 * n + rng.normal(0, 0.1, p.shape), m)
    if kind == "ball":
        return Targets.spheres((0.0, 0.0, 30.0), 29.8, n=len(p))
    return Targets.spheres((0.0, 0.0, -30.0), 30.3, concave=True, n=len(p))


@pytest.mark.parametrize("kind", ["planes", "ball", "socket"])
def test_gap_derivative_is_the_derivative_of_the_gap(kind):
    rng = np.random.default_rng(3)
    p, n = _random_springs(rng)
    targets = _targets(kind, rng, p, n)
    c = np.array([1.0, -2.0, 4.0])
    y = np.array([0.1, -0.2, 0.05, 0.2, -0.1, 0.3])

    def gaps(y):
        return G.evaluate(targets, p, n, Rot.pose_matrix(y, c)).s

    g = G.evaluate(targets, p, n, Rot.pose_matrix(y, c))
    assert g.valid.sum() > len(p) // 2
    rows = g.rows(c + y[:3])
    J = Rot.left_jacobian(y[3:])
    for j in range(6):
        e = np.zeros(6)
        e[j] = 1e-7
        fd = (gaps(y + e) - gaps(y - e)) / 2e-7
        motion = np.zeros(6)  # (v, omega) of a unit rate of coordinate j
        motion[:3] = e[:3] / 1e-7
        motion[3:] = J @ (e[3:] / 1e-7)
        assert np.allclose((motion @ rows)[g.valid], fd[g.valid], atol=1e-6)


@pytest.mark.parametrize("kind", ["planes", "ball", "socket"])
def test_the_tangent_is_the_jacobian_of_the_residual(kind):
    rng = np.random.default_rng(5)
    p, n = _random_springs(rng, 150)
    system = FiniteSystem(
        p,
        n,
        rng.uniform(0.5, 1.0, len(p)),
        rng.uniform(2.0, 3.0, len(p)),
        _targets(kind, rng, p, n),
        np.array([1.0, 2.0, 5.0]),
        np.array([0, 2, 3, 4]),
        np.array([0.0, 0.1, 0.0, 0.0, 0.0, 0.2]),
        np.array([1.0, 2.0, -50.0]),
        np.array([10.0, -20.0, 5.0]),
    )
    law = d.CubicLaw(H, 0.3)
    x = np.array([0.05, -0.3, 0.1, -0.05])
    state = system.state(system.coordinates(x), law)
    assert (state.eps < 0).sum() > 10
    fd = np.column_stack(
        [
            (
                system.state(system.coordinates(x + e), law).residual()
                - system.state(system.coordinates(x - e), law).residual()
            )
            / 2e-7
            for e in np.eye(4) * 1e-7
        ]
    )
    K = state.tangent()
    assert np.abs(K - fd).max() <= 1e-6 * np.abs(K).max()
    assert np.abs(K - K.T).max() > 1e-3 * np.abs(K).max()  # not symmetric: no energy behind it


# --- the flat punch --------------------------------------------------------------------------


def _second_moment(layer):
    return float(layer.areas @ layer.points[:, 0] ** 2)


@pytest.mark.parametrize("degrees", [10.0, 15.0, 20.0, 25.0])
def test_tilted_punch_in_full_contact_tan_theta_is_m_over_k_i(degrees):
    layer = punch()
    k, I = H / THICK, _second_moment(layer)
    force = 1.6 * k * layer.areas.sum() * (PUNCH / 2) * np.tan(np.radians(25.0))  # keeps every spring compressed
    moment = k * I * np.tan(np.radians(degrees))
    finite = solve(punch_problem(layer, force, moment))
    assert finite.success and (finite.strain < 0).all()
    assert abs(np.tan(finite.u[10]) - moment / (k * I)) < 1e-12
    assert abs(finite.u[8] + force / (k * layer.areas.sum())) < 1e-12
    resultant, about = springs_on_body2(finite)
    assert np.allclose(resultant, [0.0, 0.0, force], atol=1e-9 * force)  # along the bed's normal
    assert abs(about[1] + moment) < 1e-9 * moment
    small = solve(
        d.ContactProblem(
            layer, d.LinearLaw(H), force=(0, 0, -force), moment=(0, moment, 0), reference=(0, 0, 0), free=("uz", "ry")
        )
    )
    assert abs(small.u[10] - moment / (k * I)) < 1e-9  # the small kinematics: theta itself
    assert abs(finite.u[10] - np.arctan(small.u[10])) < 1e-9


def test_lifted_punch_matches_the_closed_form_and_the_discrete_one():
    # one row of springs along x: the continuous closed form up to the cell size
    length, n = PUNCH, 3000
    layer = plate_layer(length, PUNCH, n, 1, thickness=THICK)
    k = H / THICK
    force, arm = 20.0, 0.6 * length / 2
    finite = solve(punch_problem(layer, force, force * arm))
    assert finite.success
    ell = 3 * (length / 2 - arm)
    assert abs(np.tan(finite.u[10]) - 2 * force / (k * PUNCH * ell**2)) < 2e-4 * np.tan(finite.u[10])
    assert abs(finite.contact_area / PUNCH - ell) < 2 * length / n
    # The discrete punch: in contact where w - x tan(theta) < 0; given the contact set the two
    # equilibrium equations are linear in (w, tan(theta)).
    x = layer.points[:, 0]
    contact = finite.strain < 0
    S, kS = layer.areas[contact], k * layer.areas[contact]
    # sum f = -force and sum f x = -force arm (the springs' moment about y is -sum f x), f = k S (w - x tan)
    xc = x[contact]
    A = np.array([[kS.sum(), -(kS * xc).sum()], [(kS * xc).sum(), -(kS * xc**2).sum()]])
    w, tan = np.linalg.solve(A, [-force, -force * arm])
    assert abs(w - finite.u[8]) < 1e-10 and abs(tan - np.tan(finite.u[10])) < 1e-10
    gap = w - x * tan
    assert ((gap < 0) == contact).all()
    resultant, about = springs_on_body2(finite)
    assert abs(resultant[2] - force) < 1e-9 * force and abs(about[1] + force * arm) < 1e-9 * force * arm
    assert S.sum() == pytest.approx(finite.contact_area)


def test_finite_and_small_agree_to_second_order():
    """Targets normal to the springs (a flat punch on a bed), the reference z_c above the face: the
    tilt is the same closed form, and the reference rises z_c (sec(theta) - 1) higher; the difference of
    the two answers shrinks as the square of the rotation (fitted slope 2)."""
    layer, z_c = punch(30, 6), 8.0
    k, I, area = H / THICK, _second_moment(layer), layer.areas.sum()
    force = 50.0
    angles, differences = [], []
    for degrees in (0.25, 0.5, 1.0, 2.0, 4.0):
        moment = k * I * np.tan(np.radians(degrees))
        finite = solve(punch_problem(layer, force, moment, reference=(0.0, 0.0, z_c)))
        small = solve(
            d.ContactProblem(
                layer,
                d.LinearLaw(H),
                force=(0, 0, -force),
                moment=(0, moment, 0),
                reference=(0, 0, z_c),
                free=("uz", "ry"),
            )
        )
        assert (finite.strain < 0).all() and (small.strain < 0).all()
        theta = finite.u[10]
        assert abs(np.tan(theta) - moment / (k * I)) < 1e-12
        assert abs(finite.u[8] - (-force / (k * area) + z_c * (1 / np.cos(theta) - 1))) < 1e-12
        angles.append(theta)
        differences.append(np.abs(finite.u - small.u).max())
    slope = np.polyfit(np.log(angles), np.log(differences), 1)[0]
    print(f"\nfinite - small against the rotation: log-log slope {slope:.4f}")
    assert abs(slope - 2.0) < 0.02


# --- spheres ---------------------------------------------------------------------------------


def test_sphere_on_a_bed_pressed_straight_down_is_the_small_answer():
    """A vertical translation moves a sphere straight along every vertical ray: the exact gaps are
    the small model's, and so is the answer."""
    layer = sphere_on_bed_layer(25.0, 2.0, 7.0, 40, 32)
    targets = Targets.spheres((0.0, 0.0, 25.0), 25.0, n=len(layer))
    kw = {"force": (0.0, 0.0, -40.0), "reference": (0.0, 0.0, 25.0), "free": ("uz",)}
    finite = solve(d.ContactProblem(layer, d.LinearLaw(1.0), kinematics="finite", targets=targets, **kw))
    small = solve(d.ContactProblem(layer, d.LinearLaw(1.0), **kw))
    assert abs(finite.u[8] - small.u[8]) < 1e-12
    assert np.allclose(finite.pressure, small.pressure, atol=1e-12)


def test_ball_in_socket_turns_freely_and_agrees_with_small_to_second_order():
    """Concentric spheres: the socket's springs point at the centre, the ball is their target.
    Rotations about the centre change no gap (held, unresisted); a push off the axis moves the
    ball, and finite and small agree to second order in the motion."""
    layer = socket_layer(radius=25.0, thickness=2.0, coverage=80.0, n_rings=30, n_sectors=60, gap=0.2)
    targets = Targets.spheres((0.0, 0.0, 0.0), 24.8, n=len(layer))
    motions, differences = [], []
    for scale in (0.5, 1.0, 2.0, 4.0):
        kw = {
            "force": (3.0 * scale, 1.0 * scale, -10.0 * scale),
            "reference": (0.0, 0.0, 0.0),
            "free": ("ux", "uy", "uz"),
        }
        finite = solve(d.ContactProblem(layer, d.LinearLaw(1.0), kinematics="finite", targets=targets, **kw))
        small = solve(d.ContactProblem(layer, d.LinearLaw(1.0), **kw))
        resultant, _ = springs_on_body2(finite)
        assert np.allclose(resultant, -np.array(kw["force"]), atol=1e-9 * abs(kw["force"][2]))
        motions.append(np.abs(finite.u[6:9]).max())
        differences.append(np.abs(finite.u - small.u).max())
    slope = np.polyfit(np.log(motions), np.log(differences), 1)[0]
    assert slope > 1.9
    turned = d.ContactProblem(
        layer,
        d.LinearLaw(1.0),
        force=(0, 0, -10.0),
        reference=(0, 0, 0),
        free=("uz", "rx", "ry"),
        kinematics="finite",
        targets=targets,
    )
    held = solve(turned)
    assert held.success and held.info.get("held") and abs(held.u[9:]).max() == 0.0


# --- Newton and IPOPT ------------------------------------------------------------------------


def _cases():
    layer = punch(20, 4)
    k, I = H / THICK, _second_moment(layer)
    force = 1.6 * k * layer.areas.sum() * (PUNCH / 2) * np.tan(np.radians(25.0))
    rng = np.random.default_rng(11)
    tilted = plate_layer(8.0, 8.0, 12, 12, thickness=3.0)
    m = -tilted.normals + np.column_stack(
        [rng.normal(0, 0.15, len(tilted)), rng.normal(0, 0.15, len(tilted)), np.zeros(len(tilted))]
    )
    planes = Targets.planes(tilted.points, m)
    out = {
        "punch 20 deg": punch_problem(layer, force, k * I * np.tan(np.radians(20.0))),
        "lifted punch": punch_problem(layer, 20.0, 20.0 * 0.6 * PUNCH / 2),
        "punch, Ateshian law, ux free (held)": punch_problem(
            layer, force, k * I * np.tan(np.radians(15.0)), free=("ux", "uz", "ry"), law=d.AteshianLaw(H, 0.3)
        ),
        "tilted planes, moments on three axes": d.ContactProblem(
            tilted,
            d.CubicLaw(H, 0.2),
            force=(0.0, 0.0, -300.0),
            moment=(150.0, -200.0, 80.0),
            reference=(0.5, -0.3, 4.0),
            free=("uz", "rx", "ry"),
            kinematics="finite",
            targets=planes,
        ),
        "prescribed rotation of 20 deg": d.ContactProblem(
            tilted,
            d.LinearLaw(H),
            body2=d.Body(
                reference=(0.0, 0.0, 4.0), free=("uz", "ry"), force=(0, 0, -400.0), prescribed={"rx": np.radians(20.0)}
            ),
            kinematics="finite",
            targets=planes,
        ),
        "ball in a socket, pushed off its axis": d.ContactProblem(
            socket_layer(radius=25.0, thickness=2.0, coverage=80.0, n_rings=20, n_sectors=40, gap=0.2),
            d.AteshianLaw(1.0, 0.2),
            force=(6.0, 2.0, -20.0),
            reference=(0.0, 0.0, 0.0),
            free=("ux", "uy", "uz"),
            kinematics="finite",
            targets=Targets.spheres((0.0, 0.0, 0.0), 24.8, n=800),
        ),
        "sphere on a bed, rolled": d.ContactProblem(
            sphere_on_bed_layer(25.0, 2.0, 7.0, 20, 24),
            d.LinearLaw(1.0),
            force=(0, 0, -30.0),
            moment=(0, 40.0, 0),
            reference=(0.0, 0.0, 20.0),
            free=("uz", "ry"),
            kinematics="finite",
            targets=Targets.spheres((0.0, 0.0, 25.0), 25.0, n=480),
        ),
    }
    return out


CASES = _cases()


@pytest.mark.parametrize("name", list(CASES))
def test_newton_and_ipopt_agree(name):
    problem = CASES[name]
    newton = solve(problem, "newton")
    results = [newton, solve(problem, "nlp"), solve(problem, "nlp", form="reduced")]
    for other in results[1:]:
        assert other.success
        scale = max(np.abs(newton.u).max(), 1e-300)
        assert np.abs(other.u - newton.u).max() <= 1e-6 * scale
        assert np.abs(other.pressure - newton.pressure).max() <= 1e-6 * newton.peak_pressure
    resultant, about = springs_on_body2(newton)
    problem = newton.problem
    free = [i for i in range(6) if d.DOFS[i] in problem.body2.free]
    load = np.concatenate([problem.body2.force, problem.body2.moment])
    J = Rot.left_jacobian(newton.u[9:12])
    net = np.concatenate([resultant, about]) + load  # springs' push plus the load, about c'
    generalized = np.concatenate([net[:3], J.T @ net[3:]])
    size = max(np.abs(load[:3]).max(), np.abs(resultant).max())
    radius = np.sqrt(np.mean(np.sum((problem.layer.points - problem.body2.reference - newton.u[6:9]) ** 2, axis=1)))
    scaled = generalized / np.array([1, 1, 1, radius, radius, radius])
    assert np.abs(scaled[free]).max() <= 1e-9 * size


def test_statuses_are_the_vocabulary_of_every_method():
    layer = punch(10, 2)
    unloaded = solve(
        d.ContactProblem(
            layer.with_gap(0.1), d.LinearLaw(H), reference=(0, 0, 0), free=("uz", "ry"), kinematics="finite"
        )
    )
    assert unloaded.success and unloaded.status is d.Status.UNLOADED and not unloaded.pressure.any()
    pressed = solve(
        d.ContactProblem(layer.with_gap(-0.1), d.LinearLaw(H), reference=(0, 0, 0), free=("ry",), kinematics="finite")
    )
    assert pressed.success and pressed.status is d.Status.PRELOADED and pressed.pressure.min() > 0
    assert solve(punch_problem(layer, 50.0, 0.0)).status is d.Status.CONVERGED


def test_auto_is_newton_and_certified():
    problem = CASES["tilted planes, moments on three axes"]
    auto = solve(problem, "auto")
    assert auto.success and auto.method == "finite" and auto.info["fallback"] is None


# --- the solution, its pose and reactions -------------------------------------------------------


def test_pose_and_reactions_at_the_solved_pose():
    problem = CASES["prescribed rotation of 20 deg"]
    solution = solve(problem)
    c = np.asarray(problem.body2.reference)
    R = Rotation.from_rotvec(solution.u[9:12]).as_matrix()
    assert np.allclose(solution.pose[:3, :3], R, atol=1e-14)
    assert np.allclose(solution.pose[:3, 3], c + solution.u[6:9] - R @ c, atol=1e-12)
    assert abs(np.degrees(np.linalg.norm(solution.u[9:12])) - 20.0) < 10.0
    resultant, about = springs_on_body2(solution)
    reactions = solution.reactions
    load = problem.body2.force
    # the supports hold ux, uy: minus the springs' push minus the load along them
    assert reactions["body2.ux"] == pytest.approx(-resultant[0] - load[0], abs=1e-9)
    assert reactions["body2.uy"] == pytest.approx(-resultant[1] - load[1], abs=1e-9)
    J = Rot.left_jacobian(solution.u[9:12])
    assert reactions["body2.rx"] == pytest.approx(-(J.T @ about)[0], rel=1e-9)
    assert np.allclose(solution.contact_moment, about)
    small = solve(d.ContactProblem(problem.layer, problem.law, body2=problem.body2))
    T2 = Rot.pose_matrix(small.u[6:], c)
    assert np.allclose(small.pose, T2)


def test_validity_of_finite_kinematics_judges_rotations_by_the_half_turn_not_the_small_limit():
    problem = CASES["prescribed rotation of 20 deg"]
    validity = solve(problem).validity
    assert validity["gap_error"].passed is None  # the small kinematics' error: not theirs
    assert validity["rotation"].passed is True and validity["rotation"].limit == 180.0
    assert validity["rotation"].value == pytest.approx(20.0, abs=0.01)
    small = d.ContactProblem(problem.layer, problem.law, body2=problem.body2)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        solution = d.solve(small)
    assert solution.validity["rotation"].passed is False
    assert "kinematics='finite'" in solution.validity["rotation"].advice
    assert any("kinematics='finite'" in str(w.message) for w in caught)


def test_an_answer_whose_rotation_vector_wound_past_a_half_turn_is_outside_the_model():
    """The same pose, its rotation vector a whole turn longer (a warm start there): the forces
    balance as before, but its components no longer turn body 2 about their axes."""
    problem = punch_problem(punch(20, 4), 20.0, 10.0)
    plain = solve(problem)
    assert plain.success and plain.validity.valid
    uz, ry = plain.u[8], plain.u[10]
    wound = solve(problem, x0=[uz, ry + 2.0 * np.pi])
    assert wound.success and np.allclose(wound.pose, plain.pose, atol=1e-9)
    force, _ = springs_on_body2(wound)
    assert np.allclose(force, [0.0, 0.0, 20.0], atol=1e-6 * 20.0)
    check = wound.validity["rotation"]
    assert not wound.validity.valid and check.passed is False
    assert check.value == pytest.approx(np.degrees(abs(ry + 2.0 * np.pi)), rel=1e-9) and check.value > 180.0
    assert "past a half turn" in check.advice and "prescribed" in check.advice


# --- bad input ---------------------------------------------------------------------------------


def test_bad_input_is_named():
    layer = punch(10, 2)
    with pytest.raises(d.InputError, match="kinematics must be one of"):
        d.ContactProblem(layer, d.LinearLaw(H), kinematics="large")
    with pytest.raises(d.InputError, match="targets are for kinematics='finite'"):
        d.ContactProblem(layer, d.LinearLaw(H), targets=Targets.facing(layer))
    with pytest.raises(d.InputError, match="targets must be"):
        d.ContactProblem(layer, d.LinearLaw(H), kinematics="finite", targets=np.zeros((20, 3)))
    problem = punch_problem(layer, 10.0, 0.0)
    with pytest.raises(d.InputError, match="method 'qp' cannot solve 'finite' kinematics.*method='finite'"):
        d.solve(problem, "qp")
    with pytest.raises(d.InputError, match="unknown option 'tolerance'"):
        d.solve(problem, tolerance=1e-3)
    with pytest.raises(d.InputError, match="body1 has free dofs"):
        d.solve(d.ContactProblem(layer, d.LinearLaw(H), body1=d.Body(free=("uz",)), kinematics="finite"))
    wrong = Targets.planes(layer.points + 0.5 * layer.normals, -layer.normals)
    with pytest.raises(d.InputError, match="reproduce the layer's gaps"):
        d.solve(punch_problem(layer, 10.0, 0.0, targets=wrong))
    with pytest.raises(d.InputError, match="one per spring"):
        d.solve(punch_problem(layer, 10.0, 0.0, targets=Targets.facing(punch(5, 2))))
    with pytest.raises(d.LoadNotSupportedError):
        d.solve(punch_problem(layer, -10.0, 0.0))  # pulls the punch off the bed


# --- random problems, checked by sums written here ------------------------------------------------


@pytest.mark.parametrize("seed", range(8))
def test_random_tilted_problems_are_in_equilibrium_by_our_own_sums(seed):
    """Random targets tilted up to 15 degrees off the springs, random loads, moments and free
    rotations: Newton's answer balances the load on the free coordinates (forces along the springs'
    normals, moments about the reference where it is, through J^T), and IPOPT's is the same."""
    rng = np.random.default_rng(100 + seed)
    layer = plate_layer(8.0, 8.0, 10, 10, thickness=3.0)
    tilt = rng.normal(0.0, 0.12, (len(layer), 2))
    m = np.column_stack([tilt, -np.ones(len(layer))])
    gaps = rng.uniform(-0.02, 0.05, len(layer))
    layer = layer.with_gap(gaps)
    targets = Targets.planes(layer.points + gaps[:, None] * layer.normals, m)
    # springs along z resist no turn about z: rz stays fixed, its moment a reaction
    free = ("uz", *rng.choice(["rx", "ry"], size=int(rng.integers(1, 3)), replace=False))
    free = tuple(dof for dof in d.DOFS if dof in free)
    force = (0.0, 0.0, -float(rng.uniform(50, 400)))
    moment = tuple(float(v) for v in rng.normal(0.0, 60.0, 3))
    reference = tuple(float(v) for v in rng.normal(0.0, 1.0, 3) + [0.0, 0.0, 3.0])
    law = [d.LinearLaw(H), d.CubicLaw(H, 0.3), d.AteshianLaw(H, 0.4)][seed % 3]
    problem = d.ContactProblem(
        layer, law, force=force, moment=moment, reference=reference, free=free, kinematics="finite", targets=targets
    )
    newton = solve(problem, "finite")
    resultant, about = springs_on_body2(newton)
    J = Rot.left_jacobian(newton.u[9:12])
    net = np.concatenate([resultant + force, J.T @ (about + np.array(moment))])
    index = [d.DOFS.index(dof) for dof in free]
    assert np.abs(net[index]).max() <= 1e-8 * max(abs(force[2]), np.abs(moment).max())
    ipopt = solve(problem, "finite_nlp", form="reduced")
    assert np.abs(ipopt.u - newton.u).max() <= 1e-6 * np.abs(newton.u).max()


def test_bad_options_frames_and_starts_are_named():
    layer = punch(10, 2)
    problem = punch_problem(layer, 10.0, 0.0)
    with pytest.raises(d.InputError, match="recast_shift must be a number in"):
        d.solve(problem, recast_shift=-1.0)
    with pytest.raises(d.InputError, match="form must be one of"):
        d.solve(problem, "finite_nlp", form="dense")
    with pytest.raises(d.InputError, match="x0 must have shape"):
        d.solve(problem, x0=[0.0])
    skew = np.eye(4)
    skew[0, 1] = 0.5
    with pytest.raises(d.InputError, match="frame is not rigid"):
        finite.solve(problem, frame=skew)
    with pytest.raises(d.InputError, match="prescribed motion"):
        d.solve(
            d.ContactProblem(layer, d.LinearLaw(H), body1=d.Body(free=(), prescribed={"uz": 0.1}), kinematics="finite")
        )
    with pytest.raises(d.InputError, match="must be finite"):
        Targets.planes(np.full((20, 3), np.nan), -layer.normals)
    from dea_opt.sensitivity import sensitivities

    with pytest.raises(d.InputError, match="derivatives of the small kinematics"):
        sensitivities(solve(punch_problem(layer, 10.0, 0.0)))


def test_a_path_frame_the_springs_cannot_carry_is_recorded_and_the_next_starts_cold():
    layer = punch(20, 4)
    problem = punch_problem(layer, 0.0, 0.0)
    loads = np.array([[0, 0, -200.0, 0, 40.0, 0], [0, 0, 200.0, 0, 0, 0], [0, 0, -250.0, 0, 40.0, 0]])
    result = solve_path_quietly(problem, loads)
    assert list(result.table["success"]) == [True, False, True]
    assert result.table["status"][1] == d.Status.NOT_SUPPORTED
    alone = solve(problem.with_load(force=loads[2, :3], moment=loads[2, 3:]))
    assert np.abs(result.solutions[2].u - alone.u).max() <= 1e-10


def solve_path_quietly(problem, loads):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        return d.solve_path(problem, loads)
