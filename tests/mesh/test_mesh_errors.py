"""Bad mesh files, oversized meshes and meshes of absurd size: each a named InputError.

Every reader failure names the file, the format its extension promises and what the file
holds instead (a garbage ``.stl`` once reported ``No module named 'charset_normalizer'``);
every generator and cast checks its size before allocating and gives an estimate of the
memory it would need; meshes too small or too large to compute with are refused, and inside
that range the springs' normals are unit vectors and the gaps scale exactly.
"""

from __future__ import annotations

import struct

import numpy as np
import pytest
import trimesh

import dea_opt as d
from dea_opt import geometry
from dea_opt import mesh as M
from dea_opt._checks import memory
from dea_opt.mesh import budget

STL_EXPECTED = "is not an STL surface"


def binary_stl(n_declared: int, n_written: int) -> bytes:
    record = struct.pack("<12fH", 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0)
    return b"\0" * 80 + struct.pack("<I", n_declared) + record * n_written


def ascii_stl(z="0") -> str:
    return (
        "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
        f"vertex 0 1 {z}\nendloop\nendfacet\nendsolid t\n"
    )


OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"

# name: (file name, bytes, the words the message must hold besides the file's name)
BAD_FILES = {
    "binary garbage .stl": (
        "garbage.stl",
        np.random.default_rng(1).bytes(5000),
        [STL_EXPECTED, "binary data (5000 bytes", "header declares"],
    ),
    "binary garbage .obj": (
        "garbage.obj",
        np.random.default_rng(2).bytes(3000),
        ["is not an OBJ surface", "'v x y z'", "binary data (3000 bytes)"],
    ),
    "binary garbage .off": (
        "garbage.off",
        np.random.default_rng(3).bytes(3000),
        ["is not an OFF surface", "binary data"],
    ),
    "binary garbage .ply": (
        "garbage.ply",
        np.random.default_rng(4).bytes(3000),
        ["is not a PLY surface", "binary data"],
    ),
    "binary garbage .vtk": (
        "garbage.vtk",
        np.random.default_rng(5).bytes(3000),
        ["is not a legacy VTK file", "# vtk DataFile", "binary data"],
    ),
    "binary garbage .vtp": (
        "garbage.vtp",
        np.random.default_rng(6).bytes(3000),
        ["is not a VTK XML PolyData file", "binary data"],
    ),
    "truncated binary STL": (
        "cut.stl",
        binary_stl(100, 10),
        [STL_EXPECTED, "header declares 100 triangles, which take 5084 bytes", "584 bytes"],
    ),
    "text in an .stl": (
        "notes.stl",
        b"hello world\nthis is no mesh\n",
        [STL_EXPECTED, "text whose first line is 'hello world'"],
    ),
    "blank lines": ("blank.stl", b"  \n\n \n", [STL_EXPECTED, "only blank lines"]),
    "OBJ in an .stl": ("obj.stl", OBJ.encode(), ["holds OBJ text", "extension .stl", "rename it to .obj"]),
    "ASCII STL in an .obj": ("stl.obj", ascii_stl().encode(), ["holds ASCII STL text", "rename it to .stl"]),
    "binary STL in a .ply": (
        "stl.ply",
        binary_stl(1, 1),
        ["holds a binary STL", "extension .ply", "rename it to .stl"],
    ),
    "binary STL in a .vtk": ("stl.vtk", binary_stl(1, 1), ["holds a binary STL", "rename it to .stl"]),
    "PLY in an .off": ("ply.off", b"ply\nformat ascii 1.0\nend_header\n", ["holds a PLY file", "rename it to .ply"]),
    "VTK XML in a .vtk": (
        "xml.vtk",
        b'<?xml version="1.0"?>\n<VTKFile type="PolyData">\n',
        ["holds a VTK XML file", "rename it to .vtp"],
    ),
    "NaN vertex in an ASCII STL": (
        "nan.stl",
        ascii_stl("nan").encode(),
        ["vertices must be finite", "1 of 3 vertices", "nan"],
    ),
    "inf vertex in an OBJ": ("inf.obj", OBJ.replace("1 0 0", "1 0 inf").encode(), ["vertices must be finite", "inf"]),
    "NaN vertex in a binary STL": (
        "nan_binary.stl",
        b"\0" * 80 + struct.pack("<I", 1) + struct.pack("<12fH", 0, 0, 1, 0, 0, 0, 1, 0, float("nan"), 0, 1, 0, 0),
        ["vertices must be finite"],
    ),
    "face index out of range": (
        "index.obj",
        OBJ.replace("f 1 2 3", "f 1 2 9").encode(),
        ["could not be read as OBJ", "expected an OBJ surface"],
    ),
    "zero bytes": ("empty.stl", b"", ["is empty (0 bytes)", "expected a .stl triangle surface"]),
    "legacy VTK 5.1 that ends in its POLYGONS": (
        "cut.vtk",
        b"# vtk DataFile Version 5.1\nx\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n0 0 0 1 0 0 0 1 0\nPOLYGONS 2 3\n",
        ["could not be read as legacy VTK POLYDATA", "the file ends before a section"],
    ),
}


@pytest.mark.parametrize("case", BAD_FILES)
def test_a_bad_mesh_file_is_named_with_what_is_wrong(tmp_path, case):
    name, data, words = BAD_FILES[case]
    path = tmp_path / name
    path.write_bytes(data)
    with pytest.raises(d.InputError) as info:
        M.load_mesh(path)
    message = str(info.value)
    assert str(path) in message
    for word in words:
        assert word in message, (word, message)
    assert "charset_normalizer" not in message and "No module named" not in message
    assert not isinstance(info.value, ImportError)


def test_text_trimesh_cannot_decode_is_named_not_a_missing_module(tmp_path, monkeypatch):
    # trimesh asks the optional charset_normalizer for text that is not UTF-8; its absence is
    # the file's fault, not a broken install
    path = tmp_path / "latin.obj"
    path.write_bytes("v 0 0 0 \xe9\n".encode("latin-1") * 3 + b"f 1 2 3\n")

    def load(*args, **kwargs):
        raise ModuleNotFoundError("No module named 'charset_normalizer'", name="charset_normalizer")

    monkeypatch.setattr(trimesh, "load", load)
    with pytest.raises(d.InputError, match="could not be read as OBJ: its bytes are not text in UTF-8") as info:
        M.load_mesh(path)
    assert str(path) in str(info.value) and "No module" not in str(info.value)


def test_a_directory_is_not_a_mesh_file(tmp_path):
    path = tmp_path / "femur.stl"
    path.mkdir()
    with pytest.raises(d.InputError, match="is a directory, not a file; expected an STL surface") as info:
        M.load_mesh(path)
    assert str(path) in str(info.value)


def test_a_nul_byte_in_the_path_is_named(tmp_path):
    path = str(tmp_path / "fe\0mur.stl")
    with pytest.raises(d.InputError, match="contains a NUL byte") as info:
        M.load_mesh(path)
    assert repr(path) in str(info.value)


@pytest.mark.parametrize("path", [b"femur.stl", 42, None])
def test_a_path_of_the_wrong_type_is_named(path):
    with pytest.raises(d.InputError, match="file path"):
        M.load_mesh(path)


def test_an_unreadable_file_is_named(tmp_path, monkeypatch):
    # the permission error a reader meets (simulated: root reads files whatever their mode)
    path = tmp_path / "locked.stl"
    path.write_text(ascii_stl())

    def refuse(_path, *args):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(M.sniff, "sniff", refuse)
    with pytest.raises(d.InputError, match=r"could not be read \(Permission denied\); expected an STL") as info:
        M.load_mesh(path)
    assert str(path) in str(info.value)


@pytest.mark.parametrize("ext", ["stl", "obj", "ply", "off"])
def test_good_files_still_read(tmp_path, ext):
    slab = geometry.slab_mesh(4.0, 3.0, 1.0, 4, 3)
    path = tmp_path / f"slab.{ext}"
    slab.export(path)
    assert len(M.load_mesh(path).faces) == len(slab.faces)


def test_comment_lines_before_the_header_are_allowed(tmp_path):
    (tmp_path / "c.off").write_text("# made by hand\nOFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    (tmp_path / "c.obj").write_text("# made by hand\n" + OBJ)
    for name in ("c.off", "c.obj"):
        assert len(M.load_mesh(tmp_path / name).faces) == 1


def test_an_ascii_stl_and_a_binary_stl_whose_header_says_solid_read(tmp_path):
    (tmp_path / "a.stl").write_text(ascii_stl())
    assert len(M.load_mesh(tmp_path / "a.stl").faces) == 1
    data = bytearray(binary_stl(1, 1))
    data[:5] = b"solid"  # some exporters begin binary STL headers with "solid"
    (tmp_path / "b.stl").write_bytes(bytes(data))
    assert len(M.load_mesh(tmp_path / "b.stl").faces) == 1


# --------------------------------------------------------------------------------------------
# Memory guards: sizes checked before allocating, with an estimate
# --------------------------------------------------------------------------------------------
HUGE = {
    "hip_meshes(step=0.01)": lambda: geometry.hip_meshes(step=0.01),
    "knee_meshes(n_plateau=": lambda: geometry.knee_meshes(n_plateau=200_000),
    "plate_meshes(nx=": lambda: geometry.plate_meshes(nx=10**6, ny=10**5),
    "sphere_on_bed_meshes(n_bed=": lambda: geometry.sphere_on_bed_meshes(n_bed=10**6),
    "slab_mesh(nx=": lambda: geometry.slab_mesh(nx=10**6, ny=10**6),
    "spherical_shell_mesh(step=": lambda: geometry.spherical_shell_mesh(step=1e-300),
    "plate_layer(nx=": lambda: geometry.plate_layer(nx=10**7, ny=10**6),
    "sphere_on_bed_layer(n_rings=": lambda: geometry.sphere_on_bed_layer(n_rings=10**7, n_sectors=10**6),
    "socket_layer(n_rings=": lambda: geometry.socket_layer(n_rings=10**7, n_sectors=10**6),
}


@pytest.mark.parametrize("what", HUGE)
def test_an_oversized_generator_is_refused_before_allocating(what):
    # each request needs more than a terabyte: refused on any machine, before any array is made
    with pytest.raises(
        d.InputError, match=r"would need about [0-9.e+]+ (TB|PB) of memory, and this machine has"
    ) as info:
        HUGE[what]()
    assert what in str(info.value)


def test_the_guard_estimates_the_memory_from_the_face_count(monkeypatch):
    monkeypatch.setattr(memory, "available_memory", lambda: 10**6)
    n_polar, n_azimuth = 29, 120  # ceil(85 / 3) polar rows, 360 / 3 azimuths
    faces = 4 * n_polar * n_azimuth + 4 * (n_polar + n_azimuth)
    expected = memory.format_bytes(budget.BYTES_PER_GENERATED_FACE * faces)
    with pytest.raises(
        d.InputError,
        match=rf"\({faces} faces\) would need about {expected} of memory, "
        r"and this machine has 1 MB free",
    ):
        geometry.spherical_shell_mesh(24.0, 2.0, 85.0, step=3.0)
    monkeypatch.setattr(memory, "available_memory", lambda: budget.BYTES_PER_GENERATED_FACE * faces)
    assert len(geometry.spherical_shell_mesh(24.0, 2.0, 85.0, step=3.0).faces) <= faces


def test_the_face_counts_bound_what_is_built():
    for nx, ny in ((1, 1), (3, 7), (20, 5)):
        assert len(geometry.slab_mesh(nx=nx, ny=ny).faces) == geometry.meshes._slab_faces(nx, ny)
    for args in ((85.0, 25.0, 60.0, 3.0), (105.0, 0.0, 0.0, 4.0), (180.0, 0.0, 0.0, 10.0)):
        shell = geometry.spherical_shell_mesh(24.0, 2.0, args[0], fossa=args[1], notch=args[2], step=args[3])
        assert len(shell.faces) <= geometry.meshes._shell_grid(*args)[2]


def test_the_estimates_bound_the_measured_peak(tmp_path):
    # The bytes-per-face constants are upper bounds of a generation's peak memory, measured
    # here in a fresh process (peak resident set, above the baseline after imports).
    import subprocess
    import sys

    script = (
        "import resource, dea_opt.geometry as g\n"
        "g.slab_mesh(nx=2, ny=2)\n"
        "base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
        "m = g.slab_mesh(40, 40, 2, 400, 400)\n"
        "peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
        "print(len(m.faces), (peak - base) * 1024)\n"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True)
    faces, used = (int(v) for v in out.stdout.split())
    assert used <= budget.BYTES_PER_GENERATED_FACE * faces


def test_a_cast_between_huge_meshes_is_refused_before_casting(monkeypatch):
    pair = geometry.plate_meshes(nx=8, ny=2)
    monkeypatch.setattr(memory, "available_memory", lambda: 1000)
    with pytest.raises(
        d.InputError,
        match=r"casting springs from mesh1 \(104 faces\) onto mesh2 \(104 faces\) "
        r"would need about .* of memory",
    ):
        M.springs_from_meshes(pair.mesh1, pair.mesh2, thickness2=0.0)


def test_a_huge_mesh_file_is_refused_before_reading(tmp_path, monkeypatch):
    path = tmp_path / "big.stl"
    path.write_bytes(binary_stl(1000, 1000))
    monkeypatch.setattr(memory, "available_memory", lambda: 1000)
    with pytest.raises(d.InputError, match=r"reading mesh file .*big.stl \(50.1 kB\) would need about 601 kB"):
        M.load_mesh(path)


def test_available_memory_is_a_positive_count():
    assert memory.available_memory() > 10**6


# --------------------------------------------------------------------------------------------
# Meshes of absurd size are refused; inside the range normals are unit and gaps scale
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize("scale", [1e-4, 1e-2, 1e3, 1e7])
@pytest.mark.parametrize("given", ["trimesh", "arrays"])
def test_mesh_derived_normals_are_unit_and_gaps_scale_at_any_size_in_range(scale, given):
    pair = geometry.sphere_on_bed_meshes(n_bed=12, step=6.0)
    reference = M.cast_springs(pair.mesh1, pair.mesh2, thickness2=0.0)
    meshes = []
    for mesh in (pair.mesh1, pair.mesh2):
        scaled = mesh.copy()
        scaled.apply_scale(scale)
        meshes.append(scaled if given == "trimesh" else (scaled.vertices, scaled.faces))
    cast = M.cast_springs(*meshes, thickness2=0.0, max_gap=2.0 * scale, max_overlap=scale)
    layer = cast.layer
    np.testing.assert_array_equal(layer.source_face, reference.layer.source_face)
    for normals in (layer.normals, layer.target_normals):
        np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, rtol=0, atol=1e-14)
    np.testing.assert_allclose(layer.normals, reference.layer.normals, atol=1e-12)
    np.testing.assert_allclose(layer.gap / scale, reference.layer.gap, rtol=0, atol=1e-9)
    np.testing.assert_allclose(layer.thickness / scale, reference.layer.thickness, rtol=1e-9)


@pytest.mark.parametrize(
    "scale, words",
    [(1e-7, "spans only"), (1e-200, "spans only"), (1e11, "has coordinates up to"), (1e200, "has coordinates up to")],
)
@pytest.mark.parametrize("given", ["trimesh", "arrays"])
def test_meshes_too_small_or_too_large_are_named(scale, words, given):
    mesh = geometry.slab_mesh(4.0, 3.0, 1.0, 4, 3)
    vertices = mesh.vertices * scale
    given_mesh = trimesh.Trimesh(vertices, mesh.faces, process=False) if given == "trimesh" else (vertices, mesh.faces)
    with pytest.raises(d.InputError, match=f"mesh1 {words}.*give the mesh in mm"):
        M.springs_from_meshes(given_mesh, mesh)


def test_a_file_in_metres_is_inside_the_range(tmp_path):
    slab = geometry.slab_mesh(40.0, 30.0, 2.0, 8, 6)
    slab.apply_scale(1e-3)
    slab.export(tmp_path / "metres.stl")
    assert M.load_mesh(tmp_path / "metres.stl").extents.max() == pytest.approx(0.04, rel=1e-6)
