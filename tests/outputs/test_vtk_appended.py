"""Binary VTK files as raw appended data: meshio and dea-opt's own reader get every
array back bit for bit, whatever the arrays' sizes, types, bytes and memory layout."""

from __future__ import annotations

import meshio
import numpy as np
import pytest

from dea_opt import InputError, io
from dea_opt.io.surface import SurfaceData
from dea_opt.io.vtkxml import read_appended

DTYPES = [np.float64, np.float32, np.int64, np.int32, np.uint8, np.int8, np.uint16]


def random_surface(seed: int) -> SurfaceData:
    """Triangles on random points with a random number of cell and point arrays of every type;
    the values are random bit patterns (newlines, underscores and '<' among their bytes)."""
    rng = np.random.default_rng(seed)
    n_points = int(rng.integers(3, 400))
    n_cells = int(rng.integers(1, 300))
    points = rng.normal(size=(n_points, 3)) * 10.0 ** rng.integers(-3, 4)
    cells = rng.integers(0, n_points, size=(n_cells, 3))

    def array(n):
        dtype = np.dtype(DTYPES[rng.integers(len(DTYPES))])
        raw = rng.integers(0, 256, size=n * dtype.itemsize * (3 if rng.random() < 0.2 else 1), dtype=np.uint8)
        values = raw.view(dtype)
        if dtype.kind == "f":
            values = np.where(np.isfinite(values), values, -0.0)  # NaN payloads are not our business
        return values.reshape(n, 3) if values.size == 3 * n else values

    cell_data = {f"c{k}": array(n_cells) for k in range(int(rng.integers(1, 9)))}
    point_data = {f"p{k}": array(n_points) for k in range(int(rng.integers(0, 4)))}
    return SurfaceData(points, cells, "triangle", cell_data, point_data)


@pytest.mark.parametrize("seed", range(40))
def test_meshio_and_our_reader_get_every_array_back_exactly(tmp_path, seed):
    surface = random_surface(seed)
    path = io.write_surface(surface, tmp_path / "s.vtu")
    assert b'<AppendedData encoding="raw">' in path.read_bytes()
    mesh = meshio.read(path)
    np.testing.assert_array_equal(mesh.points, surface.points)
    np.testing.assert_array_equal(mesh.cells[0].data, surface.cells)
    for name, want in surface.cell_data.items():
        got = mesh.cell_data[name][0]
        assert got.dtype == want.dtype and got.shape == want.shape, name
        np.testing.assert_array_equal(got, want, err_msg=name)
    for name, want in surface.point_data.items():
        assert mesh.point_data[name].dtype == want.dtype
        np.testing.assert_array_equal(mesh.point_data[name], want, err_msg=name)
    # our own reader: every appended array, by the XML's names
    root, arrays = read_appended(path)
    named = {e.get("Name"): arrays[int(e.get("offset"))] for e in root.iter("DataArray")}
    for name, want in {**surface.cell_data, **surface.point_data}.items():
        np.testing.assert_array_equal(named[name], want, err_msg=name)
    np.testing.assert_array_equal(named["connectivity"].reshape(-1, 3), surface.cells)
    np.testing.assert_array_equal(named["offsets"], 3 * np.arange(1, len(surface.cells) + 1))
    assert (named["types"] == 5).all()


@pytest.mark.parametrize("seed", range(8))
def test_a_vtp_with_appended_data_reads_back_exactly(tmp_path, seed):
    surface = random_surface(seed)
    back = io.read_vtk(io.write_surface(surface, tmp_path / "s.vtp"))
    np.testing.assert_array_equal(back.points, surface.points)
    np.testing.assert_array_equal(back.cells, surface.cells)
    for name, want in surface.cell_data.items():
        np.testing.assert_array_equal(back.cell_data[name], want, err_msg=name)


def test_arrays_in_any_memory_layout_are_written_as_their_values(tmp_path, monkeypatch):
    """Big-endian, Fortran-ordered and strided arrays are copied a chunk at a time in order."""
    from dea_opt.io import vtkxml

    monkeypatch.setattr(vtkxml, "_RAW", 64)  # many chunks per array
    rng = np.random.default_rng(5)
    n = 101
    wide = rng.normal(size=(n, 6))
    surface = SurfaceData(
        np.asfortranarray(rng.normal(size=(n, 3))),
        rng.integers(0, n, size=(n, 3)),
        "triangle",
        {
            "big_endian": rng.normal(size=n).astype(">f8"),
            "strided": wide[:, ::2],
            "column": wide[:, 1],
            "fortran": np.asfortranarray(rng.normal(size=(n, 3))),
        },
    )
    mesh = meshio.read(io.write_surface(surface, tmp_path / "s.vtu"))
    np.testing.assert_array_equal(mesh.points, surface.points)
    for name, want in surface.cell_data.items():
        np.testing.assert_array_equal(mesh.cell_data[name][0], want, err_msg=name)


def test_a_truncated_file_is_named(tmp_path):
    surface = random_surface(1)
    path = io.write_surface(surface, tmp_path / "s.vtu")
    data = path.read_bytes()
    cut = data.index(b"_", data.index(b"<AppendedData")) + 100
    path.write_bytes(data[:cut] + b"\n  </AppendedData>\n</VTKFile>\n")
    with pytest.raises(InputError, match="truncated"):
        read_appended(path)


def test_compressed_and_ascii_files_are_still_written_on_request(tmp_path):
    surface = random_surface(2)
    for kwargs, marker in (
        ({"compress": True}, b'compressor="vtkZLibDataCompressor"'),
        ({"binary": False}, b'format="ascii"'),
    ):
        path = io.write_surface(surface, tmp_path / "s.vtu", **kwargs)
        assert marker in path.read_bytes() and b"AppendedData" not in path.read_bytes()
        mesh = meshio.read(path)
        for name, want in surface.cell_data.items():
            np.testing.assert_array_equal(mesh.cell_data[name][0], want, err_msg=name)
