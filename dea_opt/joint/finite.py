"""A joint under finite kinematics: exact poses, gaps at the current pose per layer, exact lengths.

Written math: ``formulations/joint.md`` ("Finite kinematics"). Each step builds the joint at the
current pose (:class:`~dea_opt.joint.configuration.Configuration`: every spring's gap to its
target there, every bundle's exact length, the rows of the bodies' coordinate rates) and moves the
coordinates by Newton's step on the exact forces (their tangent by differences), or, where that
is no descent direction, by the small-kinematics energy at the pose solved for the increment (the
joint's Newton, or IPOPT for ``method="nlp"``, with the bundles' geometric stiffness), a line
search on the exact forces' power deciding how far; the pose is then taken exactly again. At the
fixed point the forces balance at the exact pose. Springs
cast from meshes (``Contact(targets=SpringCast)``) are cast again at the solved pose
(:func:`dea_opt.mesh.recast` of the cast they started from) until the springs that carry load no
longer change. The answer is certified there, and its stability measured from the tangent of
the exact forces.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from .._checks.threads import single_threaded_blas
from ..errors import InputError, LoadNotSupportedError
from ..formulations._parts import joint_ipopt, joint_newton
from ..formulations._parts.options import Option, validate
from ..formulations.joint import internal_force, joint_scaling, law_stresses
from ..kinematics import DOFS
from ..status import CERTIFIABLE, Status
from .certificate import body_forces, certify_joint
from .checks import check_joint_unresisted, finish, start_vector
from .configuration import Configuration, initial_states
from .model import line_operator
from .results import JointSolution, body_results, layer_solutions, ligament_results
from .validity import assess_joint

__all__ = ["OPTIONS", "exact_residual", "solve_finite_joint", "stability"]

#: The options of a finite-kinematics joint solve (beside those of the inner method).
OPTIONS = (
    Option(
        "gtol",
        float,
        1e-12,
        "scaled residual of the exact forces that counts as equilibrium",
        range=(0, 1),
        tolerance=True,
    ),
    Option("max_steps", int, 60, "steps (solves at a pose) per set of springs, at most", range=(1, None)),
    Option("recast", bool, True, "cast springs from meshes again at the solved pose (Contact(targets=SpringCast))"),
    Option("max_recasts", int, 10, "casts of the springs again, at most", range=(0, None)),
)
_OWN = {o.name for o in OPTIONS}
#: A step turns no body more than this (rad): no linearisation reaches farther.
_MAX_TURN = 0.5


def solve_finite_joint(joint, method: str, *, certificate_tol: float, strict: bool, **options) -> JointSolution:
    """The certified equilibrium of a ``kinematics="finite"`` joint (see :func:`dea_opt.solve`).

    ``method``: ``"auto"`` or ``"newton"`` (each step by the joint's Newton), ``"nlp"`` (by IPOPT);
    the QP is a small-kinematics method. Options: :data:`OPTIONS`, the inner method's, and ``x0``
    (the free coordinates' start: translations and rotation vectors).
    """
    if method == "qp":
        raise InputError(
            "method 'qp' is a small-kinematics method: use 'auto', 'newton' or 'nlp' for kinematics='finite'"
        )
    own = validate("finite joint", OPTIONS, {k: v for k, v in options.items() if k in _OWN})
    inner = {k: v for k, v in options.items() if k not in _OWN and k != "x0"}
    x0 = start_vector(joint, options.get("x0"))
    name = "nlp" if method == "nlp" else "newton"
    validate(name, joint_newton.OPTIONS if name == "newton" else joint_ipopt.NLP_OPTIONS, inner)
    with single_threaded_blas():
        solution = _solve(joint, name, method, certificate_tol, own, inner, x0)
    return finish(solution, strict)


def _coordinates(joint, x) -> dict:
    """``{body: 6-vector}`` of coordinates from the free vector ``x`` (prescribed values elsewhere)."""
    return joint.body_u(np.zeros(len(joint.free_index)) if x is None else x)


def _residual(system) -> float:
    """The scaled residual of the forces at zero increment (the joint Newton's measure)."""
    if not system.n_dofs:
        return 0.0
    scale = joint_scaling(system)
    T, E0 = scale.T, scale.energy_scale
    with np.errstate(invalid="ignore", over="ignore"):
        q = internal_force(system, law_stresses(system, np.zeros(system.n_dofs)))
    qt, rt = T.T @ q / E0, T.T @ system.load / E0
    return float(np.linalg.norm(qt - rt)) / max(float(np.linalg.norm(qt)), float(np.linalg.norm(rt)), 1.0)


def _step(name: str, system, inner: dict, residual: float):
    """One increment at the pose: the small-kinematics energy there, solved from zero; loose while
    far from equilibrium (the next pose moves the elements anyway)."""
    options = dict(inner)
    if name == "newton":
        options["gtol"] = max(options.get("gtol", 1e-12), min(1e-6, 1e-2 * residual))
        return joint_newton.solve(system, **options)
    return joint_ipopt.solve_nlp(system, **options)


def _solve(joint, name, method, tol, own, inner, x0) -> JointSolution:
    start = time.perf_counter()
    free = list(joint.free_index)
    x = np.zeros(len(free)) if x0 is None else x0.copy()
    states = tuple(initial_states(joint))
    config = Configuration(joint, _coordinates(joint, x), states)
    system = config.solver_system()
    refused = None
    if system.load.any():
        # A direction no element resists at the start may be held once the bodies move (a bundle
        # pulled taut turns and holds sideways): the load is refused only if the solve fails too.
        try:
            check_joint_unresisted(config, system)
        except LoadNotSupportedError as exc:
            refused = exc
    history, steps, recasts, evaluations, newton_steps = [], 0, 0, 0, 0
    status, message = Status.MAX_ITERATIONS, f"no equilibrium within {own['max_steps']} steps at a pose"
    radius = joint.extent
    while True:
        residual = _residual(config.solver_system())
        history.append(residual)
        if not math.isfinite(residual):
            status, message = Status.NON_FINITE, "the forces at the pose are not finite"
            break
        if residual <= own["gtol"]:
            new = _recast(config) if own["recast"] else None
            if new is None:
                status, message = Status.CONVERGED, "the forces balance at the exact pose"
                break
            config = Configuration(joint, config.y, new)
            if _residual(config.solver_system()) <= own["gtol"]:
                status, message = Status.CONVERGED, "the forces balance at the exact pose, with the springs cast there"
                break
            if recasts >= own["max_recasts"]:
                # the springs still changed where the forces balanced: never checked at its own pose
                status = Status.MAX_ITERATIONS
                message = (
                    f"the springs cast at the solved pose still change the forces after {recasts} casts "
                    f"(max_recasts): the answer was never checked at its own pose"
                )
                break
            recasts += 1
            continue
        if steps >= own["max_steps"]:
            break
        steps += 1
        dx = _newton_step(joint, config, x) if name == "newton" else None
        if dx is None:
            result = _step(name, config.solver_system(), inner, residual)
            if not np.isfinite(result.x).all():
                status, message = Status(result.status), f"the solve at a pose failed: {result.message}"
                break
            dx = result.x
        else:
            newton_steps += 1
        turn = max((abs(float(v)) for (body, dof), v in zip(free, dx) if dof[0] == "r"), default=0.0)
        if turn > _MAX_TURN:
            dx = dx * (_MAX_TURN / turn)
        alpha, used = _along(joint, config.states, x, dx, max(turn, 1e-300))
        evaluations += used
        x = x + alpha * dx
        y = _coordinates(joint, x)
        if any(np.linalg.norm(v[3:]) > math.pi or np.linalg.norm(v[:3]) > 4 * radius for v in y.values()):
            status = Status.UNBOUNDED
            message = (
                "the bodies ran away (a turn past 180 deg or a slide past 4 times the joint's extent): nothing in "
                "the joint holds them near the start under this load"
            )
            config = Configuration(joint, y, config.states)
            break
        config = Configuration(joint, y, config.states)
    if refused is not None and status not in CERTIFIABLE:
        raise refused
    info = {
        "steps": steps,
        "recasts": recasts,
        "line_evaluations": evaluations,
        "tangent_steps": newton_steps,
        "residual_history": history,
        "native_status": str(status),
    }
    return _certified(joint, config, method, status, message, steps, time.perf_counter() - start, tol, info)


def _newton_step(joint, config: Configuration, x) -> np.ndarray | None:
    """Newton's step on the exact forces, ``K dx = -r`` with ``K`` their tangent by differences, where
    it is a descent direction of their power (``r . dx < 0``); None otherwise (then the step of the
    small kinematics at the pose). The small kinematics' step alone knows the material's stiffness
    but not the geometry's (a condyle's curvature under a load, the turn of a line): it converges,
    slowly, where ``K`` converges in a few steps."""
    r = config.net_force()
    K = tangent(joint, config.states, x)
    if not (np.isfinite(K).all() and np.isfinite(r).all()):
        return None
    try:
        dx = -np.linalg.solve(K, r)
    except np.linalg.LinAlgError:
        return None
    return dx if float(r @ dx) < 0 else None


def _along(joint, states, x, dx, turn: float) -> tuple[float, int]:
    """``(alpha, evaluations)``: the step along ``dx`` where the exact forces' power along it,
    ``psi'(alpha) = r(x + alpha dx) . dx``, has fallen to a tenth of its start (the full step where
    it has fallen to half already): the small-kinematics step at a pose knows the material's
    stiffness, not how the pose changes the geometry (a condyle rolling, a line turning), and the
    exact forces along its direction decide how far to go."""
    slope0 = float(exact_residual(joint, states, x) @ dx)
    if not slope0 < 0:
        return 1.0, 1
    limit = _MAX_TURN / turn
    lo, s_lo, hi, s_hi = 0.0, slope0, None, 0.0
    alpha, used = 1.0, 1
    for used in range(2, 40):
        s = float(exact_residual(joint, states, x + alpha * dx) @ dx)
        if not np.isfinite(s):
            hi, s_hi = alpha, np.inf
        elif abs(s) <= (0.5 if alpha == 1.0 and hi is None and lo == 0.0 else 0.1) * abs(slope0):
            return alpha, used
        elif s < 0:
            lo, s_lo = alpha, s
        else:
            hi, s_hi = alpha, s
        if hi is None:
            if alpha >= limit:
                return alpha, used
            alpha = min(2.0 * alpha, limit)
        elif np.isfinite(s_hi) and s_hi > s_lo:
            # regula falsi between a descending and a rising end, kept inside the bracket
            alpha = lo - s_lo * (hi - lo) / (s_hi - s_lo)
            alpha = min(max(alpha, lo + 0.05 * (hi - lo)), hi - 0.05 * (hi - lo))
        else:
            alpha = 0.5 * (lo + hi)
    return (lo if lo > 0 else alpha), used


def _recast(config: Configuration) -> tuple | None:
    """The contacts' springs cast again at the pose where they came from a cast, or None where no
    contact was cast from meshes."""
    from ..mesh import recast

    states, any_cast = [], False
    for i, state in enumerate(config.states):
        if state.cast is None:
            states.append(state)
            continue
        any_cast = True
        again = recast(state.cast, config.relative(i))
        layer = again.cast.layer
        from ..formulations.finite import Targets

        targets = Targets.from_layer(layer, pose=state.targets.frame)
        states.append(replace(state, layer=layer, targets=targets, dropped=again.dropped))
    return tuple(states) if any_cast else None


def _world_forces(config: Configuration, layer_forces, ligament_forces) -> dict:
    """``{body: 6-vector}`` every element takes from each body, in world axes about its reference at
    the pose (the layers' own answers are written in them)."""
    out = config.world.on_body(layer_forces)
    p1, p2 = config.insertions
    for group, f in zip(config.joint.ligament_groups, ligament_forces):
        idx = list(group.members)
        G = line_operator(p1[idx], p2[idx], config.references[group.body1], config.references[group.body2])
        q = np.asarray(f) @ G
        out[group.body1] += q[:6]
        out[group.body2] += q[6:]
    return out


def _certified(joint, config, method, status, message, steps, elapsed, tol, info) -> JointSolution:
    system = config.system()
    zero = np.zeros(system.n_dofs)
    with np.errstate(invalid="ignore", over="ignore"):
        stresses = law_stresses(system, zero)
        forces = [g.forces(s) for g, s in zip(system.groups, stresses)]
    certificate = certify_joint(config, zero, stresses, tol)
    success = bool(certificate.passed and status in CERTIFIABLE)
    if not success and status in CERTIFIABLE:
        status, message = Status.INACCURATE, f"{message}; the answer fails dea-opt's certificate"
    y = config.y
    n = len(joint.contacts)
    on_body = body_forces(config, forces)
    world = config.world
    common = dict(
        certificate=certificate,
        tolerance=tol,
        method=method,
        success=success,
        status=status,
        message=message,
        iterations=steps,
        solve_time=elapsed,
    )
    dropped = [s.dropped for s in config.states]
    contacts = layer_solutions(
        world,
        {k: np.zeros(6) for k in y},
        _world_forces(config, forces[:n], forces[n:]),
        forces[:n],
        [layer.gap / layer.thickness for layer in config.layers],
        common,
        dropped,
    )
    ligaments = ligament_results(config, {k: np.zeros(6) for k in y}, forces, config.insertions)
    value, along = stability(config) if success else (None, "")
    validity = assess_joint(config, y, ligaments, tuple(c.validity for c in contacts), stability=value, softest=along)
    info = dict(info, stability=value, softest=along)
    bodies = body_results(joint, y, on_body)
    return JointSolution(
        joint=joint,
        x=np.array([y[b][DOFS.index(d)] for b, d in joint.free_index]),
        bodies=bodies,
        contacts=contacts,
        ligaments=ligaments,
        certificate=certificate,
        validity=validity,
        method=method,
        success=success,
        status=status,
        message=message,
        iterations=steps,
        solve_time=elapsed,
        info=info,
    )


def exact_residual(joint, states, x) -> np.ndarray:
    """The net generalized force on the free coordinates at the pose of ``x`` (N, N mm): the exact
    forces of every element there, minus the loads (``J^T`` of the moments for rotations)."""
    return Configuration(joint, _coordinates(joint, x), states).net_force()


def tangent(joint, states, x) -> np.ndarray:
    """``dr/dx`` of :func:`exact_residual` on the free coordinates by central differences (1e-6 mm
    of the elements' motion: rotations over each body's radius), shape (m, m)."""
    m = len(joint.free_index)
    lengths = joint.lengths
    K = np.zeros((m, m))
    for j, (_, dof) in enumerate(joint.free_index):
        h = 1e-6 if dof[0] == "u" else 1e-6 / lengths[j]
        step = np.zeros(m)
        step[j] = h
        K[:, j] = (exact_residual(joint, states, x + step) - exact_residual(joint, states, x - step)) / (2 * h)
    return K


def stability(config: Configuration) -> tuple[float, str]:
    """``(value, along)``: ``-min Re(lambda) / max |lambda|`` over the eigenvalues of the tangent of the
    exact forces on the free coordinates (central differences, rotations over each body's radius),
    above 0 where a disturbance grows; and the motion that gives way, in words."""
    joint = config.joint
    free = list(joint.free_index)
    if not free:
        return 0.0, ""
    x = np.array([config.y[b][DOFS.index(d)] for b, d in free])
    lengths = joint.lengths
    K = tangent(joint, config.states, x)
    scaled = K / lengths[:, None] / lengths[None, :]
    if not np.isfinite(scaled).all():
        return float("nan"), ""
    values, vectors = np.linalg.eig(scaled)
    largest = float(np.abs(values).max())
    if largest == 0.0:
        return 0.0, ""
    k = int(np.argmin(values.real))
    v = vectors[:, k].real
    v = v / v[np.argmax(np.abs(v))]
    words = [
        f"{b}.{d} {z:+.3g} mm" if d[0] == "u" else f"{b}.{d} {math.degrees(z / length):+.3g} deg"
        for (b, d), z, length in zip(free, v, lengths)
        if abs(z) >= 1e-3
    ]
    return float(-values.real[k] / largest) + 0.0, ", ".join(words)
