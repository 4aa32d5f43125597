"""``read_model``: an OpenSim model file (``.osim``) read without OpenSim into plain objects.

The file is parsed by :mod:`~dea_opt.opensim.safexml` (no DOCTYPE, no entities: a model from
elsewhere is untrusted input), its components named by path (:mod:`~dea_opt.opensim.document`),
then read into the immutable objects of :mod:`~dea_opt.opensim.model`: frames, joints and
coordinates here, contact and ligaments in :mod:`~dea_opt.opensim.forces`. What dea-opt does
not model goes into ``not_modelled`` by name. The conventions: ``formulations/opensim.md``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import OpenSimModelError
from . import forces
from .document import Document
from .kinematics import body_fixed_xyz
from .model import (
    Constant,
    Coordinate,
    Frame,
    Joint,
    LinearFunction,
    MultiplierFunction,
    NotModelled,
    TransformAxis,
    UnsupportedFunction,
    frozen_array,
    frozen_mapping,
)
from .osimmodel import OsimModel
from .safexml import parse_file

__all__ = ["read_model"]

_AXES = ("rotation1", "rotation2", "rotation3", "translation1", "translation2", "translation3")
_DEFAULT_AXES = ((1, 0, 0), (0, 1, 0), (0, 0, 1)) * 2


def read_model(path) -> OsimModel:
    """Read an OpenSim 4 model file (``.osim``) safely, without OpenSim.

    Parameters
    ----------
    path : str or path-like
        The model file. Its contact meshes are looked for next to it and in its ``Geometry/``
        folder, as OpenSim looks.

    Returns
    -------
    OsimModel
        Bodies, frames, joints and coordinates, the ``Smith2018ContactMesh`` surfaces and
        ``Smith2018ArticularContactForce`` pairs, every ``Blankevoort1991Ligament``, the wrap
        objects, and ``not_modelled``: every part of the model dea-opt does not model, by name
        (wrap objects with each bundle's straight line at the default pose, via points, muscles
        and other forces, constraints, joints and functions it does not evaluate). In mm, N, MPa.

    Raises
    ------
    OpenSimModelError
        The file is missing or not an OpenSim 4 model, is malformed or declares a DOCTYPE or
        entities (refused), or a component is incomplete or inconsistent; the message names the
        file, the component and the line.

    Notes
    -----
    The XML is read by the standard library's expat with every document type declaration
    refused before it is read (:mod:`dea_opt.opensim.safexml`): entities can be declared only
    there, so none is expanded and nothing outside the file is fetched.
    """
    path = Path(path)
    doc = Document.of(parse_file(path), str(path))
    units = doc.model.child_text("length_units")
    if units not in (None, "", "m", "meters", "meter"):
        raise OpenSimModelError(f"{path}: its length_units are {units!r}; dea-opt reads models in metres (m)")
    skipped: list[NotModelled] = []
    frames = _frames(doc)
    bodies = tuple(f.name for f in frames.values() if f.kind == "body")
    joints, coordinates = _joints(doc, frames, skipped)
    parts = forces.read_forces(doc, path, frames, skipped)
    model = OsimModel(
        path=path,
        name=doc.model.name or path.stem,
        bodies=bodies,
        frames=frozen_mapping(frames),
        joints=frozen_mapping(joints),
        coordinates=frozen_mapping(coordinates),
        contact_meshes=frozen_mapping(parts["contact_meshes"]),
        contact_pairs=frozen_mapping(parts["contact_pairs"]),
        ligaments=frozen_mapping(parts["ligaments"]),
        wrap_objects=frozen_mapping(parts["wrap_objects"]),
        not_modelled=(),
    )
    skipped += forces.pose_reports(model, parts["wrapped"], parts["via"])
    _check_frames_of_parts(model)
    object.__setattr__(model, "not_modelled", tuple(skipped))
    return model


# --- frames -----------------------------------------------------------------------------------


def _frames(doc: Document) -> dict:
    """Ground, bodies and offset frames by path, with the body each is fixed to."""
    raw: dict = {}
    for element in doc.model.iter():
        path = doc.paths.get(id(element))
        if path is None or element is doc.model:
            continue
        if element.tag == "Ground":
            raw[path] = ("ground", None, np.eye(4), element)
        elif element.tag == "Body":
            raw[path] = ("body", None, np.eye(4), element)
        elif element.tag == "PhysicalOffsetFrame":
            parent = doc.socket(element, "socket_parent", kinds=("Ground", "Body", "PhysicalOffsetFrame"))
            T = np.eye(4)
            T[:3, :3] = body_fixed_xyz(doc.floats(element, "orientation", 3, [0, 0, 0]))
            T[:3, 3] = doc.floats(element, "translation", 3, [0, 0, 0]) * 1000.0  # m -> mm
            raw[path] = ("offset", doc.path(parent), T, element)
    if not any(kind == "ground" for kind, *_ in raw.values()):
        raw["/ground"] = ("ground", None, np.eye(4), doc.model)
    frames = {}
    for path, (kind, parent, T, element) in raw.items():
        body, seen, p = None, {path}, path
        while body is None:
            k, par, _, e = raw[p]
            if k != "offset":
                body = "ground" if k == "ground" else e.name
            elif par in seen or par not in raw:
                raise OpenSimModelError(f"{doc.where(element)}: its chain of parent frames does not reach a body")
            else:
                seen.add(par)
                p = par
        frames[path] = Frame(path, element.name or "ground", kind, body, parent, frozen_array(T), element.line)
    return frames


def _frame_path(doc: Document, owner, tag: str, frames: dict) -> str:
    target = doc.socket(owner, tag, kinds=("Ground", "Body", "PhysicalOffsetFrame"))
    path = doc.path(target) or "/ground"
    if path not in frames:
        raise OpenSimModelError(f"{doc.where(owner)}: its <{tag}> is not a frame dea-opt knows")
    return path


# --- joints and coordinates -----------------------------------------------------------------------


def _joints(doc: Document, frames: dict, skipped: list) -> tuple:
    joints, coordinates = {}, {}
    for element in doc.objects("JointSet"):
        name = element.name or f"<{element.tag}>"
        parent = _frame_path(doc, element, "socket_parent_frame", frames)
        child = _frame_path(doc, element, "socket_child_frame", frames)
        owned = element.child("coordinates")
        coords = [c for c in (owned.children if owned is not None else []) if c.tag == "Coordinate"]
        axes: tuple = ()
        if element.tag == "CustomJoint":
            axes = _spatial_transform(doc, element, skipped)
        elif element.tag != "WeldJoint":
            skipped.append(
                NotModelled(
                    "joint",
                    name,
                    f"a {element.tag}: dea-opt evaluates CustomJoint and WeldJoint only; the bodies it moves have no "
                    f"pose (coordinates {', '.join(c.name or '?' for c in coords) or 'none'})",
                    element.line,
                )
            )
        used = {c for axis in axes for c in axis.coordinates}
        motion = _motion_types(axes)
        for c in coords:
            if c.name in coordinates:
                raise OpenSimModelError(f"{doc.where(c)}: a second coordinate named {c.name!r}")
            if axes and c.name not in used:
                skipped.append(NotModelled("joint", c.name, f"coordinate of {name} that no axis uses", c.line))
            lo, hi = doc.floats(c, "range", 2, [-np.pi, np.pi])
            coordinates[c.name] = Coordinate(
                name=c.name,
                joint=name,
                default_value=doc.number(c, "default_value", 0.0),
                range=(float(lo), float(hi)),
                clamped=doc.flag(c, "clamped", True),
                locked=doc.flag(c, "locked", False),
                motion=motion.get(c.name, "coupled" if element.tag == "CustomJoint" else "unknown"),
                line=c.line,
            )
            if c.child("prescribed_function") is not None and doc.flag(c, "prescribed", False):
                skipped.append(NotModelled("joint_function", c.name, "a prescribed function of time", c.line))
        missing = sorted(used - {c.name for c in coords})
        if missing:
            raise OpenSimModelError(f"{doc.where(element)}: its axes use coordinates it does not own: {missing}")
        joints[name] = Joint(
            name=name,
            kind=element.tag,
            parent_frame=parent,
            child_frame=child,
            parent_body=frames[parent].body,
            child_body=frames[child].body,
            coordinates=tuple(c.name for c in coords),
            axes=axes,
            line=element.line,
        )
    return joints, coordinates


def _spatial_transform(doc: Document, joint, skipped: list) -> tuple:
    st = joint.child("SpatialTransform")
    axes = []
    for k, tag in enumerate(_AXES):
        element = next((e for e in (st.children if st is not None else []) if e.name == tag), None)
        if element is None:  # an axis left out: OpenSim's default, no coordinate and 0
            axes.append(TransformAxis(tag, frozen_array(_DEFAULT_AXES[k]), (), Constant(0.0)))
            continue
        where = f"{joint.name}/{tag}"
        axis = doc.floats(element, "axis", 3, _DEFAULT_AXES[k])
        norm = float(np.linalg.norm(axis))
        if not norm > 1e-12:
            raise OpenSimModelError(f"{doc.source}, line {element.line}: the axis of {where} has zero length")
        names = tuple((element.child_text("coordinates") or "").split())
        function, given = _function(doc, element, names, where, skipped)
        axes.append(TransformAxis(tag, frozen_array(axis / norm), names, function, given))
    for start in (0, 3):  # Simbody refuses collinear axes (OpenSim: "has collinear axes")
        a = [axes[start + i].axis for i in range(3)]
        for i, j in ((0, 1), (0, 2), (1, 2)):
            if np.linalg.norm(np.cross(a[i], a[j])) < 1e-5:
                kind = "rotation" if start == 0 else "translation"
                raise OpenSimModelError(
                    f"{doc.where(joint)}: its {kind} axes {_AXES[start + i]} and {_AXES[start + j]} are collinear "
                    f"(OpenSim refuses such a joint too)"
                )
    return tuple(axes)


_FUNCTIONS = ("LinearFunction", "Constant", "MultiplierFunction")


def _function(doc: Document, axis, names: tuple, where: str, skipped: list):
    found = [c for c in axis.children if c.name == "function" or c.tag in _FUNCTIONS or c.tag.endswith("Function")]
    found = [c for c in found if c.tag not in ("coordinates", "axis")]
    if not found:
        if len(names) > 1:
            raise OpenSimModelError(f"{doc.where(axis)}: {where} takes {len(names)} coordinates but has no function")
        if names:
            # OpenSim 4.6 moves nothing along an axis that names a coordinate but gives no function
            # (tests/data/opensim/make_reference.py recorded it): the same here, and said.
            skipped.append(
                NotModelled(
                    "property",
                    where,
                    f"names the coordinate {names[0]} but gives no function: OpenSim 4.6 moves nothing along this "
                    f"axis, and neither does dea-opt",
                    axis.line,
                )
            )
        return Constant(0.0), False
    element = found[0]
    function = _read_function(doc, element, where)
    if isinstance(function, UnsupportedFunction):
        skipped.append(
            NotModelled("joint_function", where, f"a {function.kind}: the bodies it moves have no pose", element.line)
        )
    elif len(names) > 1:
        raise OpenSimModelError(f"{doc.where(axis)}: {where} takes {len(names)} coordinates; a {element.tag} takes one")
    elif not names and not isinstance(function, Constant):
        raise OpenSimModelError(f"{doc.where(axis)}: {where} has a {element.tag} but no coordinate")
    return function, True


def _read_function(doc: Document, element, where: str):
    if element.tag == "LinearFunction":
        slope, intercept = doc.floats(element, "coefficients", 2, [1.0, 0.0])
        return LinearFunction(float(slope), float(intercept))
    if element.tag == "Constant":
        return Constant(doc.number(element, "value", 0.0))
    if element.tag == "MultiplierFunction":
        # OpenSim writes the wrapped function inside a <function> property element
        holder = element.child("function")
        inner = holder.children[0] if holder is not None and holder.children else None
        if inner is None:
            raise OpenSimModelError(f"{doc.where(element)}: a MultiplierFunction without its function")
        wrapped = _read_function(doc, inner, where)
        if isinstance(wrapped, UnsupportedFunction):
            return wrapped
        if isinstance(wrapped, Constant):  # a constant scaled is a constant: it needs no coordinate
            return Constant(doc.number(element, "scale", 1.0) * wrapped.value)
        return MultiplierFunction(doc.number(element, "scale", 1.0), wrapped)
    return UnsupportedFunction(element.tag, element.line, where)


def _motion_types(axes: tuple) -> dict:
    """OpenSim's motion type of each coordinate (``CustomJoint::constructCoordinates``): an axis
    whose function is a LinearFunction of slope +-1 makes it rotational (axes 1-3) or
    translational (4-6), the last such axis deciding; any other function makes it coupled
    unless an axis made it one of those. An axis the model gives no function counts as coupled,
    as OpenSim 4.6 reports it (its default function is made after the motion types)."""
    motion: dict = {}
    for k, axis in enumerate(axes):
        for name in axis.coordinates:
            f = axis.function
            if axis.given and isinstance(f, LinearFunction) and abs(f.slope) == 1.0:
                motion[name] = "rotational" if k < 3 else "translational"
            else:
                motion.setdefault(name, "coupled")
    return motion


def _check_frames_of_parts(model: OsimModel) -> None:
    """Every frame a contact mesh or path point uses is known (read_forces checked the paths)."""
    for mesh in model.contact_meshes.values():
        model.frame_in_body(mesh.frame)
