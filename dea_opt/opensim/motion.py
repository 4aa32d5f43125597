"""Motions as per-frame poses of chosen bodies: from relative 4x4 poses or from the model's coordinates.

Two sources (``formulations/opensim.md``, "Motions"):

- :func:`relative_motion`: a table of poses of one frame in another per frame (``T_A_B``,
  4x4, mm), such as the fluoroscopic poses of a femoral component on its tibial insert. Frame A's
  body is held at its pose at the model's coordinates (the defaults unless given); frame B's
  body follows: ``X_G_bodyB(k) = X_G_A T_k inv(X_bodyB_B)``.
- :func:`coordinate_motion`: an OpenSim Storage file (``.sto``/``.mot``) of the model's own
  coordinates (a column per coordinate, named by the coordinate or by its state path
  ``/jointset/<joint>/<coordinate>/value``): every chosen body's pose per frame through the
  joint tree. Rotational coordinates are read in degrees or radians as the header's
  ``inDegrees`` says, translational ones in m; the coordinates the file leaves out keep their
  default values.

Either gives a :class:`Motion`: ``times`` and ``poses[body]`` (F, 4, 4) in ground, mm, which the
joint prescribes body by body (the dofs it is told to prescribe; the others stay free).
"""

from __future__ import annotations

import csv
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError, OpenSimModelError
from .kinematics import rigid_inverse
from .model import frozen_array, frozen_mapping
from .storage import read_storage

__all__ = ["Motion", "coordinate_motion", "read_pose_table", "relative_motion", "resolve_frame"]

_T_COLUMNS = tuple(f"T{i}{j}" for i in range(4) for j in range(4))
#: How far a given 4x4 may be from rigid: ``|R^T R - I|`` and the last row.
RIGID_TOL = 1e-6


@dataclass(frozen=True)
class Motion:
    """Per-frame poses of chosen bodies.

    Attributes
    ----------
    times : ndarray (F,)
        The frames' times (the table's first column, or the file's ``time``).
    poses : mapping body -> ndarray (F, 4, 4)
        ``X_G_body`` per frame (mm).
    coordinates : mapping name -> ndarray (F,)
        The coordinate values per frame (OpenSim's units) for a motion of coordinates; empty for
        a relative motion.
    source : str
        Where it came from.
    unused : tuple of str
        Columns of a Storage file that name no coordinate (speeds, forces, ...): not used.
    """

    times: np.ndarray
    poses: Mapping
    coordinates: Mapping
    source: str
    unused: tuple = ()

    def __len__(self) -> int:
        return len(self.times)


def resolve_frame(model, name: str) -> str:
    """The path of the frame ``name``: a frame path, a body's name, or a unique frame name."""
    if name in model.frames:
        return name
    matches = [p for p, f in model.frames.items() if f.name == name]
    if len(matches) == 1:
        return matches[0]
    if len(matches) > 1:
        raise OpenSimModelError(f"{model.path}: several frames are named {name!r}: {', '.join(matches)}; give its path")
    raise OpenSimModelError(f"{model.path}: has no frame {name!r} (a frame path, a body or a frame name)")


def read_pose_table(path) -> tuple:
    """``(times (F,), T (F, 4, 4))`` from a CSV with columns ``T00``..``T33`` (mm) and a first
    column of times (any name; the row index when the first column is ``T00``)."""
    path = Path(path)
    try:
        with open(path, newline="", encoding="utf-8") as handle:
            rows = list(csv.reader(row for row in handle if not row.startswith("#")))
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"pose table {path} cannot be read: {exc}") from None
    if len(rows) < 2:
        raise InputError(f"pose table {path} has no rows of numbers under its header")
    header = [h.strip() for h in rows[0]]
    missing = [c for c in _T_COLUMNS if c not in header]
    if missing:
        raise InputError(f"pose table {path} lacks the columns {', '.join(missing)} (a 4x4 pose T00..T33 per row)")
    index = [header.index(c) for c in _T_COLUMNS]
    times, T = [], []
    for k, row in enumerate(rows[1:], start=2):
        try:
            values = [float(row[i]) for i in index]
            t = float(row[0]) if header[0] != "T00" else float(k - 2)
        except (ValueError, IndexError):
            raise InputError(f"pose table {path}, line {k}: expected numbers in {header[0]} and T00..T33") from None
        if not all(math.isfinite(v) for v in [*values, t]):
            raise InputError(f"pose table {path}, line {k}: a value is not finite")
        times.append(t)
        T.append(values)
    return np.array(times), np.array(T).reshape(-1, 4, 4)


def _check_rigid(T: np.ndarray, what: str) -> None:
    eye = np.eye(3)
    for k, M in enumerate(T):
        R = M[:3, :3]
        error = max(float(np.abs(R.T @ R - eye).max()), float(np.abs(M[3] - (0, 0, 0, 1)).max()))
        if not error <= RIGID_TOL or np.linalg.det(R) < 0:
            raise InputError(
                f"{what}, frame {k}: not a rigid transform (|R^T R - I| or its last row off by {error:.3g})"
            )


def relative_motion(model, table, moving: str, reference: str, *, times=None, coordinates=None) -> Motion:
    """The motion of ``moving``'s body given the poses of frame ``moving`` in frame ``reference``.

    Parameters
    ----------
    model : OsimModel
    table : path or array_like (F, 4, 4)
        ``T_reference_moving`` per frame (mm): a CSV of ``T00``..``T33`` (:func:`read_pose_table`)
        or the array.
    moving, reference : str
        Frames (a path, a body's name or a unique frame name), e.g. ``"femur_implant"`` on
        ``"tibia_implant"``; they must be fixed to different bodies.
    times : array_like (F,), optional
        The frames' times (an array table has 0, 1, ... otherwise).
    coordinates : mapping, optional
        Coordinate values that place the reference body (default: the model's defaults).

    Returns
    -------
    Motion
        ``poses`` of the reference body (held, the same every frame) and the moving body.
    """
    moving_path, reference_path = resolve_frame(model, moving), resolve_frame(model, reference)
    moving_body, reference_body = model.frames[moving_path].body, model.frames[reference_path].body
    if moving_body == reference_body:
        raise InputError(
            f"{moving} and {reference} are both fixed to {moving_body}: a motion moves one body on another"
        )
    if isinstance(table, (str, Path)):
        read_times, T = read_pose_table(table)
        source = str(table)
        times = read_times if times is None else times
    else:
        T = np.asarray(table, dtype=float)
        source = "a table of poses"
        if T.ndim != 3 or T.shape[1:] != (4, 4) or not np.isfinite(T).all():
            raise InputError(f"table must be finite poses of shape (F, 4, 4), got shape {T.shape}")
    times = np.arange(len(T), dtype=float) if times is None else np.asarray(times, dtype=float)
    if times.shape != (len(T),):
        raise InputError(f"times must have one value per frame ({len(T)}), got shape {times.shape}")
    _check_rigid(T, source)
    poses = model.poses(coordinates, bodies=[reference_body])
    X_ref = poses[reference_body] @ model.frame_in_body(reference_path)
    inv_moving = rigid_inverse(model.frame_in_body(moving_path))
    moved = np.einsum("ij,fjk,kl->fil", X_ref, T, inv_moving)
    held = np.broadcast_to(poses[reference_body], (len(T), 4, 4))
    return Motion(
        frozen_array(times),
        frozen_mapping({reference_body: frozen_array(held), moving_body: frozen_array(moved)}),
        frozen_mapping({}),
        source,
    )


def _column_coordinate(label: str, names) -> str | None:
    """The coordinate a Storage column names: its name, or its state path ``.../<name>/value``."""
    if label in names:
        return label
    parts = label.strip("/").split("/")
    if len(parts) >= 2 and parts[-1] == "value" and parts[-2] in names:
        return parts[-2]
    return None


def coordinate_motion(model, path, bodies) -> Motion:
    """The poses of ``bodies`` per frame of an OpenSim Storage file of the model's coordinates.

    Parameters
    ----------
    model : OsimModel
    path : path
        A ``.sto``/``.mot`` file (Inverse Kinematics, a states file): a ``time`` column and a column
        per coordinate it sets (by name, or ``/jointset/<joint>/<coordinate>/value``).
    bodies : iterable of str
        The bodies whose poses are wanted.

    Raises
    ------
    InputError
        A bad file (with its line), no column naming a coordinate, a file in degrees that sets
        a coupled coordinate (whose unit only its functions know), or a body the joint tree
        cannot place (:class:`~dea_opt.errors.OpenSimModelError`).
    """
    storage = read_storage(path, what="motion", error=InputError)
    names = set(model.coordinates)
    found: dict = {}
    unused = []
    for j, label in enumerate(storage.labels):
        name = _column_coordinate(label, names)
        if label.lower() == "time":
            continue
        if name is None:
            unused.append(label)
        elif name in found:
            raise InputError(f"motion {path}: two columns set the coordinate {name}")
        else:
            found[name] = storage.data[:, j].copy()
    if not found:
        raise InputError(
            f"motion {path}: none of its columns names a coordinate of {model.path.name} (e.g. "
            f"{', '.join(list(model.coordinates)[:4])})"
        )
    if "time" not in [label.lower() for label in storage.labels]:
        raise InputError(f"motion {path} has no time column")
    times = storage.data[:, [label.lower() for label in storage.labels].index("time")]
    degrees = storage.in_degrees
    for name, values in found.items():
        motion = model.coordinates[name].motion
        if motion == "rotational" and degrees is None:
            raise InputError(f"motion {path}: its header does not say inDegrees=yes or no, needed for {name}")
        if motion == "rotational" and degrees:
            found[name] = np.radians(values)
        elif motion not in ("rotational", "translational") and degrees:
            raise InputError(
                f"motion {path} is in degrees and sets {name}, a coupled coordinate (its functions scale it): "
                f"dea-opt cannot tell its unit; write the file in radians (inDegrees=no)"
            )
    bodies = list(bodies)
    poses = np.empty((len(bodies), len(times), 4, 4))
    for k in range(len(times)):
        at = model.poses({n: v[k] for n, v in found.items()}, bodies=bodies)
        for b, body in enumerate(bodies):
            poses[b, k] = at[body]
    return Motion(
        frozen_array(times),
        frozen_mapping({body: frozen_array(poses[b]) for b, body in enumerate(bodies)}),
        frozen_mapping({n: frozen_array(v) for n, v in found.items()}),
        str(path),
        tuple(unused),
    )
