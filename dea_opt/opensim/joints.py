"""An OpenSim joint's coordinates as the coordinates of one body of a dea-opt joint.

``formulations/opensim.md`` ("A joint's coordinates in dea-opt"): a ``CustomJoint`` between a
body held in place and a body that moves becomes a :class:`~dea_opt.joint.Coordinates` of the
moving body, so that the model's own coordinates (``knee_flex_r`` ...) are that body's dofs: a
motion file of them prescribes some, and the others are found. The moving body is the joint's
child (its parent held) or its parent (its child held: ``inverted``, as the femur on a fixed
tibia through DM's ``knee_r``). Each axis must be driven by its own coordinate through a
``LinearFunction`` (or a ``MultiplierFunction`` of one), or be a ``Constant``; translations are
made mm.
"""

from __future__ import annotations

import numpy as np

from ..errors import OpenSimModelError
from .model import Constant, LinearFunction, MultiplierFunction

__all__ = ["joint_coordinates", "movable_joints"]


def _linear(function) -> tuple | None:
    """``(slope, intercept)`` of a linear function of one coordinate, or None."""
    if isinstance(function, LinearFunction):
        return function.slope, function.intercept
    if isinstance(function, MultiplierFunction):
        inner = _linear(function.function)
        return None if inner is None else (function.scale * inner[0], function.scale * inner[1])
    return None


def joint_coordinates(model, joint: str, moving: str, coordinates=None):
    """The :class:`~dea_opt.joint.Coordinates` of body ``moving`` through the model's joint ``joint``.

    Parameters
    ----------
    model : OsimModel
    joint : str
        A ``CustomJoint`` of the model with ``moving`` on one side.
    moving : str
        The body that moves; the other side of the joint is held where the model's coordinates
        put it.
    coordinates : mapping, optional
        Coordinate values of the start pose (default: the model's defaults), OpenSim's units.

    Returns
    -------
    Coordinates
        In ground at the start pose, mm: ``names`` are the coordinates' names in dof order
        (``ux, uy, uz`` the translations 1-3, ``rx, ry, rz`` the rotations 1-3; an axis of a
        ``Constant`` is named ``<joint>/<axis>`` and held at its value).
    """
    from ..joint import Coordinates

    if joint not in model.joints:
        raise OpenSimModelError(f"{model.path}: has no joint {joint!r}")
    j = model.joints[joint]
    if j.kind != "CustomJoint" or len(j.axes) != 6:
        raise OpenSimModelError(f"{model.path}: joint {joint} is a {j.kind}: only a CustomJoint's axes are coordinates")
    if moving not in (j.parent_body, j.child_body):
        raise OpenSimModelError(
            f"{model.path}: joint {joint} connects {j.parent_body} and {j.child_body}, not {moving}"
        )
    inverted = moving == j.parent_body
    held = j.child_body if inverted else j.parent_body
    values = model.values(coordinates)
    poses = model.poses(coordinates, bodies=[held])
    frame = poses[held] @ model.frame_in_body(j.child_frame if inverted else j.parent_frame)
    names, slopes, intercepts, start, used = [], [], [], [], set()
    for k in (3, 4, 5, 0, 1, 2):  # dof order: translations, then rotations
        axis = j.axes[k]
        unit = 1000.0 if k >= 3 else 1.0  # OpenSim's translations are in m
        if isinstance(axis.function, Constant) or not axis.coordinates:
            value = float(axis.function(())) if isinstance(axis.function, Constant) else 0.0
            names.append(f"{joint}/{axis.name}")
            slopes.append(1.0)
            intercepts.append(0.0)
            start.append(unit * value)
            continue
        linear = _linear(axis.function)
        name = axis.coordinates[0]
        if linear is None or len(axis.coordinates) != 1 or name in used:
            raise OpenSimModelError(
                f"{model.path}: joint {joint}'s {axis.name} is not a linear function of a coordinate of its own "
                f"({type(axis.function).__name__} of {', '.join(axis.coordinates)}): its coordinates cannot be a "
                f"body's dofs"
            )
        used.add(name)
        names.append(name)
        slopes.append(linear[0])
        intercepts.append(unit * linear[1])
        start.append(unit * values[name])
    rotation_axes = np.array([j.axes[k].axis for k in range(3)])
    translation_axes = np.array([j.axes[k].axis for k in range(3, 6)])
    return Coordinates(
        frame,
        rotation_axes,
        translation_axes,
        np.array(start),
        np.array(slopes),
        np.array(intercepts),
        inverted,
        tuple(names),
    )


def movable_joints(model, fixed) -> dict:
    """``{body: joint}``: each body on the other side of a ``CustomJoint`` from a body of ``fixed``
    (held in place), the first such joint in the model's order; bodies that are fixed themselves,
    or whose joint's axes are not linear in coordinates of their own, have none."""
    from ..errors import DeaError

    fixed = set(fixed)
    out: dict = {}
    for name, j in model.joints.items():
        for held, moving in ((j.parent_body, j.child_body), (j.child_body, j.parent_body)):
            if held in fixed and moving not in fixed and moving not in out:
                try:
                    joint_coordinates(model, name, moving)
                except DeaError:
                    continue
                out[moving] = name
    return out
