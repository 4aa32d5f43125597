"""Acceptance 6 of the core: twelve dofs, mirrored bodies, prescribed motion and reactions."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import METHODS, solve_quietly

import dea_opt as d
from dea_opt.geometry import plate_layer

REF = (0.0, 0.0, 0.0)
FORCE, MOMENT = (0.0, 0.0, -500.0), (0.0, -2500.0, 800.0)


@pytest.fixture(scope="module")
def layer():
    return plate_layer(40.0, 10.0, 200, 10, thickness=2.0)


def _free_body(force, moment, free=("uz", "rx", "ry")):
    return d.Body(reference=REF, free=free, force=force, moment=moment)


@pytest.mark.parametrize("method", METHODS)
def test_moving_body1_under_the_opposite_load_mirrors_moving_body2(layer, method):
    law = d.LinearLaw(10.0)
    moves2 = d.ContactProblem(layer, law, body2=_free_body(FORCE, MOMENT))
    moves1 = d.ContactProblem(
        layer, law, body1=_free_body(np.negative(FORCE), np.negative(MOMENT)), body2=d.Body(reference=REF, free=())
    )
    s2, s1 = solve_quietly(moves2, method), solve_quietly(moves1, method)
    np.testing.assert_allclose(s1.body1_displacement, -s2.body2_displacement, atol=1e-9)
    np.testing.assert_allclose(s1.body2_displacement, 0.0)
    np.testing.assert_allclose(s1.pressure, s2.pressure, atol=1e-7 * s2.peak_pressure)


@pytest.mark.parametrize("method", METHODS)
def test_both_bodies_free_give_the_same_relative_motion(layer, method):
    law = d.LinearLaw(10.0)
    one = d.ContactProblem(layer, law, body2=_free_body(FORCE, MOMENT))
    both = d.ContactProblem(
        layer, law, body1=_free_body(np.negative(FORCE), np.negative(MOMENT)), body2=_free_body(FORCE, MOMENT)
    )
    s_one, s_both = solve_quietly(one, method), solve_quietly(both, method)
    relative = s_both.body2_displacement - s_both.body1_displacement
    np.testing.assert_allclose(relative, s_one.body2_displacement, atol=1e-8)
    np.testing.assert_allclose(s_both.pressure, s_one.pressure, atol=1e-7 * s_one.peak_pressure)
    assert len(s_both.problem.free_indices) == 6


@pytest.mark.parametrize("method", METHODS)
def test_prescribed_displacement_reaction_applied_as_load_returns_the_displacement(layer, method):
    law = d.LinearLaw(10.0)
    held = d.Body(reference=REF, free=("rx", "ry"), prescribed={"uz": -0.3}, moment=(0.0, -1000.0, 0.0))
    s = solve_quietly(d.ContactProblem(layer, law, body2=held), method)
    assert s.u[8] == -0.3
    reaction = s.reactions["body2.uz"]
    assert reaction < 0  # the support pushes body 2 down into the layer
    loaded = d.Body(reference=REF, free=("uz", "rx", "ry"), force=(0, 0, reaction), moment=(0.0, -1000.0, 0.0))
    back = solve_quietly(d.ContactProblem(layer, law, body2=loaded), method)
    assert back.u[8] == pytest.approx(-0.3, rel=1e-7)
    np.testing.assert_allclose(back.u[9:11], s.u[9:11], rtol=1e-6, atol=1e-12)


def test_fixed_dofs_report_reactions_that_balance(layer):
    law = d.LinearLaw(10.0)
    s = solve_quietly(d.ContactProblem(layer, law, force=FORCE, moment=MOMENT, free=("uz", "rx", "ry")), "newton")
    body1 = np.array([s.reactions[f"body1.{dof}"] for dof in d.DOFS])
    # Body 1 is held: its support carries the whole load of body 2.
    np.testing.assert_allclose(body1[:3], -np.array(FORCE), atol=1e-8)
    assert s.reactions["body2.rz"] == pytest.approx(-MOMENT[2])


def test_load_at_a_point_adds_its_moment():
    load = d.Load(force=(0, 0, -10), point=(2.0, 0, 0))
    assert load.about((0, 0, 0)) == ((0.0, 0.0, -10.0), (0.0, 20.0, 0.0))
    body = d.Body(reference=(1.0, 0, 0)).with_load(load)
    assert body.moment == (0.0, 10.0, 0.0)


def test_problem_is_immutable_and_copies(layer):
    p = d.ContactProblem(layer, d.LinearLaw(1.0), force=FORCE)
    q = p.with_load(force=(0, 0, -1.0))
    assert p.body2.force == FORCE and q.body2.force == (0.0, 0.0, -1.0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.law = d.LinearLaw(2.0)
    with pytest.raises(ValueError):
        layer.points[0, 0] = 1.0
    assert p.with_law(d.LinearLaw(2.0)).law.H == 2.0


def test_a_dof_both_free_and_prescribed_is_a_named_error():
    with pytest.raises(d.InputError, match="both free and prescribed: uz") as caught:
        d.Body(reference=REF, free=("uz", "rx"), prescribed={"uz": -0.1})
    assert "remove it from one" in str(caught.value)
    with pytest.raises(d.InputError, match="both free and prescribed: rx, ry"):
        d.Body(free="all", prescribed={"ry": 0.01, "rx": 0.0})
    # free not given: every dof that is not prescribed
    assert d.Body(prescribed={"uz": -0.1}).free == ("ux", "uy", "rx", "ry", "rz")
    held = d.Body(free=("rx",), prescribed={"uz": -0.1})
    assert held.with_prescribed(rx=0.01).free == () and held.with_prescribed(rx=0.01).prescribed == {
        "uz": -0.1,
        "rx": 0.01,
    }
    assert held.with_load(force=(0, 0, -1.0)).free == ("rx",)  # copies keep what they were given
