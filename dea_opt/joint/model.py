"""A whole joint: named rigid bodies, contact layers and ligament bundles, as one energy.

:class:`Joint` checks its parts and builds the arrays the joint formulations see
(:class:`~dea_opt.formulations.joint.JointSystem`, ``formulations/joint.md``): each contact layer
through the two-body :class:`~dea_opt.ContactProblem` of its two bodies (its rows, gaps,
prescribed motion and bonded factor, exactly as a two-body problem has them), each group of
bundles between two bodies by the linearised length of a straight line.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from functools import cached_property
from types import MappingProxyType

import numpy as np

from ..errors import InputError
from ..formulations.joint import ElementGroup, JointSystem, TensionLaw
from ..kinematics import DOFS
from ..problem import Body, ContactProblem, Load
from .coordinates import BodyLoad, Coordinates, rotation_vector_motion
from .elastic import Bushing, Spring, elastic_element_group, elastic_groups
from .elements import Contact, Ligament
from .rows import LigamentGroup, layer_basis, line_operator

__all__ = ["KINEMATICS", "Joint"]

KINEMATICS = ("small", "finite")


@dataclass(frozen=True, eq=False)
class Joint:
    """Several rigid bodies held by contact layers and ligament bundles: one energy, one answer.

    Parameters
    ----------
    bodies : mapping {name: Body}
        Each body's reference point, free, fixed and prescribed dofs and load (``Body``, as for a
        two-body problem; a body with no free dof is held where it is: ground). Loads are a force
        at the reference and a moment about it, in the global frame (a force at a point:
        ``Body(...).with_load(Load(force, point=...))``).
    contacts : sequence of Contact
        Spring layers, each between two named bodies; several may share bodies.
    ligaments : sequence of Ligament
        Straight-line bundles between insertions on two named bodies (no wrapping).
    kinematics : {"small", "finite"}
        ``"small"``: the paper's linearised motion for every body, gaps cast once, each bundle's
        length linearised consistently (first order in the motions; tension only on that
        strain). ``"finite"``: exact rigid motions, gaps at the current pose per layer, exact
        bundle lengths (``formulations/joint.md``).
    springs : sequence of Spring, optional
        Linear two-sided springs between a point on each of two bodies (:mod:`dea_opt.joint.elastic`).
    bushings : sequence of Bushing, optional
        Linear bushings between two body frames.
    loads : sequence of BodyLoad, optional
        Forces and moments at points of the bodies, in the ground or the body's frame (added to
        each ``Body``'s own force and moment, which act at its reference in the ground frame).
    coordinates : mapping {name: Coordinates}, optional
        Finite kinematics: the bodies whose six coordinates are an OpenSim ``CustomJoint``'s
        instead of the translation of the reference and the rotation vector.

    Every free body must be touched by some element (else nothing holds it: an
    :class:`~dea_opt.errors.InputError` naming it), and every element's bodies must be named in
    ``bodies``. Solve with :func:`dea_opt.solve` (``dea.solve(joint, method)``).
    """

    bodies: Mapping = field(default_factory=dict)
    contacts: tuple = ()
    ligaments: tuple = ()
    kinematics: str = "small"
    springs: tuple = ()
    bushings: tuple = ()
    loads: tuple = ()
    coordinates: Mapping = field(default_factory=dict)

    def __post_init__(self):
        set_ = object.__setattr__
        if not isinstance(self.bodies, Mapping) or not self.bodies:
            raise InputError(f"Joint.bodies must be a non-empty mapping {{name: Body}}, got {self.bodies!r}")
        for name, body in self.bodies.items():
            if not isinstance(name, str) or not name or "." in name:
                raise InputError(f"Joint.bodies' names must be non-empty str without '.', got {name!r}")
            if not isinstance(body, Body):
                raise InputError(f"Joint.bodies[{name!r}] must be a dea_opt.Body, got {type(body).__name__}")
        set_(self, "bodies", MappingProxyType(dict(self.bodies)))
        kinds = (("contacts", Contact), ("ligaments", Ligament), ("springs", Spring), ("bushings", Bushing))
        for attr, kind in (*kinds, ("loads", BodyLoad)):
            value = getattr(self, attr)
            if isinstance(value, (str, bytes)) or not hasattr(value, "__iter__"):
                raise InputError(f"Joint.{attr} must be a sequence of dea_opt.{kind.__name__}, got {value!r}")
            items = tuple(value)
            for i, item in enumerate(items):
                if not isinstance(item, kind):
                    raise InputError(f"Joint.{attr}[{i}] must be a dea_opt.{kind.__name__}, got {type(item).__name__}")
                for end in ("body1", "body2") if kind is not BodyLoad else ("body",):
                    if getattr(item, end) not in self.bodies:
                        raise InputError(
                            f"Joint.{attr}[{i}].{end} is {getattr(item, end)!r}, which is not a body of the joint "
                            f"(bodies: {list(self.bodies)})"
                        )
            set_(self, attr, items)
        if not isinstance(self.kinematics, str) or self.kinematics not in KINEMATICS:
            raise InputError(f"Joint.kinematics must be one of {KINEMATICS}, got {self.kinematics!r}")
        elements = (*self.contacts, *self.ligaments, *self.springs, *self.bushings)
        touched = {e.body1 for e in elements} | {e.body2 for e in elements}
        for name, body in self.bodies.items():
            if body.free and name not in touched:
                raise InputError(
                    f"body {name!r} has free dofs {body.free} but no contact or ligament touches it: nothing holds "
                    f"it; fix its dofs, or add an element between it and another body"
                )
        if self.kinematics == "small":
            for i, contact in enumerate(self.contacts):
                if contact.targets is not None:
                    raise InputError(
                        f"Joint.contacts[{i}].targets are for kinematics='finite' (the small kinematics use the "
                        f"layer's gaps only): pass kinematics='finite' or leave targets out"
                    )
        if not isinstance(self.coordinates, Mapping):
            raise InputError(f"Joint.coordinates must be a mapping {{body: Coordinates}}, got {self.coordinates!r}")
        for name, coordinates in self.coordinates.items():
            if name not in self.bodies:
                raise InputError(f"Joint.coordinates names {name!r}, which is not a body (bodies: {list(self.bodies)})")
            if not isinstance(coordinates, Coordinates):
                raise InputError(f"Joint.coordinates[{name!r}] must be a dea_opt.joint.Coordinates")
        if self.coordinates and self.kinematics != "finite":
            raise InputError(
                f"Joint.coordinates (an OpenSim joint's coordinates for {list(self.coordinates)}) are finite: pass "
                f"kinematics='finite'"
            )
        set_(self, "coordinates", MappingProxyType(dict(self.coordinates)))

    # --- names and dofs -------------------------------------------------------------------
    @property
    def names(self) -> tuple:
        return tuple(self.bodies)

    @cached_property
    def free_index(self) -> dict:
        """``{(body, dof): position in the free vector x}``, bodies in order, dofs as :data:`DOFS`."""
        out, at = {}, 0
        for name, body in self.bodies.items():
            for dof in DOFS:
                if dof in body.free:
                    out[(name, dof)] = at
                    at += 1
        return out

    @property
    def free_names(self) -> tuple:
        """``"femur.ux"``, ... in the order of the free vector."""
        return tuple(f"{b}.{d}" for b, d in self.free_index)

    def free_of(self, name: str) -> np.ndarray:
        """Positions in the free vector of body ``name``'s free dofs (in :data:`DOFS` order)."""
        return self._free_positions[name]

    @cached_property
    def _free_positions(self) -> dict:
        return {
            name: np.array([self.free_index[(name, d)] for d in DOFS if (name, d) in self.free_index], dtype=int)
            for name in self.bodies
        }

    @cached_property
    def free_columns(self) -> dict:
        """``{body: [column]}``: each body's free dofs as columns of its 6 (in :data:`DOFS` order)."""
        return {name: [DOFS.index(d) for d in DOFS if d in b.free] for name, b in self.bodies.items()}

    def prescribed(self, name: str) -> np.ndarray:
        """Body ``name``'s 6-vector with its prescribed values and zeros elsewhere (the start values
        of its :class:`Coordinates` where it has them)."""
        coordinates = self.coordinates.get(name)
        u = np.zeros(6) if coordinates is None else coordinates.start.copy()
        for dof, value in self.bodies[name].prescribed.items():
            u[DOFS.index(dof)] = value
        return u

    def body_u(self, x) -> dict:
        """``{name: 6-vector}`` of every body from the free vector ``x`` (mm, rad)."""
        x = np.asarray(x, dtype=float)
        out = {}
        for name in self.bodies:
            u = self.prescribed(name)
            for j, dof in enumerate(DOFS):
                if (name, dof) in self.free_index:
                    u[j] = x[self.free_index[(name, dof)]]
            out[name] = u
        return out

    def start(self) -> np.ndarray:
        """The free vector at the start pose: zeros, or the start values of :class:`Coordinates`."""
        x = np.zeros(len(self.free_index))
        for (name, dof), j in self.free_index.items():
            if name in self.coordinates:
                x[j] = self.coordinates[name].start[DOFS.index(dof)]
        return x

    def motion(self, name: str, u) -> np.ndarray:
        """Body ``name``'s rigid motion (4x4, mm) from its start pose at its 6-vector ``u`` (exact)."""
        coordinates = self.coordinates.get(name)
        if coordinates is not None:
            return coordinates.motion(u)
        return rotation_vector_motion(u, self.bodies[name].reference)[0]

    def rates(self, name: str, u, motion=None) -> np.ndarray:
        """``B`` (6, 6): the velocity of body ``name``'s reference (where ``motion`` put it) and its
        angular velocity per unit rate of each of its coordinates at ``u`` (finite kinematics)."""
        coordinates = self.coordinates.get(name)
        if coordinates is None:
            return rotation_vector_motion(u, self.bodies[name].reference)[1]
        motion = self.motion(name, u) if motion is None else motion
        c = np.asarray(self.bodies[name].reference)
        return coordinates.rates(u, motion[:3, :3] @ c + motion[:3, 3])

    def _pair_dofs(self, body1: str, body2: str) -> np.ndarray:
        """Positions in ``x`` of the free dofs of a body pair, body 1's then body 2's."""
        return np.concatenate([self.free_of(body1), self.free_of(body2)]).astype(int)

    # --- contacts as two-body problems ----------------------------------------------------
    @cached_property
    def pairs(self) -> tuple:
        """Per contact, the unloaded two-body :class:`~dea_opt.ContactProblem` of its layer between
        its bodies (references, free and prescribed dofs as in the joint): its arrays are the
        layer's rows in the joint."""
        out = []
        for c in self.contacts:
            b1, b2 = (_unloaded(self.bodies[c.body1]), _unloaded(self.bodies[c.body2]))
            out.append(ContactProblem(c.layer, c.law, body1=b1, body2=b2))
        return tuple(out)

    # --- ligaments grouped by their bodies and law ----------------------------------------
    @cached_property
    def ligament_groups(self) -> tuple:
        keys: dict = {}
        for i, lig in enumerate(self.ligaments):
            keys.setdefault((lig.body1, lig.body2, lig.law), []).append(i)
        groups = []
        for (b1, b2, law), members in keys.items():
            ligs = [self.ligaments[i] for i in members]
            p1 = np.array([lig.point1 for lig in ligs])
            p2 = np.array([lig.point2 for lig in ligs])
            G = line_operator(p1, p2, self.bodies[b1].reference, self.bodies[b2].reference)
            start = np.linalg.norm(p2 - p1, axis=1)
            slack = np.array([float(lig.slack_length) for lig in ligs])
            groups.append(LigamentGroup(b1, b2, law, tuple(members), G, slack, start))
        return tuple(groups)

    @cached_property
    def ligament_arrays(self) -> tuple:
        """Per group of :attr:`ligament_groups`: ``(point1 (n, 3), point2 (n, 3), stiffness (n,),
        TensionLaw)`` at the start pose."""
        out = []
        for g in self.ligament_groups:
            ligs = [self.ligaments[i] for i in g.members]
            out.append(
                (
                    np.array([lig.point1 for lig in ligs], dtype=float),
                    np.array([lig.point2 for lig in ligs], dtype=float),
                    np.array([lig.stiffness for lig in ligs], dtype=float),
                    TensionLaw(g.law, np.array([lig.transition_strain for lig in ligs])),
                )
            )
        return tuple(out)

    # --- the arrays of the formulations ---------------------------------------------------
    @cached_property
    def element_points(self) -> dict:
        """``{body: [arrays (n, 3)]}``: the points each body's elements act at (springs, insertions,
        spring ends, bushing origins), mm at the start pose."""
        points: dict = {name: [] for name in self.bodies}
        for c in self.contacts:
            points[c.body1].append(c.layer.points)
            points[c.body2].append(c.layer.points)
        for lig in (*self.ligaments, *self.springs):
            points[lig.body1].append(np.asarray(lig.point1)[None])
            points[lig.body2].append(np.asarray(lig.point2)[None])
        for bushing in self.bushings:
            points[bushing.body1].append(bushing.frame[None, :3, 3])
            points[bushing.body2].append(bushing.frame[None, :3, 3])
        return points

    @cached_property
    def centres(self) -> dict:
        """``{body: (3,)}``: the centroid of the points each body's elements act at (its reference
        where none do), mm: where a body's motion is measured against the joint's extent."""
        out = {}
        for name, blocks in self.element_points.items():
            n = sum(len(p) for p in blocks)
            out[name] = sum(p.sum(axis=0) for p in blocks) / n if n else np.asarray(self.bodies[name].reference)
        return out

    @cached_property
    def lengths(self) -> np.ndarray:
        """Per free dof: 1 mm for a translation; for a rotation the RMS distance from the body's
        reference of every point its elements act at (springs, insertions) (mm)."""
        points = self.element_points
        out = np.ones(len(self.free_index))
        radii: dict = {}
        for (name, dof), j in self.free_index.items():
            if dof[0] == "r" and points[name]:
                if name not in radii:
                    # the mean squared distance from c, from each block's mean and mean square
                    c = np.asarray(self.bodies[name].reference, dtype=float)
                    n = sum(len(p) for p in points[name])
                    mean = sum(p.sum(axis=0) for p in points[name]) / n
                    square = sum(float(np.einsum("ij,ij->", p, p)) for p in points[name]) / n
                    radii[name] = float(np.sqrt(max(square - 2 * c @ mean + c @ c, 0.0)))
                out[j] = radii[name] if radii[name] > 1e-12 else 1.0
        return out

    @cached_property
    def extent(self) -> float:
        """The RMS distance of every point the elements act at (springs, insertions) from their
        centroid, at least 1 mm: the joint's size, against which a motion counts as running away."""
        points = [c.layer.points for c in self.contacts]
        points += [np.array([lig.point1, lig.point2]) for lig in (*self.ligaments, *self.springs)]
        points += [b.frame[None, :3, 3] for b in self.bushings]
        if not points:
            return 1.0
        p = np.vstack(points)
        p = p - p.mean(axis=0)
        # elements at one point (a bushing alone) have no spread: 1 mm, not a size that any motion exceeds
        return max(float(np.sqrt(np.mean(np.einsum("ij,ij->i", p, p)))), 1.0)

    @cached_property
    def load(self) -> np.ndarray:
        """The generalized load on the free dofs (N, N mm about each body's reference)."""
        r = np.zeros(len(self.free_index))
        loads = self.load_vectors()
        for (name, dof), j in self.free_index.items():
            r[j] = loads[name][DOFS.index(dof)]
        return r

    def body_loads(self) -> dict:
        """``{body: (F, M)}`` on each body's 6 dofs at the start pose (:meth:`load_vectors`)."""
        return self.load_vectors()

    def load_vectors(self, motions=None) -> dict:
        """``{body: (F, M)}`` (6,): each body's whole load in the world about its reference (N, N mm),
        its own and its :class:`BodyLoad` s, at the start pose or where ``motions`` ``{body: 4x4}``
        put it (finite kinematics: points moved, body-frame components turned)."""
        out = {name: body.load_vector.astype(float) for name, body in self.bodies.items()}
        for load in self.loads:
            motion = None if motions is None else motions[load.body]
            out[load.body] = out[load.body] + load.wrench(self.bodies[load.body].reference, motion)
        return out

    def system(self) -> JointSystem:
        """The small-kinematics :class:`~dea_opt.formulations.joint.JointSystem` of this joint."""
        return self._system

    @cached_property
    def _system(self) -> JointSystem:
        groups = []
        for contact, basis in zip(self.contacts, self.bases):
            layer = contact.layer
            b1, b2 = self.bodies[contact.body1], self.bodies[contact.body2]
            free = [DOFS.index(d) for d in DOFS if d in b1.free] + [6 + DOFS.index(d) for d in DOFS if d in b2.free]
            u_p = np.concatenate([self.prescribed(contact.body1), self.prescribed(contact.body2)])
            C, rows = basis.motion(free), basis.rows
            H = _modulus(contact.law)
            groups.append(
                ElementGroup(
                    name=f"contact {contact.name}",
                    kind="contact",
                    law=contact.law,
                    dofs=self._pair_dofs(contact.body1, contact.body2),
                    AT=None,
                    e0=layer.gap / layer.thickness + (basis.motion(range(12)) @ u_p) @ rows,
                    volume=layer.areas * layer.thickness,
                    force_scale=layer.areas,
                    modulus=H,
                    factor=basis.factor(free) * np.sqrt(H),
                    stiffness=H * float(np.sum(layer.areas / layer.thickness)),
                    basis=(C, rows),
                )
            )
        for group in self.ligament_groups:
            ligs = [self.ligaments[i] for i in group.members]
            k = np.array([lig.stiffness for lig in ligs])
            free = [DOFS.index(d) for d in DOFS if d in self.bodies[group.body1].free]
            free += [6 + DOFS.index(d) for d in DOFS if d in self.bodies[group.body2].free]
            u_p = np.concatenate([self.prescribed(group.body1), self.prescribed(group.body2)])
            AT = np.ascontiguousarray(group.G[:, free].T / group.slack)
            e0 = (group.start - group.slack + group.G @ u_p) / group.slack
            volume = group.slack * k
            groups.append(
                ElementGroup(
                    name=f"ligaments {group.body1}-{group.body2} ({group.law})",
                    kind="ligament",
                    law=TensionLaw(group.law, np.array([lig.transition_strain for lig in ligs])),
                    dofs=self._pair_dofs(group.body1, group.body2),
                    AT=AT,
                    e0=e0,
                    volume=volume,
                    force_scale=k,
                    modulus=1.0,
                    factor=np.sqrt(volume)[:, None] * AT.T,
                    stiffness=float(np.sum(k / group.slack)),
                )
            )
        for group in self.elastic_groups:
            cols = [DOFS.index(d) for d in DOFS if d in self.bodies[group.body1].free]
            cols += [6 + DOFS.index(d) for d in DOFS if d in self.bodies[group.body2].free]
            u_p = np.concatenate([self.prescribed(group.body1), self.prescribed(group.body2)])
            moved = replace(group, e0=group.e0 + group.G @ u_p)
            groups.append(elastic_element_group(moved, cols, self._pair_dofs(group.body1, group.body2)))
        return JointSystem(tuple(groups), self.load, self.lengths)

    @cached_property
    def elastic_groups(self) -> tuple:
        """The springs' and bushings' :class:`~dea_opt.joint.elastic.ElasticGroup` s at the start pose."""
        return elastic_groups(self)

    @cached_property
    def bases(self) -> tuple:
        """Each contact layer's :class:`~dea_opt.joint.rows.LayerBasis` between its two bodies."""
        return tuple(
            layer_basis(c.layer, self.bodies[c.body1].reference, self.bodies[c.body2].reference) for c in self.contacts
        )

    def element_pairs(self) -> list[tuple[str, str]]:
        """The two bodies of each group of :meth:`system` (contacts first, then ligament groups)."""
        groups = (*self.ligament_groups, *self.elastic_groups)
        return [(c.body1, c.body2) for c in self.contacts] + [(g.body1, g.body2) for g in groups]

    def wrenches(self, forces) -> list[np.ndarray]:
        """Per group of :meth:`system`, ``G^T f`` (12,): what its element ``forces`` (N, tension
        positive) take from its two bodies' 6-vectors (N, N mm about each reference)."""
        out = []
        for basis, c, f in zip(self.bases, self.contacts, forces):
            out.append(basis.motion(range(12)).T @ (basis.rows @ (np.asarray(f, dtype=float) * c.layer.thickness)))
        for group, f in zip((*self.ligament_groups, *self.elastic_groups), forces[len(self.contacts) :]):
            out.append(np.asarray(f, dtype=float) @ group.G)
        return out

    def element_bodies(self) -> list[tuple[str, str, np.ndarray, np.ndarray]]:
        """Per group of :meth:`system` (contacts first, then ligament groups): ``(body1, body2,
        G (N, 12) rows over both bodies' 6-vectors, divisor (N,))``, the strain being
        ``(. + G u) / divisor``: what the certificate sums forces with."""
        out = [(c.body1, c.body2, p.normal_operator, c.layer.thickness) for c, p in zip(self.contacts, self.pairs)]
        out += [(g.body1, g.body2, g.G, g.slack) for g in self.ligament_groups]
        out += [(g.body1, g.body2, g.G, np.ones(g.e0.size)) for g in self.elastic_groups]
        return out

    def with_loads(self, loads: Mapping) -> Joint:
        """A copy whose bodies carry other loads: ``{name: Load or (force, moment)}``."""
        bodies = dict(self.bodies)
        for name, load in loads.items():
            if name not in bodies:
                raise InputError(f"with_loads names {name!r}, which is not a body of the joint")
            if not isinstance(load, Load):
                force, moment = load
                load = Load(force, moment)
            bodies[name] = bodies[name].with_load(load)
        return replace(self, bodies=bodies)

    def __repr__(self) -> str:
        extra = "".join(
            f", {name}={len(getattr(self, name))}" for name in ("springs", "bushings", "loads") if getattr(self, name)
        )
        coordinates = f", coordinates={list(self.coordinates)}" if self.coordinates else ""
        return (
            f"Joint(bodies={list(self.bodies)}, contacts={[c.name for c in self.contacts]}, "
            f"ligaments={len(self.ligaments)}{extra}, kinematics={self.kinematics!r}{coordinates})"
        )


def _unloaded(body: Body) -> Body:
    return Body(reference=body.reference, free=body.free, prescribed=dict(body.prescribed))


def _modulus(law) -> float:
    from ..formulations._parts.resistance import modulus_scale

    return modulus_scale(law.modulus)
