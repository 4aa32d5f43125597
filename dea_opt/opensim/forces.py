"""The model's contact, ligaments, wrap objects, and every force or constraint dea-opt does not model.

Read by :func:`~dea_opt.opensim.read_model`: ``Smith2018ContactMesh`` (its mesh file found
next to the model or in ``Geometry/``), ``Smith2018ArticularContactForce``,
``Blankevoort1991Ligament`` (its fixed path points, stiffness, slack length, transition strain
and damping, with OpenSim's defaults 0.06 and 0.003) and the wrap objects of the bodies. Each
other force, constraint, controller, probe and component is listed in ``not_modelled``.
"""

from __future__ import annotations

from pathlib import Path, PurePath

import numpy as np

from ..errors import OpenSimModelError
from .document import Document
from .kinematics import body_fixed_xyz
from .ligaments import point_positions, segment_crosses_wrap
from .model import (
    ContactMesh,
    ContactPair,
    Ligament,
    NotModelled,
    PathPoint,
    WrapObject,
    frozen_array,
    frozen_mapping,
)

__all__ = ["find_mesh", "pose_reports", "read_forces"]

#: Elements that only draw a component (or scale it): nothing to model.
_DISPLAY = {"Appearance", "FrameGeometry", "attached_geometry", "components", "socket_scale_frame"}
_MESH_KEYS = {"socket_frame", "mesh_file", "elastic_modulus", "poissons_ratio", "thickness", "scale_factors"}
_PAIR_KEYS = {
    "socket_casting_mesh",
    "socket_target_mesh",
    "min_proximity",
    "max_proximity",
    "elastic_foundation_formulation",
    "use_lumped_contact_model",
    "appliesForce",
}
_LIGAMENT_KEYS = {
    "GeometryPath",
    "linear_stiffness",
    "slack_length",
    "transition_strain",
    "damping_coefficient",
    "reference_strain",
    "appliesForce",
}
_WRAP_DIMENSIONS = {
    "WrapEllipsoid": (("dimensions", 3, "radii"),),
    "WrapSphere": (("radius", 1, "radius"),),
    "WrapCylinder": (("radius", 1, "radius"), ("length", 1, "length")),
    "WrapTorus": (("inner_radius", 1, "inner_radius"), ("outer_radius", 1, "outer_radius")),
}


def read_forces(doc: Document, path: Path, frames: dict, skipped: list) -> dict:
    """``contact_meshes``, ``contact_pairs``, ``ligaments``, ``wrap_objects`` (dicts by name),
    ``wrapped`` and ``via`` (the bundles whose default-pose report :func:`pose_reports` adds)."""
    folder = Path(path).resolve().parent
    meshes = {}
    for element in doc.objects("ContactGeometrySet"):
        if element.tag != "Smith2018ContactMesh":
            skipped.append(
                NotModelled("contact", element.name, f"a {element.tag} (not a Smith2018ContactMesh)", element.line)
            )
            continue
        meshes[doc.path(element)] = _mesh(doc, element, folder, frames, skipped)
    wraps = _wrap_objects(doc, frames)
    pairs, ligaments, wrapped, via = {}, {}, [], []
    for element in doc.objects("ForceSet"):
        name = element.name or f"<{element.tag}>"
        if element.tag == "Smith2018ArticularContactForce":
            pair = _pair(doc, element, meshes, skipped)
            if pair is not None:
                pairs[name] = pair
        elif element.tag == "Blankevoort1991Ligament":
            ligament = _ligament(doc, element, frames, wraps, skipped)
            if ligament is not None:
                ligaments[name] = ligament
                if ligament.wraps:
                    wrapped.append(name)
                if len(ligament.points) > 2:
                    via.append(name)
        elif "Muscle" in element.tag:
            skipped.append(NotModelled("muscle", name, f"a {element.tag}: muscles are not modelled", element.line))
        else:
            skipped.append(NotModelled("force", name, f"a {element.tag}: not modelled", element.line))
    for set_tag, kind in (("ConstraintSet", "constraint"), ("ControllerSet", "component"), ("ProbeSet", "component")):
        for element in doc.objects(set_tag):
            skipped.append(
                NotModelled(kind, element.name or element.tag, f"a {element.tag}: not modelled", element.line)
            )
    extra = doc.model.child("components")
    for element in extra.children if extra is not None else []:
        if element.tag != "PhysicalOffsetFrame":
            skipped.append(NotModelled("component", element.name or element.tag, f"a {element.tag}", element.line))
    markers = doc.objects("MarkerSet")
    if markers:
        skipped.append(
            NotModelled("component", "markerset", f"{len(markers)} markers (no mechanics: not used)", markers[0].line)
        )
    return {
        "contact_meshes": {m.name: m for m in meshes.values()},
        "contact_pairs": pairs,
        "ligaments": ligaments,
        "wrap_objects": wraps,
        "wrapped": wrapped,
        "via": via,
    }


# --- contact ----------------------------------------------------------------------------------


def find_mesh(folder: Path, file: str) -> tuple:
    """``(resolved path or None, places searched)``: ``file`` next to the model, then in its
    ``Geometry/`` folder, as OpenSim looks. A name that is absolute or climbs out (``..``) is
    looked for nowhere: a model from elsewhere names no file outside its folders."""
    pure = PurePath(file)
    if not file or pure.is_absolute() or ".." in pure.parts or "\0" in file:
        return None, ()
    searched = (folder / file, folder / "Geometry" / file)
    for candidate in searched:
        if candidate.is_file():
            return candidate, searched
    return None, searched


def _mesh(doc: Document, element, folder: Path, frames: dict, skipped: list) -> ContactMesh:
    frame = doc.path(doc.socket(element, "socket_frame", kinds=("Ground", "Body", "PhysicalOffsetFrame")))
    frame = frame or "/ground"
    E = doc.number(element, "elastic_modulus", 1.0e6) / 1.0e6  # Pa -> MPa
    nu = doc.number(element, "poissons_ratio", 0.5)
    h = doc.number(element, "thickness", 0.005) * 1000.0  # m -> mm
    if not (E > 0 and 0 <= nu < 0.5 and h > 0):
        raise OpenSimModelError(
            f"{doc.where(element)}: needs elastic_modulus > 0, 0 <= poissons_ratio < 0.5 (0.5 is incompressible: "
            f"an infinite aggregate modulus) and thickness > 0; got {E * 1e6} Pa, {nu}, {h / 1000.0} m"
        )
    file = element.child_text("mesh_file") or ""
    resolved, searched = find_mesh(folder, file)
    _note_unread(doc, element, _MESH_KEYS, skipped)
    return ContactMesh(
        name=element.name,
        path=doc.path(element),
        frame=frame,
        body=frames[frame].body,
        file=file,
        resolved=resolved,
        searched=searched,
        elastic_modulus=E,
        poissons_ratio=nu,
        thickness=h,
        scale=frozen_array(doc.floats(element, "scale_factors", 3, [1, 1, 1]) * 1000.0),  # m -> mm
        line=element.line,
    )


def _pair(doc: Document, element, meshes: dict, skipped: list) -> ContactPair | None:
    name = element.name
    if not doc.flag(element, "appliesForce", True):
        skipped.append(NotModelled("contact", name, "disabled in the model (appliesForce false)", element.line))
        return None
    kinds = ("Smith2018ContactMesh",)
    casting = meshes[doc.path(doc.socket(element, "socket_casting_mesh", kinds=kinds))]
    target = meshes[doc.path(doc.socket(element, "socket_target_mesh", kinds=kinds))]
    formulation = (element.child_text("elastic_foundation_formulation") or "linear").lower()
    if formulation not in ("linear", "nonlinear"):
        raise OpenSimModelError(
            f"{doc.where(element)}: elastic_foundation_formulation must be linear or nonlinear, got {formulation!r}"
        )
    pair = ContactPair(
        name=name,
        casting=casting,
        target=target,
        min_proximity=doc.number(element, "min_proximity", 0.0) * 1000.0,  # m -> mm
        max_proximity=doc.number(element, "max_proximity", 0.01) * 1000.0,
        formulation=formulation,
        lumped=doc.flag(element, "use_lumped_contact_model", True),
        line=element.line,
    )
    if pair.max_proximity <= pair.min_proximity:
        raise OpenSimModelError(f"{doc.where(element)}: max_proximity must exceed min_proximity")
    if not pair.lumped and formulation == "nonlinear":
        skipped.append(
            NotModelled(
                "contact",
                name,
                "nonlinear formulation without the lumped model: two logarithmic layers in series have no dea-opt "
                "law; the pair is read but gives no law",
                element.line,
            )
        )
    _note_unread(doc, element, _PAIR_KEYS, skipped)
    return pair


# --- ligaments ---------------------------------------------------------------------------------


def _ligament(doc: Document, element, frames: dict, wraps: dict, skipped: list) -> Ligament | None:
    name = element.name
    if not doc.flag(element, "appliesForce", True):
        skipped.append(NotModelled("ligament", name, "disabled in the model (appliesForce false)", element.line))
        return None
    gp = element.child("GeometryPath")
    pps = None if gp is None else gp.child("PathPointSet")
    objects = None if pps is None else pps.child("objects")
    raw = list(objects.children) if objects is not None else []
    if len(raw) < 2:
        raise OpenSimModelError(f"{doc.where(element)}: its GeometryPath has {len(raw)} path points, needs 2 or more")
    for end in (raw[0], raw[-1]):
        if end.tag != "PathPoint":
            skipped.append(
                NotModelled(
                    "ligament", name, f"its insertion {end.name} is a {end.tag}: the bundle is left out", end.line
                )
            )
            return None
    points = []
    for p in raw:
        if p.tag != "PathPoint":
            kind = "conditional_path_point" if p.tag == "ConditionalPathPoint" else "moving_path_point"
            skipped.append(NotModelled(kind, f"{name}/{p.name}", f"a {p.tag} of {name}: left out of its path", p.line))
            continue
        frame = doc.path(doc.socket(p, "socket_parent_frame", kinds=("Ground", "Body", "PhysicalOffsetFrame")))
        frame = frame or "/ground"
        location = frozen_array(doc.floats(p, "location", 3) * 1000.0)  # m -> mm
        points.append(PathPoint(p.name, frame, frames[frame].body, location, p.tag, p.line))
    wrap_names = []
    pws = None if gp is None else gp.child("PathWrapSet")
    for pw in pws.child("objects").children if pws is not None and pws.child("objects") is not None else []:
        wrap = pw.child_text("wrap_object")
        if wrap not in wraps:
            raise OpenSimModelError(f"{doc.where(pw)}: its wrap_object {wrap!r} is not a wrap object of the model")
        wrap_names.append(wrap)
    stiffness = doc.number(element, "linear_stiffness", 1.0)
    transition = doc.number(element, "transition_strain", 0.06)
    damping = doc.number(element, "damping_coefficient", 0.003)
    has_slack = element.child("slack_length") is not None
    slack = doc.number(element, "slack_length", 0.0) * 1000.0  # m -> mm
    reference = doc.number(element, "reference_strain") if element.child("reference_strain") is not None else None
    if stiffness < 0 or transition <= 0 or damping < 0:
        raise OpenSimModelError(
            f"{doc.where(element)}: needs linear_stiffness >= 0, transition_strain > 0 and damping_coefficient >= 0"
        )
    if not slack > 0 and reference is None:
        raise OpenSimModelError(
            f"{doc.where(element)}: its slack_length is {'0' if has_slack else 'missing'} and it gives no "
            f"reference_strain: a bundle needs a slack length > 0"
        )
    _note_unread(doc, element, _LIGAMENT_KEYS, skipped)
    return Ligament(
        name=name,
        points=tuple(points),
        stiffness=stiffness,
        slack_length=slack if slack > 0 else float("nan"),
        slack_from="slack_length" if slack > 0 else "reference_strain",
        reference_strain=reference,
        transition_strain=transition,
        damping=damping,
        wraps=tuple(wrap_names),
        applies_force=True,
        line=element.line,
    )


def _wrap_objects(doc: Document, frames: dict) -> dict:
    wraps: dict = {}
    for element in doc.model.iter():
        if element.tag != "WrapObjectSet":
            continue
        body = doc.path(element.parent) if element.parent is not None else ""
        objects = element.child("objects")
        for w in objects.children if objects is not None else []:
            T = np.eye(4)
            T[:3, :3] = body_fixed_xyz(doc.floats(w, "xyz_body_rotation", 3, [0, 0, 0]))
            T[:3, 3] = doc.floats(w, "translation", 3, [0, 0, 0]) * 1000.0
            dims = {}
            for tag, n, key in _WRAP_DIMENSIONS.get(w.tag, ()):
                values = doc.floats(w, tag, n) * 1000.0
                dims[key] = tuple(float(v) for v in values) if n > 1 else float(values[0])
            frame = frames.get(body)
            wraps.setdefault(
                w.name,
                WrapObject(
                    w.name, w.tag, frame.body if frame else "ground", frozen_array(T), frozen_mapping(dims), w.line
                ),
            )
    return wraps


def _note_unread(doc: Document, element, known: set, skipped: list) -> None:
    """A property of ``element`` dea-opt does not read, set to something, is listed."""
    for child in element.children:
        if child.tag in known or child.tag in _DISPLAY or child.tag.startswith("socket_"):
            continue
        if child.text.lower() in ("", "false", "0") and not child.children:
            continue
        skipped.append(
            NotModelled(
                "property", f"{element.name}.{child.tag}", f"a property of a {element.tag} not read", child.line
            )
        )


# --- reports at the default pose ---------------------------------------------------------------------


def pose_reports(model, wrapped: list, via: list) -> list:
    """The ``not_modelled`` entries of wrapped bundles and bundles with via points, with their
    lengths at the model's default pose, and the slack lengths given as reference strains."""
    reports, poses, failed = [], {"ground": np.eye(4)}, {}
    needed = sorted({p.body for lig in model.ligaments.values() for p in lig.points} - {"ground"})
    for body in needed:  # one at a time: a body without a pose spoils only its own bundles
        try:
            poses.update(model.poses(bodies=[body]))
        except OpenSimModelError as exc:
            failed[body] = str(exc)
    fixed = dict(model.ligaments)
    for name, lig in model.ligaments.items():
        if lig.slack_from == "reference_strain" and not _blocked(lig, failed):
            x = point_positions(model, lig, poses)
            length = float(np.sum(np.linalg.norm(np.diff(x, axis=0), axis=1)))
            fixed[name] = _replace(lig, slack_length=length / (1.0 + lig.reference_strain))
        elif lig.slack_from == "reference_strain":
            raise OpenSimModelError(f"{model.path}: bundle {name} gives a reference strain but {_blocked(lig, failed)}")
    object.__setattr__(model, "ligaments", frozen_mapping(fixed))
    for name in wrapped + [n for n in via if n not in wrapped]:
        lig = model.ligaments[name]
        detail: dict = {"slack_length_mm": lig.slack_length}
        blocked = _blocked(lig, failed)
        if blocked:
            detail["default_pose"] = blocked
        else:
            x = point_positions(model, lig, poses)
            straight = float(np.linalg.norm(x[-1] - x[0]))
            detail["straight_length_mm"] = straight
            detail["straight_strain"] = straight / lig.slack_length - 1.0
            if len(x) > 2:
                detail["path_length_mm"] = float(np.sum(np.linalg.norm(np.diff(x, axis=0), axis=1)))
            crosses = []
            for w in lig.wraps:
                wrap = model.wrap_objects[w]
                T = poses.get(wrap.body)
                hit = None if T is None else segment_crosses_wrap(x[0], x[-1], wrap, T @ wrap.transform)
                crosses.append(f"{w}: {'not checked' if hit is None else ('crosses' if hit else 'clear')}")
            if crosses:
                detail["line_at_default_pose"] = tuple(crosses)
        if lig.wraps:
            what = (
                f"wraps around {', '.join(lig.wraps)} in OpenSim; dea-opt's bundle is the straight line from "
                f"{lig.points[0].name} to {lig.points[-1].name} (where the line crosses a wrap object, OpenSim's "
                f"path is longer)"
            )
            reports.append(NotModelled("wrap", name, what, lig.line, frozen_mapping(detail)))
        if len(lig.points) > 2:
            what = (
                f"{len(lig.points) - 2} via point(s) ({', '.join(p.name for p in lig.points[1:-1])}); dea-opt's bundle "
                f"is the straight line from the first to the last point"
            )
            reports.append(NotModelled("via_points", name, what, lig.line, frozen_mapping(detail)))
    return reports


def _blocked(ligament, failed: dict) -> str:
    bodies = [p.body for p in ligament.points if p.body in failed]
    return f"no pose for {bodies[0]}: {failed[bodies[0]]}" if bodies else ""


def _replace(ligament, **changes):
    from dataclasses import replace

    return replace(ligament, **changes)
