"""VTK XML files (``.vtu`` UnstructuredGrid, ``.vtp`` PolyData) written array by array to the file.

Nothing is built in memory beyond one chunk of one array. Three encodings:

* ``"raw"`` (the default for binary files): every array's bytes appended after the XML
  (``<AppendedData encoding="raw">``), each behind its UInt64 byte count, written from the
  array with NumPy: no base64, no compression, as fast as the disk. ParaView, VTK and meshio
  read it; :func:`read_appended` reads it back here.
* ``"zlib"``: inline base64 of zlib-compressed blocks (``vtkZLibDataCompressor``), ``.vtu``
  only: about a fifth smaller on a contact surface's arrays (floats hardly compress), and
  several times slower to write.
* ``"ascii"``: every float as its shortest round-trip text (``repr``), so nothing is lost.
"""

from __future__ import annotations

import base64
import html
import re
import zlib
from typing import Any, Literal

import numpy as np

from ..errors import InputError

__all__ = ["ENCODINGS", "VTK_TYPES", "quoteattr", "read_appended", "write_vtk_xml"]

#: The encodings :func:`write_vtk_xml` writes.
ENCODINGS = ("raw", "zlib", "ascii")

VTK_TYPES: dict[np.dtype, str] = {
    np.dtype(np.float64): "Float64",
    np.dtype(np.float32): "Float32",
    np.dtype(np.int64): "Int64",
    np.dtype(np.int32): "Int32",
    np.dtype(np.int16): "Int16",
    np.dtype(np.int8): "Int8",
    np.dtype(np.uint64): "UInt64",
    np.dtype(np.uint32): "UInt32",
    np.dtype(np.uint16): "UInt16",
    np.dtype(np.uint8): "UInt8",
}
#: The NumPy dtype of each VTK DataArray type.
NUMPY_TYPES: dict[str, np.dtype] = {v: k for k, v in VTK_TYPES.items()}
#: VTK cell type numbers (UnstructuredGrid) by meshio's names.
_CELL_TYPES = {"vertex": 1, "triangle": 5, "quad": 9}
_BLOCK = 1 << 20  # bytes per compressed block
_CHUNK = 3 * (1 << 18)  # bytes per base64 chunk: a multiple of 3, so the chunks join into one stream
_RAW = 1 << 22  # bytes per write of an appended array (a byte-swapped or strided array is copied this much at a time)
_ROWS = 1 << 16  # values per line batch of ASCII arrays
_LEVEL = 1  # zlib level: the fastest, within a few per cent of the default's size on these arrays


def quoteattr(text: str) -> str:
    """``text`` as a double-quoted XML attribute value (``xml.sax.saxutils`` would import
    ``urllib.request`` and ``http`` for it)."""
    return '"' + html.escape(str(text), quote=True) + '"'


class _Ramp:
    """``step * (1, 2, ..., n)`` or ``n`` copies of ``step`` without the array: VTK's offsets
    and cell types, made a chunk at a time."""

    def __init__(self, n: int, step: int, dtype, constant: bool = False):
        self.n, self.step, self.dtype, self.constant = int(n), int(step), np.dtype(dtype), constant
        self.shape, self.ndim, self.size = (self.n,), 1, self.n

    def chunk(self, start: int, stop: int) -> np.ndarray:
        if self.constant:
            return np.full(stop - start, self.step, dtype=self.dtype)
        return (self.step * np.arange(start + 1, stop + 1)).astype(self.dtype)


def _chunks(values, items: int):
    """The values, flattened and little-endian, ``items`` at a time (views of a C-contiguous
    little-endian array; copies a chunk at a time otherwise, or made by a _Ramp)."""
    if isinstance(values, _Ramp):
        for start in range(0, values.n, items):
            yield values.chunk(start, min(start + items, values.n))
        return
    little = values.dtype.newbyteorder("<")
    if values.dtype == little and values.flags.c_contiguous:
        flat = values.reshape(-1)
        for start in range(0, len(flat), items):
            yield flat[start : start + items]
        return
    rows = max(items // max(int(np.prod(values.shape[1:])), 1), 1)
    for start in range(0, len(values), rows):
        yield np.ascontiguousarray(values[start : start + rows], dtype=little).reshape(-1)


class _Base64:
    """base64 of a stream of byte pieces, written as it comes (pieces need not align to 3)."""

    def __init__(self, handle):
        self.handle, self.carry = handle, b""

    def write(self, piece) -> None:
        block = self.carry + bytes(piece)
        cut = len(block) - len(block) % 3
        self.handle.write(base64.b64encode(block[:cut]))
        self.carry = block[cut:]

    def close(self) -> None:
        self.handle.write(base64.b64encode(self.carry))
        self.carry = b""


def _vtk_type(name: str, values) -> str:
    vtk_type = VTK_TYPES.get(np.dtype(values.dtype).newbyteorder("="))
    if vtk_type is None:
        raise InputError(f"data array {name!r} has dtype {values.dtype}, which VTK cannot store")
    return vtk_type


def _write_array(handle, name: str, values, fmt: str, indent: str, offset: int | None = None) -> None:
    """One DataArray: inline (``ascii``, ``zlib``, ``base64``), or its tag only (``raw``, at
    ``offset`` bytes into the appended data)."""
    vtk_type = _vtk_type(name, values)
    components = f' NumberOfComponents="{values.shape[1]}"' if values.ndim == 2 else ""
    if fmt == "raw":
        handle.write(
            f'{indent}<DataArray type="{vtk_type}" Name={quoteattr(name)}{components} format="appended" '
            f'offset="{offset}"/>\n'.encode("ascii")
        )
        return
    kind = "ascii" if fmt == "ascii" else "binary"
    handle.write(
        f'{indent}<DataArray type="{vtk_type}" Name={quoteattr(name)}{components} format="{kind}">'.encode("ascii")
    )
    itemsize = np.dtype(values.dtype).itemsize
    n_bytes = int(values.size) * itemsize
    if fmt == "ascii":
        floating = vtk_type.startswith("Float")
        for part in _chunks(values, _ROWS):
            part = part.tolist()
            handle.write(((" ".join(map(repr, part)) if floating else " ".join(map(str, part))) + " ").encode("ascii"))
    elif fmt == "zlib":
        # The header lists every block's compressed size, so the blocks are made first (they
        # are the compressed array: no larger than it), then written one by one.
        blocks = [zlib.compress(part, _LEVEL) for part in _chunks(values, _BLOCK // itemsize)]
        size = (_BLOCK // itemsize) * itemsize
        last = n_bytes % size  # VTK: the last block's size when it is partial, else 0
        header = np.array([len(blocks), size, last, *map(len, blocks)], dtype="<u8")
        handle.write(base64.b64encode(header.tobytes()))
        stream = _Base64(handle)
        blocks.reverse()
        while blocks:  # each block freed once written
            stream.write(blocks.pop())
        stream.close()
    else:
        stream = _Base64(handle)
        stream.write(np.array([n_bytes], dtype="<u8").tobytes())
        for part in _chunks(values, max(_CHUNK // itemsize, 1)):
            stream.write(memoryview(part).cast("B"))
        stream.close()
    handle.write(b"</DataArray>\n")


def _append_raw(handle, values) -> None:
    """An appended array: its byte count (UInt64) and its bytes, a chunk at a time."""
    itemsize = np.dtype(values.dtype).itemsize
    handle.write(np.array([int(values.size) * itemsize], dtype="<u8").tobytes())
    for part in _chunks(values, max(_RAW // itemsize, 1)):
        handle.write(memoryview(part).cast("B"))


def write_vtk_xml(path, surface, *, binary: bool = True, polydata: bool = False, encoding: str | None = None) -> None:
    """Write ``surface`` (:class:`~dea_opt.io.surface.SurfaceData`) as VTK XML to ``path``.

    Parameters
    ----------
    path : path-like
        The file to write (the caller makes it atomic).
    surface : SurfaceData
    binary : bool
        Binary (``encoding="raw"``) or ASCII, when ``encoding`` is not given.
    polydata : bool
        PolyData (``.vtp``) instead of UnstructuredGrid (``.vtu``).
    encoding : {"raw", "zlib", "ascii"}, optional
        See the module's docstring. ``"zlib"`` writes PolyData, and arrays of no values,
        as uncompressed inline base64.
    """
    encoding = encoding or ("raw" if binary else "ascii")
    if encoding not in ENCODINGS:
        raise InputError(f"encoding must be one of {', '.join(ENCODINGS)}, got {encoding!r}")
    cells = np.asarray(surface.cells)
    if cells.dtype not in (np.dtype(np.int32), np.dtype(np.int64)):
        cells = cells.astype(np.int64)
    n_cells, per_cell = cells.shape
    kind = "PolyData" if polydata else "UnstructuredGrid"
    block = "Cells"
    if polydata:
        block = "Verts" if surface.cell_type == "vertex" else "Polys"
    elif _CELL_TYPES.get(surface.cell_type) is None:
        raise InputError(f"cannot write cells of type {surface.cell_type!r} to .vtu")
    # Every array in the order it is written: (section, name, values).
    arrays: list[tuple[str, str, Any]] = [
        ("PointData", name, np.asarray(value)) for name, value in surface.point_data.items()
    ]
    arrays += [("CellData", name, np.asarray(value)) for name, value in surface.cell_data.items()]
    arrays += [
        ("Points", "Points", np.asarray(surface.points, dtype=np.float64)),
        (block, "connectivity", cells),
        (block, "offsets", _Ramp(n_cells, per_cell, np.int64)),
    ]
    if not polydata:
        arrays.append((block, "types", _Ramp(n_cells, _CELL_TYPES[surface.cell_type], np.uint8, constant=True)))
    for _, name, values in arrays:
        _vtk_type(name, values)
    fmt = encoding
    if encoding == "zlib" and (polydata or not all(values.size for _, _, values in arrays)):
        fmt = "base64"
    compressor = ' compressor="vtkZLibDataCompressor"' if fmt == "zlib" else ""
    # The appended data holds the arrays in the reverse of their order in the XML. Any order
    # is valid VTK, but meshio's raw reader renumbers the offsets one array at a time and finds
    # each by its offset: this order makes an offset it has already rewritten never shadow one
    # still to come (the first DataArray with that offset in the document is the right one).
    offsets, position = [0] * len(arrays), 0
    for k in reversed(range(len(arrays))):
        offsets[k] = position
        values = arrays[k][2]
        position += 8 + int(values.size) * np.dtype(values.dtype).itemsize
    with open(path, "wb") as handle:
        handle.write(b'<?xml version="1.0"?>\n')
        handle.write(
            f'<VTKFile type="{kind}" version="1.0" byte_order="LittleEndian" '
            f'header_type="UInt64"{compressor}>\n  <{kind}>\n'.encode("ascii")
        )
        if polydata:
            counts = {"Verts": 0, "Lines": 0, "Strips": 0, "Polys": 0}
            counts[block] = n_cells
            handle.write(
                (
                    f'    <Piece NumberOfPoints="{len(surface.points)}" '
                    + " ".join(f'NumberOf{k}="{v}"' for k, v in counts.items())
                    + ">\n"
                ).encode("ascii")
            )
        else:
            handle.write(
                f'    <Piece NumberOfPoints="{len(surface.points)}" NumberOfCells="{n_cells}">\n'.encode("ascii")
            )
        section = None
        for (tag, name, values), offset in zip(arrays, offsets):
            if tag != section:
                if section is not None:
                    handle.write(f"      </{section}>\n".encode("ascii"))
                data = surface.point_data if tag == "PointData" else surface.cell_data
                scalars = ' Scalars="pressure"' if tag in ("PointData", "CellData") and "pressure" in data else ""
                handle.write(f"      <{tag}{scalars}>\n".encode("ascii"))
                section = tag
            _write_array(handle, name, values, fmt, "        ", offset)
        handle.write(f"      </{section}>\n    </Piece>\n  </{kind}>\n".encode("ascii"))
        if fmt == "raw":
            # "_" starts the data; the newline after it ends it for meshio's reader.
            handle.write(b'  <AppendedData encoding="raw">\n   _')
            for _, _, values in reversed(arrays):
                _append_raw(handle, values)
            handle.write(b"\n  </AppendedData>\n")
        handle.write(b"</VTKFile>\n")


_APPENDED = re.compile(rb'<AppendedData[^>]*encoding="raw"[^>]*>\s*_')


def read_appended(path) -> tuple:
    """The XML tree and the arrays of a VTK XML file with raw appended data.

    Returns
    -------
    root : xml.etree.ElementTree.Element
        The file's XML without its appended bytes.
    arrays : dict {offset: ndarray}
        Each appended DataArray by its ``offset`` attribute, as its type says (reshaped to
        ``(-1, NumberOfComponents)`` for more than one component).
    """
    from xml.etree import ElementTree

    with open(path, "rb") as handle:
        data = handle.read()
    found = _APPENDED.search(data)
    if found is None:
        raise InputError(f"path: {str(path)!r} has no raw AppendedData")
    tail = data.rfind(b"</AppendedData>")
    try:
        root = ElementTree.fromstring(data[: found.start()] + data[tail + len(b"</AppendedData>") :])
    except ElementTree.ParseError as exc:
        raise InputError(f"path: {str(path)!r} is not a VTK XML file ({exc})") from None
    if root.get("compressor"):
        raise InputError(f"read_appended reads uncompressed appended data, {str(path)!r} is compressed")
    order: Literal["<", ">"] = "<" if root.get("byte_order", "LittleEndian") == "LittleEndian" else ">"
    header = NUMPY_TYPES[root.get("header_type", "UInt32")].newbyteorder(order)
    start, arrays = found.end(), {}
    for element in root.iter("DataArray"):
        if element.get("format") != "appended":
            continue
        vtk_type = element.get("type", "")
        if vtk_type not in NUMPY_TYPES:
            raise InputError(
                f"path: {str(path)!r} has a DataArray of type {element.get('type')!r}, which dea-opt does not read"
            )
        offset_text = element.get("offset", "")
        if not offset_text.isdigit():
            raise InputError(
                f"path: {str(path)!r} has a DataArray {element.get('Name')!r} without a valid offset "
                f"(found {offset_text!r})"
            )
        offset = int(offset_text)
        at = start + offset
        n_bytes = int(np.frombuffer(data, header, count=1, offset=at)[0]) if at + header.itemsize <= tail else tail
        dtype = NUMPY_TYPES[vtk_type].newbyteorder(order)
        if at + header.itemsize + n_bytes > tail:
            raise InputError(f"path: {str(path)!r} is truncated: array {element.get('Name')!r} runs past its data")
        values = np.frombuffer(data, dtype, count=n_bytes // dtype.itemsize, offset=at + header.itemsize)
        values = values.astype(dtype.newbyteorder("="))
        components = int(element.get("NumberOfComponents", "1"))
        arrays[offset] = values.reshape(-1, components) if components > 1 else values
    return root, arrays
