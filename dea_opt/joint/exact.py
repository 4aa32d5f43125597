"""A joint's exact forces at a pose, on its free coordinates (finite kinematics).

Written math: ``formulations/joint.md`` ("Finite kinematics": the exact forces at a pose are
summed over the elements that carry load and projected by each body's ``B^T``). The solve calls
this at every pose it tries (a step, a line search, the tangent's differences): each group's
wrench is summed in one pass over its elements and moved as two 3-vectors, no row of a solve made.
"""

from __future__ import annotations

import numpy as np

from .coordinates import cross

__all__ = ["cross_sum", "exact_forces"]


def cross_sum(a, b) -> np.ndarray:
    """``sum_i a_i x b_i`` of two (N, 3) arrays: three pairs of dot products, no (N, 3) product made."""
    return np.array(
        [
            a[:, 1] @ b[:, 2] - a[:, 2] @ b[:, 1],
            a[:, 2] @ b[:, 0] - a[:, 0] @ b[:, 2],
            a[:, 0] @ b[:, 1] - a[:, 1] @ b[:, 0],
        ]
    )


def exact_forces(config) -> tuple[np.ndarray, np.ndarray]:
    """``(q, load)``: the generalized force on the free coordinates at the pose (N, N mm): every element's
    exact force there takes from the bodies and their loads, both projected by each body's rates
    (``B^T``) on the free coordinates (N, N mm). Computed from the elements that carry load alone
    (compressed springs, taut bundles), without the arrays of a solve: the tangent's differences
    call it. Each group's wrench is summed in its own frame (``sum f n``, ``sum p x f n``) and moved
    to the world as two vectors: no row of a solve is made."""
    joint = config.joint
    taken = {name: np.zeros(6) for name, b in joint.bodies.items() if b.free}
    if not taken:
        return np.zeros(0), np.zeros(0)

    def add(body1, body2, force, moment) -> None:
        """The wrench ``(force, moment about the origin)`` of a group's elements on body 2 (N, N mm,
        world), minus it on body 1, about each body's reference."""
        if body1 in taken:
            taken[body1] -= np.concatenate([force, moment - cross(config.references[body1], force)])
        if body2 in taken:
            taken[body2] += np.concatenate([force, moment - cross(config.references[body2], force)])

    with np.errstate(invalid="ignore", over="ignore"):
        for c, state, gaps in zip(joint.contacts, config.states, config.gaps):
            if c.body1 not in taken and c.body2 not in taken:
                continue
            active = np.flatnonzero(gaps.s < 0)  # an open spring (or a missed target) carries nothing
            if not active.size:
                continue
            layer = state.layer
            h = layer.thickness[active] if np.ndim(layer.thickness) else layer.thickness
            f = layer.areas[active] * c.law.stress(gaps.s[active] / h)
            fn = layer.normals[active] * f[:, None]  # in body 1's start frame
            force, moment = fn.sum(axis=0), cross_sum(layer.points[active], fn)
            T = config.poses[c.body1]
            R, t = T[:3, :3], T[:3, 3]
            force = R @ force
            add(c.body1, c.body2, force, R @ moment + cross(t, force))
        p1, p2 = config.insertions
        for g, (_, _, k, law) in zip(joint.ligament_groups, joint.ligament_arrays):
            if g.body1 not in taken and g.body2 not in taken:
                continue
            idx = g.index
            a, b = p1[idx], p2[idx]
            d = b - a
            length = np.sqrt(np.einsum("ij,ij->i", d, d))
            f = k * law.force(length / g.slack - 1.0)
            taut = f > 0
            if taut.any():
                fe = d[taut] * (f[taut] / length[taut])[:, None]
                force = fe.sum(axis=0)
                if g.body1 in taken:
                    taken[g.body1] -= np.concatenate(
                        [force, cross_sum(a[taut], fe) - cross(config.references[g.body1], force)]
                    )
                if g.body2 in taken:
                    taken[g.body2] += np.concatenate(
                        [force, cross_sum(b[taut], fe) - cross(config.references[g.body2], force)]
                    )
        for e in config.world_elastic:
            q = (e.k * e.e0) @ e.G
            if e.body1 in taken:
                taken[e.body1] += q[:6]
            if e.body2 in taken:
                taken[e.body2] += q[6:]
    out, load = np.zeros(len(joint.free_index)), np.zeros(len(joint.free_index))
    for name, q in taken.items():
        cols = joint.free_columns[name]
        B = config.rates[name]
        with np.errstate(invalid="ignore", over="ignore"):  # a law past its domain: inf, which the solve sees
            out[joint.free_of(name)] = (B.T @ q)[cols]
        load[joint.free_of(name)] = (B.T @ config.world_loads[name])[cols]
    return out, load
