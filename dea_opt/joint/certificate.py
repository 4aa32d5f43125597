"""The certificate of a joint's answer: equilibrium of every free body, and each element's checks.

Computed by dea_opt from the answer's motion and the element forces the formulation reported,
never taken from the solver (``formulations/joint.md``, "The certificate"). Every measure is
absolute, as the two-body certificate's (:func:`dea_opt.certify`): a residual in N (moments over
a length), relative only to what is in equilibrium at the answer, the loads and the element
forces there, body by body.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..formulations._parts.resistance import unresisted
from ..formulations.joint import JointSystem, assemble, internal_force, law_stresses
from ..kinematics import DOFS

__all__ = ["JointCertificate", "body_forces", "certify_joint"]


@dataclass(frozen=True)
class JointCertificate:
    """Residuals of a joint's answer, each at most ``tolerance`` for a success.

    Attributes
    ----------
    equilibrium : float
        The largest over the free bodies of ``max_j |q_j - r_j| / L_j / F_b`` (``q`` what the
        elements' forces at the answer apply to the body's free dof ``j``, ``r`` its load, ``L_j``
        1 mm or the body's radius, ``F_b`` the body's force scale: the largest of its load, the sum
        of the magnitudes of the forces of every element that touches it, and the force of their
        initial overlap or stretch); also the part of the load along directions no element resists
        and the forces the answer's motion along them produces (as the two-body certificate).
    tension : float
        ``sum max(f_rep, 0) / F`` over the springs of every layer (``F`` the larger scale of the two
        bodies of the layer): no spring pulls.
    compression : float
        ``sum max(-f_rep, 0) / F`` over the bundles: no ligament pushes.
    complementarity : float
        ``sum |f_rep| max(eps, 0)`` over open springs plus ``sum |f_rep| max(-eps, 0)`` over slack
        bundles, over ``F``: inactive elements carry nothing.
    consistency : float
        How far reported forces lie outside what the law gives within the certified precision of
        the strain, over ``F``.
    energy : float
        ``g^T K^+ g / 2`` (``g`` the joint's gradient, ``K`` its tangent over the active elements,
        in its scaled variables) over the energy stored plus the load's work.
    bodies : dict
        ``{name: equilibrium residual}`` of every free body.
    elements : dict
        ``{group name: {check: residual}}``.
    tolerance : float
    """

    equilibrium: float
    tension: float
    compression: float
    complementarity: float
    consistency: float
    energy: float
    bodies: dict = field(default_factory=dict)
    elements: dict = field(default_factory=dict)
    tolerance: float = 1e-6

    _NAMES = ("equilibrium", "tension", "compression", "complementarity", "consistency", "energy")

    @property
    def passed(self) -> bool:
        return all(np.isfinite(getattr(self, n)) and getattr(self, n) <= self.tolerance for n in self._NAMES)

    def worst(self) -> tuple[str, float]:
        """The name and value of the largest residual."""
        values = {n: getattr(self, n) for n in self._NAMES}
        name = max(values, key=lambda k: values[k] if np.isfinite(values[k]) else np.inf)
        return name, values[name]

    def as_dict(self) -> dict:
        out = {n: getattr(self, n) for n in self._NAMES}
        extra = {"bodies": dict(self.bodies), "elements": dict(self.elements), "tolerance": self.tolerance}
        return out | extra | {"passed": self.passed}


def _ratio(numerator: float, scale: float) -> float:
    if numerator == 0.0:
        return 0.0
    return numerator / scale if scale > 0 else float("inf")


def body_forces(joint, forces) -> dict:
    """``{name: 6-vector}``: the generalized force every element's ``forces`` (N, tension positive,
    per group of :meth:`Joint.element_pairs`) applies against each body's dofs, ``G^T f``
    (N, N mm about its reference): at equilibrium, the body's load on its free dofs."""
    out = {name: np.zeros(6) for name in joint.bodies}
    for (b1, b2), q in zip(joint.element_pairs(), joint.wrenches(forces)):
        out[b1] += q[:6]
        out[b2] += q[6:]
    return out


def certify_joint(joint, x, stresses, tolerance: float = 1e-6) -> JointCertificate:
    """The :class:`JointCertificate` of the free vector ``x`` (mm, rad) with the reported law outputs
    ``stresses`` (per group of :meth:`Joint.system`)."""
    system: JointSystem = joint.system()
    groups = system.groups
    x = np.asarray(x, dtype=float)
    strains = system.strains(x)
    nan = float("nan")
    with np.errstate(invalid="ignore", over="ignore"):
        law = law_stresses(system, x)
        forces = [g.forces(s) for g, s in zip(groups, law)]
        reported = [g.forces(np.asarray(s, dtype=float)) for g, s in zip(groups, stresses)]
    if not all(np.isfinite(a).all() for a in (*forces, *reported)):
        return JointCertificate(nan, nan, nan, nan, nan, nan, tolerance=tolerance)
    on_body = body_forces(joint, forces)
    scale = _body_scales(joint, groups, forces)
    bodies, worst = {}, 0.0
    lengths = dict(zip(joint.free_index, system.lengths))
    loads = joint.body_loads()
    for name, body in joint.bodies.items():
        if not body.free:
            continue
        load = loads[name]
        residual = 0.0
        for j, dof in enumerate(DOFS):
            if dof in body.free:
                residual = max(residual, abs(on_body[name][j] - load[j]) / lengths[(name, dof)])
        bodies[name] = _ratio(residual, scale[name])
        worst = max(worst, bodies[name])
    res = system.resistance
    if res.null.shape[1]:
        worst = max(worst, res.load_fraction(system.load))
        z = res.motion_part(x)
        if z.any():
            with np.errstate(invalid="ignore", over="ignore"):
                held = [g.forces(s) for g, s in zip(groups, law_stresses(system, x - z))]
            moved = sum(float(np.abs(a - b).sum()) for a, b in zip(forces, held))
            worst = max(worst, _ratio(moved, max(scale.values(), default=0.0)))
    elements, sums = {}, dict.fromkeys(("tension", "compression", "complementarity", "consistency"), 0.0)
    for (b1, b2), g, eps, rep in zip(joint.element_pairs(), groups, strains, reported):
        F = max(scale[b1], scale[b2])
        checks = (
            _two_sided_checks(g, eps, rep, tolerance, F) if g.two_sided else _element_checks(g, eps, rep, tolerance, F)
        )
        elements[g.name] = checks
        for key, value in checks.items():
            sums[key] = max(sums[key], value)
    energy = _energy_residual(system, x, strains, law) if x.size else 0.0
    return JointCertificate(
        worst,
        sums["tension"],
        sums["compression"],
        sums["complementarity"],
        sums["consistency"],
        energy,
        bodies,
        elements,
        tolerance,
    )


def _body_scales(joint, groups, forces) -> dict:
    """Each body's force scale: its load (moments over its radius), the sum of the magnitudes of the
    element forces on it, and the force of its elements' initial overlap or stretch (N)."""
    lengths = dict(zip(joint.free_index, joint.system().lengths))
    scale = {}
    loads = joint.body_loads()
    radii = {}
    for name in joint.bodies:
        load = loads[name]
        radius = max((lengths[(name, d)] for d in DOFS[3:] if (name, d) in lengths), default=1.0)
        radii[name] = radius
        scale[name] = max(float(np.abs(load[:3]).max()), float(np.abs(load[3:]).max()) / radius)
    rows = joint.element_bodies() if any(g.two_sided for g in groups) else None
    for i, ((b1, b2), g, f) in enumerate(zip(joint.element_pairs(), groups, forces)):
        f = np.abs(f)
        if g.two_sided and rows is not None:  # a bushing's moments count over the radius, as the loads' do
            G = rows[i][2]
            moments = (np.abs(G[:, 0:3]).max(axis=1) == 0) & (np.abs(G[:, 6:9]).max(axis=1) == 0)
            f = np.where(moments, f / max(radii[b1], radii[b2]), f)
        total = float(f.sum())
        start = np.abs(g.e0) if g.two_sided else np.maximum(-g.e0, 0.0) if g.contact else np.maximum(g.e0, 0.0)
        preload = float((g.force_scale * g.modulus) @ start) if start.any() else 0.0
        for name in (b1, b2):
            scale[name] = max(scale[name], total, preload)
    return scale


def _element_checks(g, eps, reported, tolerance, F) -> dict:
    """Sign, complementarity and consistency of one group's reported forces (N) at its strains."""
    sign = 1.0 if g.contact else -1.0
    wrong = float(np.maximum(sign * reported, 0.0).sum())  # springs pulling, bundles pushing
    inactive = float(np.abs(reported) @ np.maximum(sign * eps, 0.0))
    active = np.minimum(eps, 0.0) if g.contact else np.maximum(eps, 0.0)
    start = np.minimum(g.e0, 0.0) if g.contact else np.maximum(g.e0, 0.0)
    delta = tolerance * max(float(np.abs(active).max(initial=0.0)), float(np.abs(start).max(initial=0.0)))
    with np.errstate(invalid="ignore", over="ignore"):
        low = g.forces(g.stress(eps - delta))
        high = g.forces(g.stress(eps + delta))
    bottom, top = np.minimum(low, high), np.maximum(low, high)
    excess = np.maximum(bottom - reported, 0.0) + np.maximum(reported - top, 0.0)
    consistency = float(np.nan_to_num(excess, nan=np.inf).sum())
    return {
        ("tension" if g.contact else "compression"): _ratio(wrong, F),
        "complementarity": _ratio(inactive, F),
        "consistency": _ratio(consistency, F),
    }


def _two_sided_checks(g, eps, reported, tolerance, F) -> dict:
    """Consistency of a linear two-sided group (springs, bushings): its reported forces (N, N mm)
    against ``k e`` within the certified precision of its deflections."""
    delta = tolerance * max(float(np.abs(eps).max(initial=0.0)), float(np.abs(g.e0).max(initial=0.0)))
    excess = np.maximum(np.abs(reported - g.forces(eps)) - g.force_scale * delta, 0.0)
    return {"consistency": _ratio(float(np.nan_to_num(excess, nan=np.inf).sum()), F)}


def _energy_residual(system: JointSystem, x, strains, law) -> float:
    """``g^T K^+ g / 2`` in the resisted directions (``T1^T K0 T1 = I``), over the energy scale."""
    res = system.resistance
    if not res.n_resisted:
        return 0.0
    groups = system.groups
    with np.errstate(invalid="ignore", over="ignore"):
        weights = [g.volume * g.tangent(e) for g, e in zip(groups, strains)]
        stored = sum(float(g.volume @ g.energy(e)) for g, e in zip(groups, strains))
    if not any(w.any() for w in weights):
        return 0.0
    T1 = res.T1
    K = assemble(system, weights, T1)
    gt = T1.T @ (internal_force(system, law) - system.load)
    if not (np.isfinite(K).all() and np.isfinite(gt).all() and np.isfinite(stored)):
        return float("nan")
    vals, vecs = np.linalg.eigh(K)
    keep = ~unresisted(vals, max(float(vals[-1]), 1.0))
    coeff = vecs[:, keep].T @ gt
    decrement = float(coeff @ (coeff / vals[keep]))
    scale = max(stored + abs(float(system.load @ x)), system.e0_overlap() ** 2 / 2.0)
    return _ratio(0.5 * abs(decrement), scale)
