"""A model's kinematics without OpenSim: the pose of every body for given coordinate values.

The joint tree is walked from ground (``formulations/opensim.md``, "Kinematics"). A joint
places its child frame in its parent frame by ``X_FM(q)``; for a ``CustomJoint`` this is
Simbody's ``MobilizedBody::FunctionBased`` (what OpenSim builds from the SpatialTransform)::

    R = Rot(f_1(q), a_1) Rot(f_2(q), a_2) Rot(f_3(q), a_3)    (body-fixed: each about its axis
                                                               in the frame the ones before made)
    p = f_4(q) a_4 + f_5(q) a_5 + f_6(q) a_6                  (in the parent frame F)

with the six axes ``a_k`` normalised and ``f_k`` the axes' functions. A ``WeldJoint`` is the
identity. Then ``X_G_child_frame = X_G_parent_frame X_FM`` and the child body is
``X_G_child_frame inv(X_body_child_frame)``. A joint walked from its child to its parent (a
tree OpenSim reversed) uses the inverse. Offset frames are their ``translation`` and their
body-fixed x-y-z ``orientation``: ``R = Rx(a) Ry(b) Rz(c)``. Translations are returned in mm.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np

from ..errors import OpenSimModelError

__all__ = ["axis_rotation", "body_fixed_xyz", "joint_transform", "pose_bodies", "rigid_inverse"]


def axis_rotation(angle: float, axis) -> np.ndarray:
    """The rotation (3, 3) by ``angle`` (rad) about the unit ``axis`` (Rodrigues' formula)."""
    x, y, z = axis
    c, s = math.cos(angle), math.sin(angle)
    C = 1.0 - c
    return np.array(
        [
            [c + x * x * C, x * y * C - z * s, x * z * C + y * s],
            [y * x * C + z * s, c + y * y * C, y * z * C - x * s],
            [z * x * C - y * s, z * y * C + x * s, c + z * z * C],
        ]
    )


def body_fixed_xyz(angles) -> np.ndarray:
    """``Rx(a) Ry(b) Rz(c)`` (3, 3): OpenSim's ``orientation`` of an offset frame (rad)."""
    a, b, c = (float(v) for v in angles)
    return axis_rotation(a, (1.0, 0.0, 0.0)) @ axis_rotation(b, (0.0, 1.0, 0.0)) @ axis_rotation(c, (0.0, 0.0, 1.0))


def rigid_inverse(T: np.ndarray) -> np.ndarray:
    """The inverse of the rigid transform ``T`` (4, 4)."""
    R, p = T[:3, :3], T[:3, 3]
    out = np.eye(4)
    out[:3, :3] = R.T
    out[:3, 3] = -R.T @ p
    return out


def joint_transform(joint, values: Mapping) -> np.ndarray:
    """``X_FM`` (4, 4, mm) of ``joint`` (a :class:`~dea_opt.opensim.model.Joint`) at the
    coordinate ``values`` (name -> value in OpenSim's units)."""
    if joint.kind == "WeldJoint":
        return np.eye(4)
    if joint.kind != "CustomJoint":
        raise OpenSimModelError(
            f"joint {joint.name} (line {joint.line}) is a {joint.kind}, which dea-opt does not evaluate (it "
            f"evaluates CustomJoint and WeldJoint): the bodies it moves have no pose here"
        )
    amounts = []
    for axis in joint.axes:
        amounts.append(float(axis.function(tuple(values[c] for c in axis.coordinates))))
    R = np.eye(3)
    for k in range(3):
        R = R @ axis_rotation(amounts[k], joint.axes[k].axis)
    p = sum(amounts[k] * joint.axes[k].axis for k in range(3, 6)) * 1000.0  # m -> mm
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p
    return T


def pose_bodies(model, values: Mapping, bodies=None) -> dict:
    """``{body: X_G_body}`` (4, 4, mm) at the coordinate ``values`` (every coordinate given).

    ``bodies`` limits the walk to what those bodies need (None: every body a supported joint
    reaches). A body asked for that no joint connects to ground, or only through a joint or
    function dea-opt does not evaluate, raises :class:`~dea_opt.errors.OpenSimModelError`
    naming what is in the way.
    """
    base = {path: model.frame_in_body(path) for path in {p for j in model.joints.values() for p in _ends(j)}}
    known = {"ground": np.eye(4)}
    wanted = None if bodies is None else set(bodies)
    blocked: dict = {}
    # Breadth first from ground: each round places the bodies one joint further out.
    pending = list(model.joints.values())
    while pending and (wanted is None or not wanted <= known.keys()):
        progress, rest = False, []
        for joint in pending:
            parent_in, child_in = joint.parent_body in known, joint.child_body in known
            if parent_in == child_in:
                if not parent_in:
                    rest.append(joint)
                continue
            try:
                X = joint_transform(joint, values)
            except OpenSimModelError as exc:
                blocked[joint.child_body if parent_in else joint.parent_body] = str(exc)
                continue
            P, C = base[joint.parent_frame], base[joint.child_frame]
            if parent_in:  # X_G_child = X_G_parent P X inv(C)
                known[joint.child_body] = known[joint.parent_body] @ P @ X @ rigid_inverse(C)
            else:
                known[joint.parent_body] = known[joint.child_body] @ C @ rigid_inverse(X) @ rigid_inverse(P)
            progress = True
        pending = rest
        if not progress:
            break
    if wanted is not None:
        for body in sorted(wanted - known.keys()):
            if body not in model.bodies and body != "ground":
                raise OpenSimModelError(f"{model.path}: has no body {body!r} (its bodies: {', '.join(model.bodies)})")
            reason = _blocked_reason(model, body, blocked)
            raise OpenSimModelError(f"{model.path}: body {body} has no pose: {reason}")
        return {b: known[b] for b in bodies}
    return known


def _ends(joint) -> tuple:
    return (joint.parent_frame, joint.child_frame)


def _blocked_reason(model, body: str, blocked: dict) -> str:
    """Why ``body`` was not reached: the first unevaluated joint on its way to ground."""
    seen = set()
    while body not in seen:
        seen.add(body)
        if body in blocked:
            return blocked[body]
        joint = next((j for j in model.joints.values() if j.child_body == body), None)
        if joint is None:
            return "no joint connects it to ground"
        body = joint.parent_body
    return "its joints form a loop without ground"
