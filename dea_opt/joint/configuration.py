"""A joint at a pose: every element where the bodies' exact motions put it, as the arrays of a solve.

Finite kinematics (``formulations/joint.md``, "Finite kinematics"): each body ``b`` is at the
exact rigid motion of its coordinates ``y_b = (t_b, theta_b)`` (the translation of its reference
and its rotation vector). At that pose every spring's gap is taken to its target on the other
body (:func:`~dea_opt.formulations.finite.Targets`: the tangent plane of the face its ray met,
a sphere, or its own plane), every bundle's length is the exact distance between its insertions,
and the joint's small-kinematics arrays are built there, with the rotation coordinates' rates
``omega = J(theta) dtheta``: at zero increment they give the exact forces, generalized forces
and tangent of the material, and a step of them moves every body by a first-order increment of
its coordinates.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from types import MappingProxyType

import numpy as np

from ..formulations._parts.finite_geometry import evaluate, left_jacobian, pose_matrix
from ..formulations.joint import ElementGroup, JointSystem, TensionLaw
from ..formulations.resistance import modulus_scale
from ..kinematics import DOFS, normal_operator
from ..layer import SpringLayer
from ..problem import Body
from .model import Joint, line_operator

__all__ = ["Configuration", "ContactState"]

#: The gap (mm) given to a spring whose ray misses its target: it is open, and stays so.
OPEN = 1e6


@dataclass(frozen=True, eq=False)
class ContactState:
    """A contact layer's springs and what they look at, in its first body's own (start) frame.

    ``layer`` the springs (points and normals on body 1, gaps at the pose they were cast or given
    at), ``targets`` their targets in body 2's own frame and ``frame`` (4x4: body 2's own frame at
    the start pose, in the world), ``cast`` the :class:`~dea_opt.mesh.SpringCast` that made them
    (None for springs given as a layer).
    """

    layer: SpringLayer
    targets: object
    cast: object = None
    dropped: int | None = None


def initial_states(joint) -> list[ContactState]:
    """Each contact's springs and targets at the start pose."""
    from ..formulations.finite import Targets
    from ..mesh.springs import SpringCast

    out = []
    for c in joint.contacts:
        if isinstance(c.targets, SpringCast):
            out.append(ContactState(c.targets.layer, Targets.from_layer(c.targets.layer, c.targets.pose), c.targets))
        elif c.targets is not None:
            out.append(ContactState(c.layer, c.targets))
        elif getattr(c.layer, "has_targets", False):
            out.append(ContactState(c.layer, Targets.from_layer(c.layer)))
        else:
            out.append(ContactState(c.layer, Targets.facing(c.layer)))
    return out


@dataclass(frozen=True, eq=False)
class Configuration:
    """The joint at the coordinates ``y`` (``{body: 6-vector}``) with the contacts' ``states``.

    Duck-types the parts of :class:`~dea_opt.joint.Joint` the certificate and the results read
    (``bodies``, ``free_index``, ``free_names``, ``system()``, ``element_bodies()``, ``contacts``,
    ``ligaments``, ``ligament_groups``), at the pose: body references where the motion took them,
    loads on the coordinates (forces, and ``J^T`` of the moments), the elements' rows of the
    coordinates' rates.
    """

    joint: Joint
    y: dict
    states: tuple

    # --- the pose --------------------------------------------------------------------------
    @cached_property
    def poses(self) -> dict:
        return {n: pose_matrix(self.y[n], b.reference) for n, b in self.joint.bodies.items()}

    @cached_property
    def jacobians(self) -> dict:
        return {n: left_jacobian(self.y[n][3:]) for n in self.joint.bodies}

    @cached_property
    def references(self) -> dict:
        """Each body's reference where the motion took it (mm)."""
        return {n: np.asarray(b.reference) + self.y[n][:3] for n, b in self.joint.bodies.items()}

    @cached_property
    def bodies(self) -> MappingProxyType:
        """The bodies at the pose: references moved, loads on the coordinates (``J^T M``)."""
        out = {}
        for n, b in self.joint.bodies.items():
            out[n] = Body(
                reference=self.references[n],
                free=b.free,
                force=b.force,
                moment=self.jacobians[n].T @ np.asarray(b.moment),
            )
        return MappingProxyType(out)

    @property
    def free_index(self) -> dict:
        return self.joint.free_index

    @property
    def free_names(self) -> tuple:
        return self.joint.free_names

    @property
    def contacts(self) -> tuple:
        return self.joint.contacts

    @property
    def ligaments(self) -> tuple:
        return self.joint.ligaments

    @property
    def kinematics(self) -> str:
        return "finite"

    @cached_property
    def world(self) -> WorldView:
        """The pose in world axes: each layer's two-body problem there, the bodies' loads as
        forces and moments, for the layers' own answers (:func:`~dea_opt.joint.results.layer_solutions`)."""
        from ..problem import ContactProblem

        bodies = {}
        for n, b in self.joint.bodies.items():
            # Rotations are free about world axes only where all three are (then the rotation
            # vector's rates span the same motions); otherwise the layer's problem holds them.
            rotations = all(d in b.free for d in DOFS[3:])
            free = tuple(d for d in b.free if d[0] == "u" or rotations)
            bodies[n] = Body(reference=self.references[n], free=free, force=b.force, moment=b.moment)
        pairs = tuple(
            ContactProblem(layer, c.law, body1=_unloaded(bodies[c.body1]), body2=_unloaded(bodies[c.body2]))
            for c, layer in zip(self.joint.contacts, self.layers)
        )
        return WorldView(self.joint.contacts, pairs, MappingProxyType(bodies))

    def _chain(self, name) -> np.ndarray:
        """``diag(I, J)`` of a body: its motion's rates per unit rate of its coordinates."""
        B = np.eye(6)
        B[3:, 3:] = self.jacobians[name]
        return B

    def relative(self, i: int) -> np.ndarray:
        """Contact ``i``'s body 2 own frame in body 1's start frame: ``T_1^-1 T_2 frame``."""
        c = self.joint.contacts[i]
        frame = np.asarray(self.states[i].targets.frame)
        return np.linalg.inv(self.poses[c.body1]) @ self.poses[c.body2] @ frame

    # --- the springs at the pose -------------------------------------------------------------
    @cached_property
    def gaps(self) -> list:
        """Each contact's :class:`~dea_opt.formulations._parts.finite_geometry.Gaps` at the pose."""
        return [
            evaluate(s.targets, s.layer.points, s.layer.normals, self.relative(i)) for i, s in enumerate(self.states)
        ]

    @cached_property
    def layers(self) -> list[SpringLayer]:
        """Each contact's springs at the pose, in the world: moved with body 1, their gaps the exact
        ones (:data:`OPEN` where a ray misses its target)."""
        out = []
        for c, s, gaps in zip(self.joint.contacts, self.states, self.gaps):
            T = self.poses[c.body1]
            gap = np.where(np.isfinite(gaps.s), gaps.s, OPEN)
            layer = s.layer
            surface = layer.surface
            if surface is not None:
                vertices, faces = surface
                surface = (np.asarray(vertices) @ T[:3, :3].T + T[:3, 3], faces)
            out.append(
                SpringLayer(
                    layer.points @ T[:3, :3].T + T[:3, 3],
                    layer.normals @ T[:3, :3].T,
                    layer.areas,
                    layer.thickness,
                    gap,
                    source_face=layer.source_face,
                    surface=surface,
                    labels=layer.labels,
                )
            )
        return out

    # --- the bundles at the pose -------------------------------------------------------------
    @cached_property
    def insertions(self) -> tuple[np.ndarray, np.ndarray]:
        """``(P1, P2)`` (n, 3): every bundle's insertions at the pose (mm, world)."""
        n = len(self.joint.ligaments)
        p1, p2 = np.zeros((n, 3)), np.zeros((n, 3))
        for i, lig in enumerate(self.joint.ligaments):
            T1, T2 = self.poses[lig.body1], self.poses[lig.body2]
            p1[i] = T1[:3, :3] @ np.asarray(lig.point1) + T1[:3, 3]
            p2[i] = T2[:3, :3] @ np.asarray(lig.point2) + T2[:3, 3]
        return p1, p2

    @cached_property
    def ligament_groups(self) -> tuple:
        """The joint's groups of bundles at the pose (rows over the coordinates' rates, exact lengths)."""
        from .model import LigamentGroup

        p1, p2 = self.insertions
        out = []
        for g in self.joint.ligament_groups:
            idx = list(g.members)
            G = line_operator(p1[idx], p2[idx], self.references[g.body1], self.references[g.body2])
            G = G @ np.block([[self._chain(g.body1), np.zeros((6, 6))], [np.zeros((6, 6)), self._chain(g.body2)]])
            start = np.linalg.norm(p2[idx] - p1[idx], axis=1)
            out.append(LigamentGroup(g.body1, g.body2, g.law, g.members, G, g.slack, start))
        return tuple(out)

    # --- the arrays of the solve -------------------------------------------------------------
    def _free(self, body1: str, body2: str) -> tuple[list, np.ndarray]:
        """Columns of a pair's 12 coordinates that are free, and their positions in ``x``."""
        cols = [DOFS.index(d) for d in DOFS if d in self.joint.bodies[body1].free]
        cols += [6 + DOFS.index(d) for d in DOFS if d in self.joint.bodies[body2].free]
        return cols, self.joint._pair_dofs(body1, body2)

    @cached_property
    def contact_rows(self) -> list[np.ndarray]:
        """Each layer's rows ``n . B`` over its two bodies' coordinate rates (N, 12)."""
        out = []
        for c, layer in zip(self.joint.contacts, self.layers):
            G = normal_operator(layer.points, layer.normals, self.references[c.body1], self.references[c.body2])
            G = np.ascontiguousarray(G)
            G[:, 3:6] = G[:, 3:6] @ self.jacobians[c.body1]
            G[:, 9:12] = G[:, 9:12] @ self.jacobians[c.body2]
            out.append(G)
        return out

    def net_force(self) -> np.ndarray:
        """The net generalized force on the free coordinates at the pose (N, N mm): every element's
        exact force there taken from the bodies, minus the loads (``J^T`` of the moments). Zero at
        equilibrium; computed without the arrays of a solve (the tangent's differences call it)."""
        x = np.zeros(len(self.joint.free_index))
        with np.errstate(invalid="ignore", over="ignore"):
            for c, G, layer in zip(self.joint.contacts, self.contact_rows, self.layers):
                f = layer.areas * c.law.stress(np.minimum(layer.gap / layer.thickness, 0.0))
                cols, dofs = self._free(c.body1, c.body2)
                x[dofs] += f @ G[:, cols]
            for g in self.ligament_groups:
                ligs = [self.joint.ligaments[i] for i in g.members]
                law = TensionLaw(g.law, np.array([lig.transition_strain for lig in ligs]))
                f = np.array([lig.stiffness for lig in ligs]) * law.force(g.start / g.slack - 1.0)
                cols, dofs = self._free(g.body1, g.body2)
                x[dofs] += f @ g.G[:, cols]
        load = [
            np.asarray(self.bodies[n].load_vector)[[DOFS.index(d) for d in b.free]]
            for n, b in self.joint.bodies.items()
        ]
        return x - (np.concatenate(load) if load else np.zeros(0))

    def element_pairs(self) -> list[tuple[str, str]]:
        return [(c.body1, c.body2) for c in self.joint.contacts] + [(g.body1, g.body2) for g in self.ligament_groups]

    def wrenches(self, forces) -> list[np.ndarray]:
        """Per group, ``G^T f`` (12,) over the two bodies' coordinates at the pose."""
        return [np.asarray(f, dtype=float) @ G for (_, _, G, _), f in zip(self.element_bodies(), forces)]

    def element_bodies(self) -> list:
        out = [
            (c.body1, c.body2, G, layer.thickness)
            for c, G, layer in zip(self.joint.contacts, self.contact_rows, self.layers)
        ]
        out += [(g.body1, g.body2, g.G, g.slack) for g in self.ligament_groups]
        return out

    def system(self) -> JointSystem:
        """The elements at the pose: their strains at zero increment are the exact ones."""
        return self._systems[0]

    def solver_system(self) -> JointSystem:
        """:meth:`system` with the bundles' geometric stiffness: a bundle in tension resists a turn of
        its line by ``f / L`` per unit sideways motion of an end (the second-order part of its exact
        length), which the rows along the line miss; it carries nothing at zero increment."""
        return self._systems[1]

    @cached_property
    def _systems(self) -> tuple[JointSystem, JointSystem]:
        groups = []
        for c, G, layer in zip(self.joint.contacts, self.contact_rows, self.layers):
            cols, dofs = self._free(c.body1, c.body2)
            AT = np.ascontiguousarray(G[:, cols].T / layer.thickness)
            volume = layer.areas * layer.thickness
            H = modulus_scale(c.law.modulus)
            groups.append(
                ElementGroup(
                    f"contact {c.name}",
                    "contact",
                    c.law,
                    dofs,
                    AT,
                    layer.gap / layer.thickness,
                    volume,
                    layer.areas,
                    H,
                    _gram_factor(AT, volume * H),
                    H * float(np.sum(layer.areas / layer.thickness)),
                )
            )
        geometric = []
        for g in self.ligament_groups:
            ligs = [self.joint.ligaments[i] for i in g.members]
            k = np.array([lig.stiffness for lig in ligs])
            cols, dofs = self._free(g.body1, g.body2)
            AT = np.ascontiguousarray(g.G[:, cols].T / g.slack)
            law = TensionLaw(g.law, np.array([lig.transition_strain for lig in ligs]))
            e0 = g.start / g.slack - 1.0
            volume = g.slack * k
            groups.append(
                ElementGroup(
                    f"ligaments {g.body1}-{g.body2} ({g.law})",
                    "ligament",
                    law,
                    dofs,
                    AT,
                    e0,
                    volume,
                    k,
                    1.0,
                    _gram_factor(AT, volume),
                    float(np.sum(k / g.slack)),
                )
            )
            tension = k * law.force(e0)
            if (tension > 0).any():
                geometric.append(self._geometric(g, cols, dofs, tension))
        load = (
            np.concatenate(
                [
                    np.asarray(self.bodies[n].load_vector)[[DOFS.index(d) for d in b.free]]
                    for n, b in self.joint.bodies.items()
                ]
            )
            if self.joint.free_index
            else np.zeros(0)
        )
        physical = JointSystem(tuple(groups), load, self.joint.lengths)
        return physical, JointSystem(tuple(groups + geometric), load, self.joint.lengths)

    def _geometric(self, g, cols, dofs, tension) -> ElementGroup:
        """Two bilateral rows per bundle in tension, sideways to its line, of stiffness ``f / L``."""
        p1, p2 = self.insertions
        idx = list(g.members)
        e = (p2[idx] - p1[idx]) / g.start[:, None]
        side1 = np.cross(e, np.where(np.abs(e[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]]))
        side1 /= np.linalg.norm(side1, axis=1)[:, None]
        side2 = np.cross(e, side1)
        B = np.block([[self._chain(g.body1), np.zeros((6, 6))], [np.zeros((6, 6)), self._chain(g.body2)]])
        keep = tension > 0
        rows, weights = [], []
        for side in (side1, side2):
            G = line_operator(p1[idx], p1[idx] + side, self.references[g.body1], self.references[g.body2])
            # the row of the sideways motion of both ends: body 2's end at P2, not at P1 + side
            G[:, 9:12] = np.cross(p2[idx] - self.references[g.body2], side)
            rows.append((G @ B)[keep][:, cols])
            weights.append((tension / g.start)[keep])
        AT = np.ascontiguousarray(np.vstack(rows).T)
        volume = np.concatenate(weights)
        return ElementGroup(
            f"geometric {g.body1}-{g.body2}",
            "bilateral",
            None,
            dofs,
            AT,
            np.zeros(volume.size),
            volume,
            np.zeros(volume.size),
            1.0,
            _gram_factor(AT, volume),
            0.0,
        )


@dataclass(frozen=True, eq=False)
class WorldView:
    """The layers at a pose with world-axis bodies: what :func:`~dea_opt.joint.results.layer_solutions` reads."""

    contacts: tuple
    pairs: tuple
    bodies: MappingProxyType

    def on_body(self, forces) -> dict:
        """``{name: 6-vector}`` the layers' ``forces`` (N) take from each body, about its reference."""
        out = {name: np.zeros(6) for name in self.bodies}
        for c, pair, f in zip(self.contacts, self.pairs, forces):
            q = np.asarray(f, dtype=float) @ pair.normal_operator
            out[c.body1] += q[:6]
            out[c.body2] += q[6:]
        return out


def _unloaded(body: Body) -> Body:
    return Body(reference=body.reference, free=body.free)


def _gram_factor(AT, weight) -> np.ndarray:
    """``Z`` with ``Z^T Z = A^T diag(weight) A`` from the small Gram matrix (m_g x m_g)."""
    M = (AT * weight) @ AT.T
    vals, vecs = np.linalg.eigh(M)
    vals = np.maximum(vals, 0.0)
    return (vecs * np.sqrt(vals)).T
