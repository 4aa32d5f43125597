"""A joint's load and motion path: loads and prescribed dofs per frame, from up to three files.

``[load_path]`` of a :class:`~dea_opt.scenario.joint_schema.JointScenario`: ``file`` (a CSV of
``time`` and ``<body>.<quantity>`` columns: a load ``femur.Fz`` in N, ``femur.Mx`` in N mm, or a
prescribed dof ``femur.rx`` in mm or rad), ``motion`` (an OpenSim ``.sto``/``.mot`` of the bodies'
coordinates, by their names) or ``poses`` (a CSV of 4x4 poses of a frame in another per frame,
``T00``..``T33`` in mm, such as a fluoroscopic gait: the moving frame's body follows, its
coordinates found by :meth:`~dea_opt.joint.Coordinates.inverse`). ``prescribe`` chooses which
dofs the motion sets; the others stay free. Errors are :class:`~dea_opt.errors.ScenarioError`
naming the file, the column or the row.
"""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import numpy as np

from ..errors import DeaError, ScenarioError
from ..kinematics import DOFS
from .joint_schema import JointScenario

__all__ = ["LOADS", "JointPath", "read_joint_path"]

LOADS = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")


@dataclasses.dataclass(frozen=True)
class JointPath:
    """A joint's load path.

    Attributes
    ----------
    time : ndarray, shape (T,)
        s (or the motion's own time unit, e.g. percent of the gait cycle).
    loads : dict
        ``{body: (T, 6)}`` (N, N mm): the loads of the bodies a load column names (the others keep
        their own load), in the frame of the body's load (``load_frame``).
    prescribed : dict
        ``{body: {dof: (T,)}}`` (mm, rad; a :class:`~dea_opt.joint.Coordinates`' own values).
    sections : dict
        ``{body: [[bodies]] section}``: how each body's load is applied (at its point, in its
        frame); empty for a path built in Python (then a load is a force at the reference and a
        moment, in the ground frame).
    extra_loads : tuple
        The scenario's ``[[loads]]`` (:class:`~dea_opt.joint.BodyLoad`), the same every frame.
    """

    time: np.ndarray
    loads: dict
    prescribed: dict
    sections: dict = dataclasses.field(default_factory=dict)
    extra_loads: tuple | None = None

    def __len__(self) -> int:
        return len(self.time)

    def between(self, joint, k: int, fraction: float):
        """The joint at ``fraction`` of the way from frame ``k - 1`` to frame ``k`` (loads and prescribed
        dofs interpolated linearly: a path reaching a frame in smaller steps)."""
        if k == 0 or fraction >= 1.0:
            return self.frame(joint, k)
        w = float(fraction)

        def mix(values):
            return (1.0 - w) * values[k - 1] + w * values[k]

        loads = {b: np.vstack([mix(v)] * (k + 1)) for b, v in self.loads.items()}
        prescribed = {b: {d: np.full(k + 1, mix(v)) for d, v in dofs.items()} for b, dofs in self.prescribed.items()}
        return dataclasses.replace(self, loads=loads, prescribed=prescribed).frame(joint, k)

    def frame(self, joint, k: int):
        """The joint at frame ``k``: its bodies' loads and prescribed dofs of that frame."""
        from ..problem import Body
        from .joint_build import body_load

        bodies = {}
        # built from a scenario, every body's load is made again (at its point, in its frame)
        loads = list(self.extra_loads or ()) if self.sections else list(joint.loads)
        for name, body in joint.bodies.items():
            path_load = self.loads.get(name)
            section = self.sections.get(name)
            if section is not None:
                F, M = (section.force, section.moment) if path_load is None else (path_load[k, :3], path_load[k, 3:])
                force, moment, load = body_load(section, F, M)
                if load is not None:
                    loads.append(load)
            else:
                force, moment = (body.force, body.moment) if path_load is None else (path_load[k, :3], path_load[k, 3:])
            prescribed = dict(body.prescribed)
            for dof, values in self.prescribed.get(name, {}).items():
                prescribed[dof] = float(values[k])
            free = tuple(d for d in body.free if d not in prescribed)
            bodies[name] = Body(
                reference=body.reference, free=free, force=tuple(force), moment=tuple(moment), prescribed=prescribed
            )
        return dataclasses.replace(joint, bodies=bodies, loads=tuple(loads))


def _rows(path: Path) -> list:
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ScenarioError(f"{path}: cannot be read ({exc})") from None
    lines = [line for line in text.splitlines() if line.strip() and not line.lstrip().startswith("#")]
    return list(csv.reader(lines))


def _read_csv(path: Path, joint) -> tuple:
    """``(time, loads {body: {quantity: (T,)}}, prescribed {body: {dof: (T,)}})`` of a load CSV."""
    rows = _rows(path)
    if len(rows) < 2:
        raise ScenarioError(f"{path}: a load path needs a header and at least one row of numbers")
    header = [h.strip() for h in rows[0]]
    if "time" not in header:
        raise ScenarioError(f"{path}: the header needs a time column (s), got {header}")
    try:
        table = np.array([[float(v) for v in row] for row in rows[1:]], dtype=float)
    except ValueError as exc:
        raise ScenarioError(f"{path}: every value must be a number ({exc})") from None
    if table.shape[1] != len(header) or not np.isfinite(table).all():
        raise ScenarioError(f"{path}: every row needs {len(header)} finite numbers, one per column of {header}")
    loads: dict = {}
    prescribed: dict = {}
    for j, column in enumerate(header):
        if column == "time":
            continue
        name, _, quantity = column.rpartition(".")
        if name not in joint.bodies:
            raise ScenarioError(
                f"{path}: column {column!r} names no body (bodies: {list(joint.bodies)}); use <body>.<quantity>"
            )
        if quantity in LOADS:
            loads.setdefault(name, {})[quantity] = table[:, j]
        elif quantity in DOFS:
            prescribed.setdefault(name, {})[quantity] = table[:, j]
        else:
            raise ScenarioError(
                f"{path}: column {column!r}: the quantity must be one of {LOADS + DOFS}, got {quantity!r}"
            )
    return table[:, header.index("time")], loads, prescribed


def _coordinate_names(scenario: JointScenario) -> dict:
    """``{coordinate name: (body, dof)}`` of the bodies' coordinates."""
    out = {}
    for b in scenario.bodies:
        if b.coordinates is not None and b.coordinates.names is not None:
            for dof, name in zip(DOFS, b.coordinates.names):
                out[name] = (b.name, dof)
    return out


def _read_motion(path: Path, scenario: JointScenario) -> tuple:
    """``(time, {(body, dof): (T,)})`` of an OpenSim Storage file of the bodies' coordinates:
    rotations in rad (degrees where its header says so), translations in m (made mm)."""
    from ..opensim.storage import read_storage

    storage = read_storage(path, what="motion", error=ScenarioError)
    names = _coordinate_names(scenario)
    lower = [label.lower() for label in storage.labels]
    if "time" not in lower:
        raise ScenarioError(f"{path}: a motion needs a time column")
    values = {}
    for j, label in enumerate(storage.labels):
        parts = label.strip("/").split("/")
        name = parts[-2] if len(parts) >= 2 and parts[-1] == "value" else label
        if name not in names:
            continue
        body, dof = names[name]
        column = storage.data[:, j].astype(float)
        if dof[0] == "r":
            if storage.in_degrees is None:
                raise ScenarioError(f"{path}: its header does not say inDegrees=yes or no, needed for {name}")
            column = np.radians(column) if storage.in_degrees else column
        else:
            column = 1000.0 * column  # OpenSim's translations are in m
        values[(body, dof)] = column
    if not values:
        raise ScenarioError(
            f"{path}: none of its columns names a coordinate of the scenario's bodies "
            f"({', '.join(list(names)[:8]) or 'no body has coordinates with names'})"
        )
    return storage.data[:, lower.index("time")], values


def _frame(scenario: JointScenario, name: str) -> tuple:
    """``(body, 4x4 pose in the world at the start pose)`` of a ``[[frames]]`` name or a body."""
    for f in scenario.frames:
        if f.name == name:
            return f.body, np.array(f.pose, dtype=float)
    for b in scenario.bodies:
        if b.name == name:
            return b.name, np.eye(4) if b.pose is None else np.array(b.pose, dtype=float)
    frames = [f.name for f in scenario.frames] + [b.name for b in scenario.bodies]
    raise ScenarioError(f"load_path names the frame {name!r}, which is neither a [[frames]] name nor a body ({frames})")


def _read_poses(path: Path, scenario: JointScenario, joint) -> tuple:
    """``(time, {(body, dof): (T,)})``: the moving body's coordinates per frame of a pose table."""
    from ..opensim.kinematics import rigid_inverse
    from ..opensim.motion import read_pose_table

    section = scenario.load_path
    assert section is not None and section.moving is not None and section.reference is not None
    try:
        times, T = read_pose_table(path)
    except DeaError as exc:
        raise ScenarioError(str(exc)) from None
    moving, B0 = _frame(scenario, section.moving)
    held, A = _frame(scenario, section.reference)
    if moving == held:
        raise ScenarioError(f"load_path: {section.moving} and {section.reference} are both fixed to {moving}")
    if joint.bodies[held].free:
        raise ScenarioError(
            f"load_path: the poses are given in {section.reference}, on {held}, which has free dofs "
            f"{joint.bodies[held].free}: the reference frame's body must be held"
        )
    motions = np.einsum("ij,fjk,kl->fil", A, T, rigid_inverse(B0))
    coordinates = joint.coordinates.get(moving)
    c = np.asarray(joint.bodies[moving].reference, dtype=float)
    q = np.empty((len(T), 6))
    guess = None
    from scipy.spatial.transform import Rotation

    for k, D in enumerate(motions):
        if coordinates is not None:
            try:
                q[k] = coordinates.inverse(D, guess)
            except DeaError as exc:
                raise ScenarioError(f"{path}, frame {k}: {exc}") from None
        else:
            theta = Rotation.from_matrix(D[:3, :3]).as_rotvec()
            q[k, :3] = D[:3, :3] @ c + D[:3, 3] - c
            q[k, 3:] = theta
        guess = q[k]
    return times, {(moving, dof): q[:, j] for j, dof in enumerate(DOFS)}


def _chosen(values: dict, prescribe, scenario: JointScenario, source: Path) -> dict:
    """The motion's ``{(body, dof): (T,)}`` that ``prescribe`` chooses (``body.dof`` or a coordinate's
    name; default all)."""
    if prescribe is None:
        return values
    names = _coordinate_names(scenario)
    out = {}
    for item in prescribe:
        key = names.get(item)
        if key is None:
            body, _, dof = item.rpartition(".")
            key = (body, dof)
        if key not in values:
            given = sorted({f"{b}.{d}" for b, d in values})
            raise ScenarioError(
                f"load_path.prescribe names {item!r}, which {source.name} does not give (it gives {', '.join(given)})"
            )
        out[key] = values[key]
    return out


def read_joint_path(scenario: JointScenario, joint) -> JointPath:
    """The :class:`JointPath` of ``[load_path]``: a ScenarioError names the file, the column or row."""
    from ..joint import BodyLoad

    section = scenario.load_path
    assert section is not None
    time, moved = None, {}
    if section.motion is not None:
        time, moved = _read_motion(Path(section.motion), scenario)
        moved = _chosen(moved, section.prescribe, scenario, Path(section.motion))
    elif section.poses is not None:
        time, moved = _read_poses(Path(section.poses), scenario, joint)
        moved = _chosen(moved, section.prescribe, scenario, Path(section.poses))
    loads_in, prescribed = {}, {}
    if section.file is not None:
        path = Path(section.file)
        t_file, loads_in, prescribed = _read_csv(path, joint)
        if time is None:
            time = t_file
        elif len(t_file) != len(time) or not np.allclose(t_file, time, rtol=0, atol=1e-9 * max(np.ptp(time), 1.0)):
            if t_file.min() > time.min() or t_file.max() < time.max() or np.any(np.diff(t_file) <= 0):
                raise ScenarioError(
                    f"{path}: its times ({t_file.min():g} to {t_file.max():g}) must increase and cover the motion's "
                    f"({time.min():g} to {time.max():g}) to be interpolated at its {len(time)} frames"
                )
            loads_in = {b: {q: np.interp(time, t_file, v) for q, v in cols.items()} for b, cols in loads_in.items()}
            prescribed = {b: {d: np.interp(time, t_file, v) for d, v in cols.items()} for b, cols in prescribed.items()}
    assert time is not None
    for (body, dof), values in moved.items():
        if dof in prescribed.get(body, {}):
            raise ScenarioError(f"load_path: {body}.{dof} is prescribed by both {section.file} and the motion")
        prescribed.setdefault(body, {})[dof] = values
    sections = {b.name: b for b in scenario.bodies}
    loads = {}
    for name, columns in loads_in.items():
        own = sections[name]
        table = np.tile(np.array(list(own.force) + list(own.moment), dtype=float), (len(time), 1))
        for quantity, values in columns.items():
            table[:, LOADS.index(quantity)] = values
        loads[name] = table
    extra = tuple(
        BodyLoad(
            e.body,
            tuple(_axes(sections[e.body], e.frame) @ e.force),
            tuple(_axes(sections[e.body], e.frame) @ e.moment),
            None if e.point is None else tuple(e.point),
            e.frame,
        )
        for e in scenario.loads
    )
    return JointPath(np.asarray(time, dtype=float), loads, prescribed, sections, extra)


def _axes(section, frame: str) -> np.ndarray:
    return np.eye(3) if section.pose is None or frame == "ground" else np.array(section.pose)[:3, :3]
