"""A reader of legacy VTK POLYDATA files (``.vtk``, ASCII or BINARY), with no dependency.

Points and the polygons and triangle strips (split into triangles) are read; point and cell
attributes are not needed for the geometry and are not read. Versions before and after 5.0
(OFFSETS/CONNECTIVITY arrays) are both understood. Lengths as in the file.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["parse_vtk_polydata"]


_VTK_TYPES = {
    "unsigned_char": "u1",
    "char": "i1",
    "unsigned_short": "u2",
    "short": "i2",
    "unsigned_int": "u4",
    "int": "i4",
    "unsigned_long": "u8",
    "long": "i8",
    "float": "f4",
    "double": "f8",
    "vtktypeint64": "i8",
    "vtktypeint32": "i4",
    "vtkidtype": "i8",
}
_VTK_SECTIONS = {
    "POINTS",
    "VERTICES",
    "LINES",
    "POLYGONS",
    "TRIANGLE_STRIPS",
    "POINT_DATA",
    "CELL_DATA",
    "FIELD",
    "METADATA",
}


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
                line = self.data[self.pos : end].decode("ascii", "replace").split()
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

    def header(self, count: int) -> list[str]:
        """The next section header, with its ``count`` further tokens in ASCII mode (a binary
        header is its whole line); a ``ValueError`` where the file ends instead."""
        line = self.keyword()
        if line is None:
            raise ValueError("the file ends before a section it announces")
        return line if self.binary else line + self.take(count)

    def take(self, count: int) -> list[str]:
        """The next ``count`` header tokens (ASCII mode)."""
        out = [t.decode("ascii", "replace") for t in self.tokens[self.index : self.index + count]]
        self.index += count
        return out

    def array(self, count: int, vtk_type: str) -> np.ndarray:
        dtype = _VTK_TYPES.get(vtk_type.lower())
        if dtype is None:
            raise ValueError(f"unknown VTK data type {vtk_type!r}")
        if self.binary:
            size = count * np.dtype(dtype).itemsize
            raw = self.data[self.pos : self.pos + size]
            if len(raw) < size:
                raise ValueError("the file ends inside a binary array")
            self.pos += size
            return np.frombuffer(raw, dtype=">" + dtype).astype(dtype)
        chunk = self.tokens[self.index : self.index + count]
        if len(chunk) < count:
            raise ValueError("the file ends inside an ASCII array")
        self.index += count
        return np.array(chunk, dtype=float).astype(dtype)

    def skip_metadata(self) -> None:
        if self.binary:  # METADATA ends at the first empty line
            while self.pos < len(self.data):
                end = self.data.find(b"\n", self.pos)
                end = len(self.data) if end < 0 else end
                empty = not self.data[self.pos : end].strip()
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
        cell = connectivity[start : start + size]
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
        offsets_header = cursor.header(1)
        offsets = cursor.array(n_offsets, offsets_header[1])
        conn_header = cursor.header(1)
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
        conn.append(flat[pos + 1 : pos + 1 + k])
        pos += k + 1
    return np.array(sizes, dtype=np.int64), np.concatenate(conn) if conn else np.zeros(0, np.int64)


def parse_vtk_polydata(path: Path) -> tuple[np.ndarray, np.ndarray] | None:
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
                array = cursor.header(3)
                cursor.array(int(array[1]) * int(array[2]), array[3])
        elif key in ("POINT_DATA", "CELL_DATA"):
            break  # attributes are not needed for the geometry
        else:
            raise ValueError(f"unexpected section {header[0]!r}")
    faces = np.concatenate(triangles) if triangles else np.zeros((0, 3), dtype=np.int64)
    return vertices, faces
