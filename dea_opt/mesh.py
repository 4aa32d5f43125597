"""Triangle meshes in, springs out: reading surfaces, ray casting gaps and cartilage thickness.

A researcher's data are cartilage surfaces segmented from MRI or CT. This module reads them
(:func:`load_mesh`), checks and repairs them, and turns two of them into a
:class:`~dea_opt.layer.SpringLayer` (:func:`springs_from_meshes`): one spring per articular
face of mesh 1, at its centroid, along its normal, with the gap to mesh 2 and the cartilage
thickness measured by ray casting. Lengths are in mm throughout.

Ray casting uses trimesh with Intel Embree (the ``embreex`` package) when it is importable and
a numpy uniform-grid caster with exact float64 ray/triangle tests otherwise (trimesh's own
``ray_triangle`` fallback queries its r-tree once per ray and takes minutes on a knee); both
give the same springs. Every step is vectorized over faces.

Two faults of OpenSim-JAM's elastic foundation are avoided on purpose:

* a ray never takes a hit on the far (back) side of a curved mesh 2: only faces of mesh 2 that
  face the ray count, and of those the one nearest the spring;
* results need not depend on which mesh casts: :func:`springs_both_ways` casts both ways and
  measures the difference.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from numbers import Real
from pathlib import Path

import numpy as np

from .errors import InputError, MissingDependencyError
from .layer import SpringLayer

__all__ = [
    "ENGINES",
    "LOADERS",
    "MAX_ANGLE",
    "MAX_GAP",
    "MAX_OVERLAP",
    "SpringCast",
    "TwoWaySprings",
    "as_mesh",
    "cast_springs",
    "check_pose",
    "concatenate_meshes",
    "load_mesh",
    "springs_both_ways",
    "springs_from_meshes",
    "surface_thickness",
]

#: Default proximity window of :func:`springs_from_meshes`: gaps up to 2 mm, overlaps up to
#: 1 mm, normals within 60 degrees of facing each other.
MAX_GAP = 2.0
MAX_OVERLAP = 1.0
MAX_ANGLE = 60.0

_VTK_EXTRA = "pip install dea-opt[vtk]"


# --------------------------------------------------------------------------------------------
# Reading
# --------------------------------------------------------------------------------------------
def _read_with_trimesh(path: Path, kind: str) -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    try:
        loaded = trimesh.load(str(path), file_type=kind, force="mesh", process=False)
    except Exception as exc:  # trimesh raises many types for a malformed file
        raise InputError(f"mesh file {path} could not be read as {kind.upper()}: {exc}") from exc
    if not isinstance(loaded, trimesh.Trimesh):  # e.g. an empty scene or a point cloud
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    return np.asarray(loaded.vertices), np.asarray(loaded.faces)


_VTK_TYPES = {
    "unsigned_char": "u1", "char": "i1", "unsigned_short": "u2", "short": "i2",
    "unsigned_int": "u4", "int": "i4", "unsigned_long": "u8", "long": "i8",
    "float": "f4", "double": "f8", "vtktypeint64": "i8", "vtktypeint32": "i4",
    "vtkidtype": "i8",
}
_VTK_SECTIONS = {"POINTS", "VERTICES", "LINES", "POLYGONS", "TRIANGLE_STRIPS", "POINT_DATA",
                 "CELL_DATA", "FIELD", "METADATA"}


class _VtkCursor:
    """Reads a legacy VTK body as keyword lines and arrays, in ASCII or BINARY mode."""

    def __init__(self, data: bytes, pos: int, binary: bool):
        self.data, self.binary = data, binary
        if binary:
            self.pos = pos
        else:  # ASCII arrays may wrap lines anywhere: read the body as one token stream
            self.tokens = data[pos:].split()
            self.index = 0

    def keyword(self) -> list[str] | None:
        """The next section header as tokens, or None at the end of the file."""
        if self.binary:
            while self.pos < len(self.data):
                end = self.data.find(b"\n", self.pos)
                end = len(self.data) if end < 0 else end
                line = self.data[self.pos:end].decode("ascii", "replace").split()
                self.pos = end + 1
                if line:
                    return line
            return None
        if self.index >= len(self.tokens):
            return None
        head = self.tokens[self.index].decode("ascii", "replace")
        # A header is its keyword and the numbers/names that follow on its line; tokens are
        # consumed by the caller through array()/skip_to_section().
        self.index += 1
        return [head]

    def take(self, count: int) -> list[str]:
        """The next ``count`` header tokens (ASCII mode)."""
        out = [t.decode("ascii", "replace") for t in self.tokens[self.index:self.index + count]]
        self.index += count
        return out

    def array(self, count: int, vtk_type: str) -> np.ndarray:
        dtype = _VTK_TYPES.get(vtk_type.lower())
        if dtype is None:
            raise ValueError(f"unknown VTK data type {vtk_type!r}")
        if self.binary:
            size = count * np.dtype(dtype).itemsize
            raw = self.data[self.pos:self.pos + size]
            if len(raw) < size:
                raise ValueError("the file ends inside a binary array")
            self.pos += size
            return np.frombuffer(raw, dtype=">" + dtype).astype(dtype)
        chunk = self.tokens[self.index:self.index + count]
        if len(chunk) < count:
            raise ValueError("the file ends inside an ASCII array")
        self.index += count
        return np.array(chunk, dtype=float).astype(dtype)

    def skip_metadata(self) -> None:
        if self.binary:  # METADATA ends at the first empty line
            while self.pos < len(self.data):
                end = self.data.find(b"\n", self.pos)
                end = len(self.data) if end < 0 else end
                empty = not self.data[self.pos:end].strip()
                self.pos = end + 1
                if empty:
                    return
            return
        while self.index < len(self.tokens):
            if self.tokens[self.index].decode("ascii", "replace") in _VTK_SECTIONS - {"METADATA"}:
                return
            self.index += 1


def _cells_to_triangles(sizes: np.ndarray, connectivity: np.ndarray, strips: bool) -> np.ndarray:
    """Triangles from polygons (fan split) or triangle strips, shape (F, 3)."""
    if not len(sizes):
        return np.zeros((0, 3), dtype=np.int64)
    if not strips and (sizes == 3).all():  # the common case, vectorized
        return connectivity.reshape(-1, 3).astype(np.int64)
    starts = np.concatenate([[0], np.cumsum(sizes)[:-1]])
    out = []
    for start, size in zip(starts, sizes):  # mixed cells are rare: one pass per cell is fine
        cell = connectivity[start:start + size]
        for k in range(1, size - 1):
            if strips:
                tri = cell[[k - 1, k, k + 1]] if k % 2 else cell[[k, k - 1, k + 1]]
            else:
                tri = cell[[0, k, k + 1]]
            out.append(tri)
    return np.array(out, dtype=np.int64).reshape(-1, 3)


def _read_cells(cursor: _VtkCursor, header: list[str], version: float) -> tuple[np.ndarray, np.ndarray]:
    """One POLYGONS/TRIANGLE_STRIPS/LINES/VERTICES section as (sizes, connectivity)."""
    if version >= 5.0:  # OFFSETS and CONNECTIVITY arrays
        n_offsets, n_conn = int(header[1]), int(header[2])
        offsets_header = cursor.keyword() if cursor.binary else cursor.keyword() + cursor.take(1)
        offsets = cursor.array(n_offsets, offsets_header[1])
        conn_header = cursor.keyword() if cursor.binary else cursor.keyword() + cursor.take(1)
        connectivity = cursor.array(n_conn, conn_header[1])
        return np.diff(offsets), connectivity
    n_cells, size = int(header[1]), int(header[2])
    flat = cursor.array(size, "int").astype(np.int64)
    if n_cells and (flat[0] == 3) and size == 4 * n_cells and (flat[::4] == 3).all():
        return np.full(n_cells, 3), flat.reshape(-1, 4)[:, 1:].ravel()
    sizes, conn, pos = [], [], 0
    for _ in range(n_cells):  # variable-length records must be walked in order
        k = int(flat[pos])
        sizes.append(k)
        conn.append(flat[pos + 1:pos + 1 + k])
        pos += k + 1
    return np.array(sizes, dtype=np.int64), np.concatenate(conn) if conn else np.zeros(0, np.int64)


def _parse_vtk_polydata(path: Path) -> tuple[np.ndarray, np.ndarray] | None:
    """Vertices and triangles of a legacy VTK POLYDATA file; None if another dataset kind."""
    data = path.read_bytes()
    lines = data.split(b"\n", 4)
    if len(lines) < 5 or not lines[0].startswith(b"# vtk DataFile"):
        raise ValueError("the first line is not '# vtk DataFile Version x.x'")
    try:
        version = float(lines[0].split()[-1])
    except ValueError:
        version = 3.0
    mode = lines[2].strip().upper()
    if mode not in (b"ASCII", b"BINARY"):
        raise ValueError(f"line 3 must be ASCII or BINARY, got {mode.decode('ascii', 'replace')!r}")
    dataset = lines[3].split()
    if len(dataset) < 2 or dataset[0].upper() != b"DATASET":
        raise ValueError("line 4 must be 'DATASET <kind>'")
    if dataset[1].upper() != b"POLYDATA":
        return None
    cursor = _VtkCursor(data, len(b"\n".join(lines[:4])) + 1, mode == b"BINARY")
    vertices = np.zeros((0, 3))
    triangles = []
    while (header := cursor.keyword()) is not None:
        key = header[0].upper()
        if key == "POINTS":
            header = header if cursor.binary else header + cursor.take(2)
            vertices = cursor.array(3 * int(header[1]), header[2]).astype(float).reshape(-1, 3)
        elif key in ("POLYGONS", "TRIANGLE_STRIPS", "LINES", "VERTICES"):
            header = header if cursor.binary else header + cursor.take(2)
            sizes, connectivity = _read_cells(cursor, header, version)
            if key in ("POLYGONS", "TRIANGLE_STRIPS"):
                triangles.append(_cells_to_triangles(sizes, connectivity, key == "TRIANGLE_STRIPS"))
        elif key == "METADATA":
            cursor.skip_metadata()
        elif key == "FIELD":  # dataset-level field data (e.g. a time value): skip its arrays
            header = header if cursor.binary else header + cursor.take(2)
            for _ in range(int(header[2])):
                array = cursor.keyword() if cursor.binary else cursor.keyword() + cursor.take(3)
                cursor.array(int(array[1]) * int(array[2]), array[3])
        elif key in ("POINT_DATA", "CELL_DATA"):
            break  # attributes are not needed for the geometry
        else:
            raise ValueError(f"unexpected section {header[0]!r}")
    faces = np.concatenate(triangles) if triangles else np.zeros((0, 3), dtype=np.int64)
    return vertices, faces


def _read_vtk(path: Path, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """Legacy ``.vtk``: POLYDATA parsed here (no dependency); other datasets via meshio."""
    try:
        parsed = _parse_vtk_polydata(path)
    except (ValueError, IndexError) as exc:
        raise InputError(f"mesh file {path} could not be read as legacy VTK POLYDATA: {exc}") from exc
    if parsed is not None:
        return parsed
    import meshio

    try:
        data = meshio.read(str(path), file_format="vtk")
    except Exception as exc:
        raise InputError(f"mesh file {path} could not be read as legacy VTK: {exc}") from exc
    return np.asarray(data.points, dtype=float)[:, :3], _meshio_triangles(data)


def _meshio_triangles(data) -> np.ndarray:
    parts = []
    for block in data.cells:
        cells = np.asarray(block.data, dtype=np.int64)
        if block.type == "triangle":
            parts.append(cells)
        elif block.type == "quad":  # split each quad along one diagonal
            parts.append(cells[:, [0, 1, 2]])
            parts.append(cells[:, [0, 2, 3]])
    return np.concatenate(parts) if parts else np.zeros((0, 3), dtype=np.int64)


def _read_vtp(path: Path, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """VTK XML PolyData through the optional ``vtk`` package."""
    try:
        import vtk
        from vtk.util.numpy_support import vtk_to_numpy
    except ImportError:
        raise MissingDependencyError(
            f"reading {path.name}: .vtp files need the vtk package, which is not installed; "
            f"install it with `{_VTK_EXTRA}` or convert the file to .vtk, .stl or .ply"
        ) from None
    reader = vtk.vtkXMLPolyDataReader()
    reader.SetFileName(str(path))
    reader.Update()
    triangulate = vtk.vtkTriangleFilter()  # polygons and strips become triangles
    triangulate.SetInputConnection(reader.GetOutputPort())
    triangulate.Update()
    poly = triangulate.GetOutput()
    if poly is None or poly.GetPoints() is None:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    vertices = vtk_to_numpy(poly.GetPoints().GetData()).astype(float)
    cells = vtk_to_numpy(poly.GetPolys().GetData()).astype(np.int64)
    return vertices, cells.reshape(-1, 4)[:, 1:]


#: Readers by file extension; each returns ``(vertices (V, 3), faces (F, 3))``.
LOADERS = {
    ".stl": _read_with_trimesh,
    ".obj": _read_with_trimesh,
    ".ply": _read_with_trimesh,
    ".off": _read_with_trimesh,
    ".vtk": _read_vtk,
    ".vtp": _read_vtp,
}


def load_mesh(path, scale: float = 1.0):
    """Read a triangle surface from a file, checked and repaired.

    Parameters
    ----------
    path : str or path-like
        A ``.stl``, ``.obj``, ``.ply``, ``.off``, ``.vtk`` (legacy POLYDATA, ASCII or binary,
        read without extra packages) or ``.vtp`` file (needs ``pip install dea-opt[vtk]``).
    scale : float, default 1
        Factor applied to the coordinates so that they are in mm (1000 for a file in metres).

    Returns
    -------
    trimesh.Trimesh
        Duplicate vertices merged, zero-area faces dropped (with a warning giving their
        count), winding made consistent and, for a closed surface, normals pointing out.

    Raises
    ------
    InputError
        The file is missing, its extension unknown, it cannot be parsed, or it holds no
        face of nonzero area.
    MissingDependencyError
        The format needs the optional ``vtk`` package.
    """
    mesh, _ = _load(path, scale)
    return mesh


def _load(path, scale):
    try:
        path = Path(path)
    except TypeError:
        raise InputError(f"path must be a file path, got {type(path).__name__}") from None
    suffix = path.suffix.lower()
    if suffix not in LOADERS:
        raise InputError(
            f"mesh file {path} has unknown extension {path.suffix or '(none)'!r}; expected one of "
            f"{', '.join(sorted(LOADERS))}"
        )
    if not path.is_file():
        raise InputError(f"mesh file {path} does not exist (expected a {suffix} triangle surface)")
    if path.stat().st_size == 0:
        raise InputError(f"mesh file {path} is empty (0 bytes); expected a {suffix} triangle surface")
    scale = _positive("scale", scale)
    vertices, faces = LOADERS[suffix](path, suffix[1:])
    return _clean(vertices, faces, f"mesh file {path}", scale)


def _positive(name, value) -> float:
    if isinstance(value, bool) or not isinstance(value, Real) or not math.isfinite(value) or value <= 0:
        raise InputError(f"{name} must be a finite number > 0, got {value!r}")
    return float(value)


# --------------------------------------------------------------------------------------------
# Checking and repairing
# --------------------------------------------------------------------------------------------
def _clean(vertices, faces, source: str, scale: float = 1.0):
    """A checked Trimesh from arrays, and ``(input index of each face kept, input face count)``
    when faces were dropped (None when all are kept)."""
    import trimesh

    try:
        vertices = np.array(vertices, dtype=float)
        faces = np.array(faces)
    except (TypeError, ValueError):
        raise InputError(f"{source}: vertices and faces must be numeric arrays") from None
    if faces.size == 0 or vertices.size == 0:
        raise InputError(f"{source} is empty: it has no triangle faces ({len(vertices)} vertices); "
                         f"expected a triangle surface")
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise InputError(f"{source}: vertices must have shape (V, 3), got {vertices.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise InputError(f"{source}: faces must be triangles, shape (F, 3), got {faces.shape}")
    if not np.issubdtype(faces.dtype, np.integer):
        if not np.all(np.mod(faces, 1) == 0):
            raise InputError(f"{source}: faces must hold integer vertex indices, got {faces.dtype}")
        faces = faces.astype(np.int64)
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise InputError(f"{source}: face indices must lie in [0, {len(vertices) - 1}], "
                         f"got [{faces.min()}, {faces.max()}]")
    if not np.isfinite(vertices).all():
        raise InputError(f"{source}: vertices must be finite, found NaN or inf")
    if scale != 1.0:
        vertices = vertices * scale
    mesh = trimesh.Trimesh(vertices, faces, process=True)  # merges the per-face vertices of STL
    return _repair(mesh, source, copy=False)


def _repair(mesh, source: str, copy: bool):
    """Drop zero-area faces, make winding consistent and closed surfaces outward."""
    bad = ~_nondegenerate(mesh)
    kept = None
    if bad.any():
        if bad.all():
            raise InputError(f"{source}: all {len(bad)} faces are degenerate (zero area); expected a "
                             f"triangle surface with faces of nonzero area")
        if copy:
            mesh, copy = mesh.copy(), False
        kept = (np.flatnonzero(~bad), len(bad))  # input index of each face kept, input count
        mesh.update_faces(~bad)
        mesh.remove_unreferenced_vertices()
        warnings.warn(f"{source}: dropped {int(bad.sum())} degenerate (zero-area) faces of {len(bad)}",
                      stacklevel=4)
    if not mesh.is_winding_consistent:
        if copy:
            mesh, copy = mesh.copy(), False
        flipped = _fix_winding(mesh)
        if mesh.is_winding_consistent:
            warnings.warn(f"{source}: winding was inconsistent; re-wound {flipped} faces", stacklevel=4)
        else:
            warnings.warn(f"{source}: winding is inconsistent and could not be repaired (non-manifold "
                          f"edges?); face normals may point either way", stacklevel=4)
    if mesh.is_watertight and mesh.is_winding_consistent and _signed_volume(mesh) < 0:
        if copy:
            mesh, copy = mesh.copy(), False
        mesh.invert()
        warnings.warn(f"{source}: the closed surface was inside out; inverted so normals point outward",
                      stacklevel=4)
    return mesh, kept


def _fix_winding(mesh) -> int:
    """Make the winding consistent across every shared edge; returns the faces re-wound.

    Faces sharing an edge must run it in opposite directions. A breadth-first tree over the
    face adjacency gives each face its flip relative to the root of its piece (accumulated
    by pointer jumping, vectorized); each piece then keeps the orientation most of its faces
    already had. (trimesh's own ``fix_winding`` needs networkx.)
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_tree, connected_components

    faces = mesh.faces
    n = len(faces)
    pairs = np.asarray(mesh.face_adjacency)
    if not len(pairs):
        return 0
    edges = np.asarray(mesh.face_adjacency_edges)

    def runs(face, u, v):  # does the face traverse the edge u -> v?
        f = faces[face]
        return ((f == u[:, None]) & (np.roll(f, -1, axis=1) == v[:, None])).any(axis=1)

    # two faces that run their shared edge the same way need opposite flips
    differ = runs(pairs[:, 0], edges[:, 0], edges[:, 1]) == runs(pairs[:, 1], edges[:, 0], edges[:, 1])
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n)).tocsr()
    n_pieces, piece = connected_components(graph, directed=False)
    # a virtual node n joined to one face of each piece makes a single breadth-first tree
    roots = np.unique(piece, return_index=True)[1]
    rows = np.concatenate([pairs[:, 0], np.full(len(roots), n)])
    cols = np.concatenate([pairs[:, 1], roots])
    differ = np.concatenate([differ, np.zeros(len(roots), dtype=bool)])
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n + 1, n + 1)).tocsr()
    tree = breadth_first_tree(graph, n, directed=False).tocoo()
    child = np.arange(n + 1)
    parent = child.copy()
    parent[tree.col] = tree.row
    key = np.minimum(rows, cols) * (n + 1) + np.maximum(rows, cols)
    order = np.argsort(key)
    link = np.minimum(child, parent) * (n + 1) + np.maximum(child, parent)
    found = np.searchsorted(key[order], link).clip(0, len(key) - 1)
    flip = np.where(parent != child, differ[order][found], False)
    while np.any(parent != parent[parent]):  # flip relative to the root: xor along the path
        flip = flip ^ np.where(parent != child, flip[parent], False)
        parent = parent[parent]
    flip = flip[:n]
    # keep each piece's majority orientation
    share = np.bincount(piece, weights=flip.astype(float), minlength=n_pieces) / np.bincount(piece)
    flip ^= share[piece] > 0.5
    if flip.any():
        mesh.faces = np.where(flip[:, None], faces[:, ::-1], faces)
    return int(flip.sum())


def _signed_volume(mesh) -> float:
    """Enclosed volume (mm^3), negative for an inside-out closed surface (cheaper than
    trimesh's mass properties, which also compute the inertia)."""
    tri = mesh.triangles - mesh.vertices.mean(axis=0)  # centred: less cancellation
    return float(np.einsum("ij,ij->", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])) / 6.0)


def _nondegenerate(mesh) -> np.ndarray:
    area = mesh.area_faces
    return mesh.nondegenerate_faces() & (area > 1e-14 * max(mesh.scale, 1e-300) ** 2)


def as_mesh(mesh, *, name: str = "mesh", scale: float = 1.0):
    """A checked ``trimesh.Trimesh`` from a path, a Trimesh or a ``(vertices, faces)`` pair.

    Parameters
    ----------
    mesh : str, path-like, trimesh.Trimesh or tuple (vertices (V, 3), faces (F, 3))
    name : str
        The argument's name, for error messages.
    scale : float
        Coordinate factor to mm.

    Returns
    -------
    trimesh.Trimesh
        A Trimesh that needs no repair is returned as is (its ray-casting caches are
        reused); otherwise a repaired copy (see :func:`load_mesh`).
    """
    return _prepare(mesh, name, scale)[0]


def _prepare(mesh, name: str, scale: float = 1.0):
    import trimesh

    if isinstance(mesh, (str, Path)):
        return _load(mesh, scale)
    if isinstance(mesh, trimesh.Trimesh):
        if len(mesh.faces) == 0:
            raise InputError(f"{name} is an empty mesh (0 faces); expected a triangle surface")
        if scale != 1.0:
            mesh = mesh.copy()
            mesh.apply_scale(_positive("scale", scale))
            return _repair(mesh, name, copy=False)
        return _repair(mesh, name, copy=True)
    if isinstance(mesh, (tuple, list)) and len(mesh) == 2:
        return _clean(mesh[0], mesh[1], name, _positive("scale", scale))
    raise InputError(f"{name} must be a mesh file path, a trimesh.Trimesh or a (vertices, faces) "
                     f"tuple, got {type(mesh).__name__}")


def concatenate_meshes(parts):
    """One mesh from labelled parts, with a label per face.

    Parameters
    ----------
    parts : mapping {label: mesh}
        Each mesh as accepted by :func:`as_mesh`, e.g.
        ``{"medial": "medial_tibia.stl", "lateral": "lateral_tibia.stl"}``.

    Returns
    -------
    mesh : trimesh.Trimesh
        The parts side by side (faces in the order of ``parts``).
    labels : ndarray of str, shape (F,)
        The part each face came from; pass it as ``labels`` to :func:`springs_from_meshes`.
    """
    import trimesh

    if not hasattr(parts, "items") or not parts:
        raise InputError(f"parts must be a non-empty mapping {{label: mesh}}, got {parts!r}")
    meshes = {label: as_mesh(m, name=f"parts[{label!r}]") for label, m in parts.items()}
    vertices, faces, offset = [], [], 0
    for m in meshes.values():
        vertices.append(m.vertices)
        faces.append(m.faces + offset)
        offset += len(m.vertices)
    mesh = trimesh.Trimesh(np.vstack(vertices), np.vstack(faces), process=False)
    labels = np.repeat(np.array([str(k) for k in meshes]), [len(m.faces) for m in meshes.values()])
    return mesh, labels


def check_pose(pose, name: str = "pose") -> np.ndarray | None:
    """Validate a 4x4 rigid transform (rotation with det +1, last row 0 0 0 1).

    Returns the pose as a float array, or None for None. Raises :class:`InputError`.
    """
    if pose is None:
        return None
    try:
        T = np.array(pose, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a 4x4 rigid transform, got {type(pose).__name__}") from None
    if T.shape != (4, 4):
        raise InputError(f"{name} must be a 4x4 rigid transform, got shape {T.shape}")
    if not np.isfinite(T).all():
        raise InputError(f"{name} must be finite, got NaN or inf")
    if not np.allclose(T[3], [0, 0, 0, 1], rtol=0, atol=1e-9):
        raise InputError(f"{name} must have last row (0, 0, 0, 1), got {T[3].tolist()}")
    R = T[:3, :3]
    error = float(np.abs(R.T @ R - np.eye(3)).max())
    if error > 1e-6:
        raise InputError(f"{name} is not rigid: its 3x3 block must be a rotation (R^T R = I), but "
                         f"|R^T R - I| = {error:.3g} (scaling or shear?)")
    det = float(np.linalg.det(R))
    if det < 0:
        raise InputError(f"{name} is not rigid: its 3x3 block is a reflection (det = {det:.3g}), "
                         f"expected a rotation with det +1")
    return T


# --------------------------------------------------------------------------------------------
# Ray casting
# --------------------------------------------------------------------------------------------
ENGINES = ("auto", "embree", "grid")


def _expand(starts: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """``concatenate([arange(s, s + c) for s, c in zip(starts, counts)])``, vectorized."""
    total = int(counts.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    offsets = np.repeat(np.cumsum(counts) - counts, counts)
    return np.repeat(starts, counts) + (np.arange(total) - offsets)


def _box_cells(lo: np.ndarray, hi: np.ndarray):
    """Every integer cell of the boxes ``lo..hi`` (inclusive, (B, 3)): ``(box, cell (C, 3))``."""
    span = np.maximum(hi - lo + 1, 0)
    n = span.prod(axis=1)
    box = np.repeat(np.arange(len(lo)), n)
    local = _expand(np.zeros(len(lo), dtype=np.int64), n)
    s = span[box]
    k = local % s[:, 2]
    j = (local // s[:, 2]) % s[:, 1]
    i = local // (s[:, 2] * s[:, 1])
    return box, lo[box] + np.column_stack([i, j, k])


class _GridCaster:
    """Exact float64 segment/triangle intersection with a uniform-grid broad phase.

    The fallback when Embree is missing, all numpy: triangles are binned in cubic cells of
    about one edge length, each ray is cut into cell-sized pieces, candidates come from the
    cells a piece's box covers, and a Moller-Trumbore test in float64 decides.
    """

    _CHUNK = 1 << 17  # candidate pairs tested at once: small chunks stay in cache

    def __init__(self, mesh):
        self.mesh = mesh
        self.triangles = np.asarray(mesh.triangles, dtype=float)
        v0 = self.triangles[:, 0]
        # (9, F): component rows, so that gathering candidates gives contiguous rows
        self.frames = np.ascontiguousarray(
            np.hstack([v0, self.triangles[:, 1] - v0, self.triangles[:, 2] - v0]).T)
        edges = np.asarray(mesh.edges_unique_length)
        self.cell = float(edges.mean()) if len(edges) else 1.0
        self.origin = np.asarray(mesh.bounds[0], dtype=float)
        while True:  # a few huge triangles must not flood the grid
            lo, hi = self._cells(self.triangles.min(axis=1), self.triangles.max(axis=1))
            if (hi - lo + 1).prod(axis=1).sum() <= 20 * len(self.triangles) + 10**6:
                break
            self.cell *= 2.0
        self.shape = hi.max(axis=0) + 1
        face, cells = _box_cells(lo, hi)
        key = self._key(cells)
        order = np.argsort(key, kind="stable")
        self.keys, self.faces = key[order], face[order]

    def _cells(self, lo, hi):
        pad = 1e-9 * self.cell
        return (np.floor((lo - self.origin - pad) / self.cell).astype(np.int64),
                np.floor((hi - self.origin + pad) / self.cell).astype(np.int64))

    def _key(self, cells):
        return (cells[:, 0] * self.shape[1] + cells[:, 1]) * self.shape[2] + cells[:, 2]

    def hits(self, origins, directions, t0, t1):
        """All crossings with ``t0 <= t <= t1`` (scalars or (R,)): ``(ray, face, t)``."""
        n = len(origins)
        t0 = np.broadcast_to(np.asarray(t0, dtype=float), (n,))
        t1 = np.broadcast_to(np.asarray(t1, dtype=float), (n,))
        count = np.maximum(np.ceil((t1 - t0) / self.cell), 1).astype(np.int64)
        ray = np.repeat(np.arange(n), count)
        step = _expand(np.zeros(n, dtype=np.int64), count)
        start = t0[ray] + step * self.cell
        end = np.minimum(start + self.cell, t1[ray])
        a = origins[ray] + start[:, None] * directions[ray]
        b = origins[ray] + end[:, None] * directions[ray]
        lo, hi = self._cells(np.minimum(a, b), np.maximum(a, b))
        lo, hi = np.maximum(lo, 0), np.minimum(hi, self.shape - 1)  # cells outside hold nothing
        piece, cells = _box_cells(lo, hi)
        keys = self._key(cells)
        first = np.searchsorted(self.keys, keys, "left")
        number = np.searchsorted(self.keys, keys, "right") - first
        out_ray, out_face, out_t = [], [], []
        rows_o, rows_d = np.ascontiguousarray(origins.T), np.ascontiguousarray(directions.T)
        bounds = np.searchsorted(np.cumsum(number), np.arange(0, int(number.sum()), self._CHUNK), "right")
        bounds = np.append(np.unique(bounds), len(keys))
        for lo_i, hi_i in zip(bounds[:-1], bounds[1:]):  # chunks of candidates, not of faces
            cand = _expand(first[lo_i:hi_i], number[lo_i:hi_i])
            r = ray[np.repeat(piece[lo_i:hi_i], number[lo_i:hi_i])]
            f = self.faces[cand]
            t, ok = _moller_trumbore(rows_o[:, r], rows_d[:, r], self.frames[:, f])
            ok &= (t >= t0[r]) & (t <= t1[r])
            out_ray.append(r[ok])
            out_face.append(f[ok])
            out_t.append(t[ok])
        if not out_ray:
            return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0)
        ray, face, t = np.concatenate(out_ray), np.concatenate(out_face), np.concatenate(out_t)
        # a triangle met from several cells is one crossing
        _, unique = np.unique(ray * len(self.triangles) + face, return_index=True)
        return ray[unique], face[unique], t[unique]

    def nearest(self, origins, directions, t_min, t_max):
        """The first crossing with ``t_min < t <= t_max`` per ray: ``(face, t)``, -1/NaN if none.

        Searched in growing windows so that most rays stop after a short segment.
        """
        n = len(origins)
        face, dist = np.full(n, -1, dtype=np.int64), np.full(n, np.nan)
        todo = np.arange(n)
        low, high = t_min, min(t_min + 4 * self.cell, t_max)
        while len(todo):
            ray, f, t = self.hits(origins[todo], directions[todo], low, high)
            keep = t > low if low == t_min else np.ones(len(t), dtype=bool)
            ray, f, t = ray[keep], f[keep], t[keep]
            pick = _first_per_ray(ray, t, len(todo))
            found = pick >= 0
            face[todo[found]], dist[todo[found]] = f[pick[found]], t[pick[found]]
            todo = todo[~found]
            if high >= t_max:
                break
            low, high = high, min(t_min + 2 * (high - t_min), t_max)
        return face, dist


def _moller_trumbore(origins, directions, frames):
    """Distance along each ray to its triangle's plane, and whether the ray meets the triangle.

    Arrays are by component: ``origins``, ``directions`` (3, n) and ``frames`` (9, n), each
    triangle as ``(v0, v1 - v0, v2 - v0)``; written out component by component because
    ``np.cross`` on (n, 3) arrays is several times slower.
    """
    ox, oy, oz = origins
    dx, dy, dz = directions
    ax, ay, az, bx, by, bz, cx, cy, cz = frames
    px, py, pz = dy * cz - dz * cy, dz * cx - dx * cz, dx * cy - dy * cx  # d x e2
    det = bx * px + by * py + bz * pz
    ok = np.abs(det) > 1e-12 * (bx * bx + by * by + bz * bz)
    inv = np.divide(1.0, det, out=np.zeros_like(det), where=ok)
    sx, sy, sz = ox - ax, oy - ay, oz - az
    u = (sx * px + sy * py + sz * pz) * inv
    qx, qy, qz = sy * bz - sz * by, sz * bx - sx * bz, sx * by - sy * bx  # s x e1
    v = (dx * qx + dy * qy + dz * qz) * inv
    t = (cx * qx + cy * qy + cz * qz) * inv
    tol = 1e-9  # edges and vertices belong to every triangle that shares them
    ok &= (u >= -tol) & (v >= -tol) & (u + v <= 1 + tol)
    return t, ok


class _EmbreeCaster:
    """Ray casting with Intel Embree through trimesh (float32 traversal, float64 distances)."""

    def __init__(self, intersector):
        self.intersector = intersector

    def hits(self, origins, directions, t0, t1):
        t0 = np.asarray(t0, dtype=float)
        start = origins + (t0[:, None] if t0.ndim else t0) * directions
        ray, face, t = _all_hits(self.intersector, start, directions)
        t = t + (t0[ray] if t0.ndim else t0)
        keep = t <= (np.asarray(t1)[ray] if np.ndim(t1) else t1)
        return ray[keep], face[keep], t[keep]

    def nearest(self, origins, directions, t_min, t_max):
        n = len(origins)
        ray, face, t = _all_hits(self.intersector, origins, directions)
        keep = (t > t_min) & (t <= t_max)
        ray, face, t = ray[keep], face[keep], t[keep]
        pick = _first_per_ray(ray, t, n)
        found = pick >= 0
        out_face, out_t = np.full(n, -1, dtype=np.int64), np.full(n, np.nan)
        out_face[found], out_t[found] = face[pick[found]], t[pick[found]]
        return out_face, out_t


def _has_embree() -> bool:
    try:
        from trimesh.ray import ray_pyembree  # noqa: F401
    except ImportError:
        return False
    return True


def _caster(mesh, engine: str):
    """The ray caster for ``mesh``: Embree when possible (``"auto"``), else the numpy grid."""
    if engine not in ENGINES:
        raise InputError(f"engine must be one of {ENGINES}, got {engine!r}")
    if engine == "grid" or (engine == "auto" and not _has_embree()):
        cache = getattr(mesh, "_cache", None)  # trimesh empties it when the mesh changes
        cached = cache["dea_opt_grid"] if cache is not None else None
        if cached is None:
            cached = _GridCaster(mesh)
            if cache is not None:
                cache["dea_opt_grid"] = cached
        return cached
    if not _has_embree():
        raise MissingDependencyError("engine='embree' needs the embreex package: pip install embreex "
                                     "(or pip install dea-opt[fast])")
    from trimesh.ray import ray_pyembree

    intersector = mesh.ray
    if not isinstance(intersector, ray_pyembree.RayMeshIntersector):
        intersector = ray_pyembree.RayMeshIntersector(mesh)
    return _EmbreeCaster(intersector)


def _all_hits(intersector, origins: np.ndarray, directions: np.ndarray):
    """Every crossing of the rays ``origins + t directions`` (t >= 0) with the mesh.

    Returns ``(ray, face, t)``: the ray index, the face index and the distance along the
    (unit) direction, each of shape (H,).
    """
    empty = (np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(0))
    if not len(origins):
        return empty
    face, ray, location = intersector.intersects_id(
        origins, directions, multiple_hits=True, return_locations=True)
    if not len(face):
        return empty
    ray = np.asarray(ray, dtype=np.int64)
    location = np.asarray(location, dtype=float).reshape(-1, 3)
    # distance recomputed in float64 from the hit's plane point (Embree works in float32)
    t = np.einsum("ij,ij->i", location - origins[ray], directions[ray])
    return ray, np.asarray(face, dtype=np.int64), t


def _first_per_ray(ray: np.ndarray, key: np.ndarray, n_rays: int) -> np.ndarray:
    """Per ray, the index of its hit with the smallest ``key``; -1 where the ray has none."""
    out = np.full(n_rays, -1, dtype=np.int64)
    if not len(ray):
        return out
    order = np.lexsort((key, ray))
    sorted_ray = ray[order]
    first = np.ones(len(order), dtype=bool)
    first[1:] = sorted_ray[1:] != sorted_ray[:-1]
    out[sorted_ray[first]] = order[first]
    return out


def _self_epsilon(mesh) -> float:
    """Distance below which a hit is the ray's own starting face (mm)."""
    return 1e-7 * max(float(mesh.scale), 1.0)


def _through(mesh, caster, origins, directions) -> np.ndarray:
    """Distance from points on ``mesh`` along inward ``directions`` to its far side.

    The nearest crossing beyond the starting face must leave the volume (its face normal
    along the ray); a ray that first enters (it left through a hole) gives NaN.
    """
    face, t = caster.nearest(origins, directions, _self_epsilon(mesh), np.inf)
    found = face >= 0
    leaves = np.zeros(len(face), dtype=bool)
    leaves[found] = np.einsum("ij,ij->i", mesh.face_normals[face[found]], directions[found]) > 0
    return np.where(leaves, t, np.nan)


def _to_bone(bone, caster, origins, directions) -> np.ndarray:
    """Distance along ``directions`` to the first crossing of a bone mesh; NaN if none."""
    return caster.nearest(origins, directions, _self_epsilon(bone), np.inf)[1]


def surface_thickness(mesh, faces=None, *, engine: str = "auto") -> np.ndarray:
    """Cartilage thickness of a closed surface, measured through itself.

    From each face centroid a ray goes along the inward normal (minus the face normal) to the
    far (bone) side of the same surface.

    Parameters
    ----------
    mesh : mesh as accepted by :func:`as_mesh`
        A closed (or nearly closed) cartilage surface with outward normals.
    faces : array_like of int, shape (K,), optional
        The faces to measure (default all).
    engine : {"auto", "embree", "grid"}

    Returns
    -------
    ndarray, shape (K,)
        Thickness in mm; NaN where the ray leaves through a hole or meets nothing.
    """
    m = as_mesh(mesh, name="mesh")
    faces = np.arange(len(m.faces)) if faces is None else _face_index("faces", faces, len(m.faces))
    return _through(m, _caster(m, engine), m.triangles_center[faces], -m.face_normals[faces])


def _face_index(name, faces, n_faces) -> np.ndarray:
    faces = np.asarray(faces)
    if faces.ndim != 1 or not np.issubdtype(faces.dtype, np.integer):
        raise InputError(f"{name} must be a 1-D array of face indices, got {faces.dtype} {faces.shape}")
    if len(faces) and (faces.min() < 0 or faces.max() >= n_faces):
        raise InputError(f"{name} must lie in [0, {n_faces - 1}], got [{faces.min()}, {faces.max()}]")
    return faces


# --------------------------------------------------------------------------------------------
# Springs from two meshes
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class SpringCast:
    """The springs cast from mesh 1 onto mesh 2, with what each ray met.

    Attributes
    ----------
    layer : SpringLayer
        The springs (see :func:`springs_from_meshes`).
    hit_face : ndarray of int, shape (N,)
        The face of mesh 2 each spring's ray met.
    hit_point : ndarray, shape (N, 3)
        Where it met it, in mesh 1's frame (mm); ``points + gap * normals``.
    thickness1, thickness2 : ndarray, shape (N,)
        The two cartilage thicknesses whose sum is ``layer.thickness`` (mm).
    mesh1, mesh2 : trimesh.Trimesh
        The checked meshes (mesh 2 in its own frame, before ``pose``).
    pose : ndarray, shape (4, 4)
        The rigid transform applied to mesh 2.
    """

    layer: SpringLayer
    hit_face: np.ndarray
    hit_point: np.ndarray
    thickness1: np.ndarray
    thickness2: np.ndarray
    mesh1: object
    mesh2: object
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))


def _window(name, value, lo, hi=None) -> float:
    if isinstance(value, bool) or not isinstance(value, Real) or not math.isfinite(value):
        raise InputError(f"{name} must be a finite number, got {value!r}")
    if value < lo or (hi is not None and value > hi):
        bound = f">= {lo}" if hi is None else f"in [{lo}, {hi}]"
        raise InputError(f"{name} must be {bound}, got {value!r}")
    return float(value)


def _per_face(values, name, mesh, kept) -> np.ndarray:
    """A per-face array given for the mesh as the user gave it, on the checked mesh's faces."""
    n_given = len(mesh.faces) if kept is None else kept[1]
    if values.ndim != 1 or len(values) != n_given:
        raise InputError(f"{name} must have one value per face of the mesh as given, shape "
                         f"({n_given},), got shape {values.shape}")
    return values if kept is None else values[kept[0]]


def _thickness(spec, name, mesh, kept, faces, origins, directions, engine) -> np.ndarray:
    """One side's thickness at the springs from a number, per-face array, bone mesh or None."""
    import trimesh

    if spec is None:
        return _through(mesh, _caster(mesh, engine), origins, directions)
    if isinstance(spec, (trimesh.Trimesh, str, Path)):
        bone = as_mesh(spec, name=f"{name} (bone mesh)")
        return _to_bone(bone, _caster(bone, engine), origins, directions)
    if isinstance(spec, Real) and not isinstance(spec, bool):
        if not math.isfinite(spec) or spec < 0:
            raise InputError(f"{name} must be a finite number >= 0 (mm), got {spec!r}")
        return np.full(len(faces), float(spec))
    try:
        values = np.array(spec, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be None (measure through the closed surface), a number, a "
                         f"per-face array of shape (F,) or a bone mesh, got {type(spec).__name__}") from None
    values = _per_face(values, name, mesh, kept)
    if not np.isfinite(values).all() or (values < 0).any():
        raise InputError(f"{name} must be finite and >= 0 (mm) at every face")
    return values[faces]


def _per_face_labels(labels, mesh, kept) -> np.ndarray | None:
    return None if labels is None else _per_face(np.asarray(labels), "labels", mesh, kept)


def cast_springs(mesh1, mesh2, *, thickness1=None, thickness2=None, pose=None,
                 max_gap: float = MAX_GAP, max_overlap: float = MAX_OVERLAP,
                 max_angle: float = MAX_ANGLE, flip: bool = False, labels=None,
                 engine: str = "auto") -> SpringCast:
    """Like :func:`springs_from_meshes`, also returning what each ray met (:class:`SpringCast`)."""
    m1, kept1 = _prepare(mesh1, "mesh1")
    m2, kept2 = _prepare(mesh2, "mesh2")
    T = check_pose(pose)
    T = np.eye(4) if T is None else T
    max_gap = _window("max_gap", max_gap, 0.0)
    max_overlap = _window("max_overlap", max_overlap, 0.0)
    max_angle = _window("max_angle", max_angle, 0.0, 90.0)
    face_labels = _per_face_labels(labels, m1, kept1)
    R, shift = T[:3, :3], T[:3, 3]

    centroids = m1.triangles_center
    normals = -m1.face_normals if flip else m1.face_normals
    # Rays go to mesh 2's own frame (x2 = R^T (x - shift)) so that its cached ray structures
    # serve every pose of a motion; distances along the rays do not change.
    origins2 = (centroids - shift) @ R
    directions2 = normals @ R
    # Start behind the centroid so that a centroid already inside mesh 2 still finds the face
    # it went through: the line is cast both ways.
    back = max_overlap + _self_epsilon(m2)
    reach = max(max_gap, back) + _self_epsilon(m2)
    ray, face, t = _caster(m2, engine).hits(origins2, directions2, -back, reach)
    # Only faces of mesh 2 that face the ray count (never the back of a curved surface); of
    # those, the nearest to the spring.
    cos = -np.einsum("ij,ij->i", m2.face_normals[face], directions2[ray])
    facing = cos > 0
    ray, face, t, cos = ray[facing], face[facing], t[facing], cos[facing]
    pick = _first_per_ray(ray, np.abs(t), len(centroids))
    has = pick >= 0
    hit = pick[has]
    inside = (t[hit] >= -max_overlap) & (t[hit] <= max_gap)
    aligned = cos[hit] >= math.cos(math.radians(max_angle)) - 1e-12
    ok = inside & aligned
    if not ok.any():
        _raise_no_springs(m1, m2, t[hit], cos[hit], inside, origins2, max_gap, max_overlap, max_angle)
    sel = np.flatnonzero(has)[ok]
    hit = hit[ok]
    gap, hit_face = t[hit], face[hit]
    hit_point2 = origins2[sel] + gap[:, None] * directions2[sel]

    h1 = _thickness(thickness1, "thickness1", m1, kept1, sel, centroids[sel], -normals[sel], engine)
    h2 = _thickness(thickness2, "thickness2", m2, kept2, hit_face, hit_point2,
                    -m2.face_normals[hit_face], engine)
    total = h1 + h2
    good = np.isfinite(total) & (total > 0)
    if not good.all():
        _warn_dropped(h1, h2, good, thickness1, thickness2)
        if not good.any():
            raise InputError("no spring has a positive, measurable thickness: thickness1 + thickness2 "
                             "must be > 0 (mm); check that closed surfaces are closed and oriented "
                             "outward, or give the thickness as a number")
        sel, gap, hit_face, hit_point2 = sel[good], gap[good], hit_face[good], hit_point2[good]
        h1, h2, total = h1[good], h2[good], total[good]

    layer = SpringLayer(
        centroids[sel], normals[sel], m1.area_faces[sel], total, gap,
        source_face=sel.astype(np.int64), surface=(m1.vertices, m1.faces),
        labels=None if face_labels is None else face_labels[sel],
    )
    hit_point = hit_point2 @ R.T + shift
    return SpringCast(layer, hit_face, hit_point, h1, h2, m1, m2, T)


def _warn_dropped(h1, h2, good, spec1, spec2) -> None:
    parts = []
    for name, h, spec in (("thickness1", h1, spec1), ("thickness2", h2, spec2)):
        bad = int((~np.isfinite(h)).sum())
        if bad:
            how = ("the inward ray left the surface through a hole or met nothing" if spec is None
                   else "the inward ray never met the bone mesh")
            parts.append(f"{name} could not be measured at {bad} springs ({how})")
    zero = int((np.isfinite(h1 + h2) & (h1 + h2 <= 0)).sum())
    if zero:
        parts.append(f"{zero} springs have zero total thickness")
    warnings.warn("; ".join(parts) + f"; dropped {int((~good).sum())} of {len(good)} springs",
                  stacklevel=4)


def _closest_distance(points: np.ndarray, mesh) -> float:
    """Smallest distance from ``points`` to the surface of ``mesh`` (mm).

    A k-d tree over the mesh's vertices and centroids picks the 64 nearest candidates, whose
    exact closest points on the surface are then computed.
    """
    from scipy.spatial import cKDTree

    tree = cKDTree(np.vstack([mesh.vertices, mesh.triangles_center]))
    rough, _ = tree.query(points)
    best = np.argsort(rough)[:64]
    _, distance, _ = mesh.nearest.on_surface(points[best])
    return float(distance.min())


def _raise_no_springs(m1, m2, t, cos, inside, origins2, max_gap, max_overlap, max_angle):
    window = (f"the proximity window -max_overlap={max_overlap:g} <= gap <= max_gap={max_gap:g} mm "
              f"with max_angle={max_angle:g} deg")
    if len(t):
        if inside.any():
            best = float(np.degrees(np.arccos(np.clip(cos[inside].max(), -1, 1))))
            detail = (f"faces meet within the gap window but their normals are at least {best:.3g} deg "
                      f"from facing each other (raise max_angle)")
        else:
            ahead = t[t > max_gap]
            detail = (f"the smallest distance found along the normals is {ahead.min():.4g} mm "
                      f"(raise max_gap)" if len(ahead) else
                      f"the shallowest overlap found is {-t.max():.4g} mm (raise max_overlap)")
    else:
        detail = (f"no normal of mesh1 meets a face of mesh2 that faces it; the smallest distance "
                  f"found between the meshes is {_closest_distance(origins2, m2):.4g} mm (check pose, "
                  f"flip, units, and that both meshes are in the same frame)")
    raise InputError(f"mesh1 and mesh2 never face each other within {window}: {detail}")


def springs_from_meshes(mesh1, mesh2, *, thickness1=None, thickness2=None, pose=None,
                        max_gap: float = MAX_GAP, max_overlap: float = MAX_OVERLAP,
                        max_angle: float = MAX_ANGLE, flip: bool = False, labels=None,
                        engine: str = "auto") -> SpringLayer:
    """Springs between two cartilage surfaces, by ray casting (JAM's elastic foundation).

    One spring per articular face of mesh 1: a face whose normal ray meets a face of mesh 2
    that faces it inside the proximity window ``-max_overlap <= gap <= max_gap`` with the two
    normals within ``max_angle`` of facing each other.

    Parameters
    ----------
    mesh1, mesh2 : path, trimesh.Trimesh or (vertices, faces)
        Body 1's surface (carries the springs) and body 2's surface, in mm.
    thickness1, thickness2 : None, float, array_like (F,) or mesh, default None
        Each cartilage's thickness (mm): ``None`` measures it through the closed surface itself
        (from the face along the inward normal to the far, bone side: at the spring's face
        for mesh 1, at the point the ray met for mesh 2); a number applies everywhere (0 for a
        rigid body); an array gives one value per face of that mesh as given; a mesh (or
        path) is a bone surface, reached by a ray along the inward normal.
    pose : array_like (4, 4), optional
        Rigid transform applied to mesh 2 (e.g. one frame of a motion), in mesh 1's frame.
    max_gap, max_overlap : float
        Proximity window (mm): the largest gap and the largest initial overlap kept.
    max_angle : float
        Largest angle (deg, in [0, 90]) between a spring's normal and the reversed normal of
        the face of mesh 2 its ray meets.
    flip : bool
        Reverse mesh 1's normals (for an open surface wound away from mesh 2).
    labels : array_like (F,), optional
        A region label per face of mesh 1 (e.g. from :func:`concatenate_meshes`), carried to
        the springs.
    engine : {"auto", "embree", "grid"}
        Ray casting: Embree when importable (auto), or the numpy uniform-grid caster (exact
        float64 ray/triangle tests; slower, no compiled dependency).

    Returns
    -------
    SpringLayer
        ``points`` (N, 3): face centroids (mm); ``normals`` (N, 3): face normals, toward mesh
        2; ``areas`` (N,): face areas (mm^2); ``gap`` (N,): signed distance along the normal
        to mesh 2 (mm, negative where the meshes overlap); ``thickness`` (N,): ``h1 + h2`` (mm);
        ``source_face`` (N,): the face of ``surface`` = mesh 1 (vertices, faces) under each
        spring; ``labels`` as given.

    Raises
    ------
    InputError
        Bad meshes, a pose that is not rigid, a bad window or thickness, or no face of mesh 1
        facing mesh 2 within the window (the message gives the smallest distance found).
    """
    return cast_springs(mesh1, mesh2, thickness1=thickness1, thickness2=thickness2, pose=pose,
                        max_gap=max_gap, max_overlap=max_overlap, max_angle=max_angle, flip=flip,
                        labels=labels, engine=engine).layer


# --------------------------------------------------------------------------------------------
# Casting both ways
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class TwoWaySprings:
    """Springs cast from mesh 1 onto mesh 2 (``forward``) and from mesh 2 onto mesh 1 (``backward``).

    ``forward`` has body 1 = mesh 1; ``backward`` has body 1 = mesh 2 (in its posed position),
    so its normals point from mesh 2 to mesh 1. ``asymmetry`` compares the two (see
    :func:`springs_both_ways`).
    """

    forward: SpringLayer
    backward: SpringLayer
    asymmetry: dict


def _layer_measures(layer: SpringLayer) -> dict:
    stiffness = layer.areas / layer.thickness  # N/mm per MPa of modulus
    return {
        "n_springs": len(layer),
        "area": float(layer.areas.sum()),
        "stiffness": float(stiffness.sum()),
        "stiffness_vector": stiffness @ layer.normals,
    }


def springs_both_ways(mesh1, mesh2, *, thickness1=None, thickness2=None, pose=None, labels1=None,
                      labels2=None, **options) -> TwoWaySprings:
    """Cast springs from mesh 1 onto mesh 2 and from mesh 2 onto mesh 1 (JAM's ``flip_meshes``).

    With matching meshes the two layers describe the same cartilage contact; how much they
    differ measures the error of the discretization (and of choosing which mesh casts).

    Parameters
    ----------
    mesh1, mesh2, thickness1, thickness2, pose
        As in :func:`springs_from_meshes`; the backward cast uses mesh 2 in its posed position.
    labels1, labels2 : array_like, optional
        Per-face labels of mesh 1 and of mesh 2.
    **options
        ``max_gap``, ``max_overlap``, ``max_angle``, ``engine`` (``flip`` is not allowed).

    Returns
    -------
    TwoWaySprings
        ``asymmetry`` holds, for each direction, the number of springs, the total spring area
        (mm^2) and the stiffness ``sum(A/h)`` (mm, times the modulus in MPa gives N/mm), and
        ``area``, ``stiffness``: the relative differences ``|a - b| / max(a, b)``, and
        ``direction``: ``|s_f + s_b| / max(|s_f|, |s_b|)`` of the stiffness-weighted normal
        sums ``s = sum(A/h n)``, which point opposite ways when the two casts agree.
    """
    if "flip" in options:
        raise InputError("flip is not supported by springs_both_ways; orient both meshes outward")
    m2, kept2 = _prepare(mesh2, "mesh2")
    T = check_pose(pose)
    posed = m2
    if T is not None:
        posed = m2.copy()
        posed.apply_transform(T)
    if kept2 is not None:  # per-face arrays of mesh 2 refer to its faces as given
        thickness2 = _subset(thickness2, "thickness2", m2, kept2)
        labels2 = _subset(labels2, "labels2", m2, kept2)
    forward = springs_from_meshes(mesh1, posed, thickness1=thickness1, thickness2=thickness2,
                                  labels=labels1, **options)
    backward = springs_from_meshes(posed, mesh1, thickness1=thickness2, thickness2=thickness1,
                                   labels=labels2, **options)
    f, b = _layer_measures(forward), _layer_measures(backward)

    def rel(a, b):
        return abs(a - b) / max(abs(a), abs(b), 1e-300)

    sf, sb = f.pop("stiffness_vector"), b.pop("stiffness_vector")
    asymmetry = {
        "forward": f,
        "backward": b,
        "area": rel(f["area"], b["area"]),
        "stiffness": rel(f["stiffness"], b["stiffness"]),
        "direction": float(np.linalg.norm(sf + sb) / max(np.linalg.norm(sf), np.linalg.norm(sb), 1e-300)),
    }
    return TwoWaySprings(forward, backward, asymmetry)


def _subset(spec, name, mesh, kept):
    import trimesh

    if spec is None or isinstance(spec, (Real, str, Path, trimesh.Trimesh)):
        return spec
    return _per_face(np.asarray(spec), name, mesh, kept)
