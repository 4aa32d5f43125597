"""Random multi-body joints: a manufactured equilibrium found again, checked by sums written here.

Each example draws 2 to 4 bodies (the first held as ground, the others with random free dofs and
references), a contact layer from each free body to an earlier one (random points, normals, areas,
thicknesses and gaps, a linear or Ateshian law) and ligament bundles between random bodies
(Blankevoort or linear, slack or stretched at the start). A motion ``u*`` of every body is drawn,
and each body is given the load that balances the elements at ``u*``, computed here with the
small kinematics written in this module (Eq. 9-11 for springs, the linearised length for bundles).
The properties, for every method that applies (``newton``, ``nlp``, ``qp`` when every element is
linear):

* the answer balances every free body, by this module's own force and moment sums at the answer's
  motion (the forces recomputed here from the laws, not read from the solution);
* no spring pulls and no bundle pushes, and the solution's element forces are this module's;
* where the manufactured equilibrium is unique (the active elements' stiffness is positive
  definite on the free dofs, tested here), every element's strain is that of ``u*``;
* the methods agree.

Modest by default (``DEA_HYPOTHESIS_PROFILE=thorough`` draws four times as many).
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass

import numpy as np
import pytest
from hypothesis import HealthCheck, Phase, given, note, settings
from hypothesis import strategies as st

import dea_opt as d

EXAMPLES = {"ci": 80, "thorough": 320}[os.environ.get("DEA_HYPOTHESIS_PROFILE", "ci")]
DOFS = ("ux", "uy", "uz", "rx", "ry", "rz")


@dataclass
class Case:
    n_bodies: int
    seed: int
    linear: bool
    n_ligaments: int


def _phi(kind, eps, et):
    e = max(eps, 0.0)
    if kind == "linear":
        return e, float(eps > 0)
    return (e * e / (2 * et), e / et) if e < et else (e - et / 2, 1.0)


def _motion(u, c, p):
    """The small motion of point(s) ``p`` of a body moved by ``u`` about ``c`` (Eq. 9)."""
    return u[:3] + np.cross(u[3:], np.asarray(p) - c)


def element_wrenches(joint, body_u):
    """``{body: 6-vector}`` the elements apply to each body at the motions ``body_u`` (N, N mm about its
    reference), the springs' and bundles' forces (N) and strains, and the active stiffness rows."""
    out = {name: np.zeros(6) for name in joint.bodies}
    springs, bundles, rows = [], [], []
    for c in joint.contacts:
        a, b = c.body1, c.body2
        ca, cb = (np.asarray(joint.bodies[n].reference) for n in (a, b))
        L = c.layer
        rel = _motion(body_u[b], cb, L.points) - _motion(body_u[a], ca, L.points)
        eps = (L.gap + np.einsum("ij,ij->i", L.normals, rel)) / L.thickness
        pressure = -c.law.stress(np.minimum(eps, 0.0))
        push = (pressure * L.areas)[:, None] * L.normals
        out[b] += np.concatenate([push.sum(0), np.cross(L.points - cb, push).sum(0)])
        out[a] -= np.concatenate([push.sum(0), np.cross(L.points - ca, push).sum(0)])
        springs.append((eps, pressure))
        tangent = c.law.tangent(np.minimum(eps, 0.0)) * L.areas / L.thickness
        for i in np.flatnonzero(eps < 0):
            rows.append((a, b, L.points[i], L.points[i], L.normals[i], tangent[i]))
    for lig in joint.ligaments:
        a, b = lig.body1, lig.body2
        ca, cb = (np.asarray(joint.bodies[n].reference) for n in (a, b))
        p1, p2 = np.asarray(lig.point1), np.asarray(lig.point2)
        e = (p2 - p1) / np.linalg.norm(p2 - p1)
        length = np.linalg.norm(p2 - p1) + e @ (_motion(body_u[b], cb, p2) - _motion(body_u[a], ca, p1))
        eps = length / lig.slack_length - 1.0
        phi, slope = _phi(lig.law, eps, lig.transition_strain)
        f = lig.stiffness * phi
        out[a] += np.concatenate([f * e, f * np.cross(p1 - ca, e)])
        out[b] -= np.concatenate([f * e, f * np.cross(p2 - cb, e)])
        bundles.append((eps, f))
        if slope > 0:
            rows.append((a, b, p1, p2, e, lig.stiffness * slope / lig.slack_length))
    return out, springs, bundles, rows


def _unique(joint, rows) -> bool:
    """Whether the active elements' stiffness is positive definite on the free dofs."""
    index = {(n, dof): i for i, (n, dof) in enumerate((n, dof) for n, b in joint.bodies.items() for dof in b.free)}
    m = len(index)
    K = np.zeros((m, m))
    for a, b, p1, p2, e, k in rows:
        g = np.zeros(m)
        for name, p, sign in ((a, p1, -1.0), (b, p2, 1.0)):
            full = sign * np.concatenate([e, np.cross(p - np.asarray(joint.bodies[name].reference), e)])
            for j, dof in enumerate(DOFS):
                if (name, dof) in index:
                    g[index[(name, dof)]] += full[j]
        K += k * np.outer(g, g)
    vals = np.linalg.eigvalsh(K) if m else np.ones(1)
    return bool(vals.min() > 1e-8 * vals.max())


def make_joint(case: Case):
    rng = np.random.default_rng(case.seed)
    names = [f"b{i}" for i in range(case.n_bodies)]
    centres = [np.array([0.0, 0.0, 25.0 * i]) for i in range(case.n_bodies)]
    frees = [()] + [tuple(dof for dof in DOFS if rng.random() < 0.85) or ("uz",) for _ in names[1:]]
    refs = [c + rng.normal(0, 5.0, 3) for c in centres]
    contacts = []
    for i in range(1, case.n_bodies):
        j = int(rng.integers(0, i))
        n = int(rng.integers(15, 60))
        mid = 0.5 * (centres[i] + centres[j])
        axis = (centres[i] - centres[j]) / np.linalg.norm(centres[i] - centres[j])
        points = mid + rng.normal(0, 6.0, (n, 3)) * [1, 1, 0.3]
        normals = axis + rng.normal(0, 0.35, (n, 3))
        layer = d.SpringLayer(
            points, normals, rng.uniform(0.5, 3.0, n), rng.uniform(1.0, 4.0, n), rng.uniform(-0.05, 0.2, n)
        )
        law = (
            d.LinearLaw(float(rng.uniform(2, 20)))
            if case.linear
            else d.AteshianLaw(float(rng.uniform(2, 20)), float(rng.uniform(0, 0.5)))
        )
        contacts.append(d.Contact(layer, law, body1=names[j], body2=names[i]))
    ligaments = []
    for _ in range(case.n_ligaments):
        a, b = rng.choice(case.n_bodies, 2, replace=False)
        p1 = centres[a] + rng.normal(0, 12.0, 3)
        p2 = centres[b] + rng.normal(0, 12.0, 3)
        start = float(np.linalg.norm(p2 - p1))
        law = "linear" if case.linear or rng.random() < 0.3 else "blankevoort"
        ligaments.append(
            d.Ligament(
                names[a],
                p1,
                names[b],
                p2,
                stiffness=float(rng.uniform(100, 3000)),
                slack_length=start * float(rng.uniform(0.95, 1.03)),
                law=law,
                transition_strain=float(rng.uniform(0.03, 0.1)),
            )
        )
    target = {
        n: (np.zeros(6) if not f else np.concatenate([rng.normal(0, 0.05, 3), rng.normal(0, 2e-3, 3)]))
        for n, f in zip(names, frees)
    }
    for n, f in zip(names, frees):
        target[n] = np.array([v if dof in f else 0.0 for dof, v in zip(DOFS, target[n])])
    bodies = {n: d.Body(reference=r, free=f) for n, r, f in zip(names, refs, frees)}
    joint = d.Joint(bodies, contacts, ligaments)
    wrench, *_ = element_wrenches(joint, target)
    loads = {n: (-wrench[n][:3], -wrench[n][3:]) for n in names}
    loaded = d.Joint(
        {n: d.Body(reference=r, free=f, force=loads[n][0], moment=loads[n][1]) for n, r, f in zip(names, refs, frees)},
        contacts,
        ligaments,
    )
    return loaded, target


@settings(
    max_examples=EXAMPLES,
    deadline=None,
    derandomize=True,
    database=None,
    phases=(Phase.explicit, Phase.generate),
    suppress_health_check=[HealthCheck.too_slow],
)
@given(st.builds(Case, st.integers(2, 4), st.integers(0, 2**31 - 1), st.booleans(), st.integers(0, 12)))
@pytest.mark.slow
def test_random_joints_find_their_manufactured_equilibrium(case):
    note(repr(case))
    joint, target = make_joint(case)
    _, springs_t, bundles_t, rows = element_wrenches(joint, target)
    unique = _unique(joint, rows)
    methods = ["newton", "nlp"] + (["qp"] if case.linear else [])
    answers = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        for method in methods:
            answers[method] = d.solve(joint, method)
    for method, s in answers.items():
        assert s.success, (method, s.message)
        body_u = {name: s.bodies[name].u for name in joint.bodies}
        wrench, springs, bundles, _ = element_wrenches(joint, body_u)
        for name, body in joint.bodies.items():
            scale = max(
                1.0,
                *(float(np.abs(p * c.layer.areas).sum()) for (_, p), c in zip(springs, joint.contacts)),
                *(abs(f) for _, f in bundles),
            )
            net = wrench[name] + body.load_vector
            for j, dof in enumerate(DOFS):
                if dof in body.free:
                    arm = 1.0 if j < 3 else 30.0
                    assert abs(net[j]) / arm <= 1e-7 * scale, (method, name, dof, net[j])
        tol = 1e-6 if method == "qp" else 1e-8
        # pressures and forces compared against the joint's force scale (N; N/mm^2 over the areas)
        force = max(float(np.abs(b.load_vector[:3]).max()) for b in joint.bodies.values())
        force = max(force, *(float((p * c.layer.areas).sum()) for (_, p), c in zip(springs, joint.contacts)), 1e-12)
        for (_, pressure), layer, c in zip(springs, s.contacts, joint.contacts):
            assert (pressure >= 0).all()
            np.testing.assert_allclose(layer.pressure, pressure, rtol=tol, atol=tol * force / c.layer.areas.min())
        np.testing.assert_allclose(s.ligaments.force, [f for _, f in bundles], rtol=tol, atol=tol * force)
        assert (s.ligaments.force >= 0).all()
        # Clarabel stops at its own tolerances (equilibrium to about 1e-8), which the joint's
        # conditioning may amplify in the motion; Newton and IPOPT converge to rounding.
        close = 1e-4 if method == "qp" else 1e-6
        if unique:
            for (eps, _), (eps_t, _) in zip(springs, springs_t):
                np.testing.assert_allclose(eps, eps_t, rtol=0, atol=close * max(float(np.abs(eps_t).max()), 1e-3))
            for (eps, _), (eps_t, _) in zip(bundles, bundles_t):
                assert abs(eps - eps_t) <= close * max(abs(eps_t), 1e-3)
            x = answers["newton"].x
            np.testing.assert_allclose(s.x, x, rtol=0, atol=close * max(float(np.abs(x).max()), 1e-6))
