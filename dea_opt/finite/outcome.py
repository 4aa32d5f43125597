"""How a finite-kinematics solve that found no answer of the meshes says what its iterates did.

Where the iterates ran away (:func:`ran_away`: no equilibrium found near the start; along a free
dof the contact may resist less than the load), springs that carried load were lost through the
layer on the way (:func:`crushed_through`) or the springs did not settle within ``max_recasts``
updates (:func:`unsettled`), the solve failed: what it says of the load (``crushed``,
``unbounded``) stands only where :mod:`~dea_opt.finite.verdict` proves it from the problem,
else the answer is a solve that did not converge (``formulations/finite.md``, "What the layer can
carry"). :func:`crushed_at_start` gives the proved ``crushed`` before any solve. Used by
:mod:`~dea_opt.finite.driver`.
"""

from __future__ import annotations

import math

import numpy as np

from ..formulations.finite import InnerResult

__all__ = [
    "beyond_reach",
    "crushed_at_start",
    "crushed_far",
    "crushed_through",
    "ran_away",
    "unsettled",
]


def crushed_at_start(system, law, x, eps, proof) -> InnerResult:
    """A failed answer at the small kinematics' answer ``x``, which crushes the layer through
    (``eps <= -1``), where ``proof`` (a :class:`~dea_opt.finite.verdict.Proof`) shows that no
    equilibrium inside the model carries the load: ``crushed``, said before any solve (IPOPT would
    take minutes to fail)."""
    motion, _ = _motion(system.free, x, np.asarray(system.force, dtype=float))
    return InnerResult(
        x,
        system.state(system.coordinates(x), law),
        False,
        "crushed",
        f"the small kinematics on the start pose's springs reach eps = {eps:.3g} ({motion}); {proof.message()}: "
        f"{_beyond(law)}",
        info={"proved": proof.kind},
    )


#: How far a failed solve's iterate may move body 2 before it counts as run away: a turn (deg),
#: and a translation in multiples of the springs' RMS distance from its reference.
_RUN_AWAY = (180.0, 4.0)


def ran_away(system, inner, radius: float) -> bool:
    """Mark a failed solve ``unbounded`` when its iterate moved body 2 beyond :data:`_RUN_AWAY`
    (``radius``: the springs' RMS distance from body 2's reference, mm), far past any contact
    near the start: no equilibrium there carries the load, which along a free dof exceeds what
    the contact resists (a joint's torsion past the largest its articular surfaces hold; in the
    joint, the ligaments). Springs lost through the layer on the way (whose rays met mesh 2
    behind mesh 1's far side as it passed) say nothing of the load. Whether it did (the status
    ``unbounded`` stands only where :mod:`~dea_opt.finite.verdict` proves it)."""
    x = np.asarray(inner.u_free, dtype=float)
    if not beyond_reach(system, x, radius):
        return False
    motion, _ = _motion(system.free, x, np.asarray(system.force, dtype=float))
    inner.status = "unbounded"
    inner.message += (
        f"; the iterates ran away ({motion}): no equilibrium was found near the start; along the free dofs the "
        f"load may exceed what the contact resists (nothing in the model holds body 2 there; in a joint, the "
        f"ligaments): hold those dofs, or give them the loads that hold them"
    )
    return True


def beyond_reach(system, x, radius: float) -> bool:
    """Whether the free coordinates ``x`` move body 2 beyond :data:`_RUN_AWAY` (``radius``: the
    springs' RMS distance from its reference, mm), or are not finite: far past any contact near
    the start."""
    x = np.asarray(x, dtype=float)
    free = np.asarray(system.free)
    turn = float(np.linalg.norm(x[free >= 3])) if (free >= 3).any() else 0.0
    shift = float(np.linalg.norm(x[free < 3])) if (free < 3).any() else 0.0
    return not (np.isfinite(x).all() and math.degrees(turn) <= _RUN_AWAY[0] and shift <= _RUN_AWAY[1] * radius)


_FREE_DOF = (
    ": as body 2 slid or turned far, a free dof may let it go where nothing in the model holds "
    "it (in a joint, the ligaments): hold those dofs, or give them the loads that hold them"
)


def crushed_far(system, inner) -> None:
    """Add to a ``crushed`` solve's message, when body 2 slid across the load or turned far
    (:data:`_FAR`) on its way, that a free dof may be what let it go."""
    motion, far = _motion(system.free, inner.u_free, np.asarray(system.force, dtype=float))
    if far:
        inner.message += f"; {motion}{_FREE_DOF}"


#: Motion of body 2 beyond which a free dof may be what let it go: a slide across the load (mm)
#: or a turn (degrees) far outside the small rotations of the small kinematics.
_FAR = (5.0, 10.0)


def _motion(free, x, force) -> tuple[str, bool]:
    """``(text, far)``: body 2's free coordinates ``x`` (mm, rad) as ``"there body 2 moved uz -1.2 mm,
    ry 4.1 deg"``, and whether it slid across ``force`` (3,) or turned beyond :data:`_FAR`."""
    from ..kinematics import DOFS

    parts, shift, turn = [], np.zeros(3), 0.0
    for index, value in zip(free, x):
        if index < 3:
            parts.append(f"{DOFS[index]} {value:.3g} mm")
            shift[index] = value
        else:
            degrees = math.degrees(value)
            parts.append(f"{DOFS[index]} {degrees:.3g} deg")
            turn = max(turn, abs(degrees))
    size = float(np.linalg.norm(force))
    across = shift - (shift @ force) * force / size**2 if size > 0 else shift
    far = float(np.linalg.norm(across)) > _FAR[0] or turn > _FAR[1]
    return "there body 2 moved " + ", ".join(parts), far


def crushed_through(tracker, inner, law, system, radius: float) -> None:
    """Mark a failed solve ``crushed`` when springs that carried load were lost through the layer
    on the way (their rays met mesh 2 behind mesh 1's far side: the overlap passed mesh 1's
    thickness): the iterates drove body 2 into the layer until springs left the model. Unless
    the first of them were lost where the iterates had already run away (:func:`beyond_reach`,
    ``radius`` as there; the tracker's ``crushed_at``): body 2 then crossed the layer as it went
    where nothing held it, and the solve is ``unbounded`` (:func:`ran_away`). Either stands only
    where :mod:`~dea_opt.finite.verdict` proves it (another start, a load continuation or
    IPOPT may find an equilibrium); ``law`` is the layer's."""
    at = tracker.crushed_at
    if at is not None and beyond_reach(system, at[list(system.free)], radius):  # lost as body 2 passed
        inner.message += (
            f"; {tracker.crushed_through} springs that carried load were lost through the layer as body 2 passed"
        )
        if inner.status != "unbounded":
            ran_away(system, inner, radius)
        return
    inner.status = "crushed"
    inner.message += (
        f"; {tracker.crushed_through} springs that carried load were lost through the layer on the way (their "
        f"rays met mesh 2 behind mesh 1's far side: the overlap passed mesh 1's thickness)"
    )


def _beyond(law) -> str:
    """What a crushed answer tells the user to check."""
    return (
        f"the load is beyond what this layer can bear (check the load and its units, and H: {law.modulus:g} MPa "
        f"here; or use a bounded law such as AteshianLaw)"
    )


def unsettled(inner, crushing: int = 0) -> None:
    """Mark a converged solve whose springs still changed at the last update allowed
    (``max_recasts``) as failed, ``max_iterations``: an equilibrium of springs that were not
    confirmed at its own pose is not an answer of the meshes there (its certificate passes for
    those springs). ``auto`` does not fall back to IPOPT, whose springs are updated alike.
    ``crushing``: loaded springs were lost through the layer on the way (which says why, not
    ``max_recasts``)."""
    inner.success, inner.status = False, "max_iterations"
    inner.message += (
        ": they were not brought up to date at the solved pose, so the answer is not certified for the meshes there"
    )
    if not crushing:
        inner.message += " (raise max_recasts)"
