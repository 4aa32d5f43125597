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

import numpy as np

from .._checks.threads import single_threaded_blas
from ..errors import InputError, LoadNotSupportedError
from ..formulations._parts import joint_ipopt, joint_newton
from ..formulations._parts.options import Option, validate
from ..formulations.joint import internal_force, joint_scaling, law_stresses
from ..kinematics import DOFS
from ..mesh.springs import NoSpringsError
from ..status import CERTIFIABLE, Status
from .certificate import certify_joint
from .checks import check_joint_unresisted, finish, start_vector
from .configuration import Configuration
from .elastic import elastic_results
from .recasting import follow, recast
from .results import JointSolution, body_results, layer_solutions, ligament_results
from .rows import line_operator
from .states import ContactState, initial_states
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
#: A Newton step that cut the residual by less than this factor makes the next one take a fresh tangent.
_CHORD = 0.25
#: Once a step cut the residual below this fraction of where the springs last changed, the springs
#: near contact follow body 2 to the faces under them (:func:`~dea_opt.joint.recasting.follow`)
#: before the next step.
_FOLLOW = 1e-2


def solve_finite_joint(joint, method: str, *, certificate_tol: float, strict: bool, **options) -> JointSolution:
    """The certified equilibrium of a ``kinematics="finite"`` joint (see :func:`dea_opt.solve`).

    ``method``: ``"auto"`` or ``"newton"`` (each step by the joint's Newton), ``"nlp"`` (by IPOPT);
    the QP is a small-kinematics method. Options: :data:`OPTIONS`, the inner method's, ``x0``
    (the free coordinates' start: translations and rotation vectors, or a
    :class:`~dea_opt.joint.Coordinates`' values), ``contact_states`` (the contacts' springs to
    start from: a previous answer's :attr:`~dea_opt.joint.JointSolution.states`, cast where that
    answer's pose put them; a path's next frame starts there) and ``tangent`` (the exact forces'
    tangent to take the first steps with: a previous answer's ``info["tangent"]``).
    """
    if method == "qp":
        raise InputError(
            "method 'qp' is a small-kinematics method: use 'auto', 'newton' or 'nlp' for kinematics='finite'"
        )
    own = validate("finite joint", OPTIONS, {k: v for k, v in options.items() if k in _OWN})
    inner = {k: v for k, v in options.items() if k not in _OWN and k not in ("x0", "contact_states", "tangent")}
    x0 = start_vector(joint, options.get("x0"))
    states = options.get("contact_states")
    tangent0 = options.get("tangent")
    m = len(joint.free_index)
    if tangent0 is not None:
        tangent0 = np.asarray(tangent0, dtype=float)
        if tangent0.shape != (m, m) or not np.isfinite(tangent0).all():
            raise InputError(
                f"tangent must be a finite ({m}, {m}) matrix over the free dofs: a previous answer's info['tangent']"
            )
    if states is not None and (
        len(states) != len(joint.contacts) or not all(isinstance(s, ContactState) for s in states)
    ):
        raise InputError(
            f"contact_states must be one ContactState per contact ({len(joint.contacts)}): a previous answer's .states"
        )
    name = "nlp" if method == "nlp" else "newton"
    validate(name, joint_newton.OPTIONS if name == "newton" else joint_ipopt.NLP_OPTIONS, inner)
    with single_threaded_blas():
        solution = _solve(joint, name, method, certificate_tol, own, inner, x0, states, tangent0)
    return finish(solution, strict)


def _coordinates(joint, x) -> dict:
    """``{body: 6-vector}`` of coordinates from the free vector ``x`` (prescribed values elsewhere)."""
    return joint.body_u(joint.start() if x is None else x)


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


class _Measure:
    """The scaled residual of the exact forces (the joint Newton's measure), with the scaling of the
    last pose it was updated at: cheap between updates (the forces alone), exact after one."""

    def __init__(self, config: Configuration):
        self.update(config)

    def update(self, config: Configuration) -> None:
        system = config.solver_system()
        if not system.n_dofs:
            self.T, self.E0 = None, 1.0
            return
        scale = joint_scaling(system)
        self.T, self.E0 = scale.T, scale.energy_scale

    def __call__(self, config: Configuration) -> float:
        if self.T is None:
            return 0.0
        q, load = config.forces()
        qt, rt = self.T.T @ q / self.E0, self.T.T @ load / self.E0
        return float(np.linalg.norm(qt - rt)) / max(float(np.linalg.norm(qt)), float(np.linalg.norm(rt)), 1.0)

    def exact(self, config: Configuration) -> float:
        """The measure with the scaling of ``config`` itself."""
        self.update(config)
        return self(config)


def _step(name: str, system, inner: dict, residual: float):
    """One increment at the pose: the small-kinematics energy there, solved from zero; loose while
    far from equilibrium (the next pose moves the elements anyway)."""
    options = dict(inner)
    if name == "newton":
        options["gtol"] = max(options.get("gtol", 1e-12), min(1e-6, 1e-2 * residual))
        return joint_newton.solve(system, **options)
    return joint_ipopt.solve_nlp(system, **options)


def _solve(joint, name, method, tol, own, inner, x0, states=None, tangent0=None) -> JointSolution:
    start = time.perf_counter()
    free = list(joint.free_index)
    x = joint.start() if x0 is None else x0.copy()
    states = tuple(initial_states(joint)) if states is None else tuple(states)
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
    measure = _Measure(config)
    K, last = tangent0, None
    # the residual where the springs last changed, and the steps by then
    changed, changed_at, follows, tangents, casts = None, 0, 0, 0, 0
    stale = False  # the kept tangent is a previous answer's or the springs' before a cast: made again
    while True:
        residual = measure(config)
        if residual <= own["gtol"]:
            residual = measure.exact(config)  # below gtol with its own pose's scaling, or go on
        history.append(residual)
        if not math.isfinite(residual):
            status, message = Status.NON_FINITE, "the forces at the pose are not finite"
            break
        if changed is None:
            changed, changed_at = residual, steps
        if own["recast"] and own["gtol"] < residual <= _FOLLOW * changed and steps > changed_at:
            # on the way to equilibrium the springs near contact take the faces under them: the next
            # steps see the surface as it is there, and the cast where the forces balance changes little
            new = follow(config)
            if new is not None:
                follows += 1
                config = Configuration(joint, config.y, new)
                changed, last = None, None  # the tangent is kept (a few springs' planes changed)
                continue
        if residual <= own["gtol"]:
            try:
                new = recast(config) if own["recast"] else None
            except NoSpringsError as exc:
                # the springs left their targets entirely: the solve ends failed, the springs as they were
                status = Status.MAX_ITERATIONS
                message = f"no spring is left at the solved pose when cast again there: {exc}"
                break
            if new is None:
                status, message = Status.CONVERGED, "the forces balance at the exact pose"
                break
            casts += 1
            config = Configuration(joint, config.y, new)
            if measure.exact(config) <= own["gtol"]:
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
            changed, last, stale = None, None, True
            continue
        if steps >= own["max_steps"]:
            break
        steps += 1
        dx = None
        if name == "newton":
            # the tangent is kept, with Broyden's updates, while each step cuts the residual by 4 or more,
            # else made again
            fresh = K is None or stale or (last is not None and residual > _CHORD * last)
            K = tangent(joint, config.states, x, config, central=False) if fresh else K
            tangents += fresh
            stale = False
            dx = _newton_step(config, K)
            if dx is None and not fresh:
                K = tangent(joint, config.states, x, config, central=False)
                tangents += 1
                dx = _newton_step(config, K)
        last = residual
        if dx is None:
            measure.update(config)
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
        alpha, used, reached = _along(joint, config, x, dx, max(turn, 1e-300))
        evaluations += used
        if K is not None and reached is not None and name == "newton":
            # Broyden's update: the kept tangent made exact along the step just taken (the secant)
            step, change = alpha * dx, reached.net_force() - config.net_force()
            if np.isfinite(change).all() and step @ step > 0:
                K = K + np.outer(change - K @ step, step) / (step @ step)
        x = x + alpha * dx
        y = _coordinates(joint, x) if reached is None else reached.y
        if _ran_away(joint, y, radius):
            status = Status.UNBOUNDED
            message = (
                "the bodies ran away (a turn past 180 deg or a slide past 4 times the joint's extent): nothing in "
                "the joint holds them near the start under this load"
            )
            config = Configuration(joint, y, config.states)
            break
        config = Configuration(joint, y, config.states) if reached is None else reached
    if refused is not None and status not in CERTIFIABLE:
        raise refused
    info = {
        "steps": steps,
        "recasts": recasts,
        "casts": casts,
        "follows": follows,
        "tangents": tangents,
        "line_evaluations": evaluations,
        "tangent_steps": newton_steps,
        "residual_history": history,
        "native_status": str(status),
    }
    return _certified(joint, config, method, status, message, steps, time.perf_counter() - start, tol, info)


def _ran_away(joint, y: dict, radius: float) -> bool:
    """A body whose rotation vector wound past a half turn, or whose elements' centroid moved more
    than 4 times the joint's extent (a reference far from the elements, a femur's at its hip,
    would count a turn about the knee as a slide)."""
    for name, v in y.items():
        if name not in joint.coordinates and np.linalg.norm(v[3:]) > math.pi:
            return True
        T = joint.motion(name, v)
        c = joint.centres[name]
        if np.linalg.norm(T[:3, :3] @ c + T[:3, 3] - c) > 4 * radius:
            return True
    return False


def _newton_step(config: Configuration, K) -> np.ndarray | None:
    """Newton's step on the exact forces, ``K dx = -r`` with ``K`` their tangent by differences, where
    it is a descent direction of their power (``r . dx < 0``); None otherwise (then the step of the
    small kinematics at the pose). The small kinematics' step alone knows the material's stiffness
    but not the geometry's (a condyle's curvature under a load, the turn of a line): it converges,
    slowly, where ``K`` converges in a few steps."""
    r = config.net_force()
    if not (np.isfinite(K).all() and np.isfinite(r).all()):
        return None
    try:
        dx = -np.linalg.solve(K, r)
    except np.linalg.LinAlgError:
        return None
    return dx if float(r @ dx) < 0 else None


def _along(joint, config: Configuration, x, dx, turn: float) -> tuple:
    """``(alpha, evaluations, configuration)``: the step along ``dx`` where the exact forces' power along
    it, ``psi'(alpha) = r(x + alpha dx) . dx``, has fallen to a tenth of its start (the full step where
    it has fallen to half already), and the configuration there where it was made (else None): the
    small-kinematics step at a pose knows the material's stiffness, not how the pose changes the
    geometry (a condyle rolling, a line turning), and the exact forces along its direction decide
    how far to go."""
    states = config.states
    slope0 = float(config.net_force() @ dx)
    if not slope0 < 0:
        return 1.0, 1, None
    limit = _MAX_TURN / turn
    lo, s_lo, hi, s_hi = 0.0, slope0, None, 0.0
    alpha, used = 1.0, 1
    at: dict = {}

    def power(a) -> float:
        c = Configuration(joint, _coordinates(joint, x + a * dx), states)
        at[a] = c
        return float(c.net_force() @ dx)

    for used in range(2, 40):
        s = power(alpha)
        if not np.isfinite(s):
            hi, s_hi = alpha, np.inf
        elif abs(s) <= (0.5 if alpha == 1.0 and hi is None and lo == 0.0 else 0.1) * abs(slope0):
            return alpha, used, at[alpha]
        elif s < 0:
            lo, s_lo = alpha, s
        else:
            hi, s_hi = alpha, s
        if hi is None:
            if alpha >= limit:
                return alpha, used, at[alpha]
            alpha = min(2.0 * alpha, limit)
        elif np.isfinite(s_hi) and s_hi > s_lo:
            # regula falsi between a descending and a rising end, kept inside the bracket
            alpha = lo - s_lo * (hi - lo) / (s_hi - s_lo)
            alpha = min(max(alpha, lo + 0.05 * (hi - lo)), hi - 0.05 * (hi - lo))
        else:
            alpha = 0.5 * (lo + hi)
    final = lo if lo > 0 else alpha
    return final, used, at.get(final)


def _world_forces(config: Configuration, layer_forces, ligament_forces, elastic_forces=()) -> dict:
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
    from .elastic import elastic_groups

    for group, f in zip(elastic_groups(config.joint, config.poses, config.references), elastic_forces):
        q = np.asarray(f) @ group.G
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
    n, n_ligaments = len(joint.contacts), len(joint.ligament_groups)
    on_body = _world_forces(config, forces[:n], forces[n : n + n_ligaments], forces[n + n_ligaments :])
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
        on_body,
        forces[:n],
        [layer.gap / layer.thickness for layer in config.layers],
        common,
        dropped,
    )
    ligaments = ligament_results(config, {k: np.zeros(6) for k in y}, forces, config.insertions)
    value, along, K = stability(config) if success else (None, "", None)
    validity = assess_joint(config, y, ligaments, tuple(c.validity for c in contacts), stability=value, softest=along)
    info = dict(info, stability=value, softest=along, tangent=K)
    bodies = body_results(joint, y, on_body, config.world_loads, config.poses)
    elastic = elastic_results(joint, config.elastic_groups, forces[n + n_ligaments :])
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
        elastic=elastic,
        states=tuple(config.states),
    )


def exact_residual(joint, states, x) -> np.ndarray:
    """The net generalized force on the free coordinates at the pose of ``x`` (N, N mm): the exact
    forces of every element there, minus the loads (``J^T`` of the moments for rotations)."""
    return Configuration(joint, _coordinates(joint, x), states).net_force()


def tangent(joint, states, x, at: Configuration | None = None, central: bool = True) -> np.ndarray:
    """``dr/dx`` of :func:`exact_residual` on the free coordinates by differences (1e-6 mm of the
    elements' motion: rotations over each body's radius), shape (m, m): central, or forward from
    ``at`` (the configuration at ``x``, whose forces are at hand: half the evaluations, an error of
    the order of the step, which a Newton step does not see)."""
    m = len(joint.free_index)
    lengths = joint.lengths
    K = np.zeros((m, m))
    # a step of 1e-6 mm moves no spring whose gap is above 1e-3 mm into contact: only the others count
    here = Configuration(joint, _coordinates(joint, x), states) if at is None else at
    near = here.near(1e-3)
    base = None if central else here.net_force()
    for j, (_, dof) in enumerate(joint.free_index):
        h = 1e-6 if dof[0] == "u" else 1e-6 / lengths[j]
        step = np.zeros(m)
        step[j] = h
        if base is None:
            K[:, j] = (exact_residual(joint, near, x + step) - exact_residual(joint, near, x - step)) / (2 * h)
        else:
            K[:, j] = (exact_residual(joint, near, x + step) - base) / h
    return K


def stability(config: Configuration) -> tuple:
    """``(value, along, K)``: ``-min Re(lambda) / max |lambda|`` over the eigenvalues of the tangent of
    the exact forces on the free coordinates (central differences, rotations over each body's
    radius), above 0 where a disturbance grows; the motion that gives way, in words; the tangent
    ``K`` (N/mm, N, N mm)."""
    joint = config.joint
    free = list(joint.free_index)
    if not free:
        return 0.0, "", None
    x = np.array([config.y[b][DOFS.index(d)] for b, d in free])
    lengths = joint.lengths
    K = tangent(joint, config.states, x, config)
    scaled = K / lengths[:, None] / lengths[None, :]
    if not np.isfinite(scaled).all():
        return float("nan"), "", None
    values, vectors = np.linalg.eig(scaled)
    largest = float(np.abs(values).max())
    if largest == 0.0:
        return 0.0, "", K
    k = int(np.argmin(values.real))
    v = vectors[:, k].real
    v = v / v[np.argmax(np.abs(v))]
    words = [
        f"{b}.{d} {z:+.3g} mm" if d[0] == "u" else f"{b}.{d} {math.degrees(z / length):+.3g} deg"
        for (b, d), z, length in zip(free, v, lengths)
        if abs(z) >= 1e-3
    ]
    return float(-values.real[k] / largest) + 0.0, ", ".join(words), K
