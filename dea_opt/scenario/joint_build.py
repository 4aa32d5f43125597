"""Building the joint a :class:`~dea_opt.scenario.joint_schema.JointScenario` describes, and its load path.

Each contact's springs are built as a two-body scenario's ``[geometry]`` (generators, tables,
meshes, with its ``regions``) and its law by the registry; errors name the contact
(``contacts[1].law``). The load path is a CSV of ``time`` and ``<body>.<quantity>`` columns.
"""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import numpy as np

from ..errors import DeaError, ScenarioError
from ..kinematics import DOFS
from .joint_schema import JointScenario

__all__ = ["JointPath", "build_joint", "read_joint_path"]

LOADS = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")


def build_joint(scenario: JointScenario) -> tuple:
    """``(joint, casts)``: the :class:`~dea_opt.joint.Joint` of the scenario and, per contact, the
    :class:`~dea_opt.mesh.SpringCast` its springs came from (None for springs not cast from meshes)."""
    from ..joint import Contact, Joint, Ligament
    from ..laws import LAWS
    from ..problem import Body, Load
    from .build import apply_regions, build_geometry_cast

    where = scenario.source or scenario.title or "the scenario"
    bodies = {}
    for b in scenario.bodies:
        body = Body(reference=tuple(b.reference), free=tuple(b.free), prescribed=dict(b.prescribed))
        point = None if b.point is None else tuple(b.point)
        bodies[b.name] = body.with_load(Load(force=tuple(b.force), moment=tuple(b.moment), point=point))
    finite = scenario.solve.kinematics == "finite"
    contacts, casts = [], []
    for i, c in enumerate(scenario.contacts):
        try:
            layer, _, cast = build_geometry_cast(c.geometry)
        except DeaError as exc:
            raise ScenarioError(f"{where}: contacts[{i}].geometry: {exc}") from None
        if c.regions is not None:
            layer = apply_regions(layer, c.regions)
            cast = None if cast is None else dataclasses.replace(cast, layer=layer)
        try:
            law = LAWS.build(c.law.kind, c.law.parameters, prefix=f"contacts[{i}].law.")
        except DeaError as exc:
            raise ScenarioError(f"{where}: {exc}") from None
        contacts.append(
            Contact(layer, law, body1=c.body1, body2=c.body2, name=c.name, targets=cast if finite else None)
        )
        casts.append(cast)
    ligaments = []
    for i, lig in enumerate(scenario.ligaments):
        try:
            ligaments.append(
                Ligament(
                    lig.body1,
                    tuple(lig.point1),
                    lig.body2,
                    tuple(lig.point2),
                    stiffness=lig.stiffness,
                    slack_length=lig.slack_length,
                    law=lig.law,
                    transition_strain=lig.transition_strain,
                    reference_strain=lig.reference_strain,
                    name=lig.name or f"ligament {i}",
                )
            )
        except DeaError as exc:
            raise ScenarioError(f"{where}: ligaments[{i}]: {exc}") from None
    try:
        joint = Joint(bodies, tuple(contacts), tuple(ligaments), kinematics=scenario.solve.kinematics)
    except DeaError as exc:
        raise ScenarioError(f"{where}: {exc}") from None
    return joint, casts


@dataclasses.dataclass(frozen=True)
class JointPath:
    """A joint's load path: ``time`` (T,), s; ``loads`` ``{body: (T, 6)}`` (N, N mm) for the bodies a
    load column names (the others keep their own load); ``prescribed`` ``{body: {dof: (T,)}}``."""

    time: np.ndarray
    loads: dict
    prescribed: dict

    def __len__(self) -> int:
        return len(self.time)

    def frame(self, joint, k: int):
        """The joint at frame ``k``: its bodies' loads and prescribed dofs of that frame."""
        from ..joint import Joint
        from ..problem import Body

        bodies = {}
        for name, body in joint.bodies.items():
            load = self.loads.get(name)
            force, moment = (body.force, body.moment) if load is None else (tuple(load[k, :3]), tuple(load[k, 3:]))
            prescribed = dict(body.prescribed)
            for dof, values in self.prescribed.get(name, {}).items():
                prescribed[dof] = float(values[k])
            free = tuple(d for d in body.free if d not in prescribed)
            bodies[name] = Body(reference=body.reference, free=free, force=force, moment=moment, prescribed=prescribed)
        return Joint(bodies, joint.contacts, joint.ligaments, joint.kinematics)


def read_joint_path(scenario: JointScenario, joint) -> JointPath:
    """The :class:`JointPath` of ``[load_path]``: a ScenarioError names the file, the column or row."""
    assert scenario.load_path is not None
    path = Path(scenario.load_path.file)
    lines = [
        line
        for line in path.read_text(encoding="utf-8").splitlines()
        if line.strip() and not line.lstrip().startswith("#")
    ]
    rows = list(csv.reader(lines))
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
            if name not in loads:
                body = joint.bodies[name]
                loads[name] = np.tile(np.array(body.force + body.moment), (len(table), 1))
            loads[name][:, LOADS.index(quantity)] = table[:, j]
        elif quantity in DOFS:
            prescribed.setdefault(name, {})[quantity] = table[:, j]
        else:
            raise ScenarioError(
                f"{path}: column {column!r}: the quantity must be one of {LOADS + DOFS}, got {quantity!r}"
            )
    return JointPath(table[:, header.index("time")], loads, prescribed)
