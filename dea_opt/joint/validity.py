"""Is a joint's answer inside its model? Each layer's report, and the bundles' and bodies' checks.

Every contact layer carries the two-body :class:`~dea_opt.validity.Validity` of its answer (strain,
rotation and gap error of its two bodies, sizes, peak pressure, ...). The joint adds, per bundle,
its strain against the range where ligaments rupture and, under small kinematics, the error of
its linearised length, and the rotation of every body (a body held only by bundles has no layer
to report it). The math: ``formulations/joint.md``, "Validity".
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .._checks.inputs import number_in_range
from ..validity.report import Check

__all__ = ["DEFAULT_JOINT_LIMITS", "JointValidity", "LigamentLimits", "assess_joint"]


@dataclass(frozen=True)
class LigamentLimits:
    """The limits of a joint's own checks.

    Parameters
    ----------
    rupture : float, default 0.15
        Largest bundle strain. Knee ligaments fail in tension at strains of roughly 15-20 %:
        a bundle strained past 0.15 is at the onset of that range, where the law (elastic, no
        damage) no longer describes it.
    length_error : float, default 0.005
        Small kinematics: largest error of a bundle's linearised length against the exact length
        of the same motion, over its slack length (an error in strain, against working strains
        of 0.02-0.1).
    rotation : float, default 3
        Small kinematics: largest rotation of any body (degrees), as the two-body check.
    """

    rupture: float = 0.15
    length_error: float = 0.005
    rotation: float = 3.0

    def __post_init__(self):
        for name in ("rupture", "length_error"):
            object.__setattr__(
                self, name, number_in_range(f"LigamentLimits.{name}", getattr(self, name), 0.0, low_open=True)
            )
        object.__setattr__(
            self, "rotation", number_in_range("LigamentLimits.rotation", self.rotation, 0.0, 180.0, low_open=True)
        )


DEFAULT_JOINT_LIMITS = LigamentLimits()


@dataclass(frozen=True)
class JointValidity:
    """The validity of a joint's answer: the joint's checks and each layer's report.

    Attributes
    ----------
    checks : tuple of Check
        ``ligament_strain``, ``ligament_length_error`` (small kinematics) and ``body_rotation``.
    layers : tuple of Validity
        Each contact layer's two-body report, in the order of ``Joint.contacts``.
    names : tuple of str
        The layers' names.
    """

    checks: tuple
    layers: tuple = ()
    names: tuple = ()
    details: dict = field(default_factory=dict)

    @property
    def valid(self) -> bool:
        return all(c.passed is not False for c in self.checks) and all(v.valid for v in self.layers)

    @property
    def failed(self) -> tuple:
        """Failed checks: the joint's by name, a layer's as ``"<layer>: <check>"``."""
        own = tuple(c.name for c in self.checks if c.passed is False)
        return own + tuple(f"{n}: {c}" for n, v in zip(self.names, self.layers) for c in v.failed)

    def __getitem__(self, name: str) -> Check:
        for c in self.checks:
            if c.name == name:
                return c
        raise KeyError(name)

    def as_dict(self) -> dict:
        return {
            "valid": self.valid,
            "failed": list(self.failed),
            "checks": {c.name: _check_dict(c) for c in self.checks},
            "layers": {n: v.as_dict() for n, v in zip(self.names, self.layers)},
        }

    def summary(self) -> str:
        if self.valid:
            return f"valid ({len(self.checks)} joint checks and {len(self.layers)} layers passed)"
        return "outside validity: " + ", ".join(self.failed)

    def message(self) -> str:
        """Every failed check with its value, limit and advice, one per line."""
        lines = [f"{c.name} {c.value:.4g} > {c.limit:g}: {c.advice}" for c in self.checks if c.passed is False]
        for n, v in zip(self.names, self.layers):
            if not v.valid:
                lines.append(f"layer {n}: {v.message()}")
        return "the joint's answer lies outside its model: " + "; ".join(lines)


def _check_dict(c: Check) -> dict:
    value = c.value if math.isfinite(c.value) else None
    return {"value": value, "limit": c.limit, "unit": c.unit, "passed": c.passed, "advice": c.advice}


def assess_joint(
    joint,
    body_u: dict,
    ligaments,
    layers: tuple,
    limits: LigamentLimits = DEFAULT_JOINT_LIMITS,
    stability: float | None = None,
    softest: str = "",
) -> JointValidity:
    """The :class:`JointValidity` of an answer (``body_u``: each body's 6-vector; ``ligaments``:
    its :class:`~dea_opt.joint.results.LigamentResults`; ``layers``: each layer's Validity).

    Finite kinematics: ``body_rotation`` is every body's rotation vector within a half turn, and
    ``stability`` (``-min Re(lambda) / max |lambda|`` of the tangent on the free coordinates at
    the answer, ``softest`` the motion that gives way) is checked against the two-body limit
    (:class:`~dea_opt.validity.ValidityLimits`, ``stability``)."""
    checks = [_strain_check(ligaments, limits)]
    if joint.kinematics == "small":
        checks.append(_length_check(joint, body_u, limits))
        checks.append(_rotation_check(joint, body_u, limits))
    else:
        checks.append(_rotation_check(joint, body_u, limits, half_turn=True))
        checks.append(_stability_check(stability, softest))
    return JointValidity(tuple(checks), tuple(layers), tuple(c.name for c in joint.contacts))


def _stability_check(value, softest) -> Check:
    from ..validity import DEFAULT_LIMITS

    limit = DEFAULT_LIMITS.stability
    if value is None:
        return Check("stability", math.nan, limit, "", None, "not evaluated: the solve gave no equilibrium to test")
    if not math.isfinite(value):
        return Check("stability", value, limit, "", False, "the tangent at the answer is not finite")
    if value <= limit:
        return Check("stability", value, limit, "", True)
    advice = (
        f"the equilibrium is unstable: the joint gives way along {softest or 'a free direction'} at the smallest "
        f"disturbance; hold that motion, or add what holds it (a ligament, a contact)"
    )
    return Check("stability", value, limit, "", False, advice)


def _strain_check(ligaments, limits) -> Check:
    if not len(ligaments):
        return Check("ligament_strain", 0.0, limits.rupture, "", True)
    i = int(np.argmax(ligaments.strain))
    value = float(ligaments.strain[i])
    if not math.isfinite(value):
        return Check("ligament_strain", value, limits.rupture, "", False, "the value is not finite: the solve failed")
    if value <= limits.rupture:
        return Check("ligament_strain", value, limits.rupture, "", True, details=(("bundle", float(i)),))
    advice = (
        f"bundle {ligaments.names[i]!r} is strained {value:.1%}, within or past the 15-20 % where ligaments "
        f"rupture: the elastic law no longer describes it; check its slack length, the load and the motion"
    )
    return Check("ligament_strain", value, limits.rupture, "", False, advice, (("bundle", float(i)),))


def _length_check(joint, body_u, limits) -> Check:
    """The exact length of the same motion (rotation vectors taken as exact rotations) against the
    linearised one, over the slack length."""
    from ..formulations.finite.rotations import pose_matrix

    worst = 0.0
    for group in joint.ligament_groups:
        u = np.concatenate([body_u[group.body1], body_u[group.body2]])
        linear = group.start + group.G @ u
        ligs = [joint.ligaments[i] for i in group.members]
        T1 = pose_matrix(body_u[group.body1], joint.bodies[group.body1].reference)
        T2 = pose_matrix(body_u[group.body2], joint.bodies[group.body2].reference)
        p1 = np.array([lig.point1 for lig in ligs]) @ T1[:3, :3].T + T1[:3, 3]
        p2 = np.array([lig.point2 for lig in ligs]) @ T2[:3, :3].T + T2[:3, 3]
        exact = np.linalg.norm(p2 - p1, axis=1)
        worst = max(worst, float(np.max(np.abs(exact - linear) / group.slack, initial=0.0)))
    passed = worst <= limits.length_error
    advice = (
        ""
        if passed
        else "the bundles' linearised lengths are off by more than the limit: use Joint(..., kinematics='finite') "
        "(exact lengths), or reduce the motion"
    )
    return Check("ligament_length_error", worst, limits.length_error, "", passed, advice)


def _turn(joint, name: str, u) -> float:
    """A body's rotation (degrees): its rotation vector's length, or its motion's angle where its
    coordinates are a :class:`~dea_opt.joint.Coordinates`'."""
    coordinates = getattr(joint, "coordinates", {})
    if name not in coordinates:
        return float(np.degrees(np.linalg.norm(u[3:])))
    R = joint.motion(name, u)[:3, :3]
    return float(np.degrees(np.arccos(np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0))))


def _rotation_check(joint, body_u, limits, half_turn: bool = False) -> Check:
    value = max((_turn(joint, name, u) for name, u in body_u.items()), default=0.0)
    limit = 180.0 if half_turn else limits.rotation
    passed = value <= limit
    advice = "" if passed else "a body turns past the small kinematics: use Joint(..., kinematics='finite')"
    if half_turn and not passed:
        advice = "a body's rotation vector wound past a half turn: the same pose has a shorter one; check the loads"
    return Check("body_rotation", value, limit, "deg", passed, advice)
