"""What a joint's solve checks before and after it: the start, the loads no element can carry, the end.

A load with a part along free directions no element resists is refused before any solve; a load
outside the cone of what springs push and bundles pull is refused after Newton fails, or before
the QP and IPOPT (``formulations/joint.md``, "Resisted directions and scaling"): both as a
:class:`~dea_opt.errors.LoadNotSupportedError` naming the dofs. An uncertified answer raises
:class:`~dea_opt.errors.SolverError` (``strict``); a certified one outside its model warns.
"""

from __future__ import annotations

import warnings

import numpy as np

from ..errors import InputError, LoadNotSupportedError, SolverError, ValidityWarning
from ..loadcheck import _cone_residual
from .model import Joint
from .results import JointSolution

__all__ = ["check_joint_cone", "check_joint_unresisted", "finish", "start_vector"]


def finish(solution: JointSolution, strict: bool) -> JointSolution:
    if not solution.success and strict:
        raise SolverError(
            f"{solution.method} returned no certified answer for the joint (status {str(solution.status)!r}: "
            f"{solution.message}); {solution.failure}. Try method='auto', another method, or check the loads.",
            status=solution.status,
            solution=solution,
            native_status=solution.info.get("native_status"),
        )
    if solution.success and not solution.validity.valid:
        warnings.warn(solution.validity.message(), ValidityWarning, stacklevel=3)
    return solution


def start_vector(joint: Joint, x0) -> np.ndarray | None:
    if x0 is None:
        return None
    m = len(joint.free_index)
    try:
        x = np.array(x0, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"x0 must be one number per free dof ({m}: {joint.free_names}), got {x0!r}") from None
    if x.shape != (m,) or not np.isfinite(x).all():
        raise InputError(f"x0 must be {m} finite numbers, one per free dof {joint.free_names}, got {x0!r}")
    return x


def _describe(joint, vector) -> str:
    vector = np.asarray(vector, dtype=float)
    top = float(np.abs(vector).max(initial=0.0))
    parts = []
    for name, value in zip(joint.free_names, vector):
        if top == 0.0 or abs(value) < 1e-3 * top:
            continue
        body, dof = name.split(".")
        unit = "N" if dof[0] == "u" else f"N mm about {body}'s reference"
        parts.append(f"{'force' if dof[0] == 'u' else 'moment'} {value:+.4g} {unit} along {dof[1]} on {body}")
    return ", ".join(parts) or "none"


def check_joint_unresisted(joint, system=None) -> None:
    """Raise :class:`LoadNotSupportedError` when part of the load acts along free directions no
    element resists (the same one test as the scaling and the certificate); ``system`` defaults to
    the joint's."""
    system = joint.system() if system is None else system
    res = system.resistance
    fraction = res.load_fraction(system.load)
    if fraction <= 1e-7:
        return
    part = res.load_part(system.load)
    names = list(joint.free_names)
    which = "; ".join(res.describe(names)) or ", ".join(names)
    raise LoadNotSupportedError(
        f"no contact or ligament of the joint resists part of this load: {_describe(joint, part)} ({fraction:.3g} of "
        f"the load) acts along {which}. Fix those dofs, remove that part of the load, or add elements that hold them.",
        direction=dict(zip(names, part.tolist())),
    )


def check_joint_cone(joint: Joint) -> None:
    """Raise :class:`LoadNotSupportedError` when the load lies outside the cone of what the elements
    can push and pull (springs push along their normals, bundles pull along their lines)."""
    system = joint.system()
    if not system.n_dofs or not system.load.any():
        return
    flat, _ = system.flat()
    res = system.resistance
    D, Q = res.lengths, res.range
    rhs = Q.T @ (system.load / D)
    rnorm = float(np.linalg.norm(rhs))
    if rnorm == 0.0:
        return
    columns = -(Q.T @ (flat.AT / D[:, None]))
    norms = np.linalg.norm(columns, axis=0)
    keep = norms > 1e-12 * float(norms.max(initial=0.0))
    columns = columns[:, keep] / norms[keep]
    residual = _cone_residual(columns, rhs)
    if residual is None or residual[1] <= 1e-7 * rnorm:
        return
    unbalanced = D * (Q @ residual[0])
    names = list(joint.free_names)
    raise LoadNotSupportedError(
        f"the joint's springs (which only push) and ligaments (which only pull) cannot carry this load: the smallest "
        f"unbalanced part is {_describe(joint, unbalanced)} ({residual[1] / rnorm:.3g} of the load, moments over each "
        f"body's radius). Check the loads' signs and units (N, N mm), or add elements.",
        direction=dict(zip(names, unbalanced.tolist())),
    )
