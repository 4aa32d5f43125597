"""The pieces of the check before solving, against closed forms and an independent checker: the
contact's shape of a plate, the proof that a force pulls the bodies apart (against a
non-negative least-squares test of the springs' cone, written here), the lever arm a moment
needs, the powers of a thousand of a mesh's size, and the frames' ranges in words."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import nnls

import dea_opt as d
from dea_opt.geometry import plate_layer
from dea_opt.run import contact_shape
from dea_opt.run.contact_shape import (
    ContactShape,
    frame_cause,
    frame_causes,
    moment_arm,
    moment_arms,
    pulls_apart_proven,
)
from dea_opt.run.diagnose import frames_text
from dea_opt.run.preflight import MODULUS_RANGE, _thousands


def test_the_shape_of_a_plate():
    layer = plate_layer(40.0, 10.0, 40, 10, 2.0)
    shape = ContactShape.of(layer)
    np.testing.assert_allclose(shape.centre, layer.points.mean(axis=0), atol=1e-12)
    np.testing.assert_allclose(shape.normal, [0.0, 0.0, 1.0], atol=1e-12)
    span = layer.points.max(axis=0) - layer.points.min(axis=0)
    assert shape.radius == pytest.approx(0.5 * max(np.linalg.norm(span), np.sqrt(400.0)))
    assert shape.area == pytest.approx(400.0) and shape.thickness == pytest.approx(2.0)


class _Layer:
    def __init__(self, points, normals):
        self.points, self.normals = points, normals
        self.areas, self.thickness = np.ones(len(points)), np.ones(len(points))


@pytest.mark.parametrize("seed", range(40))
def test_pulls_apart_is_proven_only_where_no_spring_can_carry_the_force(seed):
    """Where the proof says so, the force lies outside the springs' cone along the free
    translations (``P f + sum lambda_i P n_i = 0`` has no solution with ``lambda >= 0``: NNLS
    leaves a residual); where the cone carries it, no proof is claimed."""
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 30))
    normals = rng.normal(size=(n, 3)) + np.array([0.0, 0.0, rng.uniform(0.0, 3.0)])
    normals /= np.linalg.norm(normals, axis=1)[:, None]
    shape = ContactShape.of(_Layer(rng.normal(size=(n, 3)), normals))
    free = [a for a in "xyz" if rng.random() < 0.7] or ["z"]
    mask = np.array([a in free for a in "xyz"], dtype=float)
    for body in (1, 2):
        for _ in range(10):
            force = rng.normal(size=3) * 100.0
            proven = pulls_apart_proven(shape, force, body, free)
            sign = 1.0 if body == 2 else -1.0  # on body 1 a spring pushes along -n
            columns = (sign * normals * mask).T
            _, residual = nnls(columns, -force * mask)
            if proven:
                assert residual > 1e-9 * np.linalg.norm(force * mask)
            if residual < 1e-9 * np.linalg.norm(force * mask):
                assert not proven


def test_frame_causes_on_a_plate():
    layer = plate_layer(40.0, 10.0, 8, 4, 2.0)
    problem = d.ContactProblem(layer, d.LinearLaw(10.0), reference=(0.0, 0.0, 0.0), free=("uz", "ry"))
    shape = ContactShape.of(layer)
    zero = (0.0, 0.0, 0.0)
    assert frame_cause(shape, problem, (0, 0, -100.0), zero, None, 2) is None
    assert frame_cause(shape, problem, (0, 0, 100.0), zero, None, 2) == "pulls_apart_proven"
    # on body 1 (held: nothing proven along its translations; free to sink: proven)
    assert frame_cause(shape, problem, (0, 0, -100.0), zero, None, 1) == "pulls_apart"
    loose = d.ContactProblem(layer, d.LinearLaw(10.0), body1=d.Body(free=("uz",)), body2=d.Body(free=()))
    assert frame_cause(shape, loose, (0, 0, -100.0), zero, None, 1) == "pulls_apart_proven"
    assert frame_cause(shape, loose, (0, 0, 100.0), zero, None, 1) is None
    assert frame_cause(shape, problem, (100.0, 0, -10.0), zero, None, 2) == "along_surface"
    # a moment needing an arm of a hundred radii (the plate's radius about 20.6 mm)
    assert frame_cause(shape, problem, (0, 0, -100.0), (0, 100.0 * 2100.0, 0), None, 2) == "moment_units"
    assert frame_cause(shape, problem, (0, 0, -100.0), (0, 100.0 * 15.0, 0), None, 2) is None


@pytest.mark.parametrize("translations", [("ux", "uz"), ("ux",)])
@pytest.mark.parametrize("body", [1, 2])
def test_the_causes_of_a_path_s_frames_at_once_are_each_frame_s(body, translations, monkeypatch):
    """Every frame of a path at once (in blocks of a few frames here, so that a path spans many):
    each frame's cause and lever arm as the rules say them, written here frame by frame."""
    monkeypatch.setattr(contact_shape, "_BLOCK", 64)
    rng = np.random.default_rng(body)
    layer = _Layer(rng.normal(size=(20, 3)), np.tile([0.0, 0.0, 1.0], (20, 1)) + 0.3 * rng.normal(size=(20, 3)))
    layer.normals /= np.linalg.norm(layer.normals, axis=1)[:, None]
    shape = ContactShape.of(layer)
    reference = (1.0, -2.0, 3.0)
    bodies = {f"body{body}": d.Body(free=(*translations, "rx", "ry"), reference=reference)}
    bodies[f"body{3 - body}"] = d.Body(free=())
    problem = d.ContactProblem(plate_layer(40.0, 10.0, 8, 4, 2.0), d.LinearLaw(10.0), **bodies)
    forces = rng.normal(size=(500, 3)) * 100.0
    forces[::50] = 0.0
    moments = rng.normal(size=(500, 3)) * rng.choice([10.0, 1e5], size=(500, 1))
    causes = frame_causes(shape, problem, forces, moments, None, body)
    arms = moment_arms(shape, problem, forces, moments, None, body)
    mask, turn = np.array([1.0, 0.0, float("uz" in translations)]), np.array([1.0, 1.0, 0.0])
    sign = 1.0 if body == 2 else -1.0
    for k, (force, moment) in enumerate(zip(forces, moments)):
        size = np.linalg.norm(force)
        about_centre = moment + np.cross(np.subtract(reference, shape.centre), force)
        arm = np.linalg.norm(about_centre * turn) / size if size else 0.0
        assert arms[k] == pytest.approx(arm, rel=1e-12, abs=1e-12)
        fraction = -sign * (force @ shape.normal) / size if size else np.nan
        if size == 0:
            expected = None
        elif (force * mask).any() and (sign * (layer.normals * mask) @ (force * mask) >= 0).all():
            expected = "pulls_apart_proven"
        elif fraction <= -0.5:
            expected = "pulls_apart"
        elif abs(fraction) < 0.5:
            expected = "along_surface"
        else:
            expected = "moment_units" if arm > 100.0 * shape.radius else None
        assert causes[k] == expected == frame_cause(shape, problem, force, moment, None, body), k
    assert {None, "along_surface", "moment_units"} <= set(causes)
    assert {"pulls_apart", "pulls_apart_proven"} & set(causes)


def test_moment_arm_about_the_contact_along_the_free_rotations():
    layer = plate_layer(40.0, 10.0, 8, 4, 2.0)
    problem = d.ContactProblem(layer, d.LinearLaw(10.0), reference=(30.0, 0.0, 5.0), free=("uz", "ry"))
    shape = ContactShape.of(layer)
    force = np.array([0.0, 0.0, -100.0])
    # acting at the reference, 30 mm along x from the centre: a moment of 3000 N mm about y
    assert moment_arm(shape, problem, force, (0, 0, 0), None, 2) == pytest.approx(30.0)
    # the same force given at the centre, with a moment about x only (rx is held): no arm
    assert moment_arm(shape, problem, force, (500.0, 0, 0), shape.centre, 2) == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize(
    "size, factor", [(68.0, 1.0), (0.068, 1000.0), (6.8e-5, 1e6), (6.8e4, 1e-3), (1.0, 1.0), (1000.0, 1.0)]
)
def test_powers_of_a_thousand_of_a_mesh_size(size, factor):
    assert _thousands(size) == factor


def test_the_modulus_range_is_the_table_of_moduli_widened():
    from dea_opt.laws.moduli import MODULI

    assert MODULUS_RANGE == (min(r.H for r in MODULI) / 10.0, max(r.H for r in MODULI) * 2.0)


def test_frames_in_words():
    assert frames_text(range(51), 51) == "every frame (51 of 51)"
    assert frames_text([0, 1, 2, 3, 4, 9], 51) == "frames 0-4, 9 (6 of 51)"
    assert frames_text([7], 51) == "frame 7 (1 of 51)"
    assert frames_text([7], 51, 0.25) == "frame 7 (0.25 s, 1 of 51)"
