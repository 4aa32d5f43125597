"""Outputs streamed within memory: chunked CSV, array-by-array VTK, surfaces through generated
layers, raster maps, and sizes checked before allocating. No timings: contents and sizes."""

from __future__ import annotations

import csv
import dataclasses
import io as textio

import meshio
import numpy as np
import pytest

import dea_opt as d
from dea_opt import io
from dea_opt._checks import memory
from dea_opt.errors import SizeLimitError
from dea_opt.gait import hip_gait_load
from dea_opt.geometry import plate_layer, socket_layer, sphere_on_bed_layer
from dea_opt.io import draw, tables, triangulate, vtkxml
from dea_opt.loadpath import check_frames, path_memory, solve_path


@pytest.fixture(scope="module")
def plate_solution():
    layer = plate_layer(20.0, 8.0, 20, 8, thickness=2.0)
    labels = np.where(layer.points[:, 0] < 0, 'medial, "M"', np.where(layer.points[:, 1] < 0, "lateral\nL", ""))
    layer = dataclasses.replace(layer, labels=labels)
    problem = d.ContactProblem(layer, d.LinearLaw(10.0), force=(0, 0, -100), moment=(0, 600, 0), free=("uz", "ry"))
    solution = d.solve(problem, "newton")
    assert 0 < solution.in_contact.sum() < len(layer)
    return solution


def reference_csv(solution) -> str:
    """The whole table built in memory with the csv module: what the file must hold."""
    layer = solution.problem.layer
    buffer = textio.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(io.CSV_COLUMNS)
    for i in range(len(layer)):
        writer.writerow(
            [
                *layer.points[i].tolist(),
                *layer.normals[i].tolist(),
                float(layer.areas[i]),
                float(layer.thickness[i]),
                float(layer.gap[i]),
                float(solution.strain[i]),
                float(solution.pressure[i]),
                float(solution.spring_force[i]),
                int(solution.in_contact[i]),
                -1,
                str(layer.labels[i]),
            ]
        )
    return buffer.getvalue()


@pytest.mark.parametrize("chunk", [1, 7, 160, 1 << 16])
def test_chunked_csv_equals_the_reference(plate_solution, tmp_path, monkeypatch, chunk):
    monkeypatch.setattr(tables, "CHUNK_ROWS", chunk)
    path = io.to_csv(plate_solution, tmp_path / "contact.csv")
    assert path.read_text(encoding="utf-8") == reference_csv(plate_solution)
    back = io.read_csv(path)
    np.testing.assert_array_equal(back["pressure_MPa"], plate_solution.pressure)
    np.testing.assert_array_equal(back["label"], plate_solution.problem.layer.labels)


@pytest.mark.parametrize("block", [64, 1 << 20])
@pytest.mark.parametrize("binary, compress", [(True, False), (True, True), (False, False)])
def test_streamed_vtu_reads_back_exactly(plate_solution, tmp_path, monkeypatch, block, binary, compress):
    monkeypatch.setattr(vtkxml, "_BLOCK", block)  # many compressed blocks per array, or one
    monkeypatch.setattr(vtkxml, "_CHUNK", 3 * 5)  # base64 chunks that do not align with anything
    monkeypatch.setattr(vtkxml, "_RAW", block)  # appended arrays written in many pieces, or one
    path = io.to_vtk(plate_solution, tmp_path / "c.vtu", binary=binary, compress=compress)
    text = path.read_bytes()
    assert (b'compressor="vtkZLibDataCompressor"' in text) == compress
    assert (b'<AppendedData encoding="raw">' in text) == (binary and not compress)
    mesh = meshio.read(path)
    layer = plate_solution.problem.layer
    np.testing.assert_array_equal(mesh.points, layer.points)
    for name, want in (
        ("pressure", plate_solution.pressure),
        ("strain", plate_solution.strain),
        ("normal", layer.normals),
        ("area", layer.areas),
    ):
        np.testing.assert_array_equal(mesh.point_data[name], want, err_msg=name)
    assert max(io.vtk_differences(plate_solution, path).values()) == 0.0


def triangle_area(points, triangles):
    a, b, c = (points[triangles[:, i]] for i in range(3))
    return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum()


def test_a_grid_is_triangulated_from_its_indices():
    layer = plate_layer(40.0, 10.0, 40, 10)
    triangles = triangulate.point_triangulation(layer)
    assert len(triangles) == 2 * 39 * 9
    # the rectangle through the outer springs' centres, covered once
    assert triangle_area(layer.points, triangles) == pytest.approx(39.0 * 9.0, rel=1e-12)
    assert triangulate.point_triangulation(layer) is triangles  # cached per layer


@pytest.mark.parametrize("coverage", [60.0, 120.0])
def test_a_socket_is_a_surface_through_every_spring(coverage):
    """A cap past 90 degrees folds over in any plane: the Gauss map charts it."""
    radius, n_rings, n_sectors = 25.0, 24, 48
    layer = socket_layer(radius=radius, coverage=coverage, n_rings=n_rings, n_sectors=n_sectors)
    triangles = triangulate.point_triangulation(layer)
    assert np.array_equal(np.unique(triangles), np.arange(len(layer)))  # every spring is a vertex
    # each edge is shared by at most two triangles: a surface, not a pile
    edges = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1)
    assert np.unique(edges, axis=0, return_counts=True)[1].max() <= 2
    # it covers the cap between the innermost and outermost rings of springs (chords: a bit less)
    polar = np.arccos(np.clip(-layer.normals @ np.array([0, 0, 1.0]) * np.sign(layer.points[:, 2].mean()), -1, 1))
    low, high = polar.min(), polar.max()
    cap = 2 * np.pi * radius**2 * (np.cos(low) - np.cos(high))
    assert 0.97 * cap < triangle_area(layer.points, triangles) <= cap


def test_scattered_springs_and_a_box_are_triangulated():
    rng = np.random.default_rng(1)
    points = np.column_stack([rng.uniform(0, 10, 400), rng.uniform(0, 10, 400), np.zeros(400)])
    layer = d.SpringLayer(points, np.tile([0, 0, 1.0], (400, 1)), 0.25, 2.0)
    triangles = triangulate.point_triangulation(layer)
    assert len(np.unique(triangles)) > 390 and triangle_area(points, triangles) > 90.0
    # springs on the six faces of a cube: each face in its own plane
    grid = np.stack(np.meshgrid(np.linspace(-4.5, 4.5, 10), np.linspace(-4.5, 4.5, 10)), -1).reshape(-1, 2)
    faces = []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            p = np.insert(grid, axis, 5.0 * sign, axis=1)
            n = np.zeros_like(p)
            n[:, axis] = sign
            faces.append((p, n))
    box = d.SpringLayer(np.concatenate([f[0] for f in faces]), np.concatenate([f[1] for f in faces]), 1.0, 2.0)
    triangles = triangulate.point_triangulation(box)
    assert triangle_area(box.points, triangles) == pytest.approx(6 * 81.0, rel=1e-12)


def test_raster_maps_keep_the_peak(plate_solution, monkeypatch, tmp_path):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.colors import ListedColormap, Normalize
    from matplotlib.figure import Figure

    monkeypatch.setattr(draw, "RASTER_LIMIT", 10)
    layer = plate_solution.problem.layer
    frame = io.map_frame(layer.points, layer.areas, layer.normals)
    geometry = draw.map_geometry(layer, frame)
    assert geometry.raster
    fig = Figure()
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    draw.draw_values(
        ax,
        geometry,
        plate_solution.pressure,
        "viridis",
        Normalize(0, 1),
        contact=plate_solution.in_contact,
        grey=ListedColormap(["0.85"]),
    )
    assert not ax.collections or all(type(c).__name__ != "TriMesh" for c in ax.collections)
    image = np.ma.filled(ax.images[-1].get_array(), np.nan)
    assert np.nanmax(image) == plate_solution.peak_pressure  # a pixel is the largest pressure in it
    assert image.size < len(layer)  # fewer pixels than springs here: decimated
    assert plate_solution.plot_pressure(tmp_path / "m.png").read_bytes()[:4] == b"\x89PNG"


def test_sizes_are_checked_before_allocating(monkeypatch):
    with pytest.raises(SizeLimitError, match=r"n_frames = 1000000000 would need about .* GB") as caught:
        hip_gait_load(n_frames=10**9)
    assert caught.value.needed > caught.value.available > 0
    # a path that would keep every spring of every frame: refused before the first frame
    layer = sphere_on_bed_layer(n_rings=10, n_sectors=16)
    problem = d.ContactProblem(layer, d.LinearLaw(10.0), reference=(0, 0, 25), free=("uz",))
    need = path_memory(4, len(layer))
    monkeypatch.setattr(memory, "available_memory", lambda: need)  # 0.8 of it is usable
    solved = []
    monkeypatch.setattr(d.ContactProblem, "system", lambda self: solved.append(1))
    with pytest.raises(
        SizeLimitError, match=r"PathOutputs\(keep_solutions=False, keep_pressures=False, series=<folder>\)"
    ) as caught:
        solve_path(problem, np.tile([0, 0, -10.0], (4, 1)))
    assert not solved and caught.value.needed == need
    check_frames(4, len(layer), keep_solutions=False, keep_pressures=False)  # fits without them


def test_path_memory_grows_with_what_is_kept():
    base = path_memory(10_000, 0)
    assert path_memory(20_000, 0) == pytest.approx(2 * base)
    kept = path_memory(10_000, 5400)
    assert kept - path_memory(10_000, 5400, keep_solutions=False, keep_pressures=False) == pytest.approx(
        10_000 * 5400 * 32.0
    )
    assert path_memory(10_000, 5400, keep_solutions=False, keep_pressures=False) == base


def test_springs_tables_keep_their_labels(tmp_path):
    layer = plate_layer(4.0, 2.0, 4, 2)
    for labels in (np.array(["medial", "lateral, L"] * 4), np.array([1, 2, 2, 1, 3, 3, 1, 1])):
        labelled = dataclasses.replace(layer, labels=labels)
        back = io.tables.read_springs(io.tables.write_springs(labelled, tmp_path / "s.csv"))
        np.testing.assert_array_equal(back.labels, labels)
        assert back.labels.dtype.kind == labels.dtype.kind
