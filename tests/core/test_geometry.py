"""Embedded geometries made in code: closed cartilage volumes and the pairs the tests, demo and
examples use. Checked against closed forms (volumes, areas, gaps, statics), not snapshots."""

from __future__ import annotations

import inspect
import warnings

import numpy as np
import pytest

import dea_opt as d
from dea_opt import geometry as g

METHODS = ("newton", "qp", "nlp")
TIGHT = {"newton": {}, "qp": {"tol": 1e-10}, "nlp": {"tol": 1e-12}}


def solve(problem, method):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        return d.solve(problem, method, **TIGHT[method])


def closed_and_outward(mesh):
    return mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0


# --------------------------------------------------------------------------------------------
# The layer builders of the core tests keep their signatures
# --------------------------------------------------------------------------------------------
def test_layer_builders_unchanged():
    assert list(inspect.signature(g.plate_layer).parameters) == ["length", "width", "nx", "ny", "thickness"]
    assert list(inspect.signature(g.sphere_on_bed_layer).parameters) == [
        "radius",
        "thickness",
        "extent",
        "n_rings",
        "n_sectors",
    ]
    assert list(inspect.signature(g.socket_layer).parameters) == [
        "radius",
        "thickness",
        "coverage",
        "n_rings",
        "n_sectors",
        "gap",
    ]
    assert isinstance(g.plate_layer(nx=4, ny=2), d.SpringLayer)


# --------------------------------------------------------------------------------------------
# Closed volumes
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("facing", ["up", "down"])
def test_slab_is_a_closed_box(facing):
    slab = g.slab_mesh(12.0, 8.0, 1.5, 12, 8, center=(3.0, -1.0), top=2.0, facing=facing)
    assert closed_and_outward(slab)
    assert slab.volume == pytest.approx(12.0 * 8.0 * 1.5)
    sign = 1 if facing == "up" else -1
    articular = sign * slab.face_normals[:, 2] > 0.5
    assert np.allclose(slab.triangles_center[articular, 2], 2.0)
    assert slab.area_faces[articular].sum() == pytest.approx(96.0)
    low, high = sorted([2.0, 2.0 - sign * 1.5])
    assert np.allclose(slab.bounds, [[-3.0, -5.0, low], [9.0, 3.0, high]])


@pytest.mark.parametrize("articular", ["outer", "inner"])
def test_spherical_cap_shell_volume_and_area(articular):
    R, h, cov = 20.0, 2.0, 60.0
    shell = g.spherical_shell_mesh(R, h, cov, articular=articular, step=2.0)
    assert closed_and_outward(shell)
    r_in, r_out = (R - h, R) if articular == "outer" else (R, R + h)
    exact = 2 * np.pi / 3 * (1 - np.cos(np.radians(cov))) * (r_out**3 - r_in**3)
    assert shell.volume == pytest.approx(exact, rel=2e-3)  # the facets lie inside the spheres
    radial = shell.triangles_center / np.linalg.norm(shell.triangles_center, axis=1)[:, None]
    outward = np.einsum("ij,ij->i", shell.face_normals, radial)
    faces = outward > 0.9 if articular == "outer" else outward < -0.9
    r = np.linalg.norm(shell.triangles_center[faces], axis=1)
    assert np.allclose(r, R, atol=0.02)  # the articular skin is the sphere of radius R
    exact_area = 2 * np.pi * R**2 * (1 - np.cos(np.radians(cov)))
    assert shell.area_faces[faces].sum() == pytest.approx(exact_area, rel=2e-3)


def test_whole_spherical_shell_is_closed_with_a_cavity():
    shell = g.spherical_shell_mesh(10.0, 1.0, 180.0, step=6.0)
    assert closed_and_outward(shell)
    assert shell.volume == pytest.approx(4 * np.pi / 3 * (10.0**3 - 9.0**3), rel=5e-3)


def test_lunate_shell_has_a_fossa_and_a_notch():
    cov, fossa, notch = 85.0, 25.0, 60.0
    lunate = g.spherical_shell_mesh(24.5, 2.0, cov, articular="inner", fossa=fossa, notch=notch, step=3.0)
    assert closed_and_outward(lunate)
    u = lunate.vertices / np.linalg.norm(lunate.vertices, axis=1)[:, None]
    polar = np.degrees(np.arccos(-u[:, 2]))  # from the pole at -z
    azimuth = np.degrees(np.arctan2(u[:, 0], u[:, 1]))  # from +y, where the notch opens
    assert polar.min() == pytest.approx(fossa) and polar.max() == pytest.approx(cov)
    assert np.abs(azimuth).min() == pytest.approx(notch / 2)
    inner = (
        np.einsum(
            "ij,ij->i",
            lunate.face_normals,
            lunate.triangles_center / np.linalg.norm(lunate.triangles_center, axis=1)[:, None],
        )
        < -0.9
    )
    exact = 2 * np.pi * 24.5**2 * (np.cos(np.radians(fossa)) - np.cos(np.radians(cov))) * (360 - notch) / 360
    assert lunate.area_faces[inner].sum() == pytest.approx(exact, rel=2e-3)


@pytest.mark.parametrize(
    "call, words",
    [
        (lambda: g.slab_mesh(nx=0), "nx"),
        (lambda: g.slab_mesh(thickness=-1.0), "thickness"),
        (lambda: g.slab_mesh(facing="left"), "facing"),
        (lambda: g.spherical_shell_mesh(10.0, 12.0), "thickness < radius"),
        (lambda: g.spherical_shell_mesh(coverage=200.0), "coverage"),
        (lambda: g.spherical_shell_mesh(fossa=95.0, coverage=90.0), "fossa"),
        (lambda: g.spherical_shell_mesh(articular="middle"), "articular"),
        (lambda: g.spherical_shell_mesh(step=0.0), "step"),
        (lambda: g.hip_meshes(head_radius=26.0, socket_radius=25.0), "head_radius < socket_radius"),
        (lambda: g.sphere_on_bed_meshes(radius=5.0, extent=8.0), "extent"),
        (lambda: g.knee_meshes(plateau=50.0), "plateau"),
    ],
)
def test_builders_reject_bad_arguments(call, words):
    with pytest.raises(d.InputError, match=words):
        call()


# --------------------------------------------------------------------------------------------
# Pairs
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("build", [g.plate_meshes, g.sphere_on_bed_meshes, g.hip_meshes, g.knee_meshes])
def test_pairs_are_closed_meshes(build):
    pair = build()
    assert isinstance(pair, g.MeshPair)
    assert closed_and_outward(pair.mesh1) and closed_and_outward(pair.mesh2)
    assert len(pair.reference1) == len(pair.reference2) == 3
    layer = pair.layer()
    assert len(layer) > 0 and layer.surface is not None and layer.source_face is not None
    assert repr(pair).startswith("MeshPair(")


@pytest.mark.parametrize("method", METHODS)
def test_plate_pair_carries_a_uniform_pressure(method):
    pair = g.plate_meshes(nx=40, ny=10)
    s = solve(pair.problem(d.LinearLaw(5.0), force=(0, 0, -800.0), free=("uz", "rx", "ry")), method)
    np.testing.assert_allclose(s.pressure, 800.0 / 400.0, rtol=1e-7)
    assert s.u[8] == pytest.approx(-2.0 / 5.0 * 2.0, rel=1e-7)


def test_hip_gaps_match_the_two_spheres():
    pair = g.hip_meshes(step=3.0)
    info = pair.info
    layer = pair.layer()
    # from a socket point P = Rs u along -u, the head sphere (centre c) is met at t with
    # |P - t u - c| = Rh
    u = layer.points / np.linalg.norm(layer.points, axis=1)[:, None]
    c = np.asarray(pair.reference2)
    p = info["socket_radius"] * u - c
    b = np.einsum("ij,ij->i", p, u)
    t = b - np.sqrt(b**2 - (np.einsum("ij,ij->i", p, p) - info["head_radius"] ** 2))
    np.testing.assert_allclose(layer.gap, t, atol=0.02)  # both spheres faceted at 3 degrees
    np.testing.assert_allclose(layer.thickness, info["head_thickness"] + info["socket_thickness"], rtol=0.01)
    assert np.allclose(np.einsum("ij,ij->i", layer.normals, -u), 1.0, atol=1e-3)


@pytest.mark.parametrize("method", METHODS)
def test_hip_solves_and_balances(method):
    pair = g.hip_meshes(step=4.0)
    problem = pair.problem(d.LinearLaw(10.0), force=(0, 0, -1500.0), free=("ux", "uy", "uz"))
    s = solve(problem, method)
    np.testing.assert_allclose(s.contact_force, [0, 0, 1500.0], atol=1e-5 * 1500)
    assert s.u[8] < 0 and s.u[7] > 0  # pressed down, and toward the notch (+y) where support is missing
    assert abs(s.u[6]) < 1e-3 * abs(s.u[8])  # the lunate is symmetric about the y-z plane
    newton = solve(problem, "newton")
    np.testing.assert_allclose(s.u, newton.u, atol=1e-6 * np.abs(newton.u).max())


def test_knee_labels_and_symmetric_share():
    pair = g.knee_meshes(condyle_radius=(30.0, 30.0), n_plateau=32, step=3.0)
    problem = pair.problem(d.LinearLaw(15.0), force=(0, 0, -600.0), free=("uz", "ry"))
    s = solve(problem, "newton")
    layer = problem.layer
    force = s.pressure * layer.areas
    share = force[layer.labels == "medial"].sum() / force.sum()
    assert share == pytest.approx(0.5, abs=1e-9)  # mirror-symmetric knee, load in the middle


@pytest.mark.parametrize("method", METHODS)
def test_knee_share_follows_the_lever_rule(method):
    """Load 5 mm toward the medial side: the tibial normals are +z, so with uz and ry free the
    medial share is (a - x_l) / (x_m - x_l), x_m, x_l the compartments' centres of force."""
    pair = g.knee_meshes(n_plateau=32, step=3.0)
    a = 5.0
    layer = pair.layer()
    body2 = d.Body(reference=(a, 0.0, pair.reference2[2]), free=("uz", "ry"), force=(0, 0, -600.0))
    problem = d.ContactProblem(layer, d.LinearLaw(15.0), body1=d.Body(free=()), body2=body2)
    s = solve(problem, method)
    force = s.pressure * layer.areas
    medial = layer.labels == "medial"
    share = force[medial].sum() / force.sum()
    x_m = force[medial] @ layer.points[medial, 0] / force[medial].sum()
    x_l = force[~medial] @ layer.points[~medial, 0] / force[~medial].sum()
    assert share == pytest.approx((a - x_l) / (x_m - x_l), rel=1e-7)
    assert 0.5 < share < 1.0
