"""Results a user can look at: ParaView files, CSV tables, JSON summaries and pressure maps.

Every file goes through :func:`write_atomic` (a temporary file in the target's directory,
``fsync``, then :func:`os.replace`), so an interrupted run leaves either the old file or
the new one, never half of one. The temporary files are hidden (``.name.<random>.tmp.ext``)
and removed when the writer fails.

=====================  ===========================================================
``to_vtk``             the contact surface with cell data, ``.vtu`` or ``.vtp``
``to_csv``             one row per spring (columns in :data:`CSV_COLUMNS`)
``to_json``            the headline numbers, regions and certificate
``plot_pressure``      a PNG pressure map
``write_results``      all four into one directory
``read_vtk``,          read back what the writers wrote, for round trips
``read_csv``,
``read_json``
=====================  ===========================================================

Units: mm, mm^2, N, N mm, MPa; strain is dimensionless.
"""

from __future__ import annotations

import base64
import contextlib
import json
import math
import os
import secrets
import stat
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from .errors import InputError, MissingDependencyError

__all__ = [
    "CSV_COLUMNS",
    "SurfaceData",
    "atomic_open",
    "atomic_path",
    "best_fit_frame",
    "contact_surface",
    "label_codes",
    "plot_pressure",
    "read_csv",
    "read_json",
    "read_vtk",
    "summary_dict",
    "to_csv",
    "to_json",
    "to_vtk",
    "vtk_differences",
    "write_atomic",
    "write_results",
]


# --- atomic writes ----------------------------------------------------------------------
def _as_path(path, argument: str = "path") -> Path:
    """``path`` as a :class:`Path` to a file (not a directory), or a named InputError."""
    if isinstance(path, bytes):
        path = os.fsdecode(path)
    if not isinstance(path, (str, os.PathLike)):
        raise InputError(f"{argument} must be a file path (str or os.PathLike), got {type(path).__name__}")
    target = Path(path)
    if not target.name or target.name in (".", ".."):
        raise InputError(f"{argument} must name a file, got {str(path)!r}")
    if target.is_dir():
        raise InputError(f"{argument} must be a file path, got the directory {str(target)!r}")
    return target


def _reserve_temporary(target: Path, argument: str) -> Path:
    """Create an empty hidden file beside ``target`` (mode from ``target`` or the umask)."""
    parent = target.parent
    for _ in range(100):
        tmp = parent / f".{target.name}.{secrets.token_hex(4)}.tmp{target.suffix}"
        try:
            fd = os.open(tmp, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666)
        except FileExistsError:
            continue
        except OSError as exc:
            raise InputError(
                f"{argument}: cannot write in the directory {str(parent)!r} ({exc.strerror or exc})"
            ) from None
        os.close(fd)
        with contextlib.suppress(OSError):
            os.chmod(tmp, stat.S_IMODE(target.stat().st_mode))
        return tmp
    raise InputError(f"{argument}: could not create a temporary file in {str(parent)!r}")  # pragma: no cover


def _fsync(path: Path, directory: bool = False) -> None:
    flags = os.O_RDONLY if (directory or os.name != "nt") else os.O_RDWR
    try:
        fd = os.open(path, flags)
    except OSError:
        if directory:  # some platforms cannot open directories; the rename still happened
            return
        raise
    try:
        os.fsync(fd)
    except OSError:
        if not directory:
            raise
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_path(path, *, argument: str = "path"):
    """Context manager yielding a temporary path that replaces ``path`` on success.

    The temporary file lies in the directory of ``path`` (created with its parents when
    missing) and already exists, empty; write it by name (any writer that opens a file
    by name works). On a clean exit it is fsynced and renamed over ``path`` with
    :func:`os.replace`; on an exception it is removed and ``path`` is left as it was.
    The temporary name keeps the extension of ``path``; writers that insist on adding
    their own extension (``numpy.save``) must be told not to.

    Parameters
    ----------
    path : str or os.PathLike
        The file to (re)write.
    argument : str
        The argument name used in error messages.

    Yields
    ------
    pathlib.Path
        The temporary file to write.

    Raises
    ------
    InputError
        ``path`` is not a path, is a directory, or its directory cannot be created or
        written.
    """
    target = _as_path(path, argument)
    parent = target.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(
            f"{argument}: cannot create the directory {str(parent)!r} ({exc.strerror or exc})"
        ) from None
    tmp = _reserve_temporary(target, argument)
    try:
        yield tmp
        _fsync(tmp)
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    _fsync(parent, directory=True)


@contextlib.contextmanager
def atomic_open(path, mode: str = "w", *, encoding: str | None = None, newline: str | None = None,
                argument: str = "path"):
    """``open`` for writing, atomically: the file appears complete or not at all.

    Parameters
    ----------
    path : str or os.PathLike
    mode : {"w", "wb"}
        Text or binary.
    encoding : str, optional
        Text encoding; default UTF-8 in text mode.
    newline : str, optional
        As for :func:`open` (use ``""`` for :mod:`csv`).
    argument : str
        The argument name used in error messages.

    Yields
    ------
    file object
    """
    if mode not in ("w", "wb"):
        raise InputError(f"mode must be 'w' or 'wb', got {mode!r}")
    binary = mode == "wb"
    if not binary and encoding is None:
        encoding = "utf-8"
    with atomic_path(path, argument=argument) as tmp:
        with open(tmp, "wb" if binary else "w", encoding=encoding, newline=newline) as handle:
            yield handle


def write_atomic(path, writer, *, argument: str = "path") -> Path:
    """Write ``path`` atomically with ``writer(temporary_path)``.

    Parameters
    ----------
    path : str or os.PathLike
        The file to (re)write; missing parent directories are created.
    writer : callable
        Called once with the temporary :class:`pathlib.Path` (same directory and
        extension as ``path``) and must write the whole file there. If it raises, the
        temporary file is removed, ``path`` keeps its old contents and the exception
        propagates.
    argument : str
        The argument name used in error messages.

    Returns
    -------
    pathlib.Path
        ``path``.

    Examples
    --------
    >>> write_atomic("out/table.txt", lambda tmp: tmp.write_text("hello"))  # doctest: +SKIP
    """
    if not callable(writer):
        raise InputError(f"writer must be callable, got {type(writer).__name__}")
    with atomic_path(path, argument=argument) as tmp:
        writer(tmp)
    return Path(path)


def write_data(path, data, *, argument: str = "path") -> Path:
    """Write ``data`` (``str`` as UTF-8, or ``bytes``) to ``path`` atomically; return the path."""

    def writer(tmp) -> None:
        if isinstance(data, (bytes, bytearray)):
            Path(tmp).write_bytes(data)
        else:
            with open(tmp, "w", encoding="utf-8", newline="") as handle:
                handle.write(data)

    return write_atomic(path, writer, argument=argument)


def _require(module: str, feature: str):
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        raise MissingDependencyError(
            f"{feature} needs {module.split('.')[0]}; install it with "
            f"`pip install {module.split('.')[0]}` (or reinstall dea-opt with its dependencies)"
        ) from None


# --- the contact surface as a mesh ------------------------------------------------------
@dataclass
class SurfaceData:
    """A mesh with cell data: what :func:`to_vtk` writes and :func:`read_vtk` returns.

    Attributes
    ----------
    points : ndarray, shape (P, 3)
        Vertex coordinates (mm).
    cells : ndarray of int64, shape (C, 3) or (C, 1)
        Triangles, or one vertex per spring.
    cell_type : {"triangle", "vertex"}
    cell_data : dict {name: ndarray, shape (C,) or (C, 3)}
        See :func:`contact_surface` for the names and units.
    """

    points: np.ndarray
    cells: np.ndarray
    cell_type: str
    cell_data: dict = field(default_factory=dict)


def _label_data(labels: np.ndarray) -> np.ndarray:
    """Integer labels as int64; any other labels as codes into ``numpy.unique(labels)``."""
    if np.issubdtype(labels.dtype, np.integer) or labels.dtype == bool:
        return labels.astype(np.int64)
    text = labels.astype(str)
    return np.searchsorted(np.unique(text), text).astype(np.int64)


def label_codes(labels) -> dict:
    """``{label: code}`` of the integer ``label`` field of :func:`to_vtk` for text labels."""
    text = np.asarray(labels).astype(str)
    return {name: i for i, name in enumerate(np.unique(text).tolist())}


def _spring_fields(solution) -> dict:
    layer = solution.problem.layer
    data = {
        "pressure": np.asarray(solution.pressure, dtype=float),
        "strain": np.asarray(solution.strain, dtype=float),
        "gap": layer.gap,
        "thickness": layer.thickness,
        "in_contact": solution.in_contact.astype(np.uint8),
        "spring_force": np.asarray(solution.spring_force, dtype=float),
        "normal": layer.normals,
        "area": layer.areas,
    }
    if layer.source_face is not None:
        data["source_face"] = layer.source_face.astype(np.int64)
    if layer.labels is not None:
        data["label"] = _label_data(layer.labels)
    return {name: np.ascontiguousarray(value) for name, value in data.items()}


def _checked_faces(layer) -> tuple:
    vertices, faces = layer.surface
    faces = faces.astype(np.int64)
    if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise InputError(
            f"layer.surface faces must index its {len(vertices)} vertices, got indices "
            f"{faces.min()}..{faces.max()}"
        )
    source = layer.source_face.astype(np.int64)
    if source.size and (source.min() < 0 or source.max() >= len(faces)):
        raise InputError(
            f"layer.source_face must index the {len(faces)} surface faces, got "
            f"{source.min()}..{source.max()}"
        )
    return vertices, faces, source


def contact_surface(solution, *, cells: str = "springs") -> SurfaceData:
    """The contact surface of ``solution`` as a mesh with cell data, ready to write.

    Parameters
    ----------
    solution : Solution
    cells : {"springs", "surface"}
        ``"springs"`` (default): one cell per spring, in spring order, so cell ``i`` is
        spring ``i``. When the layer has ``surface`` and ``source_face``, the cells are
        the springs' source faces (triangles; vertices not used by them are dropped);
        otherwise each spring is a VTK_VERTEX cell at its point.
        ``"surface"``: every face of ``layer.surface``, unused vertices included; faces
        without a spring have ``spring`` -1, ``label`` -1 and 0 in every other field
        (threshold ``spring >= 0`` in ParaView to hide them). Needs ``surface`` and
        ``source_face`` and at most one spring per face.

    Returns
    -------
    SurfaceData
        Cell data (shape (C,) unless noted):

        ==============  ========  =========================================================
        name            unit      meaning
        ==============  ========  =========================================================
        pressure        MPa       contact pressure ``-sigma`` (>= 0)
        strain          1         spring strain ``eps`` (< 0 in compression)
        gap             mm        initial gap along the normal (< 0 for an overlap)
        thickness       mm        unloaded spring length
        in_contact      1         1 where ``strain < 0``, else 0 (uint8)
        spring_force    N         ``-pressure * area``, tension positive (<= 0)
        normal          1         spring direction, body 1 to body 2, shape (C, 3)
        area            mm^2      the area the spring stands for
        source_face     -         index of the face in ``layer.surface`` (when known)
        label           -         integer labels as given; text labels as codes into
                                  their sorted unique values (:func:`label_codes`)
        spring          -         spring index, -1 for none (``cells="surface"`` only)
        ==============  ========  =========================================================
    """
    layer = solution.problem.layer
    data = _spring_fields(solution)
    has_faces = layer.surface is not None and layer.source_face is not None
    if cells not in ("springs", "surface"):
        raise InputError(f"cells must be 'springs' or 'surface', got {cells!r}")
    if cells == "surface":
        if not has_faces:
            raise InputError(
                "cells='surface' needs a layer with surface and source_face; use cells='springs'"
            )
        return _whole_surface(layer, data)
    if not has_faces:
        n = len(layer)
        return SurfaceData(layer.points.copy(), np.arange(n, dtype=np.int64)[:, None], "vertex", data)
    vertices, faces, source = _checked_faces(layer)
    triangles = faces[source]
    used, inverse = np.unique(triangles, return_inverse=True)
    return SurfaceData(vertices[used], inverse.reshape(-1, 3).astype(np.int64), "triangle", data)


def _whole_surface(layer, data) -> SurfaceData:
    vertices, faces, source = _checked_faces(layer)
    if len(np.unique(source)) != len(source):
        raise InputError(
            "cells='surface' needs at most one spring per face, but layer.source_face repeats "
            "faces; use cells='springs'"
        )
    n_faces = len(faces)
    spring = np.full(n_faces, -1, dtype=np.int64)
    spring[source] = np.arange(len(source))
    out = {}
    for name, value in data.items():
        if name == "source_face":
            continue
        fill = -1 if name == "label" else 0  # no NaN: VTK cannot read NaN from ASCII files
        full = np.full((n_faces,) + value.shape[1:], fill, dtype=value.dtype)
        full[source] = value
        out[name] = full
    out["source_face"] = np.arange(n_faces, dtype=np.int64)
    out["spring"] = spring
    return SurfaceData(vertices.copy(), faces, "triangle", out)


# --- VTK --------------------------------------------------------------------------------
_VTK_TYPES = {
    np.dtype(np.float64): "Float64", np.dtype(np.float32): "Float32",
    np.dtype(np.int64): "Int64", np.dtype(np.int32): "Int32", np.dtype(np.int16): "Int16",
    np.dtype(np.int8): "Int8", np.dtype(np.uint64): "UInt64", np.dtype(np.uint32): "UInt32",
    np.dtype(np.uint16): "UInt16", np.dtype(np.uint8): "UInt8",
}
_NUMPY_TYPES = {v: k for k, v in _VTK_TYPES.items()}
_VTK_EXTENSIONS = (".vtu", ".vtp")


def _vtk_path(path) -> tuple:
    target = _as_path(path)
    ext = target.suffix.lower()
    if ext not in _VTK_EXTENSIONS:
        raise InputError(
            f"path must end in .vtu (UnstructuredGrid) or .vtp (PolyData), got {str(path)!r}"
        )
    return target, ext


def to_vtk(solution, path, *, cells: str = "springs", binary: bool = True) -> Path:
    """Write the contact surface with its cell data for ParaView.

    Parameters
    ----------
    solution : Solution
    path : str or os.PathLike
        ``.vtu`` (VTK XML UnstructuredGrid, written by meshio) or ``.vtp`` (VTK XML
        PolyData, written here). Both open in ParaView; :func:`read_vtk` reads both back,
        and ``meshio.read`` reads the ``.vtu``.
    cells : {"springs", "surface"}
        Which cells to write; see :func:`contact_surface` (fields, units, and what faces
        without a spring carry).
    binary : bool
        Base64 binary (default; exact, zlib-compressed in ``.vtu``) or ASCII (``.vtu``
        ASCII keeps 12 significant digits, ``.vtp`` ASCII all 17).

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    InputError
        ``path`` has another extension or cannot be written; ``cells`` is unknown.
    """
    target, ext = _vtk_path(path)
    surface = contact_surface(solution, cells=cells)
    if ext == ".vtu":
        meshio = _require("meshio", "writing .vtu")
        mesh = meshio.Mesh(
            surface.points,
            [(surface.cell_type, surface.cells)],
            cell_data={name: [value] for name, value in surface.cell_data.items()},
        )
        return write_atomic(target, lambda tmp: meshio.write(tmp, mesh, file_format="vtu", binary=binary))
    return write_atomic(target, lambda tmp: _write_vtp(tmp, surface, binary=binary))


def _data_array(name: str, values: np.ndarray, binary: bool, indent: str) -> str:
    values = np.ascontiguousarray(values)
    vtk_type = _VTK_TYPES.get(values.dtype)
    if vtk_type is None:
        raise InputError(f"cell data {name!r} has dtype {values.dtype}, which VTK cannot store")
    components = f' NumberOfComponents="{values.shape[1]}"' if values.ndim == 2 else ""
    head = f'{indent}<DataArray type="{vtk_type}" Name={quoteattr(name)}{components}'
    if binary:
        raw = values.astype(values.dtype.newbyteorder("<"), copy=False).tobytes()
        text = base64.b64encode(np.uint64(len(raw)).astype("<u8").tobytes() + raw).decode("ascii")
        return f'{head} format="binary">{text}</DataArray>\n'
    flat = values.ravel().tolist()
    text = " ".join(repr(float(v)) if vtk_type.startswith("Float") else str(int(v)) for v in flat)
    return f'{head} format="ascii">{text}</DataArray>\n'


def _write_vtp(path, surface: SurfaceData, *, binary: bool = True) -> None:
    """Write ``surface`` as VTK XML PolyData (inline data, no compression)."""
    n_cells, per_cell = surface.cells.shape
    kind = "Verts" if surface.cell_type == "vertex" else "Polys"
    counts = {"Verts": 0, "Lines": 0, "Strips": 0, "Polys": 0}
    counts[kind] = n_cells
    offsets = per_cell * np.arange(1, n_cells + 1, dtype=np.int64)
    scalars = ' Scalars="pressure"' if "pressure" in surface.cell_data else ""
    parts = [
        '<?xml version="1.0"?>\n',
        '<VTKFile type="PolyData" version="1.0" byte_order="LittleEndian" header_type="UInt64">\n',
        "  <PolyData>\n",
        f'    <Piece NumberOfPoints="{len(surface.points)}" '
        + " ".join(f'NumberOf{k}="{v}"' for k, v in counts.items())
        + ">\n",
        "      <Points>\n",
        _data_array("Points", surface.points.astype(np.float64), binary, "        "),
        "      </Points>\n",
        f"      <{kind}>\n",
        _data_array("connectivity", surface.cells.astype(np.int64).ravel(), binary, "        "),
        _data_array("offsets", offsets, binary, "        "),
        f"      </{kind}>\n",
        f"      <CellData{scalars}>\n",
        *(_data_array(name, value, binary, "        ") for name, value in surface.cell_data.items()),
        "      </CellData>\n",
        "    </Piece>\n",
        "  </PolyData>\n",
        "</VTKFile>\n",
    ]
    with open(path, "w", encoding="ascii", newline="\n") as handle:
        handle.writelines(parts)


def _read_data_array(element, header_dtype, byte_order) -> np.ndarray:
    vtk_type = element.get("type")
    if vtk_type not in _NUMPY_TYPES:
        raise InputError(f"read_vtk: unsupported DataArray type {vtk_type!r}")
    dtype = _NUMPY_TYPES[vtk_type].newbyteorder(byte_order)
    text = (element.text or "").strip()
    fmt = element.get("format", "ascii")
    if fmt == "binary":
        raw = base64.b64decode(text)
        size = header_dtype.itemsize
        n_bytes = int(np.frombuffer(raw[:size], header_dtype)[0])
        values = np.frombuffer(raw[size:size + n_bytes], dtype).astype(dtype.newbyteorder("="))
    elif fmt == "ascii":
        values = np.array(text.split(), dtype=dtype.newbyteorder("="))
    else:
        raise InputError(f"read_vtk reads inline ascii or binary .vtp data, got format={fmt!r}")
    components = int(element.get("NumberOfComponents", "1"))
    return values.reshape(-1, components) if components > 1 else values


def _read_vtp(path: Path) -> SurfaceData:
    from xml.etree import ElementTree

    try:
        root = ElementTree.parse(path).getroot()
    except ElementTree.ParseError as exc:
        raise InputError(f"path: {str(path)!r} is not a VTK XML file ({exc})") from None
    if root.tag != "VTKFile" or root.get("type") != "PolyData":
        raise InputError(f"path: {str(path)!r} is not VTK XML PolyData")
    if root.get("compressor"):
        raise InputError(f"read_vtk reads uncompressed .vtp files, {str(path)!r} is compressed")
    header = np.dtype(_NUMPY_TYPES[root.get("header_type", "UInt32")])
    order = "<" if root.get("byte_order", "LittleEndian") == "LittleEndian" else ">"
    header = header.newbyteorder(order)
    piece = root.find("PolyData/Piece")
    if piece is None or piece.find("Points/DataArray") is None:
        raise InputError(f"path: {str(path)!r} has no PolyData Piece with Points")
    points = _read_data_array(piece.find("Points/DataArray"), header, order).reshape(-1, 3)
    cells, cell_type = np.zeros((0, 1), dtype=np.int64), "vertex"
    for kind, name in (("Verts", "vertex"), ("Polys", "triangle")):
        block = piece.find(kind)
        if block is None or int(piece.get(f"NumberOf{kind}", "0")) == 0:
            continue
        arrays = {a.get("Name"): _read_data_array(a, header, order) for a in block.findall("DataArray")}
        offsets = arrays["offsets"].astype(np.int64)
        sizes = np.diff(np.concatenate([[0], offsets]))
        if len(np.unique(sizes)) > 1:
            raise InputError(f"read_vtk reads one cell size per file, {str(path)!r} mixes {np.unique(sizes)}")
        cells = arrays["connectivity"].astype(np.int64).reshape(len(offsets), -1)
        cell_type = name if name == "vertex" or cells.shape[1] == 3 else f"polygon{cells.shape[1]}"
    cell_data = {a.get("Name"): _read_data_array(a, header, order) for a in piece.findall("CellData/DataArray")}
    return SurfaceData(points, cells, cell_type, cell_data)


def read_vtk(path) -> SurfaceData:
    """Read a ``.vtu`` (with meshio) or a ``.vtp`` written by :func:`to_vtk`.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    SurfaceData
        Points (mm), cells, cell type and every cell data array.
    """
    target, ext = _vtk_path(path)
    if not target.is_file():
        raise InputError(f"path: no such file {str(target)!r}")
    if ext == ".vtp":
        return _read_vtp(target)
    meshio = _require("meshio", "reading .vtu")
    mesh = meshio.read(target, file_format="vtu")
    if len(mesh.cells) != 1:
        raise InputError(f"read_vtk reads one cell block, {str(target)!r} has {len(mesh.cells)}")
    block = mesh.cells[0]
    data = {name: np.asarray(values[0]) for name, values in mesh.cell_data.items()}
    return SurfaceData(np.asarray(mesh.points), np.asarray(block.data, dtype=np.int64), block.type, data)


def vtk_differences(solution, path, *, cells: str = "springs") -> dict:
    """How far a VTK file written by :func:`to_vtk` is from ``solution``, field by field.

    Parameters
    ----------
    solution : Solution
    path : str or os.PathLike
        A ``.vtu`` or ``.vtp`` file.
    cells : {"springs", "surface"}
        As given to :func:`to_vtk`.

    Returns
    -------
    dict {name: float}
        Largest absolute difference for ``points``, ``cells`` and every field of
        :func:`contact_surface` (NaN equal to NaN); ``inf`` for a field that is missing
        or has the wrong shape. All zeros for a binary file.

    Examples
    --------
    >>> assert max(vtk_differences(solution, "knee.vtu").values()) <= 1e-12  # doctest: +SKIP
    """
    expected = contact_surface(solution, cells=cells)
    found = read_vtk(path)
    pairs = {"points": (expected.points, found.points), "cells": (expected.cells, found.cells)}
    for name, value in expected.cell_data.items():
        pairs[name] = (value, found.cell_data.get(name))
    out = {}
    for name, (want, got) in pairs.items():
        if got is None or np.shape(got) != np.shape(want):
            out[name] = math.inf
            continue
        want, got = np.asarray(want, dtype=float), np.asarray(got, dtype=float)
        both_nan = np.isnan(want) & np.isnan(got)
        diff = np.where(both_nan, 0.0, np.abs(want - got))
        out[name] = float(np.nan_to_num(diff, nan=math.inf).max(initial=0.0))
    return out


# --- CSV --------------------------------------------------------------------------------
#: Columns of :func:`to_csv`, in order.
CSV_COLUMNS = (
    "x", "y", "z", "nx", "ny", "nz", "area", "thickness", "gap", "strain", "pressure",
    "spring_force", "in_contact", "source_face", "label",
)
_FLOAT_COLUMNS = CSV_COLUMNS[:12]


def to_csv(solution, path) -> Path:
    """Write one row per spring, in spring order, with a header row.

    Columns (:data:`CSV_COLUMNS`):

    ============  =====  ===============================================================
    column        unit   meaning
    ============  =====  ===============================================================
    x, y, z       mm     spring position (face centroid)
    nx, ny, nz    1      unit normal, body 1 to body 2
    area          mm^2   area the spring stands for
    thickness     mm     unloaded spring length (total cartilage thickness)
    gap           mm     initial gap along the normal (< 0 where the surfaces overlap)
    strain        1      spring strain (< 0 in compression)
    pressure      MPa    contact pressure (>= 0)
    spring_force  N      ``-pressure * area``, tension positive (<= 0)
    in_contact    -      1 where ``strain < 0``, else 0
    source_face   -      index of the spring's face in ``layer.surface``; -1 if unknown
    label         -      the spring's region label; empty if the layer has none
    ============  =====  ===============================================================

    Floats are written with Python's shortest round-trip representation, so
    :func:`read_csv` gives back the same numbers bit for bit.

    Parameters
    ----------
    solution : Solution
    path : str or os.PathLike
        The ``.csv`` file; any extension is accepted.

    Returns
    -------
    pathlib.Path
    """
    layer = solution.problem.layer
    n = len(layer)
    floats = [
        layer.points[:, 0], layer.points[:, 1], layer.points[:, 2],
        layer.normals[:, 0], layer.normals[:, 1], layer.normals[:, 2],
        layer.areas, layer.thickness, layer.gap, solution.strain, solution.pressure, solution.spring_force,
    ]
    columns = [list(map(repr, np.asarray(c, dtype=float).tolist())) for c in floats]
    columns.append(list(map(str, solution.in_contact.astype(int).tolist())))
    source = layer.source_face.tolist() if layer.source_face is not None else [-1] * n
    columns.append(list(map(str, source)))
    labels = layer.labels.astype(str).tolist() if layer.labels is not None else [""] * n
    columns.append([_csv_text(v) for v in labels])
    lines = [",".join(CSV_COLUMNS), *(",".join(row) for row in zip(*columns))]
    with atomic_open(path, "w", newline="") as handle:
        handle.write("\n".join(lines) + "\n")
    return Path(path)


def _csv_text(value: str) -> str:
    """A CSV field: quoted (with doubled quotes) when it holds a comma, quote or line break."""
    if any(c in value for c in ',"\r\n') or value != value.strip():
        return '"' + value.replace('"', '""') + '"'
    return value


def read_csv(path) -> dict:
    """Read a file written by :func:`to_csv` back into arrays.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    dict {column: ndarray, shape (N,)}
        float64 for the float columns, bool for ``in_contact``, int64 for
        ``source_face``, str for ``label``.
    """
    pandas = _require("pandas", "read_csv")
    target = _as_path(path)
    if not target.is_file():
        raise InputError(f"path: no such file {str(target)!r}")
    with open(target, encoding="utf-8") as handle:
        header = handle.readline().rstrip("\r\n")
    if header != ",".join(CSV_COLUMNS):
        raise InputError(
            f"path: {str(target)!r} is not a dea_opt spring table; expected the header "
            f"{','.join(CSV_COLUMNS)}, got {header or 'an empty file'}"
        )
    # every column as text, then Python's float(): correctly rounded, so bit for bit
    # (pandas' own float parser is not guaranteed to be)
    table = pandas.read_csv(target, dtype=str, keep_default_na=False, encoding="utf-8")
    out = {}
    for name in CSV_COLUMNS:
        column = table[name].to_numpy(dtype=object)
        try:
            if name in _FLOAT_COLUMNS:
                out[name] = column.astype(np.float64)
            elif name in ("in_contact", "source_face"):
                out[name] = column.astype(np.int64)
            else:
                out[name] = column.astype(str)
        except ValueError as exc:
            raise InputError(f"path: column {name!r} of {str(target)!r} does not parse ({exc})") from None
    out["in_contact"] = out["in_contact"].astype(bool)
    return out


# --- JSON -------------------------------------------------------------------------------
def _jsonable(value):
    """Plain JSON values: NaN and infinities become ``None``, arrays become lists."""
    if isinstance(value, Mapping):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if hasattr(value, "as_dict"):
        return _jsonable(value.as_dict())
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        value = float(value)
        return value if math.isfinite(value) else None
    if value is None or isinstance(value, str):
        return value
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    return str(value)


_UNITS = {
    "length": "mm", "area": "mm^2", "force": "N", "moment": "N mm", "pressure": "MPa",
    "strain": "1", "rotation": "rad", "time": "s",
}


def summary_dict(solution, *, labels=None, planes=None, regions=None) -> dict:
    """Everything :func:`to_json` writes, as JSON-safe Python values (NaN -> ``None``).

    Builds on :meth:`Solution.summary` (method, status, law, ``n_springs``, peak and mean
    pressure, contact area, centre of pressure, contact force and moment, ``u``,
    iterations, build and solve times, certificate, reactions) and adds ``message``,
    ``total_normal_force``, ``moment_about`` (the body 2 reference the moment is taken
    about), ``units``, ``regions``, ``label_codes`` (text labels only), ``info`` and the
    dea_opt version.

    Parameters
    ----------
    solution : Solution
    labels, planes :
        Passed to :func:`dea_opt.regions.regional_statistics`. Without both, the layer's
        labels make the regions when it has any.
    regions : mapping {name: RegionStats}, optional
        Further regions, e.g. from :func:`dea_opt.regions.split_by_axis`.

    Returns
    -------
    dict
    """
    from . import __version__
    from .regions import RegionStats, regional_statistics

    layer = solution.problem.layer
    found = {}
    if labels is not None or planes is not None:
        found = regional_statistics(solution, labels=labels, planes=planes)
    elif layer.labels is not None:
        found = regional_statistics(solution)
    if regions is not None:
        if not hasattr(regions, "items"):
            raise InputError(f"regions must be a mapping {{name: RegionStats}}, got {type(regions).__name__}")
        for name, stats in regions.items():
            if not isinstance(stats, RegionStats):
                raise InputError(f"regions[{name!r}] must be a RegionStats, got {type(stats).__name__}")
            if str(name) in found:
                raise InputError(f"regions repeats the region name {name!r}")
            found[str(name)] = stats
    out = {"dea_opt_version": __version__, **solution.summary()}
    out.update(
        message=solution.message,
        total_normal_force=solution.total_normal_force,
        moment_about=list(solution.problem.body2.reference),
        units=_UNITS,
        regions={name: stats.as_dict() for name, stats in found.items()},
        info=solution.info,
    )
    if layer.labels is not None and not np.issubdtype(layer.labels.dtype, np.integer):
        out["label_codes"] = label_codes(layer.labels)
    return _jsonable(out)


def to_json(solution, path, *, labels=None, planes=None, regions=None, indent: int = 2) -> Path:
    """Write the summary of ``solution`` as JSON (see :func:`summary_dict` for the keys).

    The file is strict JSON: NaN (e.g. the centre of pressure without contact) is
    written as ``null``.

    Parameters
    ----------
    solution : Solution
    path : str or os.PathLike
    labels, planes, regions :
        Regions to report; see :func:`summary_dict`.
    indent : int

    Returns
    -------
    pathlib.Path
    """
    return _write_json(summary_dict(solution, labels=labels, planes=planes, regions=regions), path, indent)


def _write_json(data: dict, path, indent: int = 2) -> Path:
    text = json.dumps(data, indent=indent, allow_nan=False)
    with atomic_open(path, "w") as handle:
        handle.write(text + "\n")
    return Path(path)


def read_json(path) -> dict:
    """Read a JSON file (e.g. written by :func:`to_json`)."""
    target = _as_path(path)
    if not target.is_file():
        raise InputError(f"path: no such file {str(target)!r}")
    with open(target, encoding="utf-8") as handle:
        return json.load(handle)


# --- pictures ---------------------------------------------------------------------------
def best_fit_frame(points, weights=None, normals=None) -> tuple:
    """An orthonormal frame whose first two axes span the best-fit plane of ``points``.

    Parameters
    ----------
    points : ndarray, shape (N, 3)
        In mm.
    weights : ndarray, shape (N,), optional
        E.g. spring areas; default equal.
    normals : ndarray, shape (N, 3), optional
        When given, the third axis points to the same side as their weighted mean.

    Returns
    -------
    origin : ndarray, shape (3,)
        Weighted centroid (mm).
    axes : ndarray, shape (3, 3)
        Rows ``e1, e2, e3``: ``e3`` the plane normal (least spread, by PCA), ``e1`` the
        coordinate axis most nearly in the plane projected onto it (so a plane normal to
        z gives ``e1 = x``), ``e2 = e3 x e1`` (right-handed).
    """
    points = np.asarray(points, dtype=float)
    w = np.ones(len(points)) if weights is None else np.asarray(weights, dtype=float)
    origin = w @ points / w.sum()
    centred = points - origin
    _, vectors = np.linalg.eigh((centred * w[:, None]).T @ centred)  # 3 x 3, ascending spread
    e3 = vectors[:, 0]
    if normals is not None:
        mean = w @ np.asarray(normals, dtype=float)
        if mean @ e3 < 0:
            e3 = -e3
    k = int(np.argmin(np.abs(e3)))  # the coordinate axis most nearly in the plane
    e1 = np.eye(3)[k] - e3[k] * e3
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(e3, e1)
    return origin, np.array([e1, e2, e3])


def _axis_label(name: str, e: np.ndarray) -> str:
    k = int(np.argmax(np.abs(e)))
    if abs(e[k]) > 1 - 1e-9:
        return f"{'-' if e[k] < 0 else ''}{'xyz'[k]} (mm)"
    return f"{name} = ({e[0]:.2f}, {e[1]:.2f}, {e[2]:.2f}) (mm)"


def _boundary_edges(triangles: np.ndarray) -> np.ndarray:
    """Edges (E, 2) that belong to one triangle only: the outline of a set of triangles."""
    if len(triangles) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    edges = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    return unique[counts == 1]


def _point_triangulation(xy: np.ndarray, areas: np.ndarray):
    """Delaunay triangles of spring points, without those that bridge gaps; None if flat."""
    from matplotlib.tri import Triangulation

    try:
        tri = Triangulation(xy[:, 0], xy[:, 1])
    except (RuntimeError, ValueError):
        return None
    t = tri.triangles
    a, b, c = xy[t[:, 0]], xy[t[:, 1]], xy[t[:, 2]]
    tri_area = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    tri.set_mask(tri_area > 4.0 * areas[t].max(axis=1))
    return tri


def _draw_plane(ax, solution, frame, cmap, norm, grey):
    from matplotlib.collections import LineCollection
    from matplotlib.tri import Triangulation

    layer = solution.problem.layer
    origin, axes = frame
    contact = solution.in_contact
    surface = contact_surface(solution) if layer.surface is not None and layer.source_face is not None else None
    if surface is not None:
        xy = (surface.points - origin) @ axes[:2].T
        tris = surface.cells
        if not contact.all():
            ax.tripcolor(Triangulation(xy[:, 0], xy[:, 1], tris[~contact]), facecolors=np.zeros((~contact).sum()),
                         cmap=grey, vmin=0, vmax=1, edgecolors="none")
        if contact.any():
            ax.tripcolor(Triangulation(xy[:, 0], xy[:, 1], tris[contact]), facecolors=solution.pressure[contact],
                         cmap=cmap, norm=norm, edgecolors="none")
        edges = _boundary_edges(tris[contact])
        ax.add_collection(LineCollection(xy[edges], colors="k", linewidths=0.8))
        return xy, len(edges) > 0
    xy = (layer.points - origin) @ axes[:2].T
    tri = _point_triangulation(xy, layer.areas)
    if tri is None:
        colours = np.where(contact, solution.pressure, np.nan)
        ax.scatter(xy[~contact, 0], xy[~contact, 1], s=4, color=grey(0.5))
        ax.scatter(xy[contact, 0], xy[contact, 1], s=4, c=colours[contact], cmap=cmap, norm=norm)
        return xy, False
    base_mask = tri.mask.copy()
    ax.tripcolor(tri, np.zeros(len(xy)), cmap=grey, vmin=0, vmax=1, shading="gouraud")
    touching = contact[tri.triangles].any(axis=1)
    if touching.any():  # a triangulation of its own: matplotlib reads the mask when drawing
        loaded = Triangulation(xy[:, 0], xy[:, 1], tri.triangles, mask=base_mask | ~touching)
        ax.tripcolor(loaded, solution.pressure, cmap=cmap, norm=norm, shading="gouraud")
    if 0 < contact.sum() < len(contact):
        ax.tricontour(tri, contact.astype(float), levels=[0.5], colors="k", linewidths=0.8)
        return xy, True
    if contact.all():
        edges = _boundary_edges(tri.triangles[~base_mask])
        ax.add_collection(LineCollection(xy[edges], colors="k", linewidths=0.8))
        return xy, True
    return xy, False


def _draw_3d(ax, solution, cmap, norm, grey):
    from matplotlib.ticker import MaxNLocator
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    layer = solution.problem.layer
    contact = solution.in_contact
    colours = np.asarray(cmap(norm(solution.pressure)))
    colours[~contact] = grey(0.5)
    if layer.surface is not None and layer.source_face is not None:
        surface = contact_surface(solution)
        points, tris = surface.points, surface.cells
        ax.add_collection3d(Poly3DCollection(points[tris], facecolors=colours, edgecolors="none"))
        edges = _boundary_edges(tris[contact])
        if len(edges):
            ax.add_collection3d(Line3DCollection(points[edges], colors="k", linewidths=0.8))
        outlined = len(edges) > 0
    else:
        points = layer.points
        ax.scatter(points[:, 0], points[:, 1], points[:, 2], c=colours, s=4, depthshade=False)
        outlined = False
    low, high = points.min(axis=0), points.max(axis=0)
    span = np.maximum(high - low, 0.1 * max(float((high - low).max()), 1e-9))
    centre = 0.5 * (low + high)
    ax.set_xlim(centre[0] - span[0] / 2, centre[0] + span[0] / 2)
    ax.set_ylim(centre[1] - span[1] / 2, centre[1] + span[1] / 2)
    ax.set_zlim(centre[2] - span[2] / 2, centre[2] + span[2] / 2)
    ax.set_box_aspect(tuple(span))  # equal scale on the three axes
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)")
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(5))
    return outlined


_PICTURE_FORMATS = (".png", ".pdf", ".svg")


def plot_pressure(solution, path, *, view: str = "plane", cmap: str = "viridis", vmax: float | None = None,
                  title: str | None = None, dpi: int = 150, figsize: tuple = (6.4, 5.2),
                  elev: float | None = None, azim: float | None = None) -> Path:
    """Draw a pressure map of the contact surface to a PNG.

    Faces (or springs) in contact are coloured by pressure with a colour bar in MPa; the
    rest of the surface is light grey; the contact edge is outlined in black and the
    centre of pressure marked with a white dot. Layers with ``surface`` and
    ``source_face`` are drawn face by face; other layers by a triangulation of their
    spring points (triangles bridging gaps are dropped) or, failing that, by dots.
    Drawn with matplotlib's Agg canvas: pyplot and its backend are not touched.

    Parameters
    ----------
    solution : Solution
    path : str or os.PathLike
        ``.png`` (or ``.pdf``, ``.svg``).
    view : {"plane", "3d"}
        ``"plane"``: projected on the best-fit plane of the springs (:func:`best_fit_frame`,
        seen from body 2: the plane normal points along the springs' mean normal).
        ``"3d"``: a 3-D view, by default from 40 degrees off the springs' mean normal.
    cmap : str
        A matplotlib colormap name.
    vmax : float, optional
        Top of the colour scale (MPa); default the peak pressure.
    title : str, optional
        Default: method, peak pressure, total force and contact area.
    dpi : int
    figsize : (float, float)
        Inches.
    elev, azim : float, optional
        Camera angles of the 3-D view (degrees).

    Returns
    -------
    pathlib.Path

    Raises
    ------
    InputError
        Unknown ``view`` or extension, no springs, or a path that cannot be written.
    """
    target = _as_path(path)
    fmt = target.suffix.lower()
    if fmt not in _PICTURE_FORMATS:
        raise InputError(f"path must end in .png, .pdf or .svg, got {str(path)!r}")
    if view not in ("plane", "3d"):
        raise InputError(f"view must be 'plane' or '3d', got {view!r}")
    layer = solution.problem.layer
    if len(layer) == 0:
        raise InputError("solution has no springs to plot")
    _require("matplotlib", "plot_pressure")
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import ListedColormap, Normalize
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    try:
        colormap = matplotlib.colormaps[cmap]
    except KeyError:
        raise InputError(f"cmap must be a matplotlib colormap name, got {cmap!r}") from None
    top = solution.peak_pressure if vmax is None else float(vmax)
    norm = Normalize(0.0, top if top > 0 else 1.0)
    grey = ListedColormap(["0.85"])
    frame = best_fit_frame(layer.points, layer.areas, layer.normals)
    cop = solution.center_of_pressure

    fig = Figure(figsize=figsize, layout="constrained")
    FigureCanvasAgg(fig)
    if view == "plane":
        ax = fig.add_subplot()
        xy, outlined = _draw_plane(ax, solution, frame, colormap, norm, grey)
        if np.isfinite(cop).all():
            c = (cop - frame[0]) @ frame[1][:2].T
            ax.plot(c[0], c[1], "o", mfc="white", mec="k", ms=7, zorder=5)
        low, high = xy.min(axis=0), xy.max(axis=0)
        pad = 0.03 * max(float((high - low).max()), 1e-9)
        ax.set_xlim(low[0] - pad, high[0] + pad)
        ax.set_ylim(low[1] - pad, high[1] + pad)
        ax.set_aspect("equal")
        ax.set_xlabel(_axis_label("e1", frame[1][0]))
        ax.set_ylabel(_axis_label("e2", frame[1][1]))
    else:
        ax = fig.add_subplot(projection="3d", computed_zorder=False)
        outlined = _draw_3d(ax, solution, colormap, norm, grey)
        if np.isfinite(cop).all():
            ax.scatter([cop[0]], [cop[1]], [cop[2]], s=50, c="white", edgecolors="k", depthshade=False,
                       zorder=10)
        tilt = np.radians(40.0)  # look from 40 degrees off the mean normal, toward -e2
        eye = np.cos(tilt) * frame[1][2] - np.sin(tilt) * frame[1][1]
        ax.view_init(
            elev=float(np.degrees(np.arcsin(np.clip(eye[2], -1, 1)))) if elev is None else elev,
            azim=float(np.degrees(np.arctan2(eye[1], eye[0]))) if azim is None else azim,
        )
    handles = [Line2D([], [], color="k", lw=0.8, label="contact edge")] if outlined else []
    if np.isfinite(cop).all():
        handles.append(Line2D([], [], ls="", marker="o", mfc="white", mec="k", label="centre of pressure"))
    if handles:
        ax.legend(handles=handles, loc="upper right", fontsize="small", framealpha=0.8)
    fig.colorbar(ScalarMappable(norm=norm, cmap=colormap), ax=ax, label="pressure (MPa)", shrink=0.85)
    if title is None:
        title = (f"{solution.method}: peak {solution.peak_pressure:.4g} MPa, "
                 f"resultant {np.linalg.norm(solution.contact_force):.4g} N, area {solution.contact_area:.4g} mm$^2$")
    ax.set_title(title, fontsize="medium")
    write_atomic(target, lambda tmp: fig.savefig(tmp, format=fmt[1:], dpi=dpi))
    return target


# --- everything at once -----------------------------------------------------------------
def write_results(solution, directory, *, stem: str = "contact", vtk: str = ".vtu", cells: str = "springs",
                  labels=None, planes=None, regions=None, view: str = "plane") -> dict:
    """Write ``<stem>.vtu`` (or ``.vtp``), ``.csv``, ``.json`` and ``.png`` into ``directory``.

    Parameters
    ----------
    solution : Solution
    directory : str or os.PathLike
        Created when missing.
    stem : str
        File name without extension.
    vtk : {".vtu", ".vtp"}
    cells : {"springs", "surface"}
        See :func:`contact_surface`.
    labels, planes, regions :
        Regions for the JSON summary; see :func:`summary_dict`.
    view : {"plane", "3d"}
        See :func:`plot_pressure`.

    Returns
    -------
    dict {"vtk", "csv", "json", "png": pathlib.Path}

    Examples
    --------
    >>> from dea_opt.regions import split_by_axis
    >>> paths = write_results(s, "out", stem="knee",
    ...                       regions=split_by_axis(s, "x"))  # doctest: +SKIP
    >>> assert max(vtk_differences(s, paths["vtk"]).values()) == 0  # doctest: +SKIP
    """
    if not isinstance(stem, str) or not stem or os.sep in stem or (os.altsep and os.altsep in stem):
        raise InputError(f"stem must be a plain file name without directories, got {stem!r}")
    if vtk not in _VTK_EXTENSIONS:
        raise InputError(f"vtk must be '.vtu' or '.vtp', got {vtk!r}")
    if isinstance(directory, (str, os.PathLike)) and Path(directory).exists() and not Path(directory).is_dir():
        raise InputError(f"directory must be a directory, got the file {os.fspath(directory)!r}")
    if not isinstance(directory, (str, os.PathLike)):
        raise InputError(f"directory must be a path (str or os.PathLike), got {type(directory).__name__}")
    if view not in ("plane", "3d"):
        raise InputError(f"view must be 'plane' or '3d', got {view!r}")
    # check everything before the first file is written
    summary = summary_dict(solution, labels=labels, planes=planes, regions=regions)
    contact_surface(solution, cells=cells)
    base = Path(directory)
    out = {"vtk": to_vtk(solution, base / f"{stem}{vtk}", cells=cells)}
    out["csv"] = to_csv(solution, base / f"{stem}.csv")
    out["json"] = _write_json(summary, base / f"{stem}.json")
    out["png"] = plot_pressure(solution, base / f"{stem}.png", view=view)
    return out
