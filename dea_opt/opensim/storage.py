"""OpenSim Storage files (``.sto``, ``.mot``), read with plain Python: load paths and motions.

JointReaction and Inverse Kinematics write this text format: a name line, ``key=value``
header lines (``version``, ``nRows``, ``nColumns``, ``inDegrees=yes|no``, ...) and free
text, ``endheader``, one row of column labels, then one row of numbers per frame, the
fields separated by tabs (or spaces). The scenario's ``[load_path] columns`` table says
which column is which quantity (``Fx = "knee_r_on_femur_r_in_femur_r_fx"``; a leading
``-`` negates it); rotations are read in degrees or radians as ``inDegrees`` says and
returned in degrees; with ``units = "SI"`` (OpenSim's N, N m, m) moments and translations
are converted to N mm and mm.
"""

from __future__ import annotations

import difflib
import math
from pathlib import Path

import numpy as np

from ..errors import InputError, ScenarioError

__all__ = ["StorageFile", "load_path_columns", "read_storage"]

_ROTATIONS = ("pose_rx", "pose_ry", "pose_rz")
_TRANSLATIONS = ("pose_tx", "pose_ty", "pose_tz")
_MOMENTS = ("Mx", "My", "Mz")


class StorageFile:
    """A parsed Storage file: ``header`` (``{key: value}``, lower-case keys), ``labels`` and ``data``
    (rows x columns, float64)."""

    def __init__(self, path: Path, header: dict, labels: list, data: np.ndarray):
        self.path, self.header, self.labels, self.data = path, header, labels, data

    @property
    def in_degrees(self) -> bool | None:
        """``inDegrees`` of the header: True, False, or None when the header does not say."""
        value = self.header.get("indegrees", "").strip().lower()
        return {"yes": True, "true": True, "no": False, "false": False}.get(value)

    def column(self, spec: str, where: str) -> np.ndarray:
        """The column named ``spec`` (``-name`` negated); ``where`` names the scenario key in errors."""
        negate = spec.startswith("-")
        name = spec[1:].strip() if negate else spec.strip()
        if name not in self.labels:
            close = difflib.get_close_matches(name, self.labels, n=3)
            hint = f"; did you mean {', '.join(repr(c) for c in close)}?" if close else ""
            raise ScenarioError(
                f"{where} names the column {name!r}, which {self.path} does not have{hint} (its "
                f"columns: {_shortlist(self.labels)})"
            )
        values = self.data[:, self.labels.index(name)]
        return -values if negate else values


def _shortlist(labels: list) -> str:
    return ", ".join(labels[:12]) + (f" and {len(labels) - 12} more" if len(labels) > 12 else "")


def read_storage(path, what: str = "load path", error: type[InputError] = ScenarioError) -> StorageFile:
    """Parse an OpenSim Storage file; errors (``error``) name the file (as ``what``: "load path",
    "motion") and the line."""
    path = Path(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise error(f"{what} {path} is not UTF-8 text (byte {exc.start}): is it an OpenSim .sto/.mot file?") from None
    lines = text.splitlines()
    end = next((i for i, line in enumerate(lines) if line.strip().lower() == "endheader"), None)
    if end is None:
        raise error(
            f"{what} {path} has no 'endheader' line: an OpenSim Storage file (.sto/.mot) starts "
            f"with header lines ending in 'endheader', then a row of column labels"
        )
    header = {}
    for line in lines[:end]:
        key, sep, value = line.partition("=")
        if sep:
            header[key.strip().lower()] = value.strip()
    rows = [(number, line) for number, line in enumerate(lines[end + 1 :], start=end + 2) if line.strip()]
    if not rows:
        raise error(f"{what} {path} has no row of column labels after 'endheader'")
    tabs = "\t" in rows[0][1]

    def split(line: str) -> list:
        return [field.strip() for field in line.strip().split("\t")] if tabs else line.split()

    labels = split(rows[0][1])
    repeated = sorted({label for label in labels if labels.count(label) > 1})
    if repeated:
        raise error(f"{what} {path}, line {rows[0][0]}: repeated column labels {', '.join(repeated)}")
    data = np.empty((len(rows) - 1, len(labels)))
    for k, (number, line) in enumerate(rows[1:]):
        fields = split(line)
        if len(fields) != len(labels):
            raise error(f"{what} {path}, line {number}: {len(fields)} fields, but the label row has {len(labels)}")
        for j, field in enumerate(fields):
            try:
                value = float(field)
            except ValueError:
                value = math.nan
            if not math.isfinite(value):
                raise error(
                    f"{what} {path}, line {number}, column {labels[j]}: expected a finite number, got {field!r}"
                )
            data[k, j] = value
    if not len(data):
        raise error(f"{what} {path} has a label row but no rows of numbers")
    expected = header.get("nrows")
    if expected is not None and expected.isdigit() and int(expected) != len(data):
        raise error(f"{what} {path}: its header says nRows={expected}, but it has {len(data)} rows (a file cut short?)")
    return StorageFile(path, header, labels, data)


def load_path_columns(section) -> dict:
    """``{quantity: values}`` of the ``.sto``/``.mot`` file of ``[load_path]``, in mm, N, N mm, degrees.

    Quantities: ``time``, ``Fx``..``Mz`` and, when any pose quantity is named, all six pose
    columns (the ones not named are 0).
    """
    storage = read_storage(section.file)
    columns = dict(section.columns)
    columns.setdefault("time", "time")
    table = {q: storage.column(spec, f"load_path.columns.{q}") for q, spec in columns.items()}
    si = (section.units or "SI") == "SI"
    for quantity in _MOMENTS + _TRANSLATIONS:
        if si and quantity in table:
            table[quantity] = table[quantity] * 1000.0  # N m -> N mm, m -> mm
    rotations = [q for q in _ROTATIONS if q in table]
    if rotations:
        degrees = storage.in_degrees
        if degrees is None:
            raise ScenarioError(
                f"load path {storage.path}: its header does not say inDegrees=yes or no, so the "
                f"rotations {', '.join(section.columns[q] for q in rotations)} cannot be read; add "
                f"the line to the header"
            )
        for quantity in rotations:
            table[quantity] = table[quantity] if degrees else np.degrees(table[quantity])
    if any(q in table for q in _ROTATIONS + _TRANSLATIONS):
        for quantity in _TRANSLATIONS + _ROTATIONS:
            table.setdefault(quantity, np.zeros(len(storage.data)))
    return table
