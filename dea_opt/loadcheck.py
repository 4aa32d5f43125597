"""Which loads compression-only springs can carry: the tests ``dea_opt.solve`` runs before a solve.

A part of the load along directions no spring resists, or (finite kinematics) a load no free
motion makes any spring carry (:func:`check_unresisted`), then the cone test: the load must lie
in the cone of the springs' directions (:func:`check_cone`). Either raises
:class:`~dea_opt.errors.LoadNotSupportedError` naming the unbalanced part, in words
(``formulations/energy.md``, "When is there a solution?"; ``formulations/finite.md``, "Loads no
motion can carry").
"""

from __future__ import annotations

import numpy as np

from .errors import LoadNotSupportedError
from .formulations._parts.resistance import require_finite, unresisted
from .problem import ContactProblem

__all__ = ["check_cone", "check_load_supported", "check_unresisted", "describe_direction"]

#: Relative residual of the cone test above which a load counts as not carried.
_CONE_TOL = 1e-7


def describe_direction(problem: ContactProblem, names, vector) -> str:
    """The large components of a generalized force in words, each in its own units: a force
    in N, a moment in N mm about the body's reference point (named once per body)."""
    vector = np.asarray(vector, dtype=float)
    top = float(np.abs(vector).max(initial=0.0))
    parts = []
    for body in ("body1", "body2"):
        moments = []
        for name, value in zip(names, vector):
            if top == 0.0 or abs(value) < 1e-3 * top or not name.startswith(f"{body}."):
                continue
            dof = name.split(".")[1]
            if dof[0] == "u":
                parts.append(f"force {value:+.4g} N along {dof[1]} on {body}")
            else:
                moments.append(f"moment {value:+.4g} N mm along {dof[1]} on {body}")
        if moments:
            reference = (problem.body1 if body == "body1" else problem.body2).reference
            point = ", ".join(f"{c:.4g}" for c in reference)
            moments[-1] += f" ({'moments' if len(moments) > 1 else 'moment'} about its reference point ({point}) mm)"
            parts.extend(moments)
    return ", ".join(parts) or "none"


def check_load_supported(problem: ContactProblem) -> None:
    """Raise :class:`LoadNotSupportedError` when compression-only springs cannot carry the load.

    Two tests (``formulations/energy.md``, "When is there a solution?"): a part of the load
    along directions no spring resists (:func:`check_unresisted`, the same test as the
    formulations' scaling and the certificate), then the cone test: a solution exists iff the
    load lies in the cone of the spring directions, ``r = -A^T lambda`` with ``lambda >= 0``,
    tested with non-negative least squares over the resisted directions; the unbalanced
    remainder names the direction.
    """
    system = problem.system()
    if not system.n_dofs or not system.load.any():
        return
    check_unresisted(problem, system)
    check_cone(problem, system)


def check_unresisted(problem: ContactProblem, system) -> None:
    """Raise when more than ``_CONE_TOL`` of the load acts along directions no spring resists, or
    (finite kinematics, ``system.motion``) when no free motion changes any spring's gap and none
    is compressed: the springs' forces then stay zero, whatever their lever arms
    (``formulations/finite.md``, "Loads no motion can carry")."""
    r = system.load
    require_finite("the load", r)
    res = system.resistance
    fraction = res.load_fraction(r)
    names = list(problem.free_names)
    if fraction <= _CONE_TOL:
        motion = getattr(system, "motion", None)  # finite kinematics: does any free motion change a gap?
        if motion is not None and motion.moves_nothing and r.any():
            load = describe_direction(problem, names, r)
            raise LoadNotSupportedError(motion.message(names, load), direction=dict(zip(names, r.tolist())))
        return
    part = res.load_part(r)
    if res.n_resisted == 0:
        reason = f"no spring resists any of the free dofs {tuple(names)}"
        if not system.n_springs:
            reason += " (the layer has no springs)"
        message = (
            f"{reason}, so the load along them cannot be carried: {describe_direction(problem, names, part)}. "
            f"Fix these dofs, remove this load, or add springs that resist them."
        )
    else:
        message = (
            f"no spring resists part of this load: {describe_direction(problem, names, part)} "
            f"({fraction:.3g} of the load) acts along a direction the springs cannot push back on "
            f"({'; '.join(res.describe(names))}). Fix that dof, remove that part of the load, or add springs."
        )
    raise LoadNotSupportedError(message, direction=dict(zip(names, part.tolist())))


def check_cone(problem: ContactProblem, system) -> None:
    """The cone test over the resisted directions, in arc lengths (moments over the radius).

    The unbalanced part reported is the smallest in that measure (``formulations/energy.md``,
    "When is there a solution?"): ``|| (r - r_c) / L ||`` over every load ``r_c`` the springs
    can carry, with ``L`` 1 mm for a translation and the layer's radius for a rotation, as the
    certificate measures loads. So it is never larger than the load itself in that measure.
    """
    res = system.resistance
    D, Q = res.lengths, res.range
    rhs = Q.T @ (system.load / D)
    rnorm = float(np.linalg.norm(rhs))
    if rnorm == 0.0:
        return
    # Each spring's generalized force direction, restricted to what the springs resist; a
    # spring whose direction there is no stiffness at all (by the one test) joins no cone.
    columns = -(Q.T @ (system.AT / D[:, None]))
    norms = np.linalg.norm(columns, axis=0)
    keep = ~unresisted(system.volume * norms**2, res.scale) & (norms > 0)
    columns = columns[:, keep] / norms[keep]
    residual = _cone_residual(columns, rhs)
    if residual is None:
        return  # undecided: leave it to the solver and its certificate
    remainder, residual_norm = residual
    if residual_norm <= _CONE_TOL * rnorm:
        return
    names = list(problem.free_names)
    unbalanced = D * (Q @ remainder)
    carried = system.load - unbalanced
    radii = {
        f"{D[j]:.4g} mm about {names[j].split('.')[0]}'s reference point": None
        for j in range(len(names))
        if names[j].split(".")[1][0] == "r"
    }
    measure = (
        f"moments counted over the layer's radius, {', '.join(radii)}, as the certificate does" if radii else "in N"
    )
    raise LoadNotSupportedError(
        f"compression-only springs cannot carry this load: {_reference_note(problem)}"
        f"{_cone_cause(problem, names, system.load, D, Q, columns)}. "
        f"Smallest unbalanced part ({measure}): {describe_direction(problem, names, unbalanced)}, "
        f"{residual_norm / rnorm:.3g} of the load in that measure; the nearest load the springs can carry is "
        f"{describe_direction(problem, names, carried)}. Check the load's sign (body 2 is pushed toward body 1 by "
        f"a load along -normal) and its units (N, N mm), fix the unresisted dofs, or add springs.",
        direction=dict(zip(names, unbalanced.tolist())),
    )


def _reference_note(problem: ContactProblem) -> str:
    """The likely cause when a body free to turn has its reference point farther from the centre
    of the contact (the springs' area-weighted centroid ``c``) than the layer's radius (half the
    diagonal of the springs' bounding box) and its load's moment about ``c`` along the free
    rotations, ``M + (reference - c) x F``, is more than half the force times that radius: a
    force given without a point acts at the reference point, far from where the springs can
    balance it. Empty otherwise."""
    layer = problem.layer
    if not len(layer) or not float(np.sum(layer.areas)) > 0:
        return ""
    points, areas = np.asarray(layer.points, dtype=float), np.asarray(layer.areas, dtype=float)
    centre = areas @ points / areas.sum()
    radius = 0.5 * float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    for k, body in ((2, problem.body2), (1, problem.body1)):
        turns = [dof for dof in ("rx", "ry", "rz") if dof in set(body.free)]
        reference = np.asarray(body.reference, dtype=float)
        distance = float(np.linalg.norm(reference - centre))
        force = np.asarray(body.force, dtype=float)
        about = np.asarray(body.moment, dtype=float) + np.cross(reference - centre, force)
        about *= np.array([f"r{axis}" in turns for axis in "xyz"], dtype=float)
        size = float(np.linalg.norm(about))
        if not turns or distance <= radius or size <= 0.5 * float(np.linalg.norm(force)) * radius:
            continue
        where = ", ".join(f"{c:.4g}" for c in reference)
        middle = ", ".join(f"{c:.4g}" for c in centre)
        return (
            f"likely because body {k}'s reference point ({where}) mm is {distance:.3g} mm from the centre of the "
            f"contact ({middle}) mm, beyond the layer's radius ({radius:.3g} mm): body {k} turns "
            f"({', '.join(turns)}) about it and a force given without a point acts there, so the load's moment "
            f"about the contact is {size:.3g} N mm; put the reference at the contact (a scenario's reference = "
            f'"contact") or give the force\'s point. In detail: '
        )
    return ""


def _cone_residual(columns, rhs):
    """``(rhs - columns @ lam, its norm)`` for the ``lam >= 0`` nearest ``rhs`` (NNLS), or None
    when NNLS did not finish."""
    from scipy.optimize import nnls

    if not columns.shape[1]:
        return rhs, float(np.linalg.norm(rhs))
    # nnls is compiled code: never hand it an empty or non-finite matrix (it aborts the
    # process on an m x 0 one).
    require_finite("the spring directions", columns, rhs)
    try:
        lam, residual_norm = nnls(columns, rhs, maxiter=50 * max(len(rhs), 1) + 100)
    except RuntimeError:
        return None
    return rhs - columns @ lam, float(residual_norm)


def _cone_cause(problem, names, load, D, Q, columns) -> str:
    """Why the load lies outside the springs' cone, in words: its moment is more than the
    springs can carry with its force (when the force alone could be carried), or it pulls
    the bodies apart."""
    rotation = np.array([name.split(".")[1][0] == "r" for name in names])
    force_only = np.where(rotation, 0.0, load)
    if rotation.any() and (load[rotation] != 0).any() and force_only.any():
        rhs = Q.T @ (force_only / D)
        residual = _cone_residual(columns, rhs)
        if residual is not None and residual[1] <= _CONE_TOL * float(np.linalg.norm(rhs)):
            return (
                "its force could be carried, but its moment is more than the springs can balance with that force "
                "(the lever arms of the contact are too short)"
            )
    return "it pulls the bodies apart, or loads a direction no spring can push back on"
