"""The elements that hold a joint's bodies together: contact layers and ligament bundles.

Both couple two named bodies of a :class:`~dea_opt.joint.Joint`; the math is in
``formulations/joint.md``. Small immutable objects, checked when made: a bad value is an
:class:`~dea_opt.errors.InputError` naming the field, what was expected and what came.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from .._checks.inputs import check_range, number_in_range, vector3
from ..errors import InputError
from ..formulations.joint import TENSION_LAWS
from ..laws import Law, check_law
from ..layer import SpringLayer

__all__ = ["Contact", "Ligament"]


def _body_name(field: str, value) -> str:
    if not isinstance(value, str) or not value:
        raise InputError(f"{field} must be the name of a body of the joint (a non-empty str), got {value!r}")
    return value


@dataclass(frozen=True, eq=False)
class Contact:
    """A layer of compression-only springs between two bodies of a joint.

    Parameters
    ----------
    layer : SpringLayer
        The springs, on ``body1``'s surface, their normals pointing from ``body1`` to ``body2``
        (as for a two-body :class:`~dea_opt.ContactProblem`; a cast from ``body1``'s mesh onto
        ``body2``'s makes them so). Everything a two-body layer has (labels, compartments, the
        proximity window of its cast) holds per layer.
    law : Law
        The springs' law.
    body1, body2 : str
        The names of the two bodies in :attr:`Joint.bodies <dea_opt.joint.Joint.bodies>`.
    name : str, optional
        A label for tables and messages (default ``"body1-body2"``).
    targets : SpringCast or Targets, optional
        Finite kinematics only: what each spring looks at on ``body2`` (as
        ``ContactProblem(targets=...)``); a :class:`~dea_opt.mesh.SpringCast` lets the springs
        be cast again as the bodies move.
    """

    layer: SpringLayer
    law: Law
    body1: str = ""
    body2: str = ""
    name: str | None = None
    targets: object = None

    def __post_init__(self):
        if not isinstance(self.layer, SpringLayer):
            raise InputError(f"Contact.layer must be a SpringLayer, got {type(self.layer).__name__}")
        check_law(self.law)
        _body_name("Contact.body1", self.body1)
        _body_name("Contact.body2", self.body2)
        if self.body1 == self.body2:
            raise InputError(f"a Contact couples two different bodies, got body1 = body2 = {self.body1!r}")
        if self.name is None:
            object.__setattr__(self, "name", f"{self.body1}-{self.body2}")
        elif not isinstance(self.name, str) or not self.name:
            raise InputError(f"Contact.name must be a non-empty str, got {self.name!r}")
        if self.targets is not None:
            from ..formulations.finite import Targets
            from ..mesh.springs import SpringCast

            if not isinstance(self.targets, (Targets, SpringCast)):
                raise InputError(
                    f"Contact.targets must be a dea_opt.mesh.SpringCast, a dea_opt.formulations.finite.Targets or "
                    f"None, got {type(self.targets).__name__}"
                )


@dataclass(frozen=True, eq=False)
class Ligament:
    """A ligament bundle: a straight line between an insertion on each of two bodies, tension only.

    The force along the line is ``f = k phi(eps)`` with ``eps = L / L0 - 1`` (``L`` the length,
    ``L0`` the slack length) and, for ``law="blankevoort"`` (Blankevoort et al. 1991, as OpenSim's
    ``Blankevoort1991Ligament`` writes it, so models carry over unchanged), ``phi = 0`` for
    ``eps <= 0``, ``eps^2 / (2 eps_t)`` below the transition strain ``eps_t`` (the toe region)
    and ``eps - eps_t / 2`` beyond; ``law="linear"``: ``phi = max(eps, 0)``. OpenSim's damping
    term needs speeds: the quasi-static solves here have none and leave it out.

    **Wrapping around obstacles is not modelled**: the bundle is the straight line between its
    two insertions, shorter than a path that wraps a condyle or an ellipsoid (OpenSim's wrap
    objects). Where a model's bundle wraps, its slack length and the strain computed here refer
    to different paths: give the slack length (or reference strain) for the straight line.

    Parameters
    ----------
    body1, body2 : str
        The bodies of the two insertions (names in the joint).
    point1, point2 : array_like, shape (3,)
        The insertions in mm, in the global frame at the start pose (where every body's motion
        ``u`` is zero).
    stiffness : float
        ``k``, N per unit strain (OpenSim's ``linear_stiffness``).
    slack_length : float, optional
        ``L0`` in mm. Give it or ``reference_strain``, not both.
    reference_strain : float, optional
        The strain at the start pose: ``L0 = L_start / (1 + reference_strain)`` (> -1).
    law : {"blankevoort", "linear"}
    transition_strain : float
        ``eps_t`` (default 0.06, OpenSim's; Blankevoort's paper writes the toe up to ``2 eps_l``
        with ``eps_l = 0.03``, the same curve).
    name : str, optional
        A label for the table of results.
    """

    body1: str = ""
    point1: tuple = (0.0, 0.0, 0.0)
    body2: str = ""
    point2: tuple = (0.0, 0.0, 0.0)
    stiffness: float = 0.0
    slack_length: float | None = None
    law: str = "blankevoort"
    transition_strain: float = 0.06
    reference_strain: float | None = None
    name: str | None = None

    def __post_init__(self):
        set_ = object.__setattr__
        _body_name("Ligament.body1", self.body1)
        _body_name("Ligament.body2", self.body2)
        if self.body1 == self.body2:
            raise InputError(f"a Ligament couples two different bodies, got body1 = body2 = {self.body1!r}")
        set_(self, "point1", vector3("Ligament.point1", self.point1, "mm"))
        set_(self, "point2", vector3("Ligament.point2", self.point2, "mm"))
        if self.start_length <= 0.0:
            raise InputError(
                f"a Ligament's insertions must be two different points, got point1 = point2 = {self.point1} mm"
            )
        set_(self, "stiffness", number_in_range("Ligament.stiffness", self.stiffness, 0.0, low_open=True))
        check_range("Ligament.stiffness", self.stiffness, "N", positive=True)
        if not isinstance(self.law, str) or self.law not in TENSION_LAWS:
            raise InputError(f"Ligament.law must be one of {TENSION_LAWS}, got {self.law!r}")
        set_(
            self,
            "transition_strain",
            number_in_range("Ligament.transition_strain", self.transition_strain, 0.0, 1.0, low_open=True),
        )
        given = [n for n in ("slack_length", "reference_strain") if getattr(self, n) is not None]
        if len(given) != 1:
            raise InputError(
                "a Ligament needs its slack_length (mm) or its reference_strain at the start pose, exactly one, "
                f"got {given or 'neither'}"
            )
        if self.slack_length is not None:
            set_(self, "slack_length", number_in_range("Ligament.slack_length", self.slack_length, 0.0, low_open=True))
            check_range("Ligament.slack_length", self.slack_length, "mm", positive=True)
        else:
            strain = number_in_range("Ligament.reference_strain", self.reference_strain, -1.0, low_open=True)
            set_(self, "reference_strain", strain)
            set_(self, "slack_length", self.start_length / (1.0 + strain))
        if self.name is not None and (not isinstance(self.name, str) or not self.name):
            raise InputError(f"Ligament.name must be a non-empty str, got {self.name!r}")

    @property
    def start_length(self) -> float:
        """The straight line's length at the start pose (mm)."""
        return math.dist(self.point1, self.point2)

    @property
    def start_strain(self) -> float:
        """``L_start / L0 - 1`` at the start pose."""
        return self.start_length / float(self.slack_length) - 1.0  # type: ignore[arg-type]

    def force_at(self, strain) -> float:
        """The bundle's force (N) at a strain, by its law (for tables and checks)."""
        import numpy as np

        from ..formulations.joint import TensionLaw

        law = TensionLaw(self.law, np.array([self.transition_strain]))
        return float(self.stiffness * law.force(np.array([float(strain)]))[0])
