"""The load section ``dea-opt init`` writes (:mod:`dea_opt.run.init`): a force pressing the
bodies together, or a load file read, its sign and (OpenSim ``.sto``) its columns and units
sniffed against the contact the springs make. Units: N, N mm, mm, s.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError

__all__ = ["LoadSection", "describe_load"]

#: A contact's mean normal within this angle (degrees) of an axis presses along that axis.
SNAP_DEGREES = 15.0
_STATIC_OUTPUTS = (
    "contact.vtu (ParaView), contact.csv (one row per spring), contact.json (the numbers, the "
    "validity, the certificate) and contact.png (the pressure map)"
)
_PATH_OUTPUTS = (
    "frames.csv (one row per frame), series.pvd (ParaView, every frame), exposure.vtu, cycle.png, "
    "exposure.png and summary.json"
)


@dataclass
class LoadSection:
    """The TOML ``lines`` of ``[load]`` or ``[load_path]`` (with comments), the ``notes`` of what
    was decided, a short ``title`` and the ``outputs`` a run of it writes."""

    lines: list
    title: str
    outputs: str
    notes: list = field(default_factory=list)


def _number(load) -> float | None:
    if isinstance(load, (int, float)):
        return float(load)
    try:
        return float(str(load))
    except ValueError:
        return None


def relative_path(path, folder: Path) -> str:
    """``path`` as the scenario writes it: relative to its folder when it lies inside it, else
    absolute (a path climbing out of the folder breaks when either moves)."""
    absolute = Path(path).expanduser().resolve()
    return os.path.relpath(absolute, folder) if absolute.is_relative_to(folder) else str(absolute)


def wrapped(text: str, prefix: str, width: int = 96) -> list[str]:
    import textwrap

    return textwrap.wrap(text, width=width, initial_indent=prefix, subsequent_indent=prefix)


def describe_load(load, shape, folder: Path, sto_prefix: str | None = None) -> LoadSection:
    """The load section for ``load`` (N, or a load file's path) on the contact ``shape``
    (:class:`~dea_opt.run.contact_shape.ContactShape`); paths relative to ``folder``."""
    value = _number(load)
    if value is not None:
        return _static(value, shape)
    path = Path(str(load)).expanduser()
    if not path.is_file():
        raise InputError(f"--load must be a force in N or a load file, got {load!r}: no such file {path.resolve()}")
    if shape.normal is None:
        raise InputError("the springs' normals cancel out (a closed surface): no direction presses the bodies together")
    if path.suffix.lower() in (".sto", ".mot"):
        return _storage(path, shape, folder, sto_prefix)
    return _csv(path, shape, folder)


def _static(value: float, shape) -> LoadSection:
    if not math.isfinite(value) or value <= 0:
        raise InputError(
            f"--load is the size of the force in N (written pressing body 2 onto body 1), a number > 0; got {value:g}"
        )
    if shape.normal is None:
        raise InputError("the springs' normals cancel out (a closed surface): give the force's direction in the file")
    normal = shape.normal
    axis = int(np.argmax(np.abs(normal)))
    angle = math.degrees(math.acos(min(1.0, abs(float(normal[axis])))))
    if angle <= SNAP_DEGREES:
        direction = np.zeros(3)
        direction[axis] = -math.copysign(1.0, float(normal[axis]))
        along = f"{'-' if direction[axis] < 0 else '+'}{'xyz'[axis]}"
        why = f"{angle:.0f} degrees from {'xyz'[axis]}, so the force is along its axis"
    else:
        direction = -normal
        along = "the contact's mean normal"
        why = f"{angle:.0f} degrees from the nearest axis, so the force follows it"
    force = value * direction
    shown = "[" + ", ".join(repr(round(float(c), 6) + 0.0) for c in force) + "]"
    normal_text = "(" + ", ".join(f"{float(c):.3f}" for c in normal) + ")"
    lines = [
        "[load]",
        *_comment(
            f"{value:g} N pressing body 2 onto body 1 along {along}: the contact's mean normal (from body 1 "
            f"to body 2) is {normal_text}, {why}. It acts at the reference point (the contact's centre): "
            "point = [x, y, z] (mm) for a force acting elsewhere; moment = [...] (N mm, about the reference point)."
        ),
        f"force = {shown}",
    ]
    return LoadSection(lines, f"{value:g} N", _STATIC_OUTPUTS, [f"load: {value:g} N along {along}, force = {shown}"])


def _pressing(shape, forces) -> tuple[int, int]:
    """``(pulling, loaded)``: how many loaded frames' forces on body 2 pull it away from body 1."""
    from .preflight import loaded_frames

    frames = loaded_frames(forces)
    pulling = int(np.sum(forces[frames] @ shape.normal > 0.0))
    return pulling, len(frames)


def _csv(path: Path, shape, folder: Path) -> LoadSection:
    from ..io.tables import read_numeric_csv
    from ..scenario.load_path import _FORCE_COLUMNS, _MOMENT_COLUMNS, _POSE_COLUMNS

    table = read_numeric_csv(path, ("time", *_FORCE_COLUMNS), _MOMENT_COLUMNS + _POSE_COLUMNS, "--load")
    forces = table[list(_FORCE_COLUMNS)].to_numpy(dtype=float)
    moments = [c for c in _MOMENT_COLUMNS if c in table.columns]
    poses = [c for c in _POSE_COLUMNS if c in table.columns]
    pulling, loaded = _pressing(shape, forces)
    times = table["time"].to_numpy(dtype=float)
    text = (
        f"{path.name}: {len(times)} frames from {times[0]:g} to {times[-1]:g} s, forces up to "
        f"{np.linalg.norm(forces, axis=1).max():.4g} N; columns {', '.join(table.columns)}. Forces in N on "
        "body 2, moments in N mm about its reference point (here the contact's centre: if your moments are "
        "about another point, set [body2] reference to it)."
    )
    if poses:
        text += " Its pose columns move body 2's mesh frame by frame (the springs are cast again)."
    lines = ["[load_path]", *_comment(text), f"file = {_quote(relative_path(path, folder))}"]
    notes = [f"load path: {path.name}, {len(times)} frames" + ("" if moments else ", no moment columns")]
    if loaded and pulling > loaded / 2:
        lines += [
            *_comment(
                f"As written, the forces pull body 2 away from body 1 in {pulling} of {loaded} loaded frames: "
                "scale = -1 negates every force and moment (a joint's load presses the bodies together)."
            ),
            "scale = -1.0",
        ]
        notes.append(
            f"sign: the file's forces pull the bodies apart in {pulling} of {loaded} loaded frames: scale = -1"
        )
    return LoadSection(lines, f"{path.name} ({len(times)} frames)", _PATH_OUTPUTS, notes)


def _comment(text: str) -> list[str]:
    return wrapped(text, "# ")


def _quote(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _groups(labels) -> dict:
    """``{prefix: {"fx": label, ...}}``: the columns named ``<prefix>_fx`` ... ``<prefix>_mz``."""
    groups: dict = {}
    for label in labels:
        match = re.fullmatch(r"(.+?)_?([fm])([xyz])", label, flags=re.IGNORECASE)
        if match:
            groups.setdefault(match.group(1), {})[(match.group(2) + match.group(3)).lower()] = label
    return {p: g for p, g in groups.items() if {"fx", "fy", "fz"} <= set(g)}


def _storage(path: Path, shape, folder: Path, prefix: str | None) -> LoadSection:
    from ..opensim.storage import read_storage

    storage = read_storage(path, "--load", InputError)
    groups = _groups(storage.labels)
    if prefix is not None:
        if prefix not in groups:
            raise InputError(
                f"--sto-prefix {prefix!r}: {path.name} has no columns {prefix}_fx, {prefix}_fy, {prefix}_fz; "
                f"it has force columns for {', '.join(groups) or 'none'}"
            )
        chosen = prefix
    elif len(groups) == 1:
        chosen = next(iter(groups))
    else:
        raise InputError(
            f"{path.name} has "
            + (
                f"force columns for several joints ({', '.join(groups)}): choose one with --sto-prefix"
                if groups
                else "no force columns named <prefix>_fx, _fy, _fz: write the load as a CSV (time, Fx, Fy, Fz, Mx, My, Mz)"
            )
        )
    group = groups[chosen]
    if "time" not in storage.labels:
        raise InputError(f"{path.name} has no time column")
    forces = np.column_stack([storage.data[:, storage.labels.index(group[c])] for c in ("fx", "fy", "fz")])
    pulling, loaded = _pressing(shape, forces)
    negate = bool(loaded and pulling > loaded / 2)
    sign = "-" if negate else ""
    quantities = [q for q in ("fx", "fy", "fz", "mx", "my", "mz") if q in group]
    columns = {q[0].upper() + q[1]: sign + group[q] for q in quantities}
    units, why = _units(storage, group, forces, shape)
    text = f"{path.name}: {len(storage.data)} frames of OpenSim Storage; the columns of {chosen}"
    notes = [f"load path: {path.name}, columns {chosen}_*"]
    if negate:
        text += (
            f', each negated ("-"): as written, its forces pull body 2 away from body 1 in {pulling} of '
            f"{loaded} loaded frames"
        )
        notes.append(f"sign: the file's forces pull the bodies apart in {pulling} of {loaded} loaded frames: negated")
    text += (
        f". {why}. Forces act on body 2 in the meshes' frame: check that the file's frame is theirs. Moments "
        "are about body 2's reference point (the contact's centre): if your file gives them about another "
        "point (OpenSim's joint centre), set [body2] reference to it."
    )
    lines = [
        "[load_path]",
        *_comment(text),
        f"file = {_quote(relative_path(path, folder))}",
        f'units = "{units}"',
        "columns = { " + ", ".join(f"{q} = {_quote(c)}" for q, c in columns.items()) + " }",
    ]
    notes.append(f"units: {why}")
    return LoadSection(lines, f"{path.name} ({len(storage.data)} frames)", _PATH_OUTPUTS, notes)


def _units(storage, group, forces, shape) -> tuple[str, str]:
    """``("SI" | "mm", why)``: OpenSim's N m, unless the moments read so need a lever arm of a
    hundred layer radii about the contact and read as N mm one inside it."""
    from .contact_shape import MOMENT_ARMS
    from .preflight import loaded_frames

    if not {"mx", "my", "mz"} <= set(group):
        return "SI", 'units = "SI" (OpenSim\'s N, N m, m); the file gives no moments'
    moments = np.column_stack([storage.data[:, storage.labels.index(group[c])] for c in ("mx", "my", "mz")])
    frames = loaded_frames(forces)
    if not len(frames):
        return "SI", 'units = "SI" (OpenSim\'s N, N m, m)'
    arm = float(np.median(np.linalg.norm(moments[frames], axis=1) / np.linalg.norm(forces[frames], axis=1)))
    if arm * 1000.0 > MOMENT_ARMS * shape.radius and arm <= 2.0 * shape.radius:
        return "mm", (
            f'units = "mm": read as N m the moments would need a lever arm of {arm:.3g} m about a contact '
            f"{2 * shape.radius:.3g} mm across; as N mm, {arm:.3g} mm"
        )
    return "SI", f'units = "SI" (OpenSim\'s N m): a lever arm of {arm * 1000:.3g} mm about the contact'
