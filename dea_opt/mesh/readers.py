"""Reading triangle surfaces: STL, OBJ, PLY, OFF (trimesh), legacy VTK (parsed here), VTP (vtk).

Every reader returns ``(vertices (V, 3), faces (F, 3))``; :func:`load_mesh` and
:func:`as_mesh` then check and repair the mesh (:mod:`dea_opt.mesh.repair`). Lengths in mm
after ``scale``.
"""

from __future__ import annotations

from os import PathLike
from pathlib import Path

import numpy as np

from .._checks.inputs import number_in_range
from ..errors import InputError, MissingDependencyError
from .budget import check_file_size
from .legacy_vtk import parse_vtk_polydata
from .repair import check_size, clean, repair
from .sniff import EXPECTED, check_content, check_path

__all__ = ["LOADERS", "as_mesh", "concatenate_meshes", "load_mesh"]

_VTK_EXTRA = "pip install dea-opt[vtk]"


def _read_with_trimesh(path: Path, kind: str) -> tuple[np.ndarray, np.ndarray]:
    import trimesh

    try:
        loaded = trimesh.load(str(path), file_type=kind, force="mesh", process=False)
    except ImportError as exc:
        if getattr(exc, "name", None) != "charset_normalizer":
            raise InputError(f"mesh file {path} could not be read as {kind.upper()}: {exc}") from exc
        # trimesh guesses the encoding of text that is not UTF-8 with an optional package
        raise InputError(
            f"mesh file {path} could not be read as {kind.upper()}: its bytes are not text in "
            f"UTF-8 or another encoding trimesh reads; expected {EXPECTED[path.suffix.lower()]}"
        ) from exc
    except Exception as exc:  # trimesh raises many types for a malformed file
        raise InputError(
            f"mesh file {path} could not be read as {kind.upper()}: {type(exc).__name__}: {exc}; "
            f"expected {EXPECTED[path.suffix.lower()]}"
        ) from exc
    if not isinstance(loaded, trimesh.Trimesh):  # e.g. an empty scene or a point cloud
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    return np.asarray(loaded.vertices), np.asarray(loaded.faces)


def _read_vtk(path: Path, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """Legacy ``.vtk``: POLYDATA parsed here (no dependency); other datasets via meshio."""
    try:
        parsed = parse_vtk_polydata(path)
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
    if isinstance(path, bytes) or not isinstance(path, (str, PathLike)):
        raise InputError(f"path must be a file path (str or path-like), got {type(path).__name__}")
    shown = str(path) if "\0" not in str(path) else repr(str(path))
    suffix = Path(str(path).replace("\0", "")).suffix.lower()
    if suffix not in LOADERS:
        raise InputError(
            f"mesh file {shown} has unknown extension {suffix or '(none)'!r}; expected one of "
            f"{', '.join(sorted(LOADERS))}"
        )
    path = check_path(path)
    scale = number_in_range("scale", scale, 0, low_open=True)
    check_file_size(path)
    try:
        check_content(path)
    except OSError as exc:
        raise InputError(
            f"mesh file {path} could not be read ({exc.strerror or exc}); expected {EXPECTED[suffix]}"
        ) from None
    vertices, faces = LOADERS[suffix](path, suffix[1:])
    return clean(vertices, faces, f"mesh file {path}", scale)


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
        scale = number_in_range("scale", scale, 0, low_open=True)
        vertices = np.asarray(mesh.vertices)
        if not np.isfinite(vertices).all():
            raise InputError(f"{name}: vertices must be finite, found NaN or inf")
        check_size(vertices * scale if scale != 1.0 else vertices, name)
        if scale != 1.0:
            mesh = mesh.copy()
            mesh.apply_scale(scale)
            return repair(mesh, name, copy=False)
        return repair(mesh, name, copy=True)
    if isinstance(mesh, (tuple, list)) and len(mesh) == 2:
        return clean(mesh[0], mesh[1], name, number_in_range("scale", scale, 0, low_open=True))
    raise InputError(
        f"{name} must be a mesh file path, a trimesh.Trimesh or a (vertices, faces) tuple, got {type(mesh).__name__}"
    )


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
