"""Directions no spring resists, judged absolutely, and a certificate
that cannot be fooled (every reproducer of the failure fails it); zero load with a press fit.

Equilibrium is checked here with force and moment sums written in this file; the certificate
is only ever the thing under test.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import dea_opt as d
from dea_opt.geometry import plate_layer, socket_layer

METHODS = ("newton", "qp", "nlp", "auto")


def ball_in_socket(gap=0.0, n_rings=8, n_sectors=16):
    """A socket of radius 25 around a ball centred at the origin: every normal passes through
    the centre (up to rounding), so no spring resists a rotation about it."""
    return socket_layer(radius=25.0, thickness=2.0, coverage=90.0, n_rings=n_rings, n_sectors=n_sectors).with_gap(gap)


def rotations_only(layer, moment=(0.0, 0.0, 0.0), law=None):
    return d.ContactProblem(layer, law or d.LinearLaw(1.0), moment=moment, reference=(0, 0, 0), free=("rx", "ry", "rz"))


def springs_on_body2(layer, pressure, reference):
    """``(force, moment about reference)`` the springs exert on body 2, summed here."""
    f = (pressure * layer.areas)[:, None] * layer.normals
    return f.sum(axis=0), np.cross(layer.points - np.asarray(reference), f).sum(axis=0)


def noise_equilibrium(problem):
    """What the old code returned: the motion that balances the load through the rounding noise
    in the lever arms, ``K x = r - q0`` with ``K = A^T diag(V H) A`` over the free dofs of a
    linear layer, refined until the generalized spring force equals the load to rounding in
    dea_opt's own arrays (the strongest forgery: the per-dof balance holds exactly)."""
    system, H = problem.system(), problem.law.H
    AT, V = system.AT, system.volume
    K = (AT * (V * H)) @ AT.T
    x = np.zeros(system.n_dofs)
    for _ in range(4):
        q = AT @ (V * H * np.minimum(system.strain_at(x), 0.0))
        x = x + np.linalg.lstsq(K, system.load - q, rcond=None)[0]
    return problem.full_u(x)


# --- a ball in a socket with only its rotations free ------------------------------


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("moment", [(1000.0, 0.0, 0.0), (1e-12, 0.0, 0.0), (0.0, -3.0, 7.0)])
@pytest.mark.parametrize("gap", [0.0, -2.0 / 6.0])
def test_a_moment_on_a_ball_with_only_rotations_free_is_rejected_by_every_method(method, moment, gap):
    problem = rotations_only(ball_in_socket(gap), moment)
    with pytest.raises(d.LoadNotSupportedError) as info:
        d.solve(problem, method)
    message = str(info.value)
    assert "no spring resists any of the free dofs ('body2.rx', 'body2.ry', 'body2.rz')" in message
    assert "N mm" in message and "about its reference point (0, 0, 0) mm" in message
    # the unbalanced part is the whole moment, in N mm, per dof
    np.testing.assert_allclose(
        [info.value.direction[f"body2.r{a}"] for a in "xyz"], moment, rtol=0, atol=1e-12 * np.abs(moment).max()
    )


@pytest.mark.parametrize("moment", [(1e-13, 0.0, 0.0), (0.0, 4e-14, -3e-14)])
@pytest.mark.parametrize("gap", [-2.0 / 6.0, -2.0 / 3.0])
def test_the_certificate_fails_the_old_noise_driven_answer(moment, gap):
    """The reported reproducer (a tiny moment on a press-fitted ball, only rotations free): the
    old answer turned the ball by about 1e14 rad and balanced the moment through the rounding
    noise in the lever arms. Forged here so that every spring stays compressed and the
    generalized spring force equals the load to rounding; it must still not pass."""
    for _ in range(6):
        # the rounding noise, and so the motion, differs from layer to layer: a smaller moment
        # until every spring stays compressed (then the forgery is exact)
        problem = rotations_only(ball_in_socket(gap), moment)
        u = noise_equilibrium(problem)
        strain = problem.strain(u)
        if strain.max() < 0:
            break
        moment = tuple(0.1 * m for m in moment)
    assert strain.max() < 0
    assert np.abs(u[9:]).max() > 1e10  # the garbage answer once returned
    sigma = problem.law.stress(strain)
    _, spring_moment = springs_on_body2(problem.layer, -sigma, (0, 0, 0))
    total = float(-sigma @ problem.layer.areas)
    assert np.abs(spring_moment + moment).max() <= 1e-12 * total  # balanced, in plain sums
    certificate = d.certify(problem, u, sigma)
    assert not certificate.passed
    assert certificate.equilibrium >= 0.5  # the whole moment acts along what nothing resists


def test_the_certificate_fails_motion_along_unresisted_directions_without_a_load():
    """A press-fitted ball turned by 1e14 rad: no load anywhere, so the per-dof balance holds to
    rounding, but the strains come from rounding times 1e14 and must not pass."""
    problem = rotations_only(ball_in_socket(-2.0 / 6.0))
    u = np.zeros(12)
    u[9] = 1e14
    strain = problem.strain(u)
    assert np.abs(strain - problem.layer.gap / 2.0).max() > 1e-3  # rounding made these strains
    certificate = d.certify(problem, u, problem.law.stress(np.minimum(strain, 0.0)))
    assert not certificate.passed and certificate.equilibrium > 1e-3


@pytest.mark.parametrize("method", METHODS)
def test_no_load_along_unresisted_rotations_holds_them(method):
    """Press fit, zero moment: every rotation is held (minimum-norm answer), every spring keeps
    the pressure of its overlap, H * 1/3 / 2 = 1/6 MPa, and the answer says so."""
    problem = rotations_only(ball_in_socket(-1.0 / 3.0))
    s = d.solve(problem, method)
    assert s.success and s.status is d.Status.HELD and s.certificate.passed
    assert not s.u.any()
    np.testing.assert_allclose(s.pressure, 1.0 / 6.0, rtol=1e-14)
    assert s.info["held"] == ["body2.rx", "body2.ry", "body2.rz"]
    assert "held at zero motion" in s.message


@pytest.mark.parametrize("method", METHODS)
def test_a_plate_free_in_all_six_dofs_holds_the_unresisted_ones(method):
    """Springs along z resist uz, rx and ry only: ux, uy and rz carry no load and take no
    motion, and the solution says which it held."""
    layer = plate_layer(20.0, 10.0, 20, 10, thickness=2.0)
    H, p = 3.0, 0.05
    problem = d.ContactProblem(layer, d.LinearLaw(H), force=(0, 0, -p * layer.areas.sum()), free=d.DOFS)
    s = d.solve(problem, method)
    assert s.success
    np.testing.assert_allclose(s.pressure, p, rtol=1e-6)
    assert s.u[8] == pytest.approx(-2.0 * p / H, rel=1e-6)
    assert np.abs(s.u[[6, 7, 11]]).max() <= 1e-12 * abs(s.u[8])
    assert s.info["held"] == ["body2.ux", "body2.uy", "body2.rz"]
    assert "held at zero motion" in s.message


@pytest.mark.parametrize("method", METHODS)
def test_a_tiny_load_along_an_unresisted_dof_of_a_partly_resisted_body_is_rejected(method):
    """1e-6 of the load as an in-plane force on a plate: more than the 1e-7 the load check
    allows, by every method (Newton included, which used to check only after failing)."""
    layer = plate_layer(20.0, 10.0, 20, 10, thickness=2.0)
    problem = d.ContactProblem(layer, d.LinearLaw(3.0), force=(1e-4, 0, -100.0), free=d.DOFS)
    with pytest.raises(d.LoadNotSupportedError, match=r"force \+0.0001 N along x on body2"):
        d.solve(problem, method)


# --- zero load with a press fit ---------------------------------------------------


def box_layer(half=5.0, n=6, h=1.0, overlap=(0.1, 0.1, 0.1, 0.1, 0.1, 0.1)):
    """Springs on the six inner faces of a box around a cube of side ``2 half``, normals from
    the box (body 1) to the cube (body 2), overlapping it by ``overlap`` (-x, +x, -y, +y, -z, +z)."""
    g = (np.arange(n) + 0.5) / n * 2 * half - half
    U, V = (a.ravel() for a in np.meshgrid(g, g, indexing="ij"))
    points, normals, gaps = [], [], []
    for axis in range(3):
        others = [i for i in range(3) if i != axis]
        for k, sign in enumerate((-1.0, 1.0)):
            p = np.zeros((U.size, 3))
            p[:, axis], p[:, others[0]], p[:, others[1]] = sign * half, U, V
            normal = np.zeros((U.size, 3))
            normal[:, axis] = -sign
            points.append(p)
            normals.append(normal)
            gaps.append(np.full(U.size, -overlap[2 * axis + k]))
    area = (2 * half / n) ** 2
    return d.SpringLayer(np.vstack(points), np.vstack(normals), area, h, np.concatenate(gaps)), area * n * n


@pytest.mark.parametrize("method", METHODS)
def test_a_cube_press_fitted_into_a_box_under_no_load(method):
    """Overlaps a = 0.12 (-x face) and b = 0.04 (+x face): the cube moves by (a - b) / 2 along x,
    where both faces press with H (a + b) / (2 h); the other faces keep H * 0.1 / h."""
    a, b, H = 0.12, 0.04, 2.0
    layer, _ = box_layer(overlap=(a, b, 0.1, 0.1, 0.1, 0.1))
    problem = d.ContactProblem(layer, d.LinearLaw(H), reference=(0, 0, 0))
    s = d.solve(problem, method)
    assert s.success and s.certificate.passed
    assert s.status is d.Status.PRELOADED
    assert s.u[6] == pytest.approx((a - b) / 2, rel=1e-9)
    np.testing.assert_allclose(np.delete(s.u[6:], 0), 0.0, atol=1e-12)
    x_faces = np.abs(layer.normals[:, 0]) == 1
    np.testing.assert_allclose(s.pressure[x_faces], H * (a + b) / 2, rtol=1e-9)
    np.testing.assert_allclose(s.pressure[~x_faces], H * 0.1, rtol=1e-9)
    force, moment = springs_on_body2(layer, s.pressure, (0, 0, 0))
    total = float(s.pressure @ layer.areas)
    assert np.abs(force).max() <= 1e-12 * total and np.abs(moment).max() <= 1e-12 * total * 5.0


@pytest.mark.parametrize("method", METHODS)
def test_a_small_load_on_a_press_fit_is_carried_to_a_millionth_of_itself(method):
    """A force of 1e-4 N against press-fit forces of about 100 N: the cube moves on by F h / (2 H A)
    from the press fit's position, found by every method, and the springs balance the load to 1e-6
    of the load itself (summed here), not of the press fit's forces."""
    a, b, H, F = 0.12, 0.04, 2.0, 1e-4
    layer, face = box_layer(overlap=(a, b, 0.1, 0.1, 0.1, 0.1))
    problem = d.ContactProblem(layer, d.LinearLaw(H), force=(F, 0, 0), reference=(0, 0, 0))
    s = d.solve(problem, method, **({"tol": 1e-12} if method == "qp" else {}))
    assert s.success
    assert s.u[6] - (a - b) / 2 == pytest.approx(F * 1.0 / (2 * H * face), rel=1e-6)
    force, _ = springs_on_body2(layer, s.pressure, (0, 0, 0))
    assert abs(force[0] + F) <= 1e-6 * F


@pytest.mark.parametrize("method", METHODS)
def test_a_load_below_the_rounding_of_a_press_fit_is_not_certified(method):
    """A force of 1e-9 N against press-fit forces of about 100 N: the strains of overlaps 0.1 mm deep
    are known to 1e-16 mm or so, which moves the springs' forces by more than 1e-6 of the load. No
    method's answer is certified (once they were, balanced to 1e-6 of the press fit's forces: 1e4
    times the load), and the message says why."""
    a, b, H, F = 0.12, 0.04, 2.0, 1e-9
    layer, _ = box_layer(overlap=(a, b, 0.1, 0.1, 0.1, 0.1))
    problem = d.ContactProblem(layer, d.LinearLaw(H), force=(F, 0, 0), reference=(0, 0, 0))
    s = d.solve(problem, method, strict=False, **({"tol": 1e-12} if method == "qp" else {}))
    assert not s.success and s.certificate.rounding > 1e-6
    assert "rounding of the strains" in s.message


@pytest.mark.parametrize("method", METHODS)
@pytest.mark.parametrize("gap", [0.0, 0.05])
def test_no_load_and_no_overlap_has_one_status(method, gap):
    layer, _ = box_layer(overlap=(-gap,) * 6)
    s = d.solve(d.ContactProblem(layer, d.LinearLaw(2.0), reference=(0, 0, 0)), method)
    assert s.success and s.status is d.Status.UNLOADED and not s.u.any() and not s.pressure.any()


# --- the equilibrium residual is one a reader can redo ---------------------------------------


def test_the_equilibrium_residual_is_the_documented_formula():
    """Perturb a converged answer and recompute the README's formula here: ``max_j |q_j - r_j| / L_j``
    over the load ``max_j |r_j| / L_j`` (the strains' rounding, which the certificate adds to each
    ``|q_j - r_j|``, is far below the perturbations here)."""
    layer = plate_layer(20.0, 10.0, 10, 5, thickness=2.0).with_gap(-0.01)
    reference = np.array([3.0, -2.0, 5.0])
    H = 1.5
    load = d.Load(force=(0.0, 0.0, -20.0), point=(2.0, 1.0, 0.0))
    problem = d.ContactProblem(layer, d.LinearLaw(H), load=load, reference=tuple(reference), free=("uz", "rx", "ry"))
    s = d.solve(problem, "newton")
    r = np.array([-20.0, *np.cross(np.array([2.0, 1.0, 0.0]) - reference, [0.0, 0.0, -20.0])[:2]])
    for k, delta in enumerate((1e-7, -3e-6, 2e-5)):
        u = s.u.copy()
        u[8 + k] += delta / (1.0 if k == 0 else 10.0)
        # the residual written here, from the spring forces at u
        arm = layer.points - reference
        moved = u[6:9] + np.cross(u[9:], arm)
        strain = (layer.gap + np.sum(layer.normals * moved, axis=1)) / layer.thickness
        force_i = layer.areas * H * np.minimum(strain, 0.0)  # tension positive, so <= 0
        f = -force_i[:, None] * layer.normals  # pushes body 2 along +n
        q = -np.concatenate([f.sum(axis=0), np.cross(arm, f).sum(axis=0)])[[2, 3, 4]]
        radius = np.sqrt(np.mean(np.sum(arm**2, axis=1)))
        length = np.array([1.0, radius, radius])
        mine = np.abs((q - r) / length).max() / np.abs(r / length).max()
        assert mine > 1e-9
        got = d.certify(problem, u, H * np.minimum(strain, 0.0)).equilibrium
        assert got == pytest.approx(mine, rel=1e-6)


def test_solve_is_quiet_for_held_and_preloaded_answers():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        d.solve(rotations_only(ball_in_socket(-0.1)), "auto")
        d.solve(d.ContactProblem(box_layer()[0], d.LinearLaw(1.0), reference=(0, 0, 0)), "auto")


def test_the_cli_rejects_the_ball_in_socket_reproducer(tmp_path):
    """Through the command line the reported scenario exited 0 with the garbage answer."""
    import subprocess
    import sys

    scenario = tmp_path / "socket.toml"
    scenario.write_text(
        '[geometry]\nkind = "socket"\nn_rings = 6\nn_sectors = 12\n[law]\nkind = "linear"\nH = 1.0\n'
        '[body2]\nreference = [0, 0, 0]\nfree = ["rx", "ry", "rz"]\n[load]\nmoment = [1000, 0, 0]\n'
    )
    done = subprocess.run(
        [sys.executable, "-m", "dea_opt.cli", "run", str(scenario), "-o", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert done.returncode == 2, done.stdout[-2000:] + done.stderr[-2000:]
    assert done.stderr.startswith("dea-opt: error:") and "no spring resists any of the free dofs" in done.stderr
