"""ParaView files of the contact surface: ``.vtu`` and ``.vtp``, written array by array.

Both are VTK XML with the data of :func:`~dea_opt.io.surface.contact_surface`;
:func:`read_vtk` reads both back and :func:`vtk_differences` compares a file with a
solution field by field. Units: mm, mm^2, N, MPa.
"""

from __future__ import annotations

import base64
import math
from pathlib import Path
from typing import Any, Literal

import numpy as np

from .._checks.dependencies import require
from ..errors import InputError
from ..files.atomic import file_path, write_atomic
from .surface import SurfaceData, contact_surface
from .vtkxml import NUMPY_TYPES, read_appended, write_vtk_xml

__all__ = ["VTK_EXTENSIONS", "read_vtk", "to_vtk", "vtk_differences", "write_surface"]

#: The extensions :func:`to_vtk` writes: VTK XML UnstructuredGrid and PolyData.
VTK_EXTENSIONS = (".vtu", ".vtp")


def _vtk_path(path) -> tuple:
    target = file_path(path)
    ext = target.suffix.lower()
    if ext not in VTK_EXTENSIONS:
        raise InputError(f"path must end in .vtu (UnstructuredGrid) or .vtp (PolyData), got {str(path)!r}")
    return target, ext


def to_vtk(solution, path, *, cells: str = "springs", binary: bool = True, compress: bool = False) -> Path:
    """Write the contact surface with its data for ParaView.

    Parameters
    ----------
    solution : Solution
    path : str or os.PathLike
        ``.vtu`` (VTK XML UnstructuredGrid) or ``.vtp`` (VTK XML PolyData). Both open in
        ParaView; :func:`read_vtk` reads both back, and ``meshio.read`` reads the ``.vtu``.
        Written array by array (:mod:`~dea_opt.io.vtkxml`): memory stays near one chunk.
    cells : {"springs", "surface"}
        Which cells to write; see :func:`contact_surface` (fields, units, where they sit,
        and what faces without a spring carry).
    binary : bool
        Binary (default: each array's raw bytes appended after the XML, exact and as fast as
        the disk) or ASCII (exact too: every float as its shortest round-trip text).
    compress : bool
        Binary ``.vtu`` as zlib-compressed inline blocks instead: about a fifth smaller for a
        contact surface (its floats hardly compress) and several times slower to write.

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    InputError
        ``path`` has another extension or cannot be written; ``cells`` is unknown.
    """
    target, _ = _vtk_path(path)
    return write_surface(contact_surface(solution, cells=cells), target, binary=binary, compress=compress)


def write_surface(surface: SurfaceData, path, *, binary: bool = True, compress: bool = False) -> Path:
    """Write any :class:`SurfaceData` as ``.vtu`` or ``.vtp`` (atomically, array by array;
    ``binary`` and ``compress`` as for :func:`to_vtk`)."""
    target, ext = _vtk_path(path)
    encoding = "ascii" if not binary else ("zlib" if compress else "raw")
    return write_atomic(target, lambda tmp: write_vtk_xml(tmp, surface, polydata=ext == ".vtp", encoding=encoding))


def _read_data_array(element, header_dtype, byte_order, appended=None) -> np.ndarray:
    vtk_type = element.get("type", "")
    if vtk_type not in NUMPY_TYPES:
        raise InputError(f"read_vtk: unsupported DataArray type {vtk_type!r}")
    dtype = NUMPY_TYPES[vtk_type].newbyteorder(byte_order)
    text = (element.text or "").strip()
    fmt = element.get("format", "ascii")
    if fmt == "appended" and appended is not None:
        return appended[int(element.get("offset", "-1"))]
    if fmt == "binary":
        raw = base64.b64decode(text)
        size = header_dtype.itemsize
        n_bytes = int(np.frombuffer(raw[:size], header_dtype)[0])
        values = np.frombuffer(raw[size : size + n_bytes], dtype).astype(dtype.newbyteorder("="))
    elif fmt == "ascii":
        values = np.array(text.split(), dtype=dtype.newbyteorder("="))
    else:
        raise InputError(f"read_vtk reads ascii, inline binary or raw appended .vtp data, got format={fmt!r}")
    components = int(element.get("NumberOfComponents", "1"))
    return values.reshape(-1, components) if components > 1 else values


def _read_vtp(path: Path) -> SurfaceData:
    from xml.etree import ElementTree

    appended = None
    with open(path, "rb") as handle:
        raw = b"<AppendedData" in handle.read()
    if raw:
        root, appended = read_appended(path)
    else:
        try:
            root = ElementTree.parse(path).getroot()
        except ElementTree.ParseError as exc:
            raise InputError(f"path: {str(path)!r} is not a VTK XML file ({exc})") from None
    if root.tag != "VTKFile" or root.get("type") != "PolyData":
        raise InputError(f"path: {str(path)!r} is not VTK XML PolyData")
    if root.get("compressor"):
        raise InputError(f"read_vtk reads uncompressed .vtp files, {str(path)!r} is compressed")
    header = NUMPY_TYPES[root.get("header_type", "UInt32")]
    order: Literal["<", ">"] = "<" if root.get("byte_order", "LittleEndian") == "LittleEndian" else ">"
    header = header.newbyteorder(order)
    piece = root.find("PolyData/Piece")
    if piece is None or piece.find("Points/DataArray") is None:
        raise InputError(f"path: {str(path)!r} has no PolyData Piece with Points")
    points = _read_data_array(piece.find("Points/DataArray"), header, order, appended).reshape(-1, 3)
    cells, cell_type = np.zeros((0, 1), dtype=np.int64), "vertex"
    for kind, name in (("Verts", "vertex"), ("Polys", "triangle")):
        block = piece.find(kind)
        if block is None or int(piece.get(f"NumberOf{kind}", "0")) == 0:
            continue
        arrays = {a.get("Name"): _read_data_array(a, header, order, appended) for a in block.findall("DataArray")}
        offsets = arrays["offsets"].astype(np.int64)
        sizes = np.diff(np.concatenate([[0], offsets]))
        if len(np.unique(sizes)) > 1:
            raise InputError(f"read_vtk reads one cell size per file, {str(path)!r} mixes {np.unique(sizes)}")
        cells = arrays["connectivity"].astype(np.int64).reshape(len(offsets), -1)
        cell_type = name if name == "vertex" or cells.shape[1] == 3 else f"polygon{cells.shape[1]}"
    cell_data = {
        a.get("Name"): _read_data_array(a, header, order, appended) for a in piece.findall("CellData/DataArray")
    }
    point_data = {
        a.get("Name"): _read_data_array(a, header, order, appended) for a in piece.findall("PointData/DataArray")
    }
    return SurfaceData(points, cells, cell_type, cell_data, point_data)


def read_vtk(path) -> SurfaceData:
    """Read a ``.vtu`` (with meshio) or a ``.vtp`` written by :func:`to_vtk`.

    Parameters
    ----------
    path : str or os.PathLike

    Returns
    -------
    SurfaceData
        Points (mm), cells, cell type and every cell and point data array.
    """
    target, ext = _vtk_path(path)
    if not target.is_file():
        raise InputError(f"path: no such file {str(target)!r}")
    if ext == ".vtp":
        return _read_vtp(target)
    meshio = require("meshio", "reading .vtu")
    mesh = meshio.read(target, file_format="vtu")
    if len(mesh.cells) != 1:
        raise InputError(f"read_vtk reads one cell block, {str(target)!r} has {len(mesh.cells)}")
    block = mesh.cells[0]
    data = {name: np.asarray(values[0]) for name, values in mesh.cell_data.items()}
    point_data = {name: np.asarray(values) for name, values in mesh.point_data.items()}
    return SurfaceData(np.asarray(mesh.points), np.asarray(block.data, dtype=np.int64), block.type, data, point_data)


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
    pairs: dict[str, tuple[Any, Any]] = {
        "points": (expected.points, found.points),
        "cells": (expected.cells, found.cells),
    }
    for name, value in expected.spring_data.items():
        pairs[name] = (value, found.spring_data.get(name))
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
