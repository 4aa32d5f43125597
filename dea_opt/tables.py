"""Tables of numbers from files: load paths and springs (CSV or NPZ), with errors that name the place.

Every reader checks its columns (a missing one, and one it does not know, are both errors:
a misspelt column must not be ignored), and every cell (a word, an empty cell or a NaN is
an error naming the file, the line and the column). Lines starting with ``#`` are comments.

A springs table has columns ``x, y, z`` (mm), ``nx, ny, nz`` (the normal from body 1 to
body 2), ``area`` (mm^2), ``thickness`` (mm), and optionally ``gap`` (mm, default 0) and
``label`` (an integer region label, CSV only).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import InputError

__all__ = ["read_numeric_csv", "read_springs", "write_springs", "SPRING_COLUMNS"]

SPRING_COLUMNS = ("x", "y", "z", "nx", "ny", "nz", "area", "thickness")


def read_numeric_csv(path, required: tuple, optional: tuple = (), what: str = "table"):
    """A CSV of numbers as a DataFrame, with errors that name the file, line and column.

    Lines starting with ``#`` are comments. Columns outside ``required + optional`` are
    an error (a misspelt column should not be silently ignored).
    """
    import pandas as pd

    path = Path(path)
    try:
        table = pd.read_csv(path, comment="#", dtype=str, skipinitialspace=True)
    except pd.errors.EmptyDataError:
        raise InputError(f"{what} {path} is empty: expected a header line with columns "
                         f"{','.join(required)}") from None
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
        raise InputError(f"{what} {path}: {' and '.join(problems)}; expected columns {','.join(required)}"
                            + (f" and optionally {','.join(optional)}" if optional else ""))
    if table.empty:
        raise InputError(f"{what} {path} has a header but no rows")
    lines = _data_lines(path)
    numeric = {}
    for column in table.columns:
        raw = table[column]
        values = pd.to_numeric(raw.str.strip(), errors="coerce")
        bad = values.isna() | ~np.isfinite(values.fillna(0.0))
        if bad.any():
            row = int(np.argmax(bad.to_numpy()))
            cell = raw.iloc[row]
            line = lines[row] if row < len(lines) else None
            where = f"line {line}" if line else f"row {row + 1}"
            got = "an empty cell" if pd.isna(cell) or str(cell).strip() == "" else f"{str(cell).strip()!r}"
            raise InputError(f"{what} {path}, {where}, column {column}: expected a finite number, got {got}")
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
    body 2), ``area`` (mm^2), ``thickness`` (mm), optional ``gap`` (mm, default 0) and, in
    CSV, optional ``label`` (an integer region label).
    """
    from .layer import SpringLayer

    path = Path(path)
    if path.suffix.lower() == ".npz":
        return _springs_from_npz(path)
    table = read_numeric_csv(path, SPRING_COLUMNS, ("gap", "label"), "springs table")
    points = table[["x", "y", "z"]].to_numpy()
    normals = table[["nx", "ny", "nz"]].to_numpy()
    gap = table["gap"].to_numpy() if "gap" in table else 0.0
    labels = table["label"].to_numpy().astype(int) if "label" in table else None
    try:
        return SpringLayer(points, normals, table["area"].to_numpy(), table["thickness"].to_numpy(), gap,
                           labels=labels)
    except InputError as exc:
        raise InputError(f"springs table {path}: {exc}") from None


def _springs_from_npz(path: Path):
    from .layer import SpringLayer

    try:
        data = np.load(path)
    except (OSError, ValueError) as exc:
        raise InputError(f"springs table {path} is not a readable NPZ file: {exc}") from None
    missing = [c for c in SPRING_COLUMNS if c not in data.files]
    if missing:
        raise InputError(f"springs table {path}: missing array{'s' if len(missing) > 1 else ''} "
                         f"{', '.join(missing)}; expected {','.join(SPRING_COLUMNS)} and optionally gap")
    points = np.column_stack([data["x"], data["y"], data["z"]])
    normals = np.column_stack([data["nx"], data["ny"], data["nz"]])
    try:
        gap = data["gap"] if "gap" in data.files else 0.0
        return SpringLayer(points, normals, data["area"], data["thickness"], gap)
    except InputError as exc:
        raise InputError(f"springs table {path}: {exc}") from None


def write_springs(layer, path) -> Path:
    """Write a layer as a springs CSV that :func:`read_springs` reads back (atomically)."""
    import pandas as pd

    from .io import write_data

    table = pd.DataFrame({
        "x": layer.points[:, 0], "y": layer.points[:, 1], "z": layer.points[:, 2],
        "nx": layer.normals[:, 0], "ny": layer.normals[:, 1], "nz": layer.normals[:, 2],
        "area": layer.areas, "thickness": layer.thickness, "gap": layer.gap,
    })
    return write_data(path, table.to_csv(index=False, float_format="%.10g", lineterminator="\n"))
