"""Acceptance 4: a real knee, femoral cartilage on medial and lateral tibial cartilage.

The meshes are MRI-segmented cartilage of one right knee in ``../shared/data/knee`` (skipped
when absent). x is medial-lateral and z points from the tibia to the femur, so y is
anterior-posterior and varus-valgus is the rotation about y: ``ry``.

Body 1 is the tibia (the medial and lateral cartilage concatenated, springs labelled
``"medial"``/``"lateral"``), fixed; body 2 the femur, loaded with 1000 N along -z at the
midpoint of the two tibial cartilages' centroids, free in ``uz`` and ``ry``. Thickness is
measured through the closed cartilage surfaces on both sides. Solved by newton, qp and nlp;
``nlp`` uses its reduced form (``min_x`` of the energy over the 2 free dofs), which is exact
and fast here, where the constrained form carries one variable per spring (13 000).
"""

from __future__ import annotations

import time
import warnings
from pathlib import Path

import numpy as np
import pytest

import dea_opt as d
from dea_opt import mesh as M

KNEE = Path(__file__).resolve().parents[2] / "shared" / "data" / "knee"
FILES = ("femoral_cartilage.stl", "medial_tibial_cartilage.stl", "lateral_tibial_cartilage.stl")
METHODS = ("newton", "qp", "nlp")
OPTIONS = {"newton": {}, "qp": {"tol": 1e-11}, "nlp": {"form": "reduced"}}
MAX_GAP = 2.0
LOAD = 1000.0
MODULUS = 10.0  # MPa: strains stay below the linear law's 30 % limit


@pytest.fixture(scope="module")
def knee():
    if not all((KNEE / name).is_file() for name in FILES):
        pytest.skip(f"the knee meshes are not in {KNEE}")
    start = time.perf_counter()
    femur = M.load_mesh(KNEE / "femoral_cartilage.stl")
    medial = M.load_mesh(KNEE / "medial_tibial_cartilage.stl")
    lateral = M.load_mesh(KNEE / "lateral_tibial_cartilage.stl")
    tibia, labels = M.concatenate_meshes({"medial": medial, "lateral": lateral})
    loaded = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        cast = M.cast_springs(tibia, femur, labels=labels, max_gap=MAX_GAP)
    built = time.perf_counter()
    centre = [(m.area_faces @ m.triangles_center) / m.area for m in (medial, lateral)]
    reference = tuple(0.5 * (centre[0] + centre[1]))
    problem = d.ContactProblem(cast.layer, d.LinearLaw(MODULUS), force=(0.0, 0.0, -LOAD),
                               reference=reference, free=("uz", "ry"))
    print(f"\nknee: read {loaded - start:.2f} s, {len(cast.layer)} springs cast in {built - loaded:.2f} s")
    return {"femur": femur, "tibia": tibia, "labels": labels, "cast": cast, "problem": problem,
            "warnings": [str(w.message) for w in caught]}


@pytest.fixture(scope="module")
def solutions(knee):
    out = {}
    for method in METHODS:
        start = time.perf_counter()
        out[method] = d.solve(knee["problem"], method, **OPTIONS[method])
        print(f"knee {method}: {time.perf_counter() - start:.2f} s, {out[method]}")
    return out


def test_vtk_file_is_the_same_surface(knee):
    from_vtk = M.load_mesh(KNEE / "femoral_cartilage.vtk")
    stl = knee["femur"]
    assert len(from_vtk.faces) == len(stl.faces) == 19992
    assert from_vtk.area == pytest.approx(stl.area, rel=1e-6)
    from scipy.spatial import cKDTree

    distance, _ = cKDTree(stl.vertices).query(from_vtk.vertices)
    assert distance.max() < 1e-4  # STL stores float32


def test_meshes_read_clean(knee):
    assert knee["tibia"].is_watertight and knee["tibia"].is_winding_consistent
    assert knee["femur"].is_winding_consistent  # not watertight: resampling left holes
    assert not knee["warnings"], knee["warnings"]


def test_gaps(knee):
    cast, femur = knee["cast"], knee["femur"]
    layer = cast.layer
    assert set(layer.labels) == {"medial", "lateral"}
    assert (layer.gap <= MAX_GAP).all() and (layer.gap >= -1.0).all()
    assert 0 < layer.gap.min() < 0.5  # the surfaces sit a fraction of a millimetre apart
    # each ray met the femur at points + gap * normals, on a femoral face that faces it
    np.testing.assert_allclose(cast.hit_point, layer.points + layer.gap[:, None] * layer.normals, atol=1e-9)
    sample = np.linspace(0, len(layer) - 1, 400).astype(int)
    _, distance, _ = femur.nearest.on_surface(cast.hit_point[sample])
    assert distance.max() < 1e-6
    facing = np.einsum("ij,ij->i", femur.face_normals[cast.hit_face], layer.normals)
    assert (facing < -np.cos(np.radians(60.0)) + 1e-12).all()
    # normals are the tibial face normals, pointing up toward the femur
    assert (layer.normals[:, 2] > 0).mean() > 0.99


def test_thickness_through_the_closed_surfaces(knee):
    cast = knee["cast"]
    layer = cast.layer
    h1 = M.surface_thickness(knee["tibia"], layer.source_face)
    np.testing.assert_allclose(cast.thickness1, h1, rtol=1e-12)
    np.testing.assert_allclose(layer.thickness, cast.thickness1 + cast.thickness2)
    for h in (cast.thickness1, cast.thickness2):
        assert 0.2 < h.min() and h.max() < 8.0  # cartilage, not bone or a missed far side
        assert 1.0 < np.median(h) < 4.0


@pytest.mark.parametrize("method", METHODS)
def test_knee_solves_and_is_certified(solutions, knee, method):
    s = solutions[method]
    assert s.success and s.certificate.passed
    layer = knee["problem"].layer
    np.testing.assert_allclose(s.contact_force[2], LOAD, rtol=1e-6)
    assert s.u[8] < 0  # the femur moves down onto the tibia
    # the contact stays inside the proximity window, so the window does not shape it
    assert layer.gap[s.in_contact].max() < MAX_GAP - 0.25
    assert s.max_compressive_strain < 0.3


def test_methods_agree(solutions):
    ref = solutions["newton"]
    for method in ("qp", "nlp"):
        s = solutions[method]
        assert np.abs(s.u - ref.u).max() <= 1e-6 * np.abs(ref.u).max()
        assert np.abs(s.pressure - ref.pressure).max() <= 1e-6 * ref.peak_pressure


def test_medial_lateral_share(solutions, knee):
    layer = knee["problem"].layer
    for method, s in solutions.items():
        force = s.pressure * layer.areas
        share = {side: float(force[layer.labels == side].sum() / force.sum())
                 for side in ("medial", "lateral")}
        print(f"knee {method}: medial {share['medial']:.4f}, lateral {share['lateral']:.4f} of the load; "
              f"peak {s.peak_pressure:.3f} MPa, contact {s.contact_area:.1f} mm^2, "
              f"uz {s.u[8]:.4f} mm, ry {np.degrees(s.u[10]):.4f} deg")
        assert 0 < share["medial"] < 1 and 0 < share["lateral"] < 1
        assert share["medial"] + share["lateral"] == pytest.approx(1.0, abs=1e-12)


def test_outputs(solutions, tmp_path):
    from dea_opt import io
    if not (hasattr(io, "to_vtk") and hasattr(io, "plot_pressure")):
        pytest.skip("dea_opt.io has no to_vtk/plot_pressure yet")
    import meshio

    s = solutions["newton"]
    vtu = io.to_vtk(s, tmp_path / "knee.vtu")
    data = meshio.read(vtu)
    for name in ("pressure", "strain", "gap", "thickness", "in_contact", "spring_force"):
        assert name in data.cell_data
    np.testing.assert_allclose(np.concatenate(data.cell_data["pressure"]), s.pressure, rtol=1e-12)
    png = io.plot_pressure(s, tmp_path / "knee.png")
    assert Path(png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
