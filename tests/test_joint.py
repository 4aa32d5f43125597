"""A whole joint under small kinematics: closed forms, the two-body problems again, bad input.

Equilibrium is checked with the sums of ``tests/joint_checks.py`` (forces and moments written
there), never by calling the certificate.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pytest
from joint_checks import net_wrench, worst_imbalance

import dea_opt as d
from dea_opt.geometry import plate_layer, socket_layer, sphere_on_bed_layer

GROUND = d.Body(free=())


def _shifted(layer, dz):
    return d.SpringLayer(layer.points + [0.0, 0.0, dz], layer.normals, layer.areas, layer.thickness, layer.gap)


# --- a chain of bodies between layers -------------------------------------------------------


def _chain(law1, law2, force=-300.0):
    lower, upper = plate_layer(nx=12, ny=6, thickness=2.0), _shifted(plate_layer(nx=12, ny=6, thickness=3.0), 10.0)
    bodies = {
        "ground": GROUND,
        "middle": d.Body(reference=(0.0, 0.0, 5.0), free=("uz", "rx", "ry")),
        "top": d.Body(reference=(0.0, 0.0, 15.0), free=("uz", "rx", "ry"), force=(0.0, 0.0, force)),
    }
    contacts = [
        d.Contact(lower, law1, body1="ground", body2="middle"),
        d.Contact(upper, law2, body1="middle", body2="top"),
    ]
    return d.Joint(bodies, contacts), lower


@pytest.mark.parametrize("method", ["newton", "qp", "nlp", "auto"])
def test_a_chain_of_bodies_carries_the_load_through_each_layer(method):
    joint, layer = _chain(d.LinearLaw(5.0), d.LinearLaw(7.0))
    s = d.solve(joint, method)
    area = layer.areas.sum()
    F = 300.0
    assert s.success and s.status == "converged"
    # each layer carries the whole load, uniformly: p = F / A, and the bodies sink by p h / H
    for contact in s.contacts:
        np.testing.assert_allclose(contact.contact_force, [0.0, 0.0, F], rtol=1e-9, atol=1e-9)
        np.testing.assert_allclose(contact.pressure, F / area, rtol=1e-9)
    np.testing.assert_allclose(s.bodies["middle"].u, [0, 0, -F / area * 2.0 / 5.0, 0, 0, 0], atol=1e-10)
    expected = -F / area * (2.0 / 5.0 + 3.0 / 7.0)
    np.testing.assert_allclose(s.bodies["top"].u[2], expected, rtol=1e-9)
    assert s.bodies["ground"].reactions["uz"] == pytest.approx(F, rel=1e-9)
    assert worst_imbalance(s) < 1e-9
    # each layer is a two-body answer of its own, certified with the rest of the joint as its loads
    assert all(c.certificate.passed for c in s.contacts)


def test_a_chain_under_a_nonlinear_law_matches_the_law_s_inverse():
    law = d.AteshianLaw(H=4.0, beta=0.3)
    joint, layer = _chain(law, law, force=-2000.0)
    s = d.solve(joint, "newton")
    stress = -2000.0 / layer.areas.sum()
    # both layers are uniformly compressed to the strain where sigma = -F / A
    from scipy.optimize import brentq

    eps = brentq(lambda e: float(law.stress(np.array([e]))[0]) - stress, -0.9, 0.0)
    np.testing.assert_allclose(s.contacts[0].strain, eps, rtol=1e-9)
    np.testing.assert_allclose(s.bodies["top"].u[2], eps * 2.0 + eps * 3.0, rtol=1e-9)
    other = d.solve(joint, "nlp")
    np.testing.assert_allclose(other.x, s.x, rtol=1e-8, atol=1e-12)
    assert worst_imbalance(s) < 1e-9 and worst_imbalance(other) < 1e-8


# --- a block held by two crossed ligaments under a shear --------------------------------------

HALF, HEIGHT, K, EPS_T = 10.0, 20.0, 1000.0, 0.06
LENGTH = float(np.hypot(2 * HALF, HEIGHT))


def _crossed(shear, law="blankevoort", slack=LENGTH):
    bodies = {"ground": GROUND, "block": d.Body(reference=(0.0, 0.0, HEIGHT), free=("ux",), force=(shear, 0.0, 0.0))}
    ligaments = [
        d.Ligament(
            "ground", (-HALF, 0, 0), "block", (HALF, 0, HEIGHT), stiffness=K, slack_length=slack, law=law, name="a"
        ),
        d.Ligament(
            "ground", (HALF, 0, 0), "block", (-HALF, 0, HEIGHT), stiffness=K, slack_length=slack, law=law, name="b"
        ),
    ]
    return d.Joint(bodies, ligaments=ligaments)


@pytest.mark.parametrize("shear", [3.0, 40.0], ids=["toe", "linear"])
@pytest.mark.parametrize("method", ["newton", "nlp"])
def test_crossed_ligaments_under_a_shear_follow_blankevoort(shear, method):
    s = d.solve(_crossed(shear), method)
    # Only bundle "a" (stretched by +ux) pulls; its x-component balances the shear.
    cos = 2 * HALF / LENGTH
    force = shear / cos
    toe = force < K * EPS_T / 2  # the toe ends at f = k eps_t / 2
    eps = np.sqrt(2 * EPS_T * force / K) if toe else force / K + EPS_T / 2
    assert toe == (shear == 3.0)
    # small kinematics: the strain is e . delta / L0 with delta = ux along x
    ux = eps * LENGTH / cos
    assert s.success
    np.testing.assert_allclose(s.bodies["block"].u[0], ux, rtol=1e-9)
    np.testing.assert_allclose(s.ligaments.force, [force, 0.0], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(s.ligaments.strain, [eps, -eps], rtol=1e-9)
    assert s.ligaments["a"]["force_N"] == pytest.approx(force, rel=1e-9)
    # the ground's reaction: the bundle's pull, all of it
    assert s.bodies["ground"].reactions["ux"] == pytest.approx(-shear, rel=1e-9)
    assert worst_imbalance(s) < 1e-9


def test_crossed_linear_ligaments_by_every_method():
    s = {m: d.solve(_crossed(40.0, law="linear"), m) for m in ("newton", "qp", "nlp")}
    cos = 2 * HALF / LENGTH
    ux = 40.0 / cos / K * LENGTH / cos
    for method, solution in s.items():
        assert solution.success, method
        np.testing.assert_allclose(solution.bodies["block"].u[0], ux, rtol=1e-8)
        assert worst_imbalance(solution) < 1e-8


def test_a_reference_strain_sets_the_slack_length():
    lig = d.Ligament("g", (0, 0, 0), "b", (0, 0, 30.0), stiffness=100.0, reference_strain=0.05)
    assert lig.slack_length == pytest.approx(30.0 / 1.05)
    assert lig.start_strain == pytest.approx(0.05)
    # pre-stretched bundles carry their force at once: two of them, opposed, hold a block at rest
    bodies = {"g": GROUND, "b": d.Body(reference=(0, 0, 15.0), free=("uz",))}
    ligs = [
        d.Ligament("g", (0, 0, 0), "b", (0, 0, 10.0), stiffness=100.0, reference_strain=0.05),
        d.Ligament("g", (0, 0, 30.0), "b", (0, 0, 20.0), stiffness=300.0, reference_strain=0.05),
    ]
    s = d.solve(d.Joint(bodies, ligaments=ligs))
    assert s.status == "preloaded" and s.success
    # equal and opposite: k1 phi(e1) = k2 phi(e2) with e1 = 0.05 + u/L0, e2 = 0.05 - u/L0
    f = s.ligaments.force
    assert f[0] == pytest.approx(f[1], rel=1e-9) and f[0] > 0
    assert worst_imbalance(s) < 1e-9


# --- a two-layer sandwich against its one-layer equivalent -----------------------------------


def test_a_two_layer_sandwich_is_its_one_layer_equivalent():
    h1, h2, H1, H2 = 1.5, 2.5, 4.0, 9.0
    base = plate_layer(nx=16, ny=8, thickness=1.0)
    lower = replace(base, thickness=np.full(len(base), h1))
    upper = _shifted(replace(base, thickness=np.full(len(base), h2)), 4.0)
    load = dict(force=(0.0, 0.0, -200.0), moment=(40.0, -60.0, 0.0))
    top = d.Body(reference=(1.0, -0.5, 9.0), free=("uz", "rx", "ry"), **load)
    sandwich = d.Joint(
        {"bed": GROUND, "middle": d.Body(reference=(0.0, 0.0, 3.0), free=("uz", "rx", "ry")), "top": top},
        [
            d.Contact(lower, d.LinearLaw(H1), body1="bed", body2="middle"),
            d.Contact(upper, d.LinearLaw(H2), body1="middle", body2="top"),
        ],
    )
    h = h1 + h2
    equivalent = d.ContactProblem(
        replace(base, thickness=np.full(len(base), h)), d.LinearLaw(h / (h1 / H1 + h2 / H2)), body1=GROUND, body2=top
    )
    one = d.solve(equivalent, "newton")
    assert (one.strain < 0).all()  # full contact: the two layers act in series point by point
    for method in ("newton", "qp", "nlp"):
        two = d.solve(sandwich, method)
        np.testing.assert_allclose(two.bodies["top"].u, one.u[6:], rtol=1e-8, atol=1e-12)
        np.testing.assert_allclose(two.contacts[0].pressure, one.pressure, rtol=1e-8)
        np.testing.assert_allclose(two.contacts[1].pressure, one.pressure, rtol=1e-8)
        assert worst_imbalance(two) < 1e-8


# --- today's two-body problems through the joint -------------------------------------------


def _two_body_cases():
    bed = sphere_on_bed_layer(radius=25.0, thickness=2.0, n_rings=30, n_sectors=24)
    socket = socket_layer(radius=25.0, thickness=3.0, coverage=80.0, n_rings=12, n_sectors=24, gap=0.05)
    plate = plate_layer(nx=20, ny=5)
    yield (
        "ball",
        d.ContactProblem(
            bed,
            d.LinearLaw(3.0),
            force=(0, 0, -20.0),
            moment=(40.0, -25.0, 0.0),
            reference=(0, 0, 25.0),
            free=("uz", "rx", "ry"),
        ),
    )
    yield (
        "ball-ateshian",
        d.ContactProblem(
            bed,
            d.AteshianLaw(0.6, 0.1),
            force=(0, 0, -20.0),
            moment=(40.0, -25.0, 0.0),
            reference=(0, 0, 25.0),
            free=("uz", "rx", "ry"),
        ),
    )
    yield "socket", d.ContactProblem(socket, d.LinearLaw(10.0), force=(300.0, -150.0, -1500.0), free=("ux", "uy", "uz"))
    yield (
        "plate-both-free",
        d.ContactProblem(
            plate,
            d.CubicLaw(5.0, 0.4),
            body1=d.Body(reference=(0, 0, -3.0), free=("rx",), moment=(10.0, 0.0, 0.0)),
            body2=d.Body(reference=(2.0, 0, 4.0), free=("uz", "ry"), force=(0, 0, -100.0), moment=(0.0, 20.0, 0)),
        ),
    )
    yield (
        "plate-prescribed",
        d.ContactProblem(
            plate,
            d.LinearLaw(5.0),
            body1=GROUND,
            body2=d.Body(free=("rx", "ry"), prescribed={"uz": -0.05}, moment=(5.0, -30.0, 0.0)),
        ),
    )


CASES = dict(_two_body_cases())


def _methods(problem):
    return ["newton", "nlp"] + (["qp"] if problem.law.is_linear else [])


@pytest.mark.parametrize("case, method", [(c, m) for c, p in CASES.items() for m in _methods(p)])
def test_a_two_body_problem_through_the_joint_is_reproduced(case, method):
    problem = CASES[case]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        two = d.solve(problem, method)
        joint = d.Joint(
            {"one": problem.body1, "two": problem.body2},
            [d.Contact(problem.layer, problem.law, body1="one", body2="two")],
        )
        many = d.solve(joint, method)
    assert many.success and two.success
    scale = float(np.abs(two.u).max())
    tol = 1e-10 if method != "qp" else 1e-8  # two QP solves stop at Clarabel's own tolerances
    np.testing.assert_allclose(
        np.concatenate([many.bodies["one"].u, many.bodies["two"].u]), two.u, rtol=0, atol=tol * scale
    )
    np.testing.assert_allclose(many.contacts[0].pressure, two.pressure, rtol=0, atol=tol * two.peak_pressure)
    assert many.contacts[0].peak_pressure == pytest.approx(two.peak_pressure, rel=tol)
    np.testing.assert_allclose(many.contacts[0].center_of_pressure, two.center_of_pressure, atol=tol * 100)
    for dof, value in two.reactions.items():
        body, name = dof.split(".")
        assert many.bodies["one" if body == "body1" else "two"].reactions[name] == pytest.approx(
            value, abs=tol * 10 * max(1.0, abs(value))
        )
    assert worst_imbalance(many) < 1e-8


def test_a_layer_s_answer_is_a_two_body_solution_with_its_files(tmp_path):
    joint, _ = _chain(d.LinearLaw(5.0), d.LinearLaw(7.0))
    s = d.solve(joint)
    layer = s.contacts[1]
    assert isinstance(layer, d.Solution) and layer.validity.valid
    layer.to_csv(tmp_path / "upper.csv")
    layer.to_json(tmp_path / "upper.json")
    assert (tmp_path / "upper.csv").stat().st_size > 0
    summary = s.summary()
    assert summary["contacts"][1]["contact_force_N"][2] == pytest.approx(300.0)
    assert set(summary["certificate"]["bodies"]) == {"middle", "top"}


# --- the equilibrium the elements find, checked with sums written here ------------------------


def test_a_knee_like_joint_with_layers_and_ligaments_balances_every_body():
    socket = socket_layer(radius=20.0, thickness=2.0, coverage=60.0, n_rings=8, n_sectors=16, gap=0.02)
    cap = _shifted(plate_layer(length=20.0, width=12.0, nx=10, ny=6, thickness=3.0), 30.0)
    bodies = {
        "tibia": GROUND,
        "femur": d.Body(reference=(0, 0, 0), force=(30.0, -20.0, -800.0), moment=(500.0, -300.0, 200.0)),
        "patella": d.Body(reference=(0, 0, 32.0), free=("ux", "uy", "uz", "rx", "ry", "rz"), force=(5.0, 0.0, -50.0)),
    }
    ligs = [
        d.Ligament(
            "femur",
            (15.0 * np.cos(t), 15.0 * np.sin(t), 5.0),
            "tibia",
            (25.0 * np.cos(t + a), 25.0 * np.sin(t + a), -25.0),
            stiffness=2000.0,
            slack_length=28.0,
        )
        for t, a in zip(np.linspace(0, 2 * np.pi, 9)[:-1], [0.4, -0.4] * 4)
    ]
    ligs += [
        d.Ligament(
            "patella",
            (x, y, 34.0),
            "tibia",
            (x * 2 - s * y, y * 2 + s * x, 60.0),
            stiffness=500.0,
            reference_strain=0.02,
            law="linear",
        )
        for x, y, s in ((5, 5, 1), (-5, 5, -1), (5, -5, -1), (-5, -5, 1), (0, 6, 1), (0, -6, -1))
    ]
    ligs += [d.Ligament("patella", (0, 8, 33.0), "femur", (0, 20, 10.0), stiffness=300.0, slack_length=25.0)]
    joint = d.Joint(
        bodies,
        [
            d.Contact(socket, d.AteshianLaw(5.0, 0.2), body1="tibia", body2="femur"),
            d.Contact(cap, d.LinearLaw(8.0), body1="femur", body2="patella"),
        ],
        ligs,
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        s = d.solve(joint, "newton")
        t = d.solve(joint, "nlp")
    assert s.success and t.success
    assert worst_imbalance(s) < 1e-9 and worst_imbalance(t) < 1e-8
    np.testing.assert_allclose(t.x, s.x, rtol=0, atol=1e-8 * float(np.abs(s.x).max()))
    assert (s.ligaments.force >= 0).all() and (s.contacts[0].pressure >= 0).all()
    # the ground carries everything: its reactions balance the loads of the free bodies
    total = sum(np.array(b.force) for b in joint.bodies.values())
    reactions = s.bodies["tibia"].reactions
    np.testing.assert_allclose([reactions["ux"], reactions["uy"], reactions["uz"]], -total, rtol=1e-8, atol=1e-8)
    wrench = net_wrench(s)
    assert np.abs(wrench["femur"][0]).max() < 1e-7 * 800


# --- what needs no solver -------------------------------------------------------------------


def test_the_answers_without_a_solver():
    bodies = {"g": GROUND, "b": d.Body(reference=(0, 0, 10.0), free=("uz",))}
    layer = plate_layer(nx=4, ny=4)
    joint = d.Joint(bodies, [d.Contact(layer, d.LinearLaw(1.0), body1="g", body2="b")])
    assert d.solve(joint).status == "unloaded"
    fixed = d.Joint(
        {"g": GROUND, "b": d.Body(free=(), prescribed={"uz": -0.1})},
        [d.Contact(layer, d.LinearLaw(1.0), body1="g", body2="b")],
    )
    s = d.solve(fixed)
    assert s.status == "no_free_dofs"
    np.testing.assert_allclose(s.contacts[0].strain, -0.05)
    assert s.bodies["b"].reactions["uz"] == pytest.approx(-0.05 * 1.0 * layer.areas.sum())
    press = d.Joint(
        bodies, [d.Contact(replace(layer, gap=np.full(len(layer), -0.1)), d.LinearLaw(1.0), body1="g", body2="b")]
    )
    s = d.solve(press, "qp")
    assert s.status == "preloaded" and s.success and s.bodies["b"].u[2] >= 0.1 - 1e-12


# --- bad input --------------------------------------------------------------------------------


def _ok():
    return dict(
        bodies={"g": GROUND, "b": d.Body(free=("uz",))},
        contacts=[d.Contact(plate_layer(nx=3, ny=3), d.LinearLaw(1.0), body1="g", body2="b")],
    )


@pytest.mark.parametrize(
    "change, words",
    [
        (dict(bodies={}), "non-empty mapping"),
        (dict(bodies={"g": GROUND, "b": "femur"}), "must be a dea_opt.Body"),
        (dict(bodies={"g.1": GROUND, "b": d.Body()}), "without '.'"),
        (
            dict(bodies={"g": GROUND, "b": d.Body(free=("uz",)), "lost": d.Body(free=("ux",))}),
            "body 'lost' has free dofs",
        ),
        (
            dict(contacts=[d.Contact(plate_layer(nx=3, ny=3), d.LinearLaw(1.0), body1="g", body2="tibia")]),
            "'tibia', which is not a body",
        ),
        (dict(contacts="contact"), "sequence of dea_opt.Contact"),
        (dict(contacts=[1]), "Joint.contacts[0] must be a dea_opt.Contact"),
        (
            dict(ligaments=[d.Contact(plate_layer(nx=3, ny=3), d.LinearLaw(1.0), body1="g", body2="b")]),
            "must be a dea_opt.Ligament",
        ),
        (dict(kinematics="large"), "kinematics must be one of"),
    ],
)
def test_a_bad_joint_is_an_input_error_naming_what_is_wrong(change, words):
    with pytest.raises(
        d.InputError,
        match=words.replace("(", r"\(").replace(")", r"\)").replace("[", r"\[").replace("]", r"\]").replace(".", r"\."),
    ):
        d.Joint(**(_ok() | change))


@pytest.mark.parametrize(
    "kwargs, words",
    [
        (dict(body2="g"), "two different bodies"),
        (dict(point2=(0, 0, 0)), "two different points"),
        (dict(stiffness=-1.0), "stiffness must be"),
        (dict(stiffness=float("nan")), "stiffness must be"),
        (dict(slack_length=None), "exactly one"),
        (dict(reference_strain=0.02), "exactly one"),
        (dict(slack_length=0.0), "slack_length must be"),
        (dict(law="hill"), "law must be one of"),
        (dict(transition_strain=0.0), "transition_strain must be"),
        (dict(point1=(0, "a", 0)), "point1"),
        (dict(body1=3), "body1 must be the name"),
        (dict(name=""), "name must be"),
    ],
)
def test_a_bad_ligament_is_an_input_error(kwargs, words):
    good = dict(body1="g", point1=(0, 0, 0), body2="b", point2=(0, 0, 10.0), stiffness=10.0, slack_length=9.0)
    with pytest.raises(d.InputError, match=words):
        d.Ligament(**(good | kwargs))


@pytest.mark.parametrize(
    "kwargs, words",
    [
        (dict(layer="springs"), "must be a SpringLayer"),
        (dict(law=3.0), "law"),
        (dict(body2="g"), "two different bodies"),
        (dict(body1=""), "body1 must be the name"),
        (dict(targets=object()), "targets must be"),
    ],
)
def test_a_bad_contact_is_an_input_error(kwargs, words):
    good = dict(layer=plate_layer(nx=3, ny=3), law=d.LinearLaw(1.0), body1="g", body2="b")
    with pytest.raises(d.InputError, match=words):
        d.Contact(**(good | kwargs))


def test_bad_methods_and_options_are_input_errors():
    joint = _crossed(3.0)
    with pytest.raises(d.InputError, match="method must be one of"):
        d.solve(joint, "finite")
    with pytest.raises(d.InputError, match="needs linear elements"):
        d.solve(joint, "qp")
    with pytest.raises(d.InputError, match="x0 must be 1 finite"):
        d.solve(joint, x0=[0.0, 1.0])
    with pytest.raises(d.InputError, match="max_iter"):
        d.solve(joint, "newton", max_iter=0)
    with pytest.raises(d.InputError, match="unknown option"):
        d.solve(joint, "auto", solver_speed=3)
    with pytest.raises(d.InputError, match="certificate_tol"):
        d.solve(joint, certificate_tol=2.0)


def test_a_load_no_element_carries_is_refused_naming_it():
    bodies = {"ground": GROUND, "block": d.Body(reference=(0.0, 0.0, HEIGHT), free=("ux", "uy"), force=(5.0, 2.0, 0.0))}
    joint = replace(_crossed(5.0), bodies=bodies)
    with pytest.raises(d.LoadNotSupportedError, match="block.uy") as err:
        d.solve(joint)
    assert err.value.direction["block.uy"] == pytest.approx(2.0)
    # a bundle only pulls: a load pushing its ends together is outside the cone, by every method
    one = d.Joint(
        {"g": GROUND, "b": d.Body(reference=(0, 0, 10.0), free=("uz",), force=(0, 0, -1.0))},
        ligaments=[d.Ligament("g", (0, 0, 0), "b", (0, 0, 10.0), stiffness=10.0, slack_length=10.0, law="linear")],
    )
    for method in ("auto", "newton", "qp", "nlp"):
        with pytest.raises(d.LoadNotSupportedError, match="only pull"):
            d.solve(one, method)


def test_a_bundle_strained_toward_rupture_is_flagged():
    joint = _crossed(200.0)
    with pytest.warns(d.ValidityWarning, match="ligament_strain"):
        s = d.solve(joint)
    assert s.success and not s.validity.valid
    assert "ligament_strain" in s.validity.failed and s.validity["ligament_strain"].value > 0.15
    assert d.solve(_crossed(3.0)).validity.valid


def test_the_blankevoort_law_is_opensim_s_and_its_energy_and_tangent_are_consistent():
    from dea_opt.formulations.joint import TensionLaw

    et = 0.06
    law = TensionLaw("blankevoort", np.full(7, et))
    eps = np.array([-0.1, 0.0, 0.01, 0.03, et, 0.09, 0.2])
    # OpenSim's Blankevoort1991Ligament: 0, k e^2 / (2 e_t), k (e - e_t / 2), per unit k
    expected = np.where(eps <= 0, 0.0, np.where(eps < et, eps**2 / (2 * et), eps - et / 2))
    np.testing.assert_allclose(law.force(eps), expected, rtol=1e-15, atol=0)
    h = 1e-7
    np.testing.assert_allclose((law.energy(eps + h) - law.energy(eps - h)) / (2 * h), law.force(eps), atol=1e-9)
    inside = eps != 0.0  # the tangent's kink at slack
    numeric = (law.force(eps + h) - law.force(eps - h)) / (2 * h)
    np.testing.assert_allclose(numeric[inside & (eps != et)], law.tangent(eps)[inside & (eps != et)], atol=1e-6)
    # both branches meet at e_t with the same force and slope (the curve of Blankevoort's 2 e_l = e_t)
    below, above = law.force(np.array([et - 1e-12] * 7)), law.force(np.array([et + 1e-12] * 7))
    assert abs(below[0] - above[0]) < 1e-11 and law.tangent(np.array([et] * 7))[0] == 1.0
    assert d.Ligament("a", (0, 0, 0), "b", (0, 0, 10), stiffness=100.0, slack_length=9.0).force_at(
        0.1
    ) == pytest.approx(100 * (0.1 - 0.03))


def test_each_layer_s_problem_is_a_two_body_problem_in_equilibrium():
    joint, _ = _chain(d.AteshianLaw(5.0, 0.2), d.LinearLaw(7.0))
    s = d.solve(joint)
    for layer in s.contacts:
        again = d.certify(layer.problem, layer.u, -layer.pressure)
        assert again.passed, again
        assert layer.certificate.equilibrium == s.certificate.equilibrium
