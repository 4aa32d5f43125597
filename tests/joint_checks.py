"""An independent check of a joint's equilibrium, for the joint tests: forces and moments summed here.

Nothing of ``dea_opt`` computes these sums: every spring pushes its two bodies apart along its
normal with ``pressure * area`` at its point, every bundle pulls its two insertions together along
its line with its force, and each body's load is a force at its reference and a moment. Small
kinematics: everything at the start pose (the paper's Eq. 6-12), the bundles along their start
direction.
"""

from __future__ import annotations

import numpy as np


def net_wrench(solution) -> dict:
    """``{body: (force (3,), moment (3,) about its reference)}``: loads plus element forces."""
    joint = solution.joint
    out = {}
    for name, body in joint.bodies.items():
        out[name] = [np.array(body.force, dtype=float), np.array(body.moment, dtype=float)]
    for contact, layer_solution in zip(joint.contacts, solution.contacts):
        layer = contact.layer
        push = (layer_solution.pressure * layer.areas)[:, None] * layer.normals  # on body 2, along +n
        for name, sign in ((contact.body1, -1.0), (contact.body2, 1.0)):
            c = np.asarray(joint.bodies[name].reference, dtype=float)
            out[name][0] += sign * push.sum(axis=0)
            out[name][1] += sign * np.cross(layer.points - c, push).sum(axis=0)
    for i, lig in enumerate(joint.ligaments):
        p1, p2 = np.asarray(lig.point1), np.asarray(lig.point2)
        e = (p2 - p1) / np.linalg.norm(p2 - p1)
        f = float(solution.ligaments.force[i])
        for name, point, sign in ((lig.body1, p1, 1.0), (lig.body2, p2, -1.0)):  # pulls the ends together
            c = np.asarray(joint.bodies[name].reference, dtype=float)
            out[name][0] += sign * f * e
            out[name][1] += sign * f * np.cross(point - c, e)
    return {name: (v[0], v[1]) for name, v in out.items()}


def worst_imbalance(solution) -> float:
    """The largest net force or moment (moments over a radius of 1 mm... per unit: N and N mm)
    on any free dof of any body, over the scale of the forces on that body."""
    joint = solution.joint
    wrench = net_wrench(solution)
    worst = 0.0
    dofs = ("ux", "uy", "uz", "rx", "ry", "rz")
    for name, body in joint.bodies.items():
        if not body.free:
            continue
        scale = _scale(solution, name)
        net = np.concatenate(wrench[name])
        for j, dof in enumerate(dofs):
            if dof in body.free:
                arm = 1.0 if j < 3 else _radius(solution, name)
                worst = max(worst, abs(net[j]) / arm / scale)
    return worst


def _radius(solution, name) -> float:
    joint = solution.joint
    points = [c.layer.points for c in joint.contacts if name in (c.body1, c.body2)]
    points += [
        np.array([lig.point1 if lig.body1 == name else lig.point2])
        for lig in joint.ligaments
        if name in (lig.body1, lig.body2)
    ]
    p = np.vstack(points) - np.asarray(joint.bodies[name].reference)
    return float(np.sqrt(np.mean(np.sum(p * p, axis=1))))


def _scale(solution, name) -> float:
    joint = solution.joint
    body = joint.bodies[name]
    total = max(float(np.abs(body.force).max()), float(np.abs(body.moment).max()) / _radius(solution, name))
    for contact, s in zip(joint.contacts, solution.contacts):
        if name in (contact.body1, contact.body2):
            total = max(total, float((s.pressure * contact.layer.areas).sum()))
    touching = [i for i, lig in enumerate(joint.ligaments) if name in (lig.body1, lig.body2)]
    total = max(total, float(np.abs(solution.ligaments.force[touching]).sum()))
    return max(total, 1e-300)


def _loads_at_pose(solution) -> dict:
    """``{body: [force, moment about its reference where it is]}`` of every load at the solved pose:
    a body's own force and moment, and each BodyLoad with its point moved by the body's pose and, in
    the body frame, its components turned."""
    joint = solution.joint
    out = {}
    for name, body in joint.bodies.items():
        T = solution.bodies[name].pose
        out[name] = [
            np.array(body.force, dtype=float),
            np.array(body.moment, dtype=float),
            T[:3, :3] @ body.reference + T[:3, 3],
        ]
    for load in joint.loads:
        T = solution.bodies[load.body].pose
        R, t = T[:3, :3], T[:3, 3]
        point = np.asarray(joint.bodies[load.body].reference if load.point is None else load.point, dtype=float)
        F, M = np.array(load.force, dtype=float), np.array(load.moment, dtype=float)
        if load.frame == "body":
            F, M = R @ F, R @ M
        ref = out[load.body][2]
        out[load.body][0] += F
        out[load.body][1] += M + np.cross(R @ point + t - ref, F)
    return out


def net_wrench_at_pose(solution) -> dict:
    """Finite kinematics: ``{body: (force, moment about its reference where it is)}`` of loads and
    element forces at the solved pose: each layer's springs where its answer puts them (world
    frame), each bundle along its line between its insertions there, each spring along the line
    between its ends moved by the poses, every load moved with its body."""
    joint = solution.joint
    out = _loads_at_pose(solution)
    refs = {n: v[2] for n, v in out.items()}
    for contact, layer_solution in zip(joint.contacts, solution.contacts):
        layer = layer_solution.problem.layer
        push = (layer_solution.pressure * layer.areas)[:, None] * layer.normals
        for name, sign in ((contact.body1, -1.0), (contact.body2, 1.0)):
            out[name][0] += sign * push.sum(axis=0)
            out[name][1] += sign * np.cross(layer.points - refs[name], push).sum(axis=0)
    ligaments = solution.ligaments
    ends = [
        (lig, ligaments.point1[i], ligaments.point2[i], float(ligaments.force[i]))
        for i, lig in enumerate(joint.ligaments)
    ]
    rows = [r for r in solution.elastic if r["kind"] == "spring"]
    for spring, row in zip(joint.springs, rows):
        T1, T2 = solution.bodies[spring.body1].pose, solution.bodies[spring.body2].pose
        p1 = T1[:3, :3] @ np.asarray(spring.point1) + T1[:3, 3]
        p2 = T2[:3, :3] @ np.asarray(spring.point2) + T2[:3, 3]
        ends.append((spring, p1, p2, float(row["force_N"])))
    for element, p1, p2, f in ends:
        e = (p2 - p1) / np.linalg.norm(p2 - p1)
        out[element.body1][0] += f * e
        out[element.body1][1] += f * np.cross(p1 - refs[element.body1], e)
        out[element.body2][0] -= f * e
        out[element.body2][1] -= f * np.cross(p2 - refs[element.body2], e)
    assert not joint.bushings, "the sums here leave bushings out"
    return {name: (v[0], v[1]) for name, v in out.items()}


def assert_balanced_at_pose(solution, tol, twists=None):
    """Finite kinematics: on every body, the net force along each free translation, and the net
    moment where all three rotations are free, at most ``tol`` of the forces on the joint (moments
    over 30 mm). ``twists`` ``{body: {dof: (v (3,), w (3,))}}`` gives, for a body whose coordinates
    are not world axes, each free coordinate's velocity of its reference and angular velocity: there
    the net generalized force ``F . v + M . w`` on each (moments over 30 mm) is checked instead."""
    wrench = net_wrench_at_pose(solution)
    scale = max(1.0, float(np.abs(solution.ligaments.force).sum()) if len(solution.ligaments) else 1.0)
    scale = max([scale] + [float((c.pressure * c.problem.layer.areas).sum()) for c in solution.contacts])
    for name, body in solution.joint.bodies.items():
        force, moment = wrench[name]
        scale_b = max(scale, float(np.abs(body.force).max()))
        if twists is not None and name in twists:
            for dof, (v, w) in twists[name].items():
                arm = 1.0 if dof[0] == "u" else 30.0
                assert abs(force @ v + moment @ w) <= tol * scale_b * arm, (name, dof, force @ v + moment @ w)
            continue
        for j, dof in enumerate(("ux", "uy", "uz")):
            if dof in body.free:
                assert abs(force[j]) <= tol * scale_b, (name, dof, force)
        if all(dof in body.free for dof in ("rx", "ry", "rz")):
            assert np.abs(moment).max() <= tol * scale_b * 30.0, (name, moment)
