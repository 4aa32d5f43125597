"""Building the joint a :class:`~dea_opt.scenario.joint_schema.JointScenario` describes.

Each contact's springs are built as a two-body scenario's ``[geometry]`` (generators, tables,
meshes, with its ``regions``), or cast between two meshes each placed in the world by its own
pose (``pose1``, ``pose2``: an OpenSim model's contact meshes in their bodies' frames, as
``dea-opt import-osim`` writes them); its law by the registry. Errors name the contact
(``contacts[1].law``). The load path is :mod:`dea_opt.scenario.joint_path`.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np

from ..errors import DeaError, ScenarioError
from .joint_schema import JointMeshGeometry, JointScenario

__all__ = ["body_load", "build_joint", "posed_cast"]


def _where(scenario) -> str:
    return scenario.source or scenario.title or "the scenario"


def body_load(section, force, moment) -> tuple:
    """``(body_force, body_moment, BodyLoad or None)`` of a ``[[bodies]]`` entry's load ``force``,
    ``moment``: in the ground frame at its reference, the body's own; at a point or in the body's
    frame (its ``pose``'s axes), a :class:`~dea_opt.joint.BodyLoad` that moves with it."""
    from ..joint import BodyLoad

    force, moment = np.asarray(force, dtype=float), np.asarray(moment, dtype=float)
    if section.load_frame == "ground" and section.point is None:
        return tuple(force), tuple(moment), None
    R = np.eye(3) if section.pose is None or section.load_frame == "ground" else np.array(section.pose)[:3, :3]
    point = None if section.point is None else tuple(section.point)
    load = BodyLoad(section.name, tuple(R @ force), tuple(R @ moment), point, section.load_frame)
    return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), load


def _coordinates(section):
    from ..joint import Coordinates

    c = section.coordinates
    return Coordinates(
        c.frame,
        c.rotation_axes,
        c.translation_axes,
        c.start,
        c.slopes,
        c.intercepts,
        c.inverted,
        None if c.names is None else tuple(c.names),
    )


def posed_cast(section: JointMeshGeometry, regions=None):
    """The :class:`~dea_opt.mesh.SpringCast` of two meshes each placed by its pose (``pose1``,
    ``pose2``; both in the world, so the cast's ``pose`` is the identity); ``regions`` cut across
    an axis of mesh 1's own frame (the frame of its file)."""
    from .build import _load_part, cast_from_mesh_section

    meshes: dict = {}
    for k in (1, 2):
        scale = getattr(section, f"scale{k}") or section.scale
        mesh, labels = _load_part(getattr(section, f"mesh{k}"), scale)
        bone = getattr(section, f"bone{k}")
        bone = None if bone is None else _load_part(bone, scale)[0]
        pose = getattr(section, f"pose{k}")
        if pose is not None:
            T = np.array(pose, dtype=float)
            mesh = mesh.copy()
            mesh.apply_transform(T)
            if bone is not None:
                bone = bone.copy()
                bone.apply_transform(T)
        meshes[f"mesh{k}"], meshes[f"labels{k}"], meshes[f"bone{k}"] = mesh, labels, bone
    cast = cast_from_mesh_section(section, meshes)
    T1 = np.eye(4) if section.pose1 is None else np.array(section.pose1, dtype=float)
    return cast if regions is None else labelled_cast(cast, regions, T1)


def labelled_cast(cast, regions, frame=None):
    """``cast`` with ``[regions]``' labels on its springs and on its mesh 1's faces (so that a cast
    again at another pose keeps them), cut across an axis of the frame ``frame`` (4x4, mesh 1's
    own frame in the world; default the world) at the springs' area centroid or at ``at``."""
    from .build import apply_regions, axis_vector

    T = np.eye(4) if frame is None else np.asarray(frame, dtype=float)
    layer = cast.layer
    own = dataclasses.replace(layer, points=(layer.points - T[:3, 3]) @ T[:3, :3])
    labelled = apply_regions(own, regions)  # refuses springs that have labels already
    cut = (
        float(regions.at)
        if regions.at != "centroid"
        else float(own.areas @ (own.points @ axis_vector(regions.split)) / own.areas.sum())
    )
    centres = (np.asarray(cast.mesh1.triangles_center) - T[:3, 3]) @ T[:3, :3]
    faces = np.where(centres @ axis_vector(regions.split) < cut, regions.names[0], regions.names[1])
    layer = dataclasses.replace(layer, labels=labelled.labels)
    return dataclasses.replace(cast, layer=layer, options={**cast.options, "labels": faces})


def _contact_layer(section, regions):
    """``(layer, cast)`` of a contact's geometry and regions."""
    from .build import apply_regions, build_geometry_cast

    if isinstance(section, JointMeshGeometry) and (section.pose1 is not None or section.pose2 is not None):
        cast = posed_cast(section, regions)
        return cast.layer, cast
    layer, _, cast = build_geometry_cast(section)
    if regions is not None and cast is not None:
        cast = labelled_cast(cast, regions)
        layer = cast.layer
    elif regions is not None:
        layer = apply_regions(layer, regions)
    return layer, cast


def build_joint(scenario: JointScenario) -> tuple:
    """``(joint, casts)``: the :class:`~dea_opt.joint.Joint` of the scenario and, per contact, the
    :class:`~dea_opt.mesh.SpringCast` its springs came from (None for springs not cast from meshes)."""
    from ..joint import BodyLoad, Bushing, Contact, Joint, Ligament, Spring
    from ..laws import LAWS
    from ..problem import Body

    where = _where(scenario)
    bodies, loads, coordinates = {}, [], {}
    for i, b in enumerate(scenario.bodies):
        force, moment, load = body_load(b, b.force, b.moment)
        try:
            body = Body(reference=tuple(b.reference), free=tuple(b.free), prescribed=dict(b.prescribed))
            bodies[b.name] = body.with_load(force=force, moment=moment)
            if b.coordinates is not None:
                coordinates[b.name] = _coordinates(b)
        except DeaError as exc:
            raise ScenarioError(f"{where}: bodies[{i}] ({b.name}): {exc}") from None
        if load is not None:
            loads.append(load)
    finite = scenario.solve.kinematics == "finite"
    contacts, casts = [], []
    for i, c in enumerate(scenario.contacts):
        try:
            layer, cast = _contact_layer(c.geometry, c.regions)
        except DeaError as exc:
            raise ScenarioError(f"{where}: contacts[{i}].geometry: {exc}") from None
        try:
            law = LAWS.build(c.law.kind, c.law.parameters, prefix=f"contacts[{i}].law.")
        except DeaError as exc:
            raise ScenarioError(f"{where}: {exc}") from None
        contacts.append(
            Contact(layer, law, body1=c.body1, body2=c.body2, name=c.name, targets=cast if finite else None)
        )
        casts.append(cast)
    elements: dict = {"ligaments": [], "springs": [], "bushings": []}
    element_sections: tuple[tuple[str, list[Any]], ...] = (
        ("ligaments", scenario.ligaments),
        ("springs", scenario.springs),
    )
    for kind, element_list in element_sections:
        for i, e in enumerate(element_list):
            try:
                item: Ligament | Spring
                if kind == "ligaments":
                    item = Ligament(
                        e.body1,
                        tuple(e.point1),
                        e.body2,
                        tuple(e.point2),
                        stiffness=e.stiffness,
                        slack_length=e.slack_length,
                        law=e.law,
                        transition_strain=e.transition_strain,
                        reference_strain=e.reference_strain,
                        name=e.name or f"ligament {i}",
                    )
                else:
                    item = Spring(
                        e.body1, tuple(e.point1), e.body2, tuple(e.point2), e.stiffness, e.rest_length, e.name
                    )
            except DeaError as exc:
                raise ScenarioError(f"{where}: {kind}[{i}]: {exc}") from None
            elements[kind].append(item)
    for i, e in enumerate(scenario.bushings):
        try:
            elements["bushings"].append(
                Bushing(
                    e.body1,
                    e.body2,
                    tuple(map(tuple, np.eye(4) if e.frame is None else np.array(e.frame))),
                    tuple(e.translational_stiffness),
                    tuple(e.rotational_stiffness),
                    e.name,
                )
            )
        except DeaError as exc:
            raise ScenarioError(f"{where}: bushings[{i}]: {exc}") from None
    body_sections = {b.name: b for b in scenario.bodies}
    for i, e in enumerate(scenario.loads):
        section = body_sections[e.body]
        R = np.eye(3) if section.pose is None or e.frame == "ground" else np.array(section.pose)[:3, :3]
        try:
            point = None if e.point is None else tuple(e.point)
            loads.append(BodyLoad(e.body, tuple(R @ e.force), tuple(R @ e.moment), point, e.frame))
        except DeaError as exc:
            raise ScenarioError(f"{where}: loads[{i}]: {exc}") from None
    try:
        joint = Joint(
            bodies,
            tuple(contacts),
            tuple(elements["ligaments"]),
            kinematics=scenario.solve.kinematics,
            springs=tuple(elements["springs"]),
            bushings=tuple(elements["bushings"]),
            loads=tuple(loads),
            coordinates=coordinates,
        )
    except DeaError as exc:
        raise ScenarioError(f"{where}: {exc}") from None
    return joint, casts
