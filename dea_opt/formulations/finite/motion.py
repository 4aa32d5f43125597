"""Finite kinematics, the load check: which motions of body 2 change the springs' gaps at its base pose.

Written math: ``formulations/finite.md`` ("Loads no motion can carry"). Rows (6, N) are per
unit translation (mm) and rotation (rad) of body 2 about its reference point.

The small kinematics takes a spring's force direction and the change of its gap as one row
``a_i = [n_i; (p_i - c) x n_i]``, so the directions the springs resist are those of the forces.
With exact gaps they differ: the gap changes as ``b_i = [m_i; (h_i - c) x m_i] / (n_i . m_i)``
(:meth:`~dea_opt.formulations.finite.geometry.Gaps.rows`), ``m_i`` the target's normal at
the hit ``h_i``. A motion with ``b_i . w = 0`` for every spring compresses none: when the targets'
normals pass through body 2's reference point (spheres centred there) turning about it moves
each target along itself, and a spring whose ray misses its target (a target facing away from
body 1) has no gap to change. Where no free motion changes a gap, the springs' forces stay those
of the base pose whatever body 2 does, however their lever arms could turn it: a load they do not
already balance is not carried. :func:`motion` decides it with the one test of unresisted
directions the forces' resistance uses (on a
:class:`~dea_opt.formulations.SpringSystem` of the gap-change rows);
:func:`~dea_opt.formulations.finite.small_system` keeps the answer, and ``dea_opt.solve``'s load
check raises :class:`~dea_opt.errors.LoadNotSupportedError` on it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._parts.resistance import Resistance, resistance
from .._parts.system import SpringSystem
from .geometry import FACING

__all__ = ["Motion", "motion"]

#: ``|(h - c) x m| / |h - c|`` below which a target's normal at the hit passes through the point ``c``.
RADIAL = 1e-9


@dataclass(frozen=True)
class Motion:
    """The free motions of body 2 that change the springs' gaps at its base pose.

    Attributes
    ----------
    resistance : Resistance
        Of the gap-change rows ``blockdiag(I, J)^T b_i / h_i`` on the free coordinates, judged as
        the force directions are (``n_resisted == 0``: no free motion changes any gap).
    n_springs : int
    missed : int
        Springs whose ray misses its target at the base pose (open whatever the motion).
    facing_away : int
        Of those, the ones whose plane target faces away from body 1 (``n . m >= 0``).
    radial : int
        Springs met whose target's normal at the hit passes through body 2's reference point there.
    compressed : int
        Springs compressed at the base pose (they carry load there).
    tracked : bool
        The targets were cast from meshes: a solve re-casts them as body 2 moves, so the base
        pose's targets do not decide what motion can do.
    centre : tuple
        Body 2's reference point at the base pose (mm).
    """

    resistance: Resistance
    n_springs: int
    missed: int
    facing_away: int
    radial: int
    compressed: int
    tracked: bool
    centre: tuple = (0.0, 0.0, 0.0)

    @property
    def moves_nothing(self) -> bool:
        """No free motion changes any spring's gap, and none carries load at the base pose."""
        return not self.tracked and self.resistance.n_resisted == 0 and not self.compressed

    def why(self) -> str:
        """Why no gap changes, in words."""
        point = ", ".join(f"{c:.4g}" for c in self.centre)
        parts = []
        if self.missed:
            away = f" ({self.facing_away} of them face away from body 1: n . m >= 0)" if self.facing_away else ""
            parts.append(f"{self.missed} of the {self.n_springs} springs' rays miss their targets{away}")
        if self.radial:
            parts.append(
                f"{self.radial} of the {self.n_springs} springs' targets have their normal at the hit through "
                f"body 2's reference point ({point}) mm (spheres centred there), so turning about it moves each "
                f"target along itself"
            )
        return "; ".join(parts) or "each target's surface moves along itself under these motions"

    def message(self, names, load: str) -> str:
        """The :class:`~dea_opt.errors.LoadNotSupportedError` message when :attr:`moves_nothing`:
        ``names`` the free dofs, ``load`` the load in words."""
        advice = ["fix those dofs or remove that load"]
        if self.missed:
            advice.append("give targets that face the springs at the start pose")
        if self.radial:
            advice.append("take a reference point the targets' normals do not pass through")
        return (
            f"no motion of the free dofs {tuple(names)} changes any spring's gap at the start pose, and no spring is "
            f"compressed there, so no spring can push back on the load: {self.why()}. Unresisted: {load} (all "
            f"of the load; the springs' lever arms cannot help, as no motion loads them). "
            f"{', or '.join(advice).capitalize()}."
        )


def motion(system, state, small: SpringSystem) -> Motion:
    """The :class:`Motion` of the :class:`~dea_opt.formulations.finite.system.FiniteSystem`
    ``system`` at ``state`` (its base pose), whose small system ``small`` (same springs, free
    coordinates, volumes, lengths and layer stiffness) the forces' resistance was decided on."""
    free = system.free
    gaps = state.gaps
    M = np.eye(6)
    M[3:, 3:] = state.J.T
    BT = np.ascontiguousarray((M @ gaps.rows(state.centre))[free] / system.thickness)
    factor = np.asarray(np.linalg.qr((BT * np.sqrt(small.volume)).T, mode="r")) if BT.size else np.zeros((0, len(free)))
    rows = SpringSystem(BT, small.e0, small.volume, small.load, small.dof_length, factor, small.stiffness)
    valid = gaps.valid
    arm = np.where(valid[:, None], gaps.hit - state.centre, 0.0)
    length = np.linalg.norm(arm, axis=1)
    twist = np.linalg.norm(np.cross(arm, gaps.m), axis=1)
    radial = valid & (twist <= RADIAL * np.maximum(length, 1.0))
    plane = system.targets.is_plane
    return Motion(
        resistance=resistance(rows),
        n_springs=len(valid),
        missed=int((~valid).sum()),
        facing_away=int((~valid & plane & (gaps.along >= -FACING)).sum()),
        radial=int(radial.sum()),
        compressed=int((valid & (state.eps < 0)).sum()),
        tracked=system.targets.faces is not None,
        centre=tuple(float(c) for c in state.centre),
    )
