"""Tables as CSV: the per-spring results of a solution, springs tables, and numeric tables read with errors that name the place.

Every file is written with the standard library's :mod:`csv` and floats as ``repr(float)``,
the shortest text that reads back to the same double, so a table written here reads back
bit for bit. Readers check their columns (a missing one, and one they do not know, are both
errors: a misspelt column must not be ignored) and every cell (a word, an empty cell or a
NaN is an error naming the file, the line and the column). Lines starting with ``#`` are
comments in the numeric tables.

A springs table has columns ``x, y, z`` (mm), ``nx, ny, nz`` (the normal from body 1 to
body 2), ``area`` (mm^2), ``thickness`` (mm), and optionally ``gap`` (mm, default 0) and
``label`` (a region label: an integer or a word such as ``medial``; CSV or NPZ).
"""

from __future__ import annotations

import csv
import io
import itertools
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..files.atomic import atomic_open, file_path, write_atomic

__all__ = [
    "CHUNK_ROWS",
    "CSV_COLUMNS",
    "SPRING_COLUMNS",
    "read_csv",
    "read_numeric_csv",
    "read_springs",
    "to_csv",
    "write_springs",
]

#: Columns of :func:`to_csv`, in order; a column's unit is the suffix of its name (:mod:`dea_opt.units`).
CSV_COLUMNS = (
    "x_mm",
    "y_mm",
    "z_mm",
    "nx",
    "ny",
    "nz",
    "area_mm2",
    "thickness_mm",
    "gap_mm",
    "strain",
    "pressure_MPa",
    "spring_force_N",
    "in_contact",
    "source_face",
    "label",
)
_FLOAT_COLUMNS = CSV_COLUMNS[:12]
#: Required columns of a springs table (``gap`` and ``label`` are optional).
SPRING_COLUMNS = ("x", "y", "z", "nx", "ny", "nz", "area", "thickness")


def _write_rows(path, header, columns) -> Path:
    """``header`` and the ``columns`` (lists of equal length) as CSV; floats as ``repr``."""
    with atomic_open(path, "w", newline="") as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(header)
        writer.writerows(zip(*columns))
    return Path(path)


# --- the results of a solution, one row per spring --------------------------------------
#: Rows per chunk of :func:`to_csv`: the text of one chunk is all that is built in memory.
CHUNK_ROWS = 1 << 16


def _texts(values: np.ndarray):
    """The CSV text of each value: ``repr`` of a float (its shortest round-trip form), ``str`` of
    an int. A column of one repeated value is formatted once; a chunk of few distinct values
    (a grid's coordinates, flags) formats each distinct value once and indexes them."""
    if not len(values):
        return []
    if values[0] == values[-1] and (values == values[0]).all():
        one = values[0].item()
        return itertools.repeat(repr(one) if isinstance(one, float) else str(one), len(values))
    form = repr if values.dtype.kind == "f" else str
    # Formatting a float costs about seven times sorting it: worth a sort to format fewer.
    distinct, index = np.unique(values, return_inverse=True)
    if len(distinct) <= len(values) // 4:
        return np.array(list(map(form, distinct.tolist())), dtype=object)[index].tolist()
    return list(map(form, values.tolist()))


def _quoted(text: str) -> str:
    """``text`` as the csv module writes it in a row of several fields (quoted when needed)."""
    if text == "":
        return ""
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerow([text])  # as in the file: a newline is quoted
    return buffer.getvalue()[:-1]


def to_csv(solution, path) -> Path:
    """Write one row per spring, in spring order, with a header row.

    Columns (:data:`CSV_COLUMNS`; each name ends with its unit, :mod:`dea_opt.units`):

    ====================  ===============================================================
    column                meaning
    ====================  ===============================================================
    x_mm, y_mm, z_mm      spring position (face centroid), mm
    nx, ny, nz            unit normal, body 1 to body 2
    area_mm2              area the spring stands for, mm^2
    thickness_mm          unloaded spring length (total cartilage thickness), mm
    gap_mm                initial gap along the normal (< 0 where the surfaces overlap), mm
    strain                spring strain (< 0 in compression)
    pressure_MPa          contact pressure (>= 0), MPa
    spring_force_N        ``-pressure * area``, tension positive (<= 0), N
    in_contact            1 where ``strain < 0``, else 0
    source_face           index of the spring's face in ``layer.surface``; -1 if unknown
    label                 the spring's region label; empty if the layer has none
    ====================  ===============================================================

    Floats are written with Python's shortest round-trip representation, so
    :func:`read_csv` gives back the same numbers bit for bit. The file is written in chunks
    of :data:`CHUNK_ROWS` rows (atomically): memory stays near one chunk's text whatever
    the number of springs, and the bytes are those the :mod:`csv` module writes.

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
        layer.points[:, 0],
        layer.points[:, 1],
        layer.points[:, 2],
        layer.normals[:, 0],
        layer.normals[:, 1],
        layer.normals[:, 2],
        layer.areas,
        layer.thickness,
        layer.gap,
        solution.strain,
        solution.pressure,
        solution.spring_force,
    ]
    columns = [
        *floats,
        solution.in_contact.astype(np.int64),
        layer.source_face if layer.source_face is not None else np.full(n, -1, dtype=np.int64),
    ]
    if layer.labels is not None:
        names, codes = np.unique(np.asarray(layer.labels).astype(str), return_inverse=True)
        quoted = [_quoted(name) for name in names.tolist()]
    with atomic_open(path, "w", newline="") as handle:
        handle.write(",".join(CSV_COLUMNS) + "\n")
        for start in range(0, n, CHUNK_ROWS):
            stop = min(start + CHUNK_ROWS, n)
            texts = [_texts(c[start:stop]) for c in columns]
            if layer.labels is not None:
                texts.append([quoted[c] for c in codes[start:stop].tolist()])
            else:
                texts.append(itertools.repeat("", stop - start))
            handle.write("\n".join(map(",".join, zip(*texts))))
            handle.write("\n")
    return Path(path)


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
    target = file_path(path)
    if not target.is_file():
        raise InputError(f"path: no such file {str(target)!r}")
    with open(target, encoding="utf-8", newline="") as handle:
        rows = list(csv.reader(handle))
    header = ",".join(rows[0]) if rows else ""
    if header != ",".join(CSV_COLUMNS):
        raise InputError(
            f"path: {str(target)!r} is not a dea_opt spring table; expected the header "
            f"{','.join(CSV_COLUMNS)}, got {header or 'an empty file'}"
        )
    rows = rows[1:]
    short = next((i for i, row in enumerate(rows) if len(row) != len(CSV_COLUMNS)), None)
    if short is not None:
        raise InputError(
            f"path: row {short + 1} of {str(target)!r} has {len(rows[short])} fields, expected {len(CSV_COLUMNS)}"
        )
    text = np.array(rows, dtype=object).reshape(len(rows), len(CSV_COLUMNS))
    out = {}
    for k, name in enumerate(CSV_COLUMNS):
        column = text[:, k]
        try:
            # Python's float() is correctly rounded, so repr() text reads back bit for bit.
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


# --- numeric tables: load paths and springs ---------------------------------------------
def read_numeric_csv(path, required: tuple, optional: tuple = (), what: str = "table", text: tuple = ()):
    """A CSV of numbers as a DataFrame, with errors that name the file, line and column.

    Lines starting with ``#`` are comments. Columns outside ``required + optional`` are
    an error (a misspelt column should not be silently ignored). Numbers are parsed by
    Python's correctly rounded ``float``, so a table written by :func:`write_springs` reads
    back bit for bit. Columns named in ``text`` are kept as strings (stripped).
    """
    import pandas as pd

    path = Path(path)
    try:
        table = pd.read_csv(path, comment="#", dtype=str, skipinitialspace=True, keep_default_na=False)
    except pd.errors.EmptyDataError:
        raise InputError(f"{what} {path} is empty: expected a header line with columns {','.join(required)}") from None
    except (pd.errors.ParserError, UnicodeDecodeError) as exc:
        raise InputError(f"{what} {path} is not a readable CSV: {exc}".replace("\n", " ")) from None
    table.columns = [str(c).strip() for c in table.columns]
    missing = [c for c in required if c not in table.columns]
    unknown = [c for c in table.columns if c not in required and c not in optional]
    if missing or unknown:
        problems = []
        if missing:
            problems.append(f"missing column{'s' if len(missing) > 1 else ''} {', '.join(missing)}")
        if unknown:
            problems.append(f"unknown column{'s' if len(unknown) > 1 else ''} {', '.join(unknown)}")
        raise InputError(
            f"{what} {path}: {' and '.join(problems)}; expected columns {','.join(required)}"
            + (f" and optionally {','.join(optional)}" if optional else "")
        )
    if table.empty:
        raise InputError(f"{what} {path} has a header but no rows")
    lines = _data_lines(path)
    numeric = {}
    for column in table.columns:
        raw = table[column]
        stripped = raw.str.strip()
        if column in text:
            numeric[column] = stripped.fillna("").to_numpy(dtype=str)
            continue
        values = pd.to_numeric(stripped, errors="coerce")
        bad = values.isna() | ~np.isfinite(values.fillna(0.0))
        if bad.any():
            row = int(np.argmax(bad.to_numpy()))
            cell = raw.iloc[row]
            line = lines[row] if row < len(lines) else None
            where = f"line {line}" if line else f"row {row + 1}"
            got = "an empty cell" if pd.isna(cell) or str(cell).strip() == "" else f"{str(cell).strip()!r}"
            raise InputError(f"{what} {path}, {where}, column {column}: expected a finite number, got {got}")
        try:
            numeric[column] = stripped.to_numpy(dtype=object).astype(np.float64)
        except ValueError:  # a spelling pandas reads and Python's float does not
            numeric[column] = values.to_numpy(dtype=float)
    return pd.DataFrame(numeric)


def _data_lines(path: Path) -> list[int]:
    """1-based line numbers of the data rows (after the header; comments and blanks skipped)."""
    numbers = []
    with open(path, encoding="utf-8", errors="replace") as handle:
        for number, line in enumerate(handle, start=1):
            stripped = line.strip()
            if stripped and not stripped.startswith("#"):
                numbers.append(number)
    return numbers[1:]


def read_springs(path):
    """A :class:`~dea_opt.layer.SpringLayer` from a springs table (CSV or NPZ).

    Columns (CSV) or arrays (NPZ): ``x, y, z`` (mm), ``nx, ny, nz`` (normal from body 1 to
    body 2), ``area`` (mm^2), ``thickness`` (mm), optional ``gap`` (mm, default 0) and
    optional ``label`` (a region label: integers, or words such as ``medial``).
    """
    from ..layer import SpringLayer

    path = Path(path)
    if path.suffix.lower() == ".npz":
        return _springs_from_npz(path)
    table = read_numeric_csv(path, SPRING_COLUMNS, ("gap", "label"), "springs table", text=("label",))
    points = table[["x", "y", "z"]].to_numpy(dtype=float)
    normals = table[["nx", "ny", "nz"]].to_numpy(dtype=float)
    gap = table["gap"].to_numpy(dtype=float) if "gap" in table else 0.0
    labels = _labels(table["label"].to_numpy(dtype=str), path) if "label" in table else None
    try:
        return SpringLayer(
            points,
            normals,
            table["area"].to_numpy(dtype=float),
            table["thickness"].to_numpy(dtype=float),
            gap,
            labels=labels,
        )
    except InputError as exc:
        raise InputError(f"springs table {path}: {exc}") from None


def _npz_array(data, name: str, path: Path, n: int | None, numeric: bool = True) -> np.ndarray:
    """One array of a springs NPZ, checked: 1-D, of a plain dtype, ``n`` long."""
    try:
        array = data[name]
    except ValueError:  # numpy's refusal to unpickle an array of Python objects
        raise InputError(
            f"springs table {path}: array {name!r} holds Python objects (saved from ragged lists or "
            f"with dtype=object), which dea-opt does not load (it never unpickles): save it as a "
            f"1-D numeric array"
        ) from None
    except Exception as exc:  # noqa: BLE001 - a damaged archive member: zipfile and zlib errors
        raise InputError(f"springs table {path}: array {name!r} cannot be read ({type(exc).__name__}: {exc})") from None
    kinds = "fiu" if numeric else "iuU"
    if array.ndim != 1 or array.dtype.kind not in kinds:
        expected = "a 1-D array of numbers" if numeric else "a 1-D array of text or integers"
        raise InputError(
            f"springs table {path}: array {name!r} must be {expected}, got shape {array.shape} and dtype {array.dtype}"
        )
    if n is not None and len(array) != n:
        raise InputError(
            f"springs table {path}: array {name!r} has {len(array)} values, but 'x' has {n}: every "
            f"array needs one value per spring"
        )
    return array


def _springs_from_npz(path: Path):
    from ..layer import SpringLayer

    try:
        data = np.load(path, allow_pickle=False)
    except Exception as exc:  # noqa: BLE001 - not a zip, a damaged zip, a folder: all "not an NPZ"
        raise InputError(f"springs table {path} is not a readable NPZ file: {type(exc).__name__}: {exc}") from None
    with data:
        missing = [c for c in SPRING_COLUMNS if c not in data.files]
        if missing:
            raise InputError(
                f"springs table {path}: missing array{'s' if len(missing) > 1 else ''} "
                f"{', '.join(missing)}; expected {','.join(SPRING_COLUMNS)} and optionally gap, label"
            )
        unknown = [c for c in data.files if c not in (*SPRING_COLUMNS, "gap", "label")]
        if unknown:
            raise InputError(
                f"springs table {path}: unknown array{'s' if len(unknown) > 1 else ''} "
                f"{', '.join(unknown)}; expected {','.join(SPRING_COLUMNS)} and optionally gap, label"
            )
        n = len(_npz_array(data, "x", path, None))
        columns = {name: _npz_array(data, name, path, n) for name in (*SPRING_COLUMNS, "gap") if name in data.files}
        labels = _npz_array(data, "label", path, n, numeric=False) if "label" in data.files else None
    points = np.column_stack([columns["x"], columns["y"], columns["z"]])
    normals = np.column_stack([columns["nx"], columns["ny"], columns["nz"]])
    try:
        gap = columns["gap"] if "gap" in columns else np.zeros(len(points))
        return SpringLayer(points, normals, columns["area"], columns["thickness"], gap, labels=labels)
    except InputError as exc:
        raise InputError(f"springs table {path}: {exc}") from None


def _labels(text: np.ndarray, path) -> np.ndarray:
    """Region labels read as text: integers when every one is an integer, else the words."""
    if (text == "").any():
        row = int(np.argmax(text == ""))
        raise InputError(
            f"springs table {path}, row {row + 1}, column label: expected a region label, got an empty cell"
        )
    try:
        return np.array([int(v) for v in text.tolist()], dtype=np.int64)
    except ValueError:
        return text


def write_springs(layer, path) -> Path:
    """Write a layer as a springs CSV that :func:`read_springs` reads back bit for bit (atomically).

    Columns ``x, y, z, nx, ny, nz, area, thickness, gap``, and ``label`` when the layer has
    labels (integers, or words such as ``medial``, quoted where the csv module must).
    A path ending in ``.npz`` gets an NPZ file instead, one array per column.
    """
    if Path(path).suffix.lower() == ".npz":
        return _write_springs_npz(layer, path)
    columns = [
        layer.points[:, 0],
        layer.points[:, 1],
        layer.points[:, 2],
        layer.normals[:, 0],
        layer.normals[:, 1],
        layer.normals[:, 2],
        layer.areas,
        layer.thickness,
        layer.gap,
    ]
    header: tuple[str, ...] = (*SPRING_COLUMNS, "gap")
    rows = [np.asarray(c, dtype=float).tolist() for c in columns]
    if layer.labels is not None:
        labels = np.asarray(layer.labels)
        integer = np.issubdtype(labels.dtype, np.integer)
        rows.append(labels.astype(np.int64).tolist() if integer else labels.astype(str).tolist())
        header = (*header, "label")
    return _write_rows(path, header, rows)


def _write_springs_npz(layer, path) -> Path:
    arrays = {
        name: np.asarray(values, dtype=float)
        for name, values in (
            ("x", layer.points[:, 0]),
            ("y", layer.points[:, 1]),
            ("z", layer.points[:, 2]),
            ("nx", layer.normals[:, 0]),
            ("ny", layer.normals[:, 1]),
            ("nz", layer.normals[:, 2]),
            ("area", layer.areas),
            ("thickness", layer.thickness),
            ("gap", layer.gap),
        )
    }
    if layer.labels is not None:
        labels = np.asarray(layer.labels)
        arrays["label"] = labels.astype(np.int64) if np.issubdtype(labels.dtype, np.integer) else labels.astype(str)
    return write_atomic(path, lambda tmp: _save_npz(tmp, arrays))


def _save_npz(tmp: Path, arrays: dict) -> None:
    with open(tmp, "wb") as handle:  # a handle: numpy would add ".npz" to a name
        np.savez(handle, **arrays)
