"""VTK XML files (``.vtu`` UnstructuredGrid, ``.vtp`` PolyData) written array by array to the file.

Nothing is built in memory beyond one array's encoded form: each DataArray is base64-encoded
in chunks straight into the file, so writing 1e7 springs costs about one array, not the whole
file. Binary ``.vtu`` arrays are zlib-compressed in blocks (``vtkZLibDataCompressor``, the
compressed inline format ParaView and meshio read); ``.vtp`` arrays are not compressed. ASCII
writes every float as its shortest round-trip text (``repr``), so nothing is lost.
"""

from __future__ import annotations

import base64
import zlib
from xml.sax.saxutils import quoteattr

import numpy as np

from ..errors import InputError

__all__ = ["VTK_TYPES", "write_vtk_xml"]

VTK_TYPES = {
    np.dtype(np.float64): "Float64", np.dtype(np.float32): "Float32",
    np.dtype(np.int64): "Int64", np.dtype(np.int32): "Int32", np.dtype(np.int16): "Int16",
    np.dtype(np.int8): "Int8", np.dtype(np.uint64): "UInt64", np.dtype(np.uint32): "UInt32",
    np.dtype(np.uint16): "UInt16", np.dtype(np.uint8): "UInt8",
}
#: VTK cell type numbers (UnstructuredGrid) by meshio's names.
_CELL_TYPES = {"vertex": 1, "triangle": 5, "quad": 9}
_BLOCK = 1 << 20  # bytes per compressed block
_CHUNK = 3 * (1 << 18)  # bytes per base64 chunk: a multiple of 3, so the chunks join into one stream
_ROWS = 1 << 16  # values per line batch of ASCII arrays
_LEVEL = 1  # zlib level: the fastest, within a few per cent of the default's size on these arrays


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
    """The values, flattened, ``items`` at a time (views of an array, or made by a _Ramp)."""
    if isinstance(values, _Ramp):
        for start in range(0, values.n, items):
            yield values.chunk(start, min(start + items, values.n))
        return
    flat = np.ascontiguousarray(values.astype(values.dtype.newbyteorder("<"), copy=False)).reshape(-1)
    for start in range(0, len(flat), items):
        yield flat[start:start + items]


class _Base64:
    """base64 of a stream of byte pieces, written as it comes (pieces need not align to 3)."""

    def __init__(self, handle):
        self.handle, self.carry = handle, b""

    def write(self, piece) -> None:
        block = self.carry + bytes(piece)
        cut = len(block) - len(block) % 3
        self.handle.write(base64.b64encode(block[:cut]).decode("ascii"))
        self.carry = block[cut:]

    def close(self) -> None:
        self.handle.write(base64.b64encode(self.carry).decode("ascii"))
        self.carry = b""


def _write_array(handle, name: str, values, fmt: str, indent: str) -> None:
    vtk_type = VTK_TYPES.get(np.dtype(values.dtype))
    if vtk_type is None:
        raise InputError(f"data array {name!r} has dtype {values.dtype}, which VTK cannot store")
    components = f' NumberOfComponents="{values.shape[1]}"' if values.ndim == 2 else ""
    kind = "ascii" if fmt == "ascii" else "binary"
    handle.write(f'{indent}<DataArray type="{vtk_type}" Name={quoteattr(name)}{components} format="{kind}">')
    itemsize = np.dtype(values.dtype).itemsize
    n_bytes = int(values.size) * itemsize
    if fmt == "ascii":
        floating = vtk_type.startswith("Float")
        for part in _chunks(values, _ROWS):
            part = part.tolist()
            handle.write((" ".join(map(repr, part)) if floating else " ".join(map(str, part))) + " ")
    elif fmt == "zlib":
        # The header lists every block's compressed size, so the blocks are made first (they
        # are the compressed array: no larger than it), then written one by one.
        blocks = [zlib.compress(part, _LEVEL) for part in _chunks(values, _BLOCK // itemsize)]
        size = (_BLOCK // itemsize) * itemsize
        last = n_bytes % size  # VTK: the last block's size when it is partial, else 0
        header = np.array([len(blocks), size, last, *map(len, blocks)], dtype="<u8")
        handle.write(base64.b64encode(header.tobytes()).decode("ascii"))
        stream = _Base64(handle)
        for k in range(len(blocks)):
            stream.write(blocks[k])
            blocks[k] = None
        stream.close()
    else:
        stream = _Base64(handle)
        stream.write(np.array([n_bytes], dtype="<u8").tobytes())
        for part in _chunks(values, max(_CHUNK // itemsize, 1)):
            stream.write(memoryview(part).cast("B"))
        stream.close()
    handle.write("</DataArray>\n")


def write_vtk_xml(path, surface, *, binary: bool = True, polydata: bool = False) -> None:
    """Write ``surface`` (:class:`~dea_opt.io.surface.SurfaceData`) as VTK XML to ``path``.

    Parameters
    ----------
    path : path-like
        The file to write (the caller makes it atomic).
    surface : SurfaceData
    binary : bool
        Base64 binary (zlib-compressed for UnstructuredGrid) or ASCII.
    polydata : bool
        PolyData (``.vtp``) instead of UnstructuredGrid (``.vtu``).
    """
    cells = np.asarray(surface.cells)
    if cells.dtype not in (np.dtype(np.int32), np.dtype(np.int64)):
        cells = cells.astype(np.int64)
    n_cells, per_cell = cells.shape
    arrays = [surface.points, cells, *surface.cell_data.values(), *surface.point_data.values()]
    compress = binary and not polydata and all(np.asarray(a).size for a in arrays)
    fmt = "ascii" if not binary else ("zlib" if compress else "raw")
    compressor = ' compressor="vtkZLibDataCompressor"' if compress else ""
    kind = "PolyData" if polydata else "UnstructuredGrid"
    offsets = _Ramp(n_cells, per_cell, np.int64)
    with open(path, "w", encoding="ascii", newline="\n") as handle:
        handle.write('<?xml version="1.0"?>\n')
        handle.write(f'<VTKFile type="{kind}" version="1.0" byte_order="LittleEndian" '
                     f'header_type="UInt64"{compressor}>\n  <{kind}>\n')
        if polydata:
            block = "Verts" if surface.cell_type == "vertex" else "Polys"
            counts = {"Verts": 0, "Lines": 0, "Strips": 0, "Polys": 0}
            counts[block] = n_cells
            handle.write(f'    <Piece NumberOfPoints="{len(surface.points)}" '
                         + " ".join(f'NumberOf{k}="{v}"' for k, v in counts.items()) + ">\n")
        else:
            block = "Cells"
            handle.write(f'    <Piece NumberOfPoints="{len(surface.points)}" NumberOfCells="{n_cells}">\n')
        for tag, data in (("PointData", surface.point_data), ("CellData", surface.cell_data)):
            scalars = ' Scalars="pressure"' if "pressure" in data else ""
            handle.write(f"      <{tag}{scalars}>\n")
            for name, value in data.items():
                _write_array(handle, name, np.asarray(value), fmt, "        ")
            handle.write(f"      </{tag}>\n")
        handle.write("      <Points>\n")
        _write_array(handle, "Points", np.asarray(surface.points, dtype=np.float64), fmt, "        ")
        handle.write(f"      </Points>\n      <{block}>\n")
        _write_array(handle, "connectivity", cells, fmt, "        ")
        _write_array(handle, "offsets", offsets, fmt, "        ")
        if not polydata:
            cell_type = _CELL_TYPES.get(surface.cell_type)
            if cell_type is None:
                raise InputError(f"cannot write cells of type {surface.cell_type!r} to .vtu")
            _write_array(handle, "types", _Ramp(n_cells, cell_type, np.uint8, constant=True), fmt, "        ")
        handle.write(f"      </{block}>\n    </Piece>\n  </{kind}>\n</VTKFile>\n")
