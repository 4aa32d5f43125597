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

from dataclasses import dataclass, replace
from functools import cached_property
from types import MappingProxyType

import numpy as np

from ..formulations._parts.resistance import modulus_scale
from ..formulations.finite.geometry import evaluate, plane_gaps
from ..formulations.joint import ElementGroup, JointSystem, TensionLaw
from ..kinematics import DOFS, normal_operator
from ..layer import SpringLayer
from ..problem import Body
from .coordinates import _rigid_inverse, cross
from .model import Joint, _unloaded
from .rows import line_operator
from .states import ContactState, WorldView

__all__ = ["Configuration"]

#: The gap (mm) given to a spring whose ray misses its target: it is open, and stays so.
OPEN = 1e6


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
        """Each body's rigid motion from its start pose (4x4, mm)."""
        return {n: self.joint.motion(n, self.y[n]) for n in self.joint.bodies}

    @cached_property
    def rates(self) -> _Rates:
        """Each body's ``B`` (6, 6): its reference's velocity and angular velocity per unit rate of
        its coordinates (``diag(I, J(theta))`` for a rotation vector); made when first asked for."""
        return _Rates(self)

    @cached_property
    def references(self) -> dict:
        """Each body's reference where the motion took it (mm)."""
        out = {}
        for n, b in self.joint.bodies.items():
            T = self.poses[n]
            out[n] = T[:3, :3] @ np.asarray(b.reference) + T[:3, 3]
        return out

    @cached_property
    def world_loads(self) -> dict:
        """Each body's whole load at the pose in world axes about its moved reference (N, N mm):
        points moved with the body, body-frame components turned with it."""
        return self.joint.load_vectors(self.poses)

    @cached_property
    def bodies(self) -> MappingProxyType:
        """The bodies at the pose: references moved, loads on the coordinates (``B^T (F, M)``)."""
        out = {}
        for n, b in self.joint.bodies.items():
            q = self.rates[n].T @ self.world_loads[n]
            out[n] = Body(reference=self.references[n], free=b.free, force=q[:3], moment=q[3:])
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

    @property
    def coordinates(self):
        return self.joint.coordinates

    @property
    def springs(self) -> tuple:
        return self.joint.springs

    @property
    def bushings(self) -> tuple:
        return self.joint.bushings

    def motion(self, name: str, u) -> np.ndarray:
        return self.joint.motion(name, u)

    def body_loads(self) -> dict:
        """``{body: 6-vector}``: each body's whole load on its coordinates at the pose."""
        return {n: b.load_vector for n, b in self.bodies.items()}

    @cached_property
    def world(self) -> WorldView:
        """The pose in world axes: each layer's two-body problem there, the bodies' loads as
        forces and moments, for the layers' own answers (:func:`~dea_opt.joint.results.layer_solutions`)."""
        from ..problem import ContactProblem

        bodies = {}
        for n in self.joint.bodies:
            load = self.world_loads[n]
            bodies[n] = Body(reference=self.references[n], free=self._world_free(n), force=load[:3], moment=load[3:])
        pairs = tuple(
            ContactProblem(layer, c.law, body1=_unloaded(bodies[c.body1]), body2=_unloaded(bodies[c.body2]))
            for c, layer in zip(self.joint.contacts, self.layers)
        )
        return WorldView(self.joint.contacts, pairs, MappingProxyType(bodies))

    def _world_free(self, name: str) -> tuple:
        """The world-axis dofs a body's free coordinates span (a translation or rotation about its
        reference along a world axis within the span of their rates): the layer's two-body
        problem holds the others."""
        b = self.joint.bodies[name]
        cols = [DOFS.index(d) for d in b.free]
        if not cols:
            return ()
        if len(cols) == 6:
            return DOFS
        B = self.rates[name][:, cols]
        scale = np.ones(6)
        scale[3:] = self.joint.lengths.max(initial=1.0)
        out = []
        for j, dof in enumerate(DOFS):
            e = np.zeros(6)
            e[j] = 1.0
            z = np.linalg.lstsq(B, e, rcond=None)[0]
            if np.linalg.norm((B @ z - e) * scale) <= 1e-9 * scale[j]:
                out.append(dof)
        return tuple(out)

    def _pair_rates(self, body1: str, body2: str) -> np.ndarray:
        B = np.zeros((12, 12))
        B[:6, :6], B[6:, 6:] = self.rates[body1], self.rates[body2]
        return B

    def relative(self, i: int) -> np.ndarray:
        """Contact ``i``'s body 2 own frame in body 1's start frame: ``T_1^-1 T_2 frame``."""
        c = self.joint.contacts[i]
        frame = np.asarray(self.states[i].targets.frame)
        return _rigid_inverse(self.poses[c.body1]) @ self.poses[c.body2] @ frame

    # --- the springs at the pose -------------------------------------------------------------
    @cached_property
    def gaps(self) -> list:
        """Each contact's :class:`~dea_opt.formulations.finite.geometry.Gaps` at the pose."""
        return [
            evaluate(s.targets, s.layer.points, s.layer.normals, self.relative(i))
            if s.plane_rows is None
            else plane_gaps(s.plane_rows, self.relative(i))
            for i, s in enumerate(self.states)
        ]

    @cached_property
    def spring_arrays(self) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Per contact ``(points, normals, gap)``: its springs moved with body 1 into the world (mm) and
        their exact gaps (:data:`OPEN` where a ray misses its target), the arrays of :attr:`layers`
        without making (and checking) a layer: the solve's arrays read these."""
        out = []
        for c, s, gaps in zip(self.joint.contacts, self.states, self.gaps):
            T = self.poses[c.body1]
            R = T[:3, :3]
            out.append(
                (s.layer.points @ R.T + T[:3, 3], s.layer.normals @ R.T, np.where(np.isfinite(gaps.s), gaps.s, OPEN))
            )
        return out

    @cached_property
    def layers(self) -> list[SpringLayer]:
        """Each contact's springs at the pose, in the world: moved with body 1, their gaps the exact
        ones (:data:`OPEN` where a ray misses its target)."""
        out = []
        for c, s, (points, normals, gap) in zip(self.joint.contacts, self.states, self.spring_arrays):
            T = self.poses[c.body1]
            layer = s.layer
            surface = layer.surface
            if surface is not None:
                vertices, faces = surface
                surface = (np.asarray(vertices) @ T[:3, :3].T + T[:3, 3], faces)
            out.append(
                SpringLayer(
                    points,
                    normals,
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
        for g, (points1, points2, _, _) in zip(self.joint.ligament_groups, self.joint.ligament_arrays):
            idx = list(g.members)
            T1, T2 = self.poses[g.body1], self.poses[g.body2]
            p1[idx] = points1 @ T1[:3, :3].T + T1[:3, 3]
            p2[idx] = points2 @ T2[:3, :3].T + T2[:3, 3]
        return p1, p2

    @cached_property
    def ligament_groups(self) -> tuple:
        """The joint's groups of bundles at the pose (rows over the coordinates' rates, exact lengths)."""
        from .rows import LigamentGroup

        p1, p2 = self.insertions
        out = []
        for g in self.joint.ligament_groups:
            idx = list(g.members)
            G = line_operator(p1[idx], p2[idx], self.references[g.body1], self.references[g.body2])
            G = G @ self._pair_rates(g.body1, g.body2)
            start = np.linalg.norm(p2[idx] - p1[idx], axis=1)
            out.append(LigamentGroup(g.body1, g.body2, g.law, g.members, G, g.slack, start))
        return tuple(out)

    @cached_property
    def elastic_groups(self) -> tuple:
        """The springs and bushings at the pose (exact lengths and relative poses), their rows over
        the coordinates' rates."""

        return tuple(replace(g, G=g.G @ self._pair_rates(g.body1, g.body2)) for g in self.world_elastic)

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
        for c, (points, normals, _) in zip(self.joint.contacts, self.spring_arrays):
            G = normal_operator(points, normals, self.references[c.body1], self.references[c.body2])
            G = np.ascontiguousarray(G)
            G[:, :6] = G[:, :6] @ self.rates[c.body1]
            G[:, 6:] = G[:, 6:] @ self.rates[c.body2]
            out.append(G)
        return out

    def net_force(self) -> np.ndarray:
        """``q - load`` of :meth:`forces`: zero at equilibrium."""
        q, load = self.forces()
        return q - load

    def forces(self) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`_forces`, computed once per configuration."""
        if "_forces_cache" not in self.__dict__:
            self.__dict__["_forces_cache"] = self._forces()
        return self.__dict__["_forces_cache"]

    def _forces(self) -> tuple[np.ndarray, np.ndarray]:
        """``(q, load)`` on the free coordinates at the pose (:func:`~dea_opt.joint.exact.exact_forces`)."""
        from .exact import exact_forces

        return exact_forces(self)

    @cached_property
    def world_elastic(self) -> tuple:
        """The springs and bushings at the pose (exact lengths and relative poses), their rows over
        the bodies' 12 dofs (:func:`~dea_opt.joint.elastic.elastic_groups`)."""
        from .elastic import elastic_groups

        return elastic_groups(self.joint, self.poses, self.references)

    def near(self, within: float) -> tuple:
        """The contacts' states cut to the springs whose gap at the pose is below ``within`` (mm):
        the only ones that carry load within that much motion (the tangent's differences)."""
        out = []
        for state, gaps in zip(self.states, self.gaps):
            keep = np.flatnonzero(gaps.s < within)
            t = state.targets
            targets = type(t)(
                t.points[keep],
                t.normals[keep],
                t.radius[keep],
                t.concave[keep],
                t.frame,
                None if t.faces is None else t.faces[keep],
            )
            out.append(ContactState(state.layer.subset(keep), targets))
        return tuple(out)

    def element_pairs(self) -> list[tuple[str, str]]:
        groups = (*self.ligament_groups, *self.elastic_groups)
        return [(c.body1, c.body2) for c in self.joint.contacts] + [(g.body1, g.body2) for g in groups]

    def wrenches(self, forces) -> list[np.ndarray]:
        """Per group, ``G^T f`` (12,) over the two bodies' coordinates at the pose."""
        return [np.asarray(f, dtype=float) @ G for (_, _, G, _), f in zip(self.element_bodies(), forces)]

    def element_bodies(self) -> list:
        out = [
            (c.body1, c.body2, G, layer.thickness)
            for c, G, layer in zip(self.joint.contacts, self.contact_rows, self.layers)
        ]
        out += [(g.body1, g.body2, g.G, g.slack) for g in self.ligament_groups]
        out += [(g.body1, g.body2, g.G, np.ones(g.e0.size)) for g in self.elastic_groups]
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
        for c, G, state, (_, _, gap) in zip(self.joint.contacts, self.contact_rows, self.states, self.spring_arrays):
            layer = state.layer
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
                    gap / layer.thickness,
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
        from .elastic import elastic_element_group

        for e in self.elastic_groups:
            cols, dofs = self._free(e.body1, e.body2)
            groups.append(elastic_element_group(e, cols, dofs))
            if e.kind == "spring" and (e.k * e.e0 > 0).any():
                geometric.append(self._spring_geometric(e, cols, dofs))
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
        return self._sideways(f"geometric {g.body1}-{g.body2}", g.body1, g.body2, p1[idx], p2[idx], cols, dofs, tension)

    def _spring_geometric(self, e, cols, dofs) -> ElementGroup:
        """The same for springs in tension (those in compression would make the step's energy
        concave sideways: left to the tangent of the exact forces)."""
        springs = [self.joint.springs[i] for i in e.members]
        T1, T2 = self.poses[e.body1], self.poses[e.body2]
        p1 = np.array([s.point1 for s in springs]) @ T1[:3, :3].T + T1[:3, 3]
        p2 = np.array([s.point2 for s in springs]) @ T2[:3, :3].T + T2[:3, 3]
        name = f"geometric springs {e.body1}-{e.body2}"
        return self._sideways(name, e.body1, e.body2, p1, p2, cols, dofs, e.k * e.e0)

    def _sideways(self, name, body1, body2, p1, p2, cols, dofs, tension) -> ElementGroup:
        length = np.linalg.norm(p2 - p1, axis=1)
        e = (p2 - p1) / length[:, None]
        side1 = cross(e, np.where(np.abs(e[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]]))
        side1 /= np.linalg.norm(side1, axis=1)[:, None]
        side2 = cross(e, side1)
        B = self._pair_rates(body1, body2)
        keep = tension > 0
        rows, weights = [], []
        for side in (side1, side2):
            G = line_operator(p1, p1 + side, self.references[body1], self.references[body2])
            # the row of the sideways motion of both ends: body 2's end at P2, not at P1 + side
            G[:, 9:12] = cross(p2 - self.references[body2], side)
            rows.append((G @ B)[keep][:, cols])
            weights.append((tension / length)[keep])
        AT = np.ascontiguousarray(np.vstack(rows).T)
        volume = np.concatenate(weights)
        zero = np.zeros(volume.size)
        return ElementGroup(name, "bilateral", None, dofs, AT, zero, volume, zero, 1.0, _gram_factor(AT, volume), 0.0)


class _Rates(dict):
    """``{body: B}`` of a :class:`Configuration`, each made when first asked for."""

    def __init__(self, config: Configuration):
        super().__init__()
        self.config = config

    def __missing__(self, name: str) -> np.ndarray:
        c = self.config
        value = c.joint.rates(name, c.y[name], c.poses[name])
        self[name] = value
        return value


def _gram_factor(AT, weight) -> np.ndarray:
    """``Z`` with ``Z^T Z = A^T diag(weight) A`` from the small Gram matrix (m_g x m_g)."""
    M = (AT * weight) @ AT.T
    vals, vecs = np.linalg.eigh(M)
    vals = np.maximum(vals, 0.0)
    return (vecs * np.sqrt(vals)).T
