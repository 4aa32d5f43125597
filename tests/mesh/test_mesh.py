"""Meshes to springs: reading, repair, ray casting, thickness, poses and bad input.

Acceptance points of the mesh issue checked here: 1 (sphere on a plate from STL files: exact
gaps, convergence to the closed form), 2 (thickness through closed surfaces), 3 (initial
overlap from a pose) and 6 (bad input). Answers are analytic, not snapshots.
"""

from __future__ import annotations

import re
import struct
import sys
import warnings

import numpy as np
import pytest
import trimesh

import dea_opt as d
from dea_opt import geometry
from dea_opt import mesh as M

METHODS = ("newton", "qp", "nlp")
TIGHT = {"newton": {}, "qp": {"tol": 1e-10}, "nlp": {"tol": 1e-12}}


def solve(problem, method, **options):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        return d.solve(problem, method, **{**TIGHT[method], **options})


def small_slab(**kw):
    return geometry.slab_mesh(**{"length": 4.0, "width": 3.0, "thickness": 1.0, "nx": 4, "ny": 3, **kw})


# --------------------------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("ext", ["stl", "obj", "ply", "off"])
def test_trimesh_formats_round_trip(tmp_path, ext):
    slab = small_slab()
    path = tmp_path / f"slab.{ext}"
    slab.export(path)
    loaded = M.load_mesh(path)
    assert isinstance(loaded, trimesh.Trimesh)
    assert loaded.is_watertight and loaded.is_winding_consistent
    assert len(loaded.faces) == len(slab.faces)
    assert loaded.volume == pytest.approx(slab.volume, rel=1e-6)


def test_scale_turns_metres_into_mm(tmp_path):
    slab = small_slab()
    slab.apply_scale(1e-3)
    slab.export(tmp_path / "metres.stl")
    loaded = M.load_mesh(tmp_path / "metres.stl", scale=1000.0)
    assert loaded.volume == pytest.approx(4.0 * 3.0 * 1.0, rel=1e-5)


def _legacy_vtk(points, polygons, binary=False, version="3.0", trailer=""):
    """A legacy VTK POLYDATA file written by hand (``polygons`` as lists of vertex ids)."""
    head = f"# vtk DataFile Version {version}\ntest\n{'BINARY' if binary else 'ASCII'}\nDATASET POLYDATA\n"
    size = sum(len(p) + 1 for p in polygons)
    flat = [v for p in polygons for v in (len(p), *p)]
    if binary:
        out = head.encode() + f"POINTS {len(points)} double\n".encode()
        out += np.asarray(points, ">f8").tobytes() + b"\n"
        out += f"POLYGONS {len(polygons)} {size}\n".encode() + np.asarray(flat, ">i4").tobytes() + b"\n"
        return out + trailer.encode()
    if version.startswith("5"):
        offsets = np.concatenate([[0], np.cumsum([len(p) for p in polygons])])
        conn = [v for p in polygons for v in p]
        body = (
            f"POINTS {len(points)} float\n" + " ".join(map(str, np.ravel(points))) + "\n"
            "METADATA\nINFORMATION 0\n\n"
            f"POLYGONS {len(offsets)} {len(conn)}\nOFFSETS vtktypeint64\n"
            + " ".join(map(str, offsets))
            + "\nCONNECTIVITY vtktypeint64\n"
            + " ".join(map(str, conn))
            + "\n"
        )
        return (head + body + trailer).encode()
    records = "\n".join(" ".join(map(str, (len(p), *p))) for p in polygons)
    body = (
        f"POINTS {len(points)} float\n" + "\n".join(" ".join(map(str, p)) for p in points) + "\n"
        f"POLYGONS {len(polygons)} {size}\n" + records + "\n"
    )
    return (head + body + trailer).encode()


SQUARE_POINTS = [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0]]
SQUARE_POLYS = [[0, 1, 2, 3], [1, 4, 2]]  # a quad (split in two) and a triangle


@pytest.mark.parametrize("binary, version", [(False, "3.0"), (True, "3.0"), (False, "5.1")])
def test_legacy_vtk_polydata_without_extra_packages(tmp_path, binary, version):
    path = tmp_path / "square.vtk"
    trailer = "POINT_DATA 5\nSCALARS s float 1\nLOOKUP_TABLE default\n0 1 2 3 4\n"
    path.write_bytes(_legacy_vtk(SQUARE_POINTS, SQUARE_POLYS, binary, version, trailer))
    loaded = M.load_mesh(path)
    assert len(loaded.faces) == 3
    assert loaded.area == pytest.approx(1.0 + 0.5)


@pytest.mark.parametrize("binary", [False, True])
def test_legacy_vtk_with_field_data_before_points(tmp_path, binary):
    text = _legacy_vtk(SQUARE_POINTS, SQUARE_POLYS, binary)
    head, body = text.split(b"POLYDATA\n", 1)
    values = np.array([1.5, 2.5], ">f8").tobytes() if binary else b"1.5 2.5"
    field = b"FIELD FieldData 1\nTimeValue 2 1 double\n" + values + b"\n"
    path = tmp_path / "field.vtk"
    path.write_bytes(head + b"POLYDATA\n" + field + body)
    assert M.load_mesh(path).area == pytest.approx(1.5)


def test_vtk_unstructured_grid_goes_through_meshio(tmp_path):
    import meshio

    path = tmp_path / "grid.vtk"
    cells = [("triangle", np.array([[0, 1, 2], [0, 2, 3]]))]
    meshio.write_points_cells(path, np.array(SQUARE_POINTS, float), cells, file_format="vtk", binary=False)
    assert M.load_mesh(path).area == pytest.approx(1.0)


def test_vtp_needs_the_vtk_extra(tmp_path, monkeypatch):
    path = tmp_path / "surface.vtp"
    path.write_text("<VTKFile/>")
    monkeypatch.setitem(sys.modules, "vtk", None)  # as if vtk were not installed
    with pytest.raises(d.MissingDependencyError, match=r"pip install dea-opt\[vtk\]") as info:
        M.load_mesh(path)
    assert isinstance(info.value, d.DeaError)


def test_loaders_are_keyed_by_extension():
    assert {".stl", ".obj", ".ply", ".vtk", ".vtp"} <= set(M.LOADERS)


def test_meshes_accepted_as_trimesh_tuple_or_path(tmp_path):
    slab = small_slab()
    slab.export(tmp_path / "slab.stl")
    for given in (slab, (slab.vertices, slab.faces), str(tmp_path / "slab.stl"), tmp_path / "slab.stl"):
        assert M.as_mesh(given).volume == pytest.approx(12.0)
    assert M.as_mesh(slab) is slab  # a clean Trimesh is used as is (its caches too)


# --------------------------------------------------------------------------------------------
# Repair
# --------------------------------------------------------------------------------------------
def test_degenerate_faces_dropped_with_count_and_labels_follow():
    slab = small_slab()
    n = len(slab.faces)
    sliver = np.array([[0, 0, 5.0], [1, 0, 5.0], [2, 0, 5.0]])  # collinear: zero area
    vertices = np.vstack([slab.vertices, sliver])
    faces = np.vstack([[[n_v, n_v + 1, n_v + 2] for n_v in [len(slab.vertices)]], slab.faces])
    with pytest.warns(UserWarning, match=r"dropped 1 degenerate \(zero-area\) faces of " + str(n + 1)):
        mesh = M.as_mesh((vertices, faces))
    assert len(mesh.faces) == n
    # per-face arrays refer to the faces as given: label 0 was the sliver
    plate = geometry.slab_mesh(4.0, 3.0, 2.0, 4, 3, top=0.0, facing="down")
    labels = np.array(["sliver"] + ["slab"] * n)
    with pytest.warns(UserWarning):
        layer = M.springs_from_meshes((vertices, faces), plate, thickness2=0.0, labels=labels)
    assert set(layer.labels) == {"slab"}


@pytest.mark.parametrize(
    "build",
    [
        small_slab,
        lambda: geometry.knee_meshes(n_plateau=8, step=8.0).mesh1,
        lambda: geometry.spherical_shell_mesh(10.0, 1.0, 180.0, step=15.0),
    ],
    ids=["slab", "two pieces", "hollow ball"],
)
def test_inconsistent_winding_is_repaired(build):
    good = build()
    faces = good.faces.copy()
    flipped = np.random.default_rng(0).random(len(faces)) < 0.3
    faces[flipped] = faces[flipped][:, ::-1]
    with pytest.warns(UserWarning, match=f"winding was inconsistent; re-wound {flipped.sum()} faces"):
        mesh = M.as_mesh((good.vertices, faces))
    assert mesh.is_winding_consistent
    np.testing.assert_array_equal(mesh.faces, good.faces)  # each piece keeps its majority winding


def test_inside_out_closed_surface_is_inverted():
    slab = small_slab()
    with pytest.warns(UserWarning, match="inside out"):
        mesh = M.as_mesh((slab.vertices, slab.faces[:, ::-1]))
    assert mesh.volume == pytest.approx(12.0)


def test_a_clean_mesh_gives_no_warning():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        M.as_mesh(small_slab())


# --------------------------------------------------------------------------------------------
# Springs from two meshes
# --------------------------------------------------------------------------------------------
def test_plate_pair_springs_are_the_top_faces():
    pair = geometry.plate_meshes(nx=20, ny=5)
    layer = M.springs_from_meshes(pair.mesh1, pair.mesh2, thickness2=0.0)
    top = np.flatnonzero(np.isclose(pair.mesh1.triangles_center[:, 2], 0.0) & (pair.mesh1.face_normals[:, 2] > 0.5))
    assert np.array_equal(np.sort(layer.source_face), top)
    np.testing.assert_allclose(layer.normals, np.tile([0, 0, 1.0], (len(layer), 1)), atol=1e-12)
    np.testing.assert_allclose(layer.gap, 0.0, atol=1e-12)
    np.testing.assert_allclose(layer.thickness, 2.0, rtol=1e-9)
    assert layer.areas.sum() == pytest.approx(40.0 * 10.0)
    vertices, faces = layer.surface
    np.testing.assert_allclose(vertices[faces[layer.source_face]].mean(axis=1), layer.points, atol=1e-12)


def test_plate_pair_uniform_pressure():
    pair = geometry.plate_meshes(nx=20, ny=5)
    problem = pair.problem(d.LinearLaw(5.0), force=(0, 0, -400.0), free=("uz", "rx", "ry"))
    s = solve(problem, "newton")
    np.testing.assert_allclose(s.pressure, 1.0, rtol=1e-9)  # 400 N over 400 mm^2
    assert s.u[8] == pytest.approx(-1.0 / 5.0 * 2.0)


def test_rays_never_take_the_back_of_a_curved_mesh():
    """A dome whose outside faces away from the springs: rays meet only its back -> no springs."""
    bed = geometry.slab_mesh(6.0, 6.0, 1.0, 12, 12)
    dome = trimesh.creation.icosphere(4, radius=5.0)
    keep = dome.triangles_center[:, 2] > 1.0  # an open cap, outward normals up and out
    cap = trimesh.Trimesh(dome.vertices, dome.faces[keep])
    with pytest.raises(d.InputError, match="max_gap"):
        M.springs_from_meshes(bed, cap, thickness2=0.0, max_gap=10.0)
    # the same cap wound the other way faces the bed: its underside is met
    under = trimesh.Trimesh(dome.vertices, dome.faces[keep][:, ::-1])
    layer = M.springs_from_meshes(bed, under, thickness2=0.0, max_gap=10.0)
    rho2 = (layer.points[:, :2] ** 2).sum(axis=1)
    np.testing.assert_allclose(layer.gap, np.sqrt(25.0 - rho2), atol=0.05)


#: The ray casters this install has: the exact numpy grid always, Embree with the ``fast`` extra.
ENGINES_HERE = ("grid", "embree") if M.raycast._has_embree() else ("grid",)


def _tilted_plane(a=0.05, b=-0.02, c=0.3, n=9, half=5.0):
    """The plane ``z = c + a x + b y`` over ``[-half, half]^2``, its faces turned down (-z)."""
    xs = np.linspace(-half, half, n)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    vertices = np.column_stack([X.ravel(), Y.ravel(), c + a * X.ravel() + b * Y.ravel()])
    k = np.arange(n * n).reshape(n, n)
    quads = np.stack([k[:-1, :-1], k[1:, :-1], k[1:, 1:], k[:-1, 1:]], axis=-1).reshape(-1, 4)
    faces = np.vstack([quads[:, [0, 2, 1]], quads[:, [0, 3, 2]]])  # wound so that normals point down
    return trimesh.Trimesh(vertices, faces, process=False)


@pytest.mark.parametrize("engine", ENGINES_HERE)
def test_each_installed_caster_measures_a_tilted_plane_exactly(engine):
    """The gap from each face of a flat bed up to the plane z = c + a x + b y is that plane's height
    above the face's centroid: a closed form every caster must meet to rounding."""
    bed = geometry.slab_mesh(6.0, 6.0, 1.0, 12, 12)
    plane = _tilted_plane()
    assert (plane.face_normals[:, 2] < -0.99).all()
    layer = M.springs_from_meshes(bed, plane, thickness2=0.0, max_gap=10.0, engine=engine)
    assert len(layer) == 2 * 12 * 12  # every articular face of the bed meets the plane
    x, y, z = layer.points.T
    np.testing.assert_allclose(layer.gap, 0.3 + 0.05 * x - 0.02 * y - z, rtol=0, atol=1e-12)


if "embree" in ENGINES_HERE:  # generated only where Embree is installed (the fast and dev extras)

    def test_embree_and_grid_engines_agree():
        pair = geometry.hip_meshes(step=6.0)
        a = M.cast_springs(pair.mesh1, pair.mesh2, engine="embree")
        b = M.cast_springs(pair.mesh1, pair.mesh2, engine="grid")
        assert np.array_equal(a.layer.source_face, b.layer.source_face)
        np.testing.assert_allclose(a.layer.gap, b.layer.gap, atol=1e-9)
        np.testing.assert_allclose(a.layer.thickness, b.layer.thickness, atol=1e-6)
        assert np.array_equal(a.hit_face, b.hit_face) or np.abs(a.hit_point - b.hit_point).max() < 1e-9


def test_without_embree_auto_falls_back_to_the_grid(monkeypatch):
    pair = geometry.hip_meshes(step=8.0)
    grid = pair.layer(engine="grid")
    monkeypatch.setattr(M.raycast, "_has_embree", lambda: False)
    fallback = pair.layer()
    assert np.array_equal(fallback.gap, grid.gap) and np.array_equal(fallback.source_face, grid.source_face)
    with pytest.raises(d.MissingDependencyError, match=re.escape("pip install dea-opt[fast]")):
        pair.layer(engine="embree")


#: Run in a process of its own where ``embreex`` cannot be imported, as on an install without the
#: ``fast`` extra: the package imports, ``auto`` is the grid caster, and its springs are returned.
WITHOUT_EMBREE = """
import importlib.abc, sys

class NoEmbree(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):
        if name.partition(".")[0] == "embreex":
            raise ModuleNotFoundError(f"No module named {name!r}")
        return None

sys.meta_path.insert(0, NoEmbree())
import numpy as np
import dea_opt
from dea_opt import geometry
from dea_opt.mesh import raycast

assert raycast._engine("auto") == "grid" and not raycast._has_embree()
layer = geometry.hip_meshes(step=8.0).layer()
try:
    geometry.hip_meshes(step=8.0).layer(engine="embree")
except dea_opt.MissingDependencyError as exc:
    assert "dea-opt[fast]" in str(exc)
else:
    raise AssertionError("engine='embree' ran without embreex")
assert not any(name.partition(".")[0] == "embreex" for name in sys.modules)
np.save(sys.argv[1], np.column_stack([layer.gap, layer.source_face]))
"""


def test_an_install_without_embree_casts_with_the_grid(tmp_path):
    import subprocess

    out = tmp_path / "springs.npy"
    subprocess.run([sys.executable, "-c", WITHOUT_EMBREE, str(out)], check=True, timeout=300)
    grid = geometry.hip_meshes(step=8.0).layer(engine="grid")
    assert np.array_equal(np.load(out), np.column_stack([grid.gap, grid.source_face]))


def test_engine_is_validated():
    with pytest.raises(d.InputError, match="engine"):
        M.springs_from_meshes(small_slab(), small_slab(), engine="gpu")


def test_hit_points_and_thickness_parts():
    pair = geometry.hip_meshes(step=6.0)
    cast = M.cast_springs(pair.mesh1, pair.mesh2)
    layer = cast.layer
    np.testing.assert_allclose(cast.hit_point, layer.points + layer.gap[:, None] * layer.normals, atol=1e-9)
    np.testing.assert_allclose(cast.thickness1 + cast.thickness2, layer.thickness)
    np.testing.assert_allclose(cast.thickness1, 2.0, rtol=0.01)
    np.testing.assert_allclose(cast.thickness2, 1.5, rtol=0.01)


@pytest.mark.parametrize("kind", ["number", "array", "bone"])
def test_thickness_as_number_array_or_bone_mesh(kind):
    bed = geometry.slab_mesh(6.0, 6.0, 1.0, 12, 12)
    plate = geometry.slab_mesh(6.0, 6.0, 1.0, 12, 12, top=0.5, facing="down")
    if kind == "number":
        spec, expected = 1.25, 1.25
    elif kind == "array":
        spec, expected = np.full(len(bed.faces), 0.75), 0.75
    else:  # a flat bone 1.5 mm below the articular surface
        spec, expected = geometry.slab_mesh(8.0, 8.0, 3.0, 4, 4, top=-1.5), 1.5
    layer = M.springs_from_meshes(bed, plate, thickness1=spec, thickness2=0.0)
    np.testing.assert_allclose(layer.thickness, expected, rtol=1e-9)
    np.testing.assert_allclose(layer.gap, 0.5, atol=1e-12)


def test_a_rotated_pose_equals_moving_the_mesh():
    pair = geometry.sphere_on_bed_meshes(n_bed=16, step=4.0)
    angle = np.radians(3.0)
    pose = np.eye(4)
    pose[:3, :3] = [[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]]
    pose[:3, 3] = [0.4, -0.2, 1.0]
    moved = pair.mesh2.copy()
    moved.apply_transform(pose)
    a = pair.layer(pose=pose)
    b = M.springs_from_meshes(pair.mesh1, moved, thickness2=0.0)
    assert np.array_equal(a.source_face, b.source_face)
    np.testing.assert_allclose(a.gap, b.gap, atol=1e-9)


def test_labels_ride_on_the_springs():
    pair = geometry.knee_meshes(n_plateau=16, step=4.0)
    layer = pair.layer()
    assert set(layer.labels) == {"medial", "lateral"}
    assert (layer.points[layer.labels == "medial", 0] > 0).all()
    assert (layer.points[layer.labels == "lateral", 0] < 0).all()


def test_concatenate_meshes_labels_faces():
    a, b = small_slab(), small_slab(center=(10.0, 0.0))
    mesh, labels = M.concatenate_meshes({"left": a, "right": b})
    assert len(mesh.faces) == len(labels) == len(a.faces) + len(b.faces)
    assert (labels[: len(a.faces)] == "left").all() and (labels[len(a.faces) :] == "right").all()


# --------------------------------------------------------------------------------------------
# Casting both ways
# --------------------------------------------------------------------------------------------
def test_both_ways_on_matching_flat_meshes_is_symmetric():
    pair = geometry.plate_meshes(nx=20, ny=5)
    both = M.springs_both_ways(pair.mesh1, pair.mesh2, thickness2=0.0)
    assert both.asymmetry["area"] < 1e-12
    assert both.asymmetry["stiffness"] < 1e-12
    assert both.asymmetry["direction"] < 1e-12
    np.testing.assert_allclose(both.backward.normals[:, 2], -1.0)
    np.testing.assert_allclose(both.backward.thickness, 2.0, rtol=1e-9)


def test_both_ways_on_the_hip_measures_the_asymmetry():
    pair = geometry.hip_meshes(step=6.0)
    both = M.springs_both_ways(pair.mesh1, pair.mesh2)
    asym = both.asymmetry
    assert asym["forward"]["n_springs"] == len(both.forward)
    assert asym["backward"]["n_springs"] == len(both.backward)
    # the head is smaller than the socket and its layer is thinner: areas and stiffnesses
    # differ by a few percent, and the two layers push in opposite directions
    assert 0 < asym["area"] < 0.2 and 0 <= asym["stiffness"] < 0.2
    assert asym["direction"] < 0.1
    assert both.forward.normals[:, 2].mean() > 0 > both.backward.normals[:, 2].mean()


# --------------------------------------------------------------------------------------------
# Acceptance 1: sphere over a flat plate, from STL files
# --------------------------------------------------------------------------------------------
R, H_BED, MODULUS, DEPTH = 25.0, 2.0, 10.0, 0.4
LEVELS = [(16, 4.0), (32, 2.0), (64, 1.0)]  # bed cells a side, sphere grid step (deg)


def closed_form():
    force = np.pi * MODULUS * DEPTH**2 * (R - DEPTH / 3) / H_BED
    return force, MODULUS * DEPTH / H_BED, np.pi * (2 * R * DEPTH - DEPTH**2)


@pytest.fixture(scope="module")
def sphere_levels(tmp_path_factory):
    """Per refinement level: the layer from STL files and the two meshes read back."""
    out = []
    for n_bed, step in LEVELS:
        folder = tmp_path_factory.mktemp(f"level{n_bed}")
        pair = geometry.sphere_on_bed_meshes(R, H_BED, extent=6.0, n_bed=n_bed, step=step)
        pair.mesh1.export(folder / "bed.stl")
        pair.mesh2.export(folder / "sphere.stl")
        layer = M.springs_from_meshes(folder / "bed.stl", folder / "sphere.stl", thickness2=0.0, max_gap=0.8)
        out.append((layer, M.load_mesh(folder / "bed.stl"), M.load_mesh(folder / "sphere.stl")))
    return out


def _height_above(points, sphere):
    """Brute force: the height of the tessellated sphere's underside above each (x, y)."""
    down = sphere.face_normals[:, 2] < 0
    tri = sphere.triangles[down]
    a, b, c = tri[:, 0, :2], tri[:, 1, :2], tri[:, 2, :2]
    heights = np.full(len(points), np.nan)
    for start in range(0, len(points), 256):
        p = points[start : start + 256, None, :2]
        v0, v1, v2 = b - a, c - a, p - a
        den = v0[:, 0] * v1[:, 1] - v0[:, 1] * v1[:, 0]
        u = (v2[..., 0] * v1[:, 1] - v2[..., 1] * v1[:, 0]) / den
        v = (v0[:, 0] * v2[..., 1] - v0[:, 1] * v2[..., 0]) / den
        inside = (u >= -1e-12) & (v >= -1e-12) & (u + v <= 1 + 1e-12)
        k = np.argmax(inside, axis=1)
        rows = np.arange(len(k))
        assert inside[rows, k].all()
        z0, z1, z2 = tri[k, 0, 2], tri[k, 1, 2], tri[k, 2, 2]
        z = z0 + u[rows, k] * (z1 - z0) + v[rows, k] * (z2 - z0)
        heights[start : start + 256] = z - points[start : start + 256, 2]
    return heights


def test_sphere_gaps_are_the_tessellated_distance(sphere_levels):
    for layer, _bed, sphere in sphere_levels[:2]:
        assert np.allclose(layer.normals, [0, 0, 1])
        np.testing.assert_allclose(layer.gap, _height_above(layer.points, sphere), rtol=0, atol=1e-9)
        np.testing.assert_allclose(layer.thickness, H_BED, rtol=1e-6)  # through the bed


@pytest.mark.parametrize("method", METHODS)
def test_sphere_contact_converges_to_the_closed_form(sphere_levels, method):
    force, peak, area = closed_form()
    err_peak, err_area = [], []
    for layer, _, _ in sphere_levels:
        problem = d.ContactProblem(
            layer, d.LinearLaw(MODULUS), force=(0, 0, -force), reference=(0.0, 0.0, R), free=("uz",)
        )
        s = solve(problem, method)
        assert s.u[8] == pytest.approx(-DEPTH, rel=0.05)  # faceting: the sphere lies inside R
        err_peak.append(abs(s.peak_pressure - peak) / peak)
        err_area.append(abs(s.contact_area - area) / area)
    h = np.array([1.0, 0.5, 0.25])  # mesh size relative to the coarsest
    order_peak = np.polyfit(np.log(h), np.log(err_peak), 1)[0]
    order_area = np.polyfit(np.log(h), np.log(err_area), 1)[0]
    print(f"{method}: peak errors {err_peak} (order {order_peak:.2f}), area errors {err_area} (order {order_area:.2f})")
    assert np.all(np.diff(err_peak) < 0) and np.all(np.diff(err_area) < 0)
    assert order_peak > 1.5  # gaps and the force integral are second order
    assert order_area > 0.8  # the contact edge cuts cells: first order
    assert err_peak[-1] < 1e-3 and err_area[-1] < 5e-3


# --------------------------------------------------------------------------------------------
# Acceptance 2: thickness through closed surfaces
# --------------------------------------------------------------------------------------------
def test_thickness_of_a_closed_slab():
    slab = geometry.slab_mesh(20.0, 10.0, 1.7, 40, 20)
    top = np.flatnonzero(slab.face_normals[:, 2] > 0.5)
    centre = slab.triangles_center[top]
    interior = top[(np.abs(centre[:, 0]) < 10.0 - 1.7) & (np.abs(centre[:, 1]) < 5.0 - 1.7)]
    np.testing.assert_allclose(M.surface_thickness(slab, interior), 1.7, rtol=0.01)
    # and through a layer cast onto another mesh
    plate = geometry.slab_mesh(20.0, 10.0, 1.0, 10, 5, top=0.3, facing="down")
    cast = M.cast_springs(slab, plate, thickness2=0.0)
    inner = np.isin(cast.layer.source_face, interior)
    np.testing.assert_allclose(cast.thickness1[inner], 1.7, rtol=0.01)


@pytest.mark.parametrize("articular", ["outer", "inner"])
def test_thickness_of_a_closed_spherical_shell(articular):
    shell = geometry.spherical_shell_mesh(20.0, 2.5, 80.0, articular=articular, step=4.0)
    assert shell.is_watertight
    centre = shell.triangles_center
    radial = centre / np.linalg.norm(centre, axis=1)[:, None]
    facing = np.einsum("ij,ij->i", shell.face_normals, radial)
    articular_faces = facing > 0.9 if articular == "outer" else facing < -0.9
    r = np.linalg.norm(centre, axis=1)
    on_sphere = np.abs(r - 20.0) < 0.2
    polar = np.degrees(np.arccos(np.clip(-radial[:, 2], -1, 1)))
    interior = np.flatnonzero(articular_faces & on_sphere & (polar < 80.0 - 2 * 4.0 - 10.0))
    assert len(interior) > 100
    np.testing.assert_allclose(M.surface_thickness(shell, interior), 2.5, rtol=0.01)


@pytest.mark.parametrize("engine", ENGINES_HERE)
def test_thickness_nan_where_the_surface_is_open(engine):
    # rays searched to infinity that meet nothing: the grid caster stops where they leave its box
    slab = small_slab()
    open_slab = trimesh.Trimesh(slab.vertices, slab.faces[slab.face_normals[:, 2] > 0.5])  # top only
    assert np.isnan(M.surface_thickness(open_slab, engine=engine)).all()


# --------------------------------------------------------------------------------------------
# Acceptance 3: initial overlap from a pose
# --------------------------------------------------------------------------------------------
def translation(z):
    pose = np.eye(4)
    pose[2, 3] = z
    return pose


def test_plate_pushed_in_gives_uniform_negative_gaps():
    pair = geometry.plate_meshes(nx=20, ny=5)
    layer = pair.layer(pose=translation(-0.3))
    np.testing.assert_allclose(layer.gap, -0.3, atol=1e-12)
    assert layer.areas.sum() == pytest.approx(400.0)


@pytest.fixture(scope="module")
def overlap_layers():
    pair = geometry.sphere_on_bed_meshes(R, H_BED, extent=6.0, n_bed=32, step=2.0)
    touching = pair.layer(max_gap=1.0)
    pushed = pair.layer(max_gap=1.0, pose=translation(-0.3))
    return pair, touching, pushed


def test_sphere_pushed_in_shifts_every_gap(overlap_layers):
    _, touching, pushed = overlap_layers
    common, i, j = np.intersect1d(touching.source_face, pushed.source_face, return_indices=True)
    assert len(common) == len(touching)  # the pushed window holds every touching spring
    np.testing.assert_allclose(pushed.gap[j], touching.gap[i] - 0.3, atol=1e-9)
    assert pushed.gap.min() == pytest.approx(-0.3, abs=0.01)
    # a centroid inside the sphere takes the face it went through, never the far side
    assert (pushed.gap > -0.3 - 1e-9).all()


@pytest.mark.parametrize("method", METHODS)
def test_overlap_pose_and_load_give_the_same_pressure(overlap_layers, method):
    pair, touching, pushed = overlap_layers
    law = d.LinearLaw(MODULUS)
    # the load that holds the pushed pose at u = 0: the springs' force there
    force = float(law.H * np.maximum(-pushed.gap, 0) @ pushed.areas / H_BED)
    solutions = {}
    for name, layer in (("touching", touching), ("pushed", pushed)):
        problem = d.ContactProblem(layer, law, force=(0, 0, -force), reference=pair.reference2, free=("uz",))
        solutions[name] = solve(problem, method)
    a, b = solutions["touching"], solutions["pushed"]
    assert a.u[8] == pytest.approx(-0.3, abs=1e-9)  # the zero-overlap pose moves the 0.3 mm
    assert b.u[8] == pytest.approx(0.0, abs=1e-9)
    pa = dict(zip(touching.source_face, a.pressure))
    pb = dict(zip(pushed.source_face, b.pressure))
    faces = sorted(set(pa) | set(pb))
    diff = max(abs(pa.get(f, 0.0) - pb.get(f, 0.0)) for f in faces)
    assert diff <= 1e-6 * a.peak_pressure
    assert b.peak_pressure == pytest.approx(a.peak_pressure, rel=1e-7)


# --------------------------------------------------------------------------------------------
# Acceptance 6: bad input, each a DeaError with a useful message
# --------------------------------------------------------------------------------------------
def test_missing_file(tmp_path):
    path = tmp_path / "nowhere.stl"
    with pytest.raises(d.InputError, match="does not exist") as info:
        M.load_mesh(path)
    assert str(path) in str(info.value) and isinstance(info.value, d.DeaError)


def test_unknown_extension(tmp_path):
    path = tmp_path / "surface.xyz"
    path.write_text("1 2 3\n")
    with pytest.raises(d.InputError, match=r"unknown extension '\.xyz'.*\.stl") as info:
        M.load_mesh(path)
    assert str(path) in str(info.value)


@pytest.mark.parametrize("case", ["zero_bytes", "stl_no_triangles", "arrays", "trimesh"])
def test_empty_mesh(tmp_path, case):
    if case == "zero_bytes":
        (tmp_path / "e.stl").write_bytes(b"")
        given = tmp_path / "e.stl"
    elif case == "stl_no_triangles":
        (tmp_path / "e.stl").write_bytes(b"\0" * 80 + struct.pack("<I", 0))
        given = tmp_path / "e.stl"
    elif case == "arrays":
        given = (np.zeros((0, 3)), np.zeros((0, 3), dtype=int))
    else:
        given = trimesh.Trimesh()
    with pytest.raises(d.InputError, match="empty"):
        M.as_mesh(given)


def test_only_degenerate_faces(tmp_path):
    vertices = np.array([[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0.0]])
    path = tmp_path / "line.ply"
    trimesh.Trimesh(vertices, [[0, 1, 2], [1, 2, 3]], process=False).export(path)
    with pytest.raises(d.InputError, match=r"all 2 faces are degenerate \(zero area\)") as info:
        M.load_mesh(path)
    assert str(path) in str(info.value)


def test_unparsable_file(tmp_path):
    path = tmp_path / "junk.vtk"
    path.write_text("not a vtk file\n" * 5)
    with pytest.raises(d.InputError, match="is not a legacy VTK file .*first line is 'not a vtk file'"):
        M.load_mesh(path)
    path.write_text("# vtk DataFile Version 3.0\nsquare\nASCII\nDATASET POLYDATA\nPOINTS 10 float\n0 0 0 1\n")
    with pytest.raises(d.InputError, match="could not be read as legacy VTK POLYDATA: the file ends inside"):
        M.load_mesh(path)


def test_meshes_too_far_apart_name_max_gap_and_distance():
    pair = geometry.sphere_on_bed_meshes(n_bed=16, step=4.0)
    with pytest.raises(d.InputError) as info:
        pair.layer(pose=translation(5.0), max_gap=2.0)
    message = str(info.value)
    assert "max_gap=2" in message
    distance = float(re.search(r"smallest distance found[^0-9]*([0-9.]+) mm", message).group(1))
    assert distance == pytest.approx(5.0, abs=0.05)  # from the nearest centroid of the bed


def test_meshes_facing_away_name_max_gap_and_distance():
    pair = geometry.sphere_on_bed_meshes(n_bed=16, step=4.0)
    with pytest.raises(d.InputError) as info:
        pair.layer(pose=translation(-30.0))  # the sphere sunk below the bed: nothing faces
    message = str(info.value)
    assert "max_gap=2" in message and "smallest distance found" in message


BAD_POSES = {
    "scaled": np.diag([1.1, 1.0, 1.0, 1.0]),
    "sheared": np.array([[1, 0.2, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]]),
    "reflection": np.diag([1.0, 1.0, -1.0, 1.0]),
    "last row": np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1.0]]),
    "3x3": np.eye(3),
    "nan": np.full((4, 4), np.nan),
}
POSE_MESSAGES = {
    "scaled": "not rigid",
    "sheared": "not rigid",
    "reflection": "reflection",
    "last row": "last row",
    "3x3": "4x4",
    "nan": "finite",
}


@pytest.mark.parametrize("name", BAD_POSES)
def test_pose_must_be_rigid(name):
    pair = geometry.plate_meshes(nx=4, ny=2)
    with pytest.raises(d.InputError, match=POSE_MESSAGES[name]) as info:
        pair.layer(pose=BAD_POSES[name])
    assert "pose" in str(info.value)


@pytest.mark.parametrize(
    "options, words",
    [
        ({"max_gap": -1.0}, "max_gap"),
        ({"max_overlap": float("nan")}, "max_overlap"),
        ({"max_angle": 120.0}, "max_angle"),
        ({"thickness1": -2.0}, "thickness1"),
        ({"thickness1": np.ones(3)}, "thickness1"),
        ({"thickness1": "bone.xyz"}, "unknown extension"),
        ({"labels": ["a", "b"]}, "labels"),
    ],
)
def test_bad_options(options, words):
    pair = geometry.plate_meshes(nx=4, ny=2)
    with pytest.raises(d.InputError, match=words):
        M.springs_from_meshes(pair.mesh1, pair.mesh2, **{"thickness2": 0.0, **options})


@pytest.mark.parametrize(
    "name, value, expected",
    [
        ("max_gap", -1.0, "max_gap must be a finite number >= 0, got -1.0"),
        ("max_gap", True, "max_gap must be a finite number >= 0, got True"),
        ("max_overlap", "1", "max_overlap must be a finite number >= 0, got '1'"),
        ("max_overlap", float("inf"), "max_overlap must be a finite number >= 0, got inf"),
        ("max_angle", 120.0, r"max_angle must be a finite number in \[0, 90\], got 120.0"),
        ("max_angle", -1e-9, r"max_angle must be a finite number in \[0, 90\], got -1e-09"),
    ],
)
def test_window_errors_name_the_range_and_what_came(name, value, expected):
    pair = geometry.plate_meshes(nx=4, ny=2)
    with pytest.raises(d.InputError, match=f"^{expected}$"):
        M.springs_from_meshes(pair.mesh1, pair.mesh2, thickness2=0.0, **{name: value})


@pytest.mark.parametrize("value", [0.0, -2.0, float("nan"), False, "1000"])
def test_scale_must_be_a_positive_number(value):
    with pytest.raises(d.InputError, match=f"^scale must be a finite number > 0, got {re.escape(repr(value))}$"):
        M.as_mesh(small_slab(), scale=value)


def test_window_edges_are_accepted():
    pair = geometry.plate_meshes(nx=4, ny=2)
    layer = M.springs_from_meshes(pair.mesh1, pair.mesh2, thickness2=0.0, max_gap=0, max_overlap=0.0, max_angle=90)
    assert len(layer) > 0 and (layer.gap == 0).all()


def test_bad_mesh_argument():
    with pytest.raises(d.InputError, match="mesh1 must be a mesh file path"):
        M.springs_from_meshes(42, small_slab())
    with pytest.raises(d.InputError, match="face indices"):
        M.as_mesh((np.eye(3), [[0, 1, 5]]))
