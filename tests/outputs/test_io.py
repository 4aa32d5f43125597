"""Output files: atomic writes, VTK/CSV round trips, the JSON summary and the pressure map."""

from __future__ import annotations

import dataclasses
import json
import os
import stat
import struct

import numpy as np
import pytest

import dea_opt as d
from dea_opt import files, io
from dea_opt.anatomy.regions import split_by_axis
from dea_opt.errors import InputError
from dea_opt.geometry import sphere_on_bed_layer

FIELDS = ("pressure", "strain", "gap", "thickness", "in_contact", "spring_force", "normal", "area")


def grid_surface_layer(n=16, half=6.0, radius=20.0, thickness=2.0):
    """A triangulated square in z = 0 under a sphere; springs on the faces away from the border.

    Faces on the outer ring carry no spring, so ``source_face`` is a strict subset;
    labels split the springs at x = 0 into "medial" (x < 0) and "lateral".
    """
    xs = np.linspace(-half, half, n + 1)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    vertices = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    idx = np.arange(len(vertices)).reshape(n + 1, n + 1)
    a, b, c, e = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    faces = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, e])])
    centroids = vertices[faces].mean(axis=1)
    keep = np.flatnonzero(np.abs(centroids[:, :2]).max(axis=1) < half - 1.0)
    points = centroids[keep]
    edge1 = vertices[faces[keep, 1]] - vertices[faces[keep, 0]]
    edge2 = vertices[faces[keep, 2]] - vertices[faces[keep, 0]]
    areas = 0.5 * np.linalg.norm(np.cross(edge1, edge2), axis=1)
    gap = radius - np.sqrt(radius**2 - (points[:, :2] ** 2).sum(axis=1))
    labels = np.where(points[:, 0] < 0, "medial", "lateral")
    return d.SpringLayer(
        points,
        np.tile([0.0, 0.0, 1.0], (len(points), 1)),
        areas,
        thickness,
        gap,
        source_face=keep,
        surface=(vertices, faces),
        labels=labels,
    )


@pytest.fixture(scope="module")
def point_solution():
    """Springs without a surface: a sphere on a bed, partly in contact."""
    layer = sphere_on_bed_layer(n_rings=20, n_sectors=24)
    problem = d.ContactProblem(layer, d.LinearLaw(5.0), force=(0, 0, -20), reference=(0, 0, 25), free=("uz",))
    solution = d.solve(problem, "newton")
    assert 0 < solution.in_contact.sum() < len(layer)
    return solution


@pytest.fixture(scope="module")
def surface_solution():
    """Springs on the faces of a triangle surface, with labels, tilted by a moment."""
    layer = grid_surface_layer()
    problem = d.ContactProblem(
        layer, d.LinearLaw(20.0), force=(0, 0, -100), moment=(0, 150, 0), reference=(0, 0, 20), free=("uz", "rx", "ry")
    )
    # It tilts about 4.5 degrees, past the small kinematics' 3: certified, and marked outside validity.
    with pytest.warns(d.ValidityWarning, match="rotation"):
        solution = d.solve(problem, "newton")
    assert solution.success and not solution.validity.valid
    assert 0 < solution.in_contact.sum() < len(layer)
    return solution


@pytest.fixture(params=["point_solution", "surface_solution"])
def solution(request):
    return request.getfixturevalue(request.param)


def leftovers(directory):
    return sorted(p.name for p in directory.iterdir() if ".tmp" in p.name)


# --- atomic writes ----------------------------------------------------------------------
def test_write_atomic_creates_parents_and_leaves_no_temporary(tmp_path):
    target = tmp_path / "a" / "b" / "out.txt"
    assert files.write_atomic(target, lambda tmp: tmp.write_text("hello")) == target
    assert target.read_text() == "hello"
    assert leftovers(target.parent) == []


def test_write_atomic_keeps_old_file_when_writer_raises(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")

    def failing(tmp):
        tmp.write_text("half a fi")
        raise RuntimeError("interrupted")

    with pytest.raises(RuntimeError, match="interrupted"):
        files.write_atomic(target, failing)
    assert target.read_text() == "old"
    assert leftovers(tmp_path) == []


def test_atomic_open_keeps_old_file_on_keyboard_interrupt(tmp_path):
    target = tmp_path / "out.bin"
    target.write_bytes(b"old")
    with pytest.raises(KeyboardInterrupt):
        with files.atomic_open(target, "wb") as handle:
            handle.write(b"new")
            raise KeyboardInterrupt
    assert target.read_bytes() == b"old"
    assert leftovers(tmp_path) == []
    with files.atomic_open(target, "w") as handle:
        handle.write("new")
    assert target.read_text() == "new"


def test_atomic_file_modes(tmp_path):
    plain = tmp_path / "plain.txt"
    plain.write_text("x")
    fresh = files.write_atomic(tmp_path / "fresh.txt", lambda tmp: tmp.write_text("x"))
    assert stat.S_IMODE(fresh.stat().st_mode) == stat.S_IMODE(plain.stat().st_mode)  # the umask, not 0600
    os.chmod(plain, 0o640)
    files.write_atomic(plain, lambda tmp: tmp.write_text("y"))
    assert stat.S_IMODE(plain.stat().st_mode) == 0o640


def test_atomic_bad_paths(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(InputError, match="path: cannot create the directory"):
        files.write_atomic(blocker / "sub" / "out.txt", lambda tmp: None)
    with pytest.raises(InputError, match="path must be a file path, got the directory"):
        files.write_atomic(tmp_path, lambda tmp: None)
    with pytest.raises(InputError, match="path must be a file path"):
        files.write_atomic(3.5, lambda tmp: None)
    with pytest.raises(InputError, match="writer must be callable"):
        files.write_atomic(tmp_path / "x", "not callable")
    with pytest.raises(InputError, match="out_dir: cannot create"):
        files.write_atomic(blocker / "x.txt", lambda tmp: None, argument="out_dir")


def test_atomic_open_bad_mode(tmp_path):
    with pytest.raises(InputError, match="mode must be 'w' or 'wb', got 'a'"):
        with files.atomic_open(tmp_path / "x.txt", "a"):
            pass
    assert not list(tmp_path.iterdir())


# --- VTK --------------------------------------------------------------------------------
def expected_fields(solution):
    layer = solution.problem.layer
    fields = {
        "pressure": solution.pressure,
        "strain": solution.strain,
        "gap": layer.gap,
        "thickness": layer.thickness,
        "in_contact": solution.in_contact,
        "spring_force": solution.spring_force,
        "normal": layer.normals,
        "area": layer.areas,
    }
    if layer.source_face is not None:
        fields["source_face"] = layer.source_face
    return fields


def test_vtu_round_trip_with_meshio(solution, tmp_path):
    import meshio

    path = solution.to_vtk(tmp_path / "out.vtu")
    mesh = meshio.read(path)
    layer = solution.problem.layer
    assert len(mesh.cells) == 1
    block = mesh.cells[0]
    assert block.type == "triangle"  # a surface, never a cloud of points
    if layer.surface is None:
        # The points are the springs, the data point data on a triangulation through them.
        data = mesh.point_data
        np.testing.assert_array_equal(mesh.points, layer.points)
    else:
        assert len(block.data) == len(layer)
        data = {name: values[0] for name, values in mesh.cell_data.items()}
        vertices, faces = layer.surface
        np.testing.assert_array_equal(mesh.points[block.data], vertices[faces[layer.source_face]])
        codes = io.label_codes(layer.labels)
        np.testing.assert_array_equal(data["label"], [codes[v] for v in layer.labels])
    for name, want in expected_fields(solution).items():
        got = data[name]
        assert got.shape == np.shape(want), name
        np.testing.assert_array_equal(got, np.asarray(want, dtype=got.dtype), err_msg=name)


@pytest.mark.parametrize("ext", [".vtu", ".vtp"])
@pytest.mark.parametrize("binary", [True, False])
def test_vtk_round_trip(solution, tmp_path, ext, binary):
    path = io.to_vtk(solution, tmp_path / f"out{ext}", binary=binary)
    differences = io.vtk_differences(solution, path)
    assert set(differences) >= {"points", "cells", *FIELDS}
    # meshio's ASCII .vtu keeps 12 significant digits; everything else is exact
    tolerance = 1e-11 if (ext == ".vtu" and not binary) else 0.0
    scale = {name: 1.0 for name in differences}
    scale["points"] = np.abs(solution.problem.layer.points).max()
    for name, value in differences.items():
        assert value <= tolerance * max(scale[name], 1.0), (name, value)
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("ext", [".vtu", ".vtp"])
def test_vtk_whole_surface(surface_solution, tmp_path, ext):
    solution = surface_solution
    layer = solution.problem.layer
    vertices, faces = layer.surface
    path = io.to_vtk(solution, tmp_path / f"all{ext}", cells="surface")
    data = io.read_vtk(path)
    assert data.cell_type == "triangle"
    np.testing.assert_array_equal(data.cells, faces)
    np.testing.assert_array_equal(data.points, vertices)
    spring = data.cell_data["spring"]
    on = layer.source_face
    np.testing.assert_array_equal(spring[on], np.arange(len(layer)))
    off = np.setdiff1d(np.arange(len(faces)), on)
    assert len(off) > 0 and (spring[off] == -1).all()
    np.testing.assert_array_equal(data.cell_data["pressure"][on], solution.pressure)
    for name in ("pressure", "strain", "thickness", "in_contact", "spring_force"):
        assert (data.cell_data[name][off] == 0).all(), name
    assert (data.cell_data["label"][off] == -1).all()
    assert max(io.vtk_differences(solution, path, cells="surface").values()) == 0.0


def test_vtk_bad_input(point_solution, surface_solution, tmp_path):
    with pytest.raises(InputError, match=r"path must end in \.vtu .* or \.vtp"):
        io.to_vtk(point_solution, tmp_path / "out.vtk")
    with pytest.raises(InputError, match="cells must be 'springs' or 'surface'"):
        io.to_vtk(point_solution, tmp_path / "out.vtu", cells="faces")
    with pytest.raises(InputError, match="cells='surface' needs a layer with surface"):
        io.to_vtk(point_solution, tmp_path / "out.vtu", cells="surface")
    layer = surface_solution.problem.layer
    twice = dataclasses.replace(layer, source_face=np.zeros(len(layer), dtype=int))
    solution = dataclasses.replace(surface_solution, problem=surface_solution.problem.with_layer(twice))
    with pytest.raises(InputError, match="at most one spring per face"):
        io.to_vtk(solution, tmp_path / "out.vtu", cells="surface")
    outside = dataclasses.replace(layer, source_face=np.full(len(layer), len(layer.surface[1])))
    solution = dataclasses.replace(surface_solution, problem=surface_solution.problem.with_layer(outside))
    with pytest.raises(InputError, match="source_face must index"):
        io.to_vtk(solution, tmp_path / "out.vtu")
    with pytest.raises(InputError, match="path: no such file"):
        io.read_vtk(tmp_path / "missing.vtp")
    assert not list(tmp_path.iterdir())


# --- CSV --------------------------------------------------------------------------------
def test_csv_round_trip(solution, tmp_path):
    path = solution.to_csv(tmp_path / "springs.csv")
    with open(path) as handle:
        assert handle.readline().strip() == ",".join(io.CSV_COLUMNS)
    table = io.read_csv(path)
    assert tuple(table) == io.CSV_COLUMNS
    layer = solution.problem.layer
    want = {
        "x_mm": layer.points[:, 0],
        "y_mm": layer.points[:, 1],
        "z_mm": layer.points[:, 2],
        "nx": layer.normals[:, 0],
        "ny": layer.normals[:, 1],
        "nz": layer.normals[:, 2],
        "area_mm2": layer.areas,
        "thickness_mm": layer.thickness,
        "gap_mm": layer.gap,
        "strain": solution.strain,
        "pressure_MPa": solution.pressure,
        "spring_force_N": solution.spring_force,
    }
    for name, value in want.items():
        np.testing.assert_allclose(table[name], value, rtol=0, atol=1e-12, err_msg=name)
        np.testing.assert_array_equal(table[name], value, err_msg=name)  # in fact bit for bit
    np.testing.assert_array_equal(table["in_contact"], solution.in_contact)
    if layer.source_face is None:
        assert (table["source_face"] == -1).all() and (table["label"] == "").all()
    else:
        np.testing.assert_array_equal(table["source_face"], layer.source_face)
        np.testing.assert_array_equal(table["label"], layer.labels)


def test_read_csv_rejects_other_tables(tmp_path):
    other = tmp_path / "other.csv"
    other.write_text("a,b\n1,2\n")
    with pytest.raises(InputError, match="not a dea_opt spring table"):
        io.read_csv(other)


# --- JSON -------------------------------------------------------------------------------
def strict_load(path):
    def no_constants(name):
        raise AssertionError(f"non-standard JSON constant {name}")

    with open(path) as handle:
        return json.loads(handle.read(), parse_constant=no_constants)


def test_json_contents(surface_solution, tmp_path):
    s = surface_solution
    split = split_by_axis(s, "y", at=0.0, names=("posterior", "anterior"))
    path = s.to_json(tmp_path / "summary.json", regions=split)
    data = strict_load(path)
    assert data == io.read_json(path)
    assert data["method"] == "newton" and data["success"] is True
    assert data["law"] == s.problem.law.describe()
    assert data["n_springs"] == len(s.problem.layer)
    for key, name in (("peak_pressure", "MPa"), ("mean_pressure", "MPa"), ("contact_area", "mm2")):
        assert data[f"{key}_{name}"] == pytest.approx(getattr(s, key), rel=1e-15), key
    magnitudes = float(s.pressure @ s.problem.layer.areas)  # no force on anything: named for what it is
    assert data["force_magnitude_sum_N"] == pytest.approx(magnitudes, rel=1e-14) and "total_normal_force" not in data
    np.testing.assert_allclose(data["center_of_pressure_mm"], s.center_of_pressure, rtol=1e-15)
    np.testing.assert_allclose(data["contact_force_N"], s.contact_force, rtol=1e-15)
    np.testing.assert_allclose(data["contact_moment_Nmm"], s.contact_moment, rtol=1e-15, atol=1e-12)
    assert data["moment_about_mm"] == list(s.problem.body2.reference)
    assert data["certificate"]["passed"] is True
    assert data["certificate"]["equilibrium"] == s.certificate.equilibrium
    assert data["solve_time_s"] == s.solve_time and data["build_time_s"] == s.build_time
    assert "units" not in data  # every key of a number names its unit
    assert set(data["regions"]) == {"lateral", "medial", "posterior", "anterior"}
    label_stats = s.regions()
    for name in ("medial", "lateral"):
        np.testing.assert_allclose(data["regions"][name]["force_vector_N"], label_stats[name].force_vector, rtol=1e-15)
        assert data["regions"][name]["share"] == pytest.approx(label_stats[name].share, rel=1e-15)
        assert "force" not in data["regions"][name]
    np.testing.assert_allclose(
        np.add(data["regions"]["medial"]["force_vector_N"], data["regions"]["lateral"]["force_vector_N"]),
        data["contact_force_N"],
        rtol=1e-12,
        atol=1e-12 * np.linalg.norm(data["contact_force_N"]),
    )
    assert sum(data["regions"][n]["share"] for n in ("medial", "lateral")) == pytest.approx(1.0, rel=1e-12)
    assert sum(data["regions"][n]["force_magnitude_sum_N"] for n in ("medial", "lateral")) == pytest.approx(
        magnitudes, rel=1e-12
    )
    assert data["regions"]["anterior"]["resultant_N"] == pytest.approx(split["anterior"].resultant, rel=1e-15)
    assert data["label_codes"] == {"lateral": 0, "medial": 1}


def test_json_without_contact_writes_null(point_solution, tmp_path):
    s = point_solution
    idle = dataclasses.replace(s, pressure=np.zeros_like(s.pressure), strain=np.abs(s.strain) + 1e-3)
    data = strict_load(io.to_json(idle, tmp_path / "idle.json", planes={"right": ((0, 0, 0), (1, 0, 0))}))
    assert data["center_of_pressure_mm"] == [None, None, None]
    assert data["regions"]["right"]["share"] is None
    assert data["contact_area_mm2"] == 0.0 and data["peak_pressure_MPa"] == 0.0


def test_json_bad_regions(point_solution, tmp_path):
    with pytest.raises(InputError, match="regions must be a mapping"):
        io.to_json(point_solution, tmp_path / "x.json", regions=[1, 2])
    with pytest.raises(InputError, match=r"regions\['a'\] must be a RegionStats"):
        io.to_json(point_solution, tmp_path / "x.json", regions={"a": 1.0})
    assert not list(tmp_path.iterdir())


# --- pictures ---------------------------------------------------------------------------
def png_size(path):
    """(width, height) from the IHDR chunk, after checking the PNG signature."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    assert data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


@pytest.mark.parametrize("view", ["plane", "3d"])
def test_plot_pressure_png(solution, tmp_path, view):
    path = solution.plot_pressure(tmp_path / "map.png", view=view, dpi=80, figsize=(6.0, 5.0))
    width, height = png_size(path)
    assert (width, height) == (480, 400)
    assert 10_000 < path.stat().st_size < 2_000_000
    assert leftovers(tmp_path) == []


def test_plot_pressure_bad_input(point_solution, tmp_path):
    with pytest.raises(InputError, match="view must be 'plane' or '3d'"):
        io.plot_pressure(point_solution, tmp_path / "x.png", view="side")
    with pytest.raises(InputError, match=r"path must end in \.png"):
        io.plot_pressure(point_solution, tmp_path / "x.jpg")
    with pytest.raises(InputError, match="cmap must be a matplotlib colormap"):
        io.plot_pressure(point_solution, tmp_path / "x.png", cmap="no-such-map")


def test_best_fit_frame_is_right_handed_and_faces_the_normals():
    rng = np.random.default_rng(0)
    points = np.column_stack([rng.uniform(-5, 5, 200), rng.uniform(-2, 2, 200), np.zeros(200)])
    origin, axes = io.best_fit_frame(points, normals=np.tile([0, 0, -1.0], (200, 1)))
    np.testing.assert_allclose(axes @ axes.T, np.eye(3), atol=1e-12)
    assert np.linalg.det(axes) == pytest.approx(1.0)
    np.testing.assert_allclose(axes[2], [0, 0, -1], atol=1e-12)
    np.testing.assert_allclose(axes[0], [1, 0, 0], atol=1e-12)
    np.testing.assert_allclose(origin, points.mean(axis=0))


# --- everything at once -----------------------------------------------------------------
def test_write_results(surface_solution, tmp_path):
    s = surface_solution
    split = split_by_axis(s, "y", names=("posterior", "anterior"))
    paths = io.write_results(s, tmp_path / "run", stem="knee", regions=split)
    assert {k: p.name for k, p in paths.items()} == {
        "vtk": "knee.vtu",
        "csv": "knee.csv",
        "json": "knee.json",
        "png": "knee.png",
    }
    assert all(p.is_file() for p in paths.values())
    assert max(io.vtk_differences(s, paths["vtk"]).values()) == 0.0
    png_size(paths["png"])
    assert set(strict_load(paths["json"])["regions"]) == {"lateral", "medial", "posterior", "anterior"}
    with pytest.raises(InputError, match="regions repeats the region name 'medial'"):
        io.write_results(s, tmp_path / "clash", regions=split_by_axis(s, "x"))
    assert not (tmp_path / "clash").exists()
    with pytest.raises(InputError, match="stem must be a plain file name"):
        io.write_results(s, tmp_path, stem="a/b")
    with pytest.raises(InputError, match="vtk must be '.vtu' or '.vtp'"):
        io.write_results(s, tmp_path, vtk=".vtk")


def test_csv_quotes_awkward_labels(surface_solution, tmp_path):
    layer = surface_solution.problem.layer
    awkward = np.where(layer.labels == "medial", 'medial, "M"', " lateral\nL ")
    solution = dataclasses.replace(
        surface_solution, problem=surface_solution.problem.with_layer(dataclasses.replace(layer, labels=awkward))
    )
    table = io.read_csv(io.to_csv(solution, tmp_path / "awkward.csv"))
    np.testing.assert_array_equal(table["label"], awkward)
    np.testing.assert_array_equal(table["pressure_MPa"], solution.pressure)


def test_read_csv_rejects_bad_numbers(point_solution, tmp_path):
    path = io.to_csv(point_solution, tmp_path / "springs.csv")
    lines = path.read_text().splitlines()
    lines[1] = "oops" + lines[1][lines[1].index(",") :]
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match="column 'x_mm' .* does not parse"):
        io.read_csv(path)
