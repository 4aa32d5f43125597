"""What a joint's answer holds: each body's motion, each layer as a two-body answer, each bundle.

:class:`JointSolution` is what :func:`dea_opt.solve` returns for a :class:`~dea_opt.joint.Joint`:
``.bodies[name]`` (:class:`BodyResult`: ``u``, ``pose``, ``reactions``), ``.contacts[i]`` (a
:class:`~dea_opt.Solution` per layer, with everything a two-body answer reports: pressure, area,
centre of pressure, files and maps), ``.ligaments`` (:class:`LigamentResults`: force, strain and
length per bundle), ``.certificate`` (:class:`~dea_opt.joint.certificate.JointCertificate`) and
``.validity`` (:class:`~dea_opt.joint.validity.JointValidity`). The math: ``formulations/joint.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import MappingProxyType
from typing import TYPE_CHECKING, Any

import numpy as np

from ..kinematics import DOFS
from ..solution import Solution
from ..status import Status
from .certificate import JointCertificate
from .validity import JointValidity

if TYPE_CHECKING:
    from .model import Joint

__all__ = ["BodyResult", "JointSolution", "LigamentResults"]


@dataclass(frozen=True)
class BodyResult:
    """One body of a joint's answer.

    Attributes
    ----------
    name : str
    u : ndarray, shape (6,)
        ``(ux, uy, uz, rx, ry, rz)`` (mm, rad) about the body's reference (small kinematics: the
        paper's linearised motion; finite: the translation and the exact rotation vector).
    pose : ndarray, shape (4, 4)
        The rigid motion ``u`` implies, in the global frame (its rotation vector taken exactly).
    reactions : dict
        ``{dof: N or N mm}`` the supports apply at each dof that is not free.
    force, moment : ndarray, shape (3,)
        The resultant the elements apply to the body at the answer (N, and N mm about its
        reference where it is): at equilibrium, minus its load on its free dofs.
    """

    name: str
    u: np.ndarray
    pose: np.ndarray
    reactions: dict
    force: np.ndarray
    moment: np.ndarray


@dataclass(frozen=True, eq=False)
class LigamentResults:
    """Every bundle at the answer, in the order of ``Joint.ligaments``.

    Attributes
    ----------
    names : tuple of str
    body1, body2 : tuple of str
    force : ndarray, shape (n,)
        Tension (N, >= 0).
    strain : ndarray, shape (n,)
        ``L / L0 - 1`` (small kinematics: on the linearised length).
    length : ndarray, shape (n,)
        ``L`` (mm).
    slack_length : ndarray, shape (n,)
        ``L0`` (mm).
    point1, point2 : ndarray, shape (n, 3)
        The insertions at the answer (mm, global frame).
    """

    names: tuple
    body1: tuple
    body2: tuple
    force: np.ndarray
    strain: np.ndarray
    length: np.ndarray
    slack_length: np.ndarray
    point1: np.ndarray
    point2: np.ndarray

    def __len__(self) -> int:
        return len(self.names)

    def rows(self) -> list[dict]:
        """One dict per bundle, units in the column names (the ligament table's columns)."""
        return [
            {
                "name": self.names[i],
                "body1": self.body1[i],
                "body2": self.body2[i],
                "force_N": float(self.force[i]),
                "strain": float(self.strain[i]),
                "length_mm": float(self.length[i]),
                "slack_length_mm": float(self.slack_length[i]),
            }
            for i in range(len(self))
        ]

    def __getitem__(self, key) -> dict:
        """The row of a bundle by position or name."""
        if isinstance(key, str):
            if key not in self.names:
                from ..errors import InputError

                raise InputError(f"no ligament named {key!r}; the bundles are {list(self.names)}")
            key = self.names.index(key)
        return self.rows()[key]


@dataclass(frozen=True, eq=False)
class JointSolution:
    """The equilibrium of a :class:`~dea_opt.joint.Joint`, certified.

    Attributes
    ----------
    joint : Joint
    x : ndarray, shape (m,)
        The free dofs (mm, rad), in the order of ``joint.free_names``.
    bodies : mapping {name: BodyResult}
    contacts : tuple of Solution
        Per layer, the two-body answer of its layer between its bodies with, as their loads, every
        other force on them at the answer (their loads and the other elements'): its certificate
        checks that layer's springs and the equilibrium it is part of; its ``validity`` is the
        layer's, as for a two-body problem.
    ligaments : LigamentResults
    elastic : list of dict
        One row per :class:`~dea_opt.joint.Spring` and :class:`~dea_opt.joint.Bushing` (springs
        first; :func:`~dea_opt.joint.elastic.elastic_results`), units in the keys.
    certificate : JointCertificate
    validity : JointValidity
    method, success, status, message, iterations, solve_time, info
        As for a two-body :class:`~dea_opt.Solution`.
    states : tuple
        Finite kinematics: each contact's springs where the answer left them (cast again at its
        pose), to start another solve from (``contact_states=``; a path's next frame).
    """

    joint: Joint
    x: np.ndarray
    bodies: MappingProxyType
    contacts: tuple
    ligaments: LigamentResults
    certificate: JointCertificate
    validity: JointValidity
    method: str
    success: bool
    status: Status
    message: str
    iterations: int
    solve_time: float
    info: dict[str, Any] = field(default_factory=dict)
    elastic: list = field(default_factory=list)
    states: tuple = field(default=(), repr=False)

    @property
    def failure(self) -> str:
        """Why this answer is not a success ("" when it is)."""
        if self.success:
            return ""
        if not self.certificate.passed:
            name, value = self.certificate.worst()
            return f"certificate residual {name} = {value:.3g} > {self.certificate.tolerance:g}"
        return f"status '{self.status}': {self.status.description}"

    def summary(self) -> dict:
        """The headline numbers as plain Python values (for JSON), each key of a number ending with
        its unit (:mod:`dea_opt.units`)."""
        from ..kinematics import DOFS
        from ..units import dof_name

        return {
            "method": self.method,
            "success": self.success,
            "status": str(self.status),
            "message": self.message,
            "iterations": self.iterations,
            "bodies": {
                name: {
                    "u": {dof_name(dof): float(v) for dof, v in zip(DOFS, b.u)},
                    "reactions": {dof_name(dof, "force"): float(v) for dof, v in b.reactions.items()},
                    "force_N": b.force.tolist(),
                    "moment_Nmm": b.moment.tolist(),
                }
                for name, b in self.bodies.items()
            },
            "contacts": [
                {
                    "name": contact.name,
                    "peak_pressure_MPa": s.peak_pressure,
                    "contact_area_mm2": s.contact_area,
                    "contact_force_N": s.contact_force.tolist(),
                    "center_of_pressure_mm": s.center_of_pressure.tolist(),
                }
                for contact, s in zip(self.joint.contacts, self.contacts)
            ],
            "ligaments": self.ligaments.rows(),
            **({"elastic": list(self.elastic)} if self.elastic else {}),
            "certificate": self.certificate.as_dict(),
            "validity": self.validity.as_dict(),
        }

    def __repr__(self) -> str:
        return (
            f"JointSolution(method={self.method!r}, success={self.success}, status='{self.status}', "
            f"bodies={list(self.bodies)}, contacts={len(self.contacts)}, ligaments={len(self.ligaments)}, "
            f"valid={self.validity.valid})"
        )


def body_results(joint, body_u: dict, on_body: dict, loads=None, poses=None) -> MappingProxyType:
    """``{name: BodyResult}`` from each body's 6-vector and what the elements take from it, ``G^T f``
    in the world about its reference (``on_body``), against its whole load ``loads`` (default
    ``joint.load_vectors()``) at its motion ``poses`` (default from ``body_u``)."""
    loads = joint.load_vectors() if loads is None else loads
    out = {}
    for name, body in joint.bodies.items():
        u = body_u[name]
        q = on_body[name]
        reaction = q - loads[name]
        held = {dof: float(reaction[j]) for j, dof in enumerate(DOFS) if dof not in body.free}
        pose = joint.motion(name, u) if poses is None else poses[name]
        # q is what the elements take from the body's dofs: the force they apply is -q.
        out[name] = BodyResult(name, u, pose, held, -q[:3], -q[3:])
    return MappingProxyType(out)


def layer_solutions(
    joint, body_u: dict, on_body: dict, layer_forces, strains, common: dict, dropped=None, own=None
) -> tuple:
    """Per contact, its two-body :class:`~dea_opt.Solution` at the answer: the layer's problem whose
    bodies carry, as loads, every other force on them (their own loads minus what the other
    elements take), its strains and pressures.

    ``joint`` gives ``contacts``, ``pairs`` (each layer's two-body problem) and ``bodies`` (their
    loads), in the frame of ``on_body`` (each body's 6-vector of what every element takes from it);
    ``strains`` each layer's strains at the answer; ``own`` (optional) the 12-vector each layer takes
    from its two bodies (else from the pair's rows); ``dropped`` (per contact, or None) the springs
    a cast's window dropped at the answer's pose. Its certificate is the joint's (``common
    ["certificate"]``), with that layer's own tension, complementarity and consistency: the
    equilibrium it is part of is the joint's (``formulations/joint.md``, "The certificate").
    """
    from ..solution import Certificate

    out = []
    dropped = dropped or [None] * len(joint.contacts)
    own = own or [None] * len(joint.contacts)
    whole = common["certificate"]
    loads = joint.body_loads()
    for c, pair, f, strain, lost, took in zip(joint.contacts, joint.pairs, layer_forces, strains, dropped, own):
        u = np.concatenate([body_u[c.body1], body_u[c.body2]])
        took = np.asarray(f, dtype=float) @ pair.normal_operator if took is None else took
        problem = pair
        for k, name in ((1, c.body1), (2, c.body2)):
            rest = loads[name] - (on_body[name] - took[6 * (k - 1) : 6 * k])
            # a failed answer's forces may not be finite: its layers then carry no load of their own
            rest = np.where((np.abs(rest) < 1e-30) | ~np.isfinite(rest), 0.0, rest)
            problem = problem.with_load(force=rest[:3], moment=rest[3:], body=k)
        with np.errstate(invalid="ignore", over="ignore"):
            pressure = 0.0 - pair.law.stress(np.minimum(strain, 0.0))
        checks = whole.elements.get(f"contact {c.name}", {})
        certificate = Certificate(
            whole.equilibrium,
            checks.get("tension", 0.0),
            checks.get("complementarity", 0.0),
            checks.get("consistency", 0.0),
            whole.energy,
            whole.tolerance,
        )
        solution = Solution(
            problem=problem,
            u=u,
            strain=strain,
            pressure=pressure,
            method=common["method"],
            success=bool(common["success"] and certificate.passed),
            status=common["status"],
            message=common["message"],
            iterations=common["iterations"],
            build_time=0.0,
            solve_time=common["solve_time"],
            certificate=certificate,
            info={"joint_contact": c.name},
        )
        out.append(solution if lost is None else solution.with_validity(dropped=int(lost)))
    return tuple(out)


def ligament_results(joint, body_u: dict, law_forces, insertions=None) -> LigamentResults:
    """Every bundle's force (N), strain and length (mm) at the answer, in ``Joint.ligaments`` order.

    Small kinematics: the length linearised in the motions (the strain the energy uses), the
    insertions moved by the linearised motion. Finite kinematics: ``joint`` is the configuration
    at the pose (its groups' lengths exact), ``body_u`` zero there, and ``insertions`` the
    insertions at the pose.
    """
    n = len(joint.ligaments)
    force, strain, length = np.zeros(n), np.zeros(n), np.zeros(n)
    p1, p2 = np.zeros((n, 3)), np.zeros((n, 3))
    offset = len(joint.contacts)
    for gi, group in enumerate(joint.ligament_groups):
        u = np.concatenate([body_u[group.body1], body_u[group.body2]])
        members = np.asarray(group.members, dtype=int)
        L = group.start + group.G @ u
        force[members] = law_forces[offset + gi]
        length[members] = L
        strain[members] = L / group.slack - 1.0
        if insertions is None:
            ends = [
                np.array([joint.ligaments[i].point1 for i in members]),
                np.array([joint.ligaments[i].point2 for i in members]),
            ]
            for k, name, points in ((0, group.body1, ends[0]), (1, group.body2, ends[1])):
                (p1, p2)[k][members] = _moved(points, body_u[name], joint.bodies[name].reference)
    if insertions is not None:
        p1, p2 = np.array(insertions[0], dtype=float), np.array(insertions[1], dtype=float)
    return LigamentResults(
        names=tuple(lig.name or f"ligament {i}" for i, lig in enumerate(joint.ligaments)),
        body1=tuple(lig.body1 for lig in joint.ligaments),
        body2=tuple(lig.body2 for lig in joint.ligaments),
        force=force,
        strain=strain,
        length=length,
        slack_length=np.array([float(lig.slack_length) for lig in joint.ligaments]),
        point1=p1,
        point2=p2,
    )


def _moved(point, u, reference) -> np.ndarray:
    """Points (3,) or (n, 3) of a body moved by the linearised motion ``u`` about ``reference`` (Eq. 9)."""
    p = np.asarray(point, dtype=float)
    return p + u[:3] + np.cross(u[3:], p - np.asarray(reference, dtype=float))
