"""A joint's contacts between solves: each layer's springs and targets (:class:`ContactState`, what a
finite solve carries from one answer to the next), and the layers at a pose seen with world-axis
bodies (:class:`WorldView`). Used by :mod:`~dea_opt.joint.configuration` and
:mod:`~dea_opt.joint.finite`.

Written math: ``formulations/joint.md`` ("Finite kinematics").
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from types import MappingProxyType

import numpy as np

from ..layer import SpringLayer

__all__ = ["ContactState", "WorldView", "initial_states"]


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

    @cached_property
    def plane_rows(self):
        """The springs and their targets as :class:`~dea_opt.formulations.finite.geometry.PlaneRows`
        where every target is a plane (else None): made once, read at every pose of a solve."""
        from ..formulations.finite.geometry import PlaneRows

        t = self.targets
        if not bool(np.all(t.is_plane)):
            return None
        return PlaneRows(t, self.layer.points, self.layer.normals)


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
class WorldView:
    """The layers at a pose with world-axis bodies: what :func:`~dea_opt.joint.results.layer_solutions` reads."""

    contacts: tuple
    pairs: tuple
    bodies: MappingProxyType

    def body_loads(self) -> dict:
        """``{body: (F, M)}``: each body's whole load in world axes about its reference at the pose."""
        return {n: b.load_vector for n, b in self.bodies.items()}

    def on_body(self, forces) -> dict:
        """``{name: 6-vector}`` the layers' ``forces`` (N) take from each body, about its reference."""
        out = {name: np.zeros(6) for name in self.bodies}
        for c, pair, f in zip(self.contacts, self.pairs, forces):
            q = np.asarray(f, dtype=float) @ pair.normal_operator
            out[c.body1] += q[:6]
            out[c.body2] += q[6:]
        return out
