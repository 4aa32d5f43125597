"""Finite kinematics, Newton: the equilibrium of body 2's free coordinates for fixed targets.

Written math: ``formulations/finite.md`` ("Newton"; "Stability" for :func:`escape_step`).
:func:`solve` runs Newton's method on the residual of a
:class:`~dea_opt.formulations.finite.system.FiniteSystem` and returns an :class:`InnerResult`,
the raw answer every finite solve gives (IPOPT's too, :mod:`~dea_opt.formulations.finite.ipopt`),
which :mod:`dea_opt.finite` re-casts and certifies at the solved pose.

The iterate is body 2's free coordinates ``x = x0 + T xi`` (m,; mm and rad) in the scaled
variables of :func:`dea_opt.formulations.scaling` (``T`` (m, k) from the layer at the start
pose). Each iteration solves ``T^T K T dxi = -T^T r`` with the exact (non-symmetric) tangent
``K`` of the residual ``r``, and searches the line with the Wolfe conditions of the small
Newton on ``phi'(a) = r(x + a T dxi) . T dxi``: the power of the net forces along the line, the
derivative of a 1-D energy whatever the forces. Where the Newton direction is no descent (the
tangent's skew part dominates) the symmetric part, then the springs' material stiffness, give
one; where the compressed springs miss a direction, the safe step of the small Newton adds the
stiffness of every spring.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from .._parts.resistance import UNRESISTED, unresisted
from ..newton import _line_search

__all__ = ["InnerResult", "escape_step", "solve"]

_WOLFE_CURVATURE = 0.9
_WOLFE_CURVATURE_SAFE = 0.01
_SAFE_WEIGHT = 1e-3
_CRUSH_WINDOW = 1e-4
#: The scaled residual below which a Newton that no longer reduces it has converged (Eq. 20's).
_ROUNDING = 1e-9
#: The largest turn (rad) of body 2 in a step the line search grew beyond Newton's: steps growing
#: fourfold past it could land turns away, where the line's energy (periodic in the springs',
#: linear in the moment's work) happens to meet the Wolfe conditions; the turn is scanned
#: instead (:func:`_scan`).
_MAX_TURN = 0.5 * np.pi


@dataclass
class InnerResult:
    """What one Newton (or IPOPT) solve with fixed targets found: the result type of finite kinematics.

    Attributes
    ----------
    u_free : ndarray (m,)
        Body 2's free coordinates at the answer (mm, rad).
    state : State
        The springs at the answer (:class:`~dea_opt.formulations.finite.system.State`).
    success : bool
        The solver converged.
    status : str
        The solver's status (``"converged"``, ``"max_iterations"``, ``"unbounded"``, ``"crushed"``, ...), which
        :func:`~dea_opt.formulations.finite.status_of` turns into a :class:`~dea_opt.status.Status`.
    message : str
        What happened, in words.
    iterations : int
        Newton iterations (IPOPT: its iterations over every outer one).
    solve_time : float
        Seconds.
    info : dict
        The solver's own records (Newton's residual history, line evaluations and the kinds of
        direction taken; IPOPT's stresses, its multipliers, as ``info["stress"]``).
    """

    u_free: np.ndarray
    state: object
    success: bool
    status: str
    message: str
    iterations: int = 0
    solve_time: float = 0.0
    info: dict = field(default_factory=dict)


class _Line:
    """``phi'(a) = r(x + a d) . d`` (scaled), one pass over the springs per evaluation; ``phi`` is its
    integral from 0 (Simpson's rule on the cached slopes), used only to accept a slight overshoot."""

    def __init__(self, system, law, x, direction, energy_scale, slope0):
        self.system, self.law, self.x, self.d = system, law, x, direction
        self.scale, self.slope0 = energy_scale, slope0
        self._cache: dict = {}

    def slope(self, alpha):
        if alpha in self._cache:
            return self._cache[alpha]
        state = self.system.state(self.system.coordinates(self.x + alpha * self.d), self.law)
        if state.crushed or not state.finite:
            out = (np.inf, state)  # beyond the law's domain, or a target lost edge-on: an overshoot
        else:
            value = float(state.residual() @ self.d) / self.scale
            out = (value if np.isfinite(value) else np.inf, state)
        self._cache = {alpha: out}
        return out

    def phi(self, alpha) -> float:
        if alpha == 0:
            return 0.0
        end = self.slope(alpha)[0]
        middle = self.slope(0.5 * alpha)[0]
        value = alpha * (self.slope0 + 4.0 * middle + end) / 6.0
        return value if np.isfinite(value) else np.inf

    energy = phi  # the name the small Newton's line search used before the registry


#: Body 2's coordinates ``y`` of a FiniteSystem, in order (``system.free`` indexes them).
_COORDINATES = ("ux", "uy", "uz", "rx", "ry", "rz")


#: Points a turn the scan of a rotating line looks at (one a degree).
_SCAN_POINTS = 360


def _scan(line, free, slope0, curvature) -> tuple:
    """``(a, state, evaluations)``: a step on a line along which the steps of the line search,
    growing fourfold, found ``phi`` descending steeply up to
    :data:`~dea_opt.formulations.newton.UNBOUNDED_STEP`, or found a step that turns body 2 past
    :data:`_MAX_TURN`.

    Along a line that turns body 2, the springs' energy is bounded (a turn brings every spring
    back) while a moment's work grows without bound, so ``Phi`` does decrease without bound; but
    a contact that resists the turn over a few degrees can lie between two of those steps. The
    line is looked at one degree apart over one turn (or, for a line that only slides body 2, not
    at all: there the springs' energy grows without bound where they resist); where ``phi'``
    rises above the Wolfe band, the step is found by bisection. ``a`` is None where nothing
    resists anywhere on the turn."""
    turn = float(np.linalg.norm(line.d[np.asarray(free) >= 3]))  # rad a unit step turns body 2
    if not turn > 0:
        return None, None, 0
    upper_ok, lower_ok = 1e-4 * slope0, curvature * slope0
    lo, hi, used = 0.0, None, 0
    for a in np.linspace(0.0, 2.0 * np.pi / turn, _SCAN_POINTS + 1)[1:]:
        value, trial = line.slope(float(a))
        used += 1
        if value > upper_ok:
            hi = float(a)
            break
        if value >= lower_ok:
            return float(a), trial, used
        lo = float(a)
    if hi is None:
        return None, None, used
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        value, trial = line.slope(mid)
        used += 1
        if value > upper_ok:
            hi = mid
        elif value < lower_ok:
            lo = mid
        else:
            return mid, trial, used
    if lo == 0.0:
        return None, None, used
    value, trial = line.slope(lo)
    return lo, trial, used + 1


#: The first step (in units of the motion, whose largest part moves the springs 1 mm) and the
#: number of doublings :func:`escape_step` tries on each side of an unstable equilibrium.
_ESCAPE_FIRST, _ESCAPE_DOUBLINGS = 1e-3, 24


def escape_step(system, law, x, motion, energy_scale, radius) -> np.ndarray | None:
    """A start away from the unstable equilibrium ``x``: the lowest point of the energy along ``motion``.

    At an equilibrium where the tangent's symmetric part has a negative eigenvalue, the energy
    falls on both sides along its eigenvector ``motion`` (m,; mm and rad, its largest part moving
    the springs 1 mm): Newton, which stops where the forces balance, stopped at a saddle or a
    crest of the energy. On each side the steps double from ``_ESCAPE_FIRST`` while ``phi'`` (the
    power of the net forces, :class:`_Line`) stays negative and body 2 turns less than
    :data:`_MAX_TURN` and slides less than 4 ``radius`` (where a solve has run away,
    :func:`~dea_opt.finite.outcome.ran_away`); where ``phi'`` turns
    positive the energy has a minimum along the line, found by bisection. Of the two sides, the
    lower one (``phi`` by the trapezoidal rule on the slopes looked at). None where the energy
    falls all the way on both sides, or rises at once (the answer is kept, and the ``stability``
    check fails it).

    Parameters
    ----------
    system : FiniteSystem
    law : Law
    x : ndarray (m,)
        The free coordinates of the equilibrium (mm, rad).
    motion : ndarray (m,)
        The direction that gives way (:func:`~dea_opt.finite.stability.softest_mode`).
    energy_scale : float
        ``E0`` (N mm): the slopes are divided by it.
    radius : float
        The springs' RMS radius about body 2's reference (mm).
    """
    free = np.asarray(system.free)
    turn = float(np.linalg.norm(motion[free >= 3]))
    slide = float(np.linalg.norm(motion[free < 3]))
    reach = min(_MAX_TURN / turn if turn > 0 else np.inf, 4.0 * radius / slide if slide > 0 else np.inf)
    best, lowest = None, 0.0
    for sign in (1.0, -1.0):
        line = _Line(system, law, x, sign * motion, energy_scale, 0.0)
        lo, slope_lo, a, energy = 0.0, 0.0, _ESCAPE_FIRST, 0.0
        for _ in range(_ESCAPE_DOUBLINGS):
            if a > reach:
                break
            value = line.slope(a)[0]
            if not np.isfinite(value) or value >= 0.0:
                lo, slope_lo, energy = _bisect(line, lo, a, slope_lo, energy)
                if lo > 0.0 and energy < lowest:
                    best, lowest = x + lo * sign * motion, energy
                break
            energy += 0.5 * (a - lo) * (slope_lo + value)
            lo, slope_lo, a = a, value, 2.0 * a
    return best


def _bisect(line, lo, hi, slope_lo, energy) -> tuple[float, float, float]:
    """``(a, slope, phi)``: where ``phi'`` crosses 0 between ``lo`` (below 0) and ``hi`` (at or above 0,
    or beyond the law's domain), and ``phi`` there (``energy`` at ``lo`` plus the trapezoid)."""
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        value = line.slope(mid)[0]
        if np.isfinite(value) and value < 0.0:
            energy += 0.5 * (mid - lo) * (slope_lo + value)
            lo, slope_lo = mid, value
        else:
            hi = mid
    return lo, slope_lo, energy


def _unbounded(system, direction) -> str:
    """Why the solve stopped where the energy decreases without bound along ``direction`` (m,)."""
    size = np.abs(direction)
    parts = [
        f"{_COORDINATES[i]} {v / size.max():+.3g}" for i, v in zip(system.free, direction) if abs(v) > 1e-3 * size.max()
    ]
    return (
        f"the energy decreases without bound along the search direction ({', '.join(parts)}), looked at over a "
        f"whole turn: the load does more work than the springs resist that way, as when it turns or slides "
        f"the surfaces along each other (a sphere turning about its own centre); hold those dofs, or give "
        f"them the loads that hold them (in a joint, the ligaments)"
    )


def _direction(K, g, material) -> tuple[np.ndarray, bool]:
    """``(d, safe)``: ``-K^{-1} g``, its pseudo-inverse where ``g`` lies in ``K``'s range, else a safe
    step ``-(K + 1e-3 K_all)^{-1} g`` (``K_all`` the material stiffness of every spring)."""
    if not g.size:
        return g.copy(), False
    if not (np.isfinite(K).all() and np.isfinite(g).all()):
        return np.full_like(g, np.nan), False
    U, sv, Vt = np.linalg.svd(K)
    keep = ~unresisted(sv, max(float(sv[0]), 1.0))
    if keep.all():
        return -np.linalg.solve(K, g), False
    coeff = U[:, keep].T @ g
    outside = g - U[:, keep] @ coeff
    if keep.any() and np.linalg.norm(outside) <= 1e-9 * np.linalg.norm(g):
        return -(Vt[keep].T @ (coeff / sv[keep])), False
    K = K + _SAFE_WEIGHT * material()
    try:
        return -np.linalg.solve(K, g), True
    except np.linalg.LinAlgError:
        return -np.linalg.lstsq(K, g, rcond=UNRESISTED)[0], True


def _descent(K, g, material) -> tuple[np.ndarray, bool, str]:
    """A direction with ``g . d < 0``: Newton's, else the symmetric part's, else the material one's."""
    d, safe = _direction(K, g, material)
    if g @ d < 0:
        return d, safe, "newton"
    d, safe = _direction(0.5 * (K + K.T), g, material)
    if g @ d < 0:
        return d, safe, "symmetric"
    Km = material()
    try:
        d = -np.linalg.solve(Km + _SAFE_WEIGHT * np.trace(Km) / max(len(g), 1) * np.eye(len(g)), g)
    except np.linalg.LinAlgError:
        d = -g
    return d, True, "material"


def solve(
    system,
    law,
    T,
    energy_scale,
    *,
    x0,
    xtol=1e-12,
    gtol=1e-12,
    max_iter=100,
    extended_start=True,
    cold=True,
    start_state=None,
) -> InnerResult:
    """Newton's method on the finite-kinematics residual of ``system`` (targets fixed).

    Parameters
    ----------
    system : FiniteSystem
    law : Law
    T : ndarray (m, k)
        The scaled directions: ``x = x0 + T xi``.
    energy_scale : float
        ``E0`` (N mm): residuals are divided by it in the scaled variables.
    x0 : ndarray (m,)
        Start (mm, rad).
    cold : bool
        ``x0`` is no warm start: the first iteration may use the extended range.
    start_state : State, optional
        ``system.state`` at ``x0`` when the caller has it (an update of the springs computes it).
    """
    start = time.perf_counter()
    free = system.free
    x = np.array(x0, dtype=float)
    state = system.state(system.coordinates(x), law) if start_state is None else start_state
    status, message, success = "max_iterations", f"no convergence in {max_iter} iterations", False
    history, evaluations, kinds = [], 0, []
    previous_active = None
    scaled = np.linalg.pinv(T) if T.size else None  # x - x0 = T xi: xi, the step's scaled size (one SVD a solve)
    it = 0
    for it in range(1, max_iter + 1):
        if not state.finite:
            status, message = "non_finite", "the law returned a non-finite stress, or a target was lost edge-on"
            break
        g = T.T @ state.residual() / energy_scale
        norm = max(
            float(np.linalg.norm(T.T @ state.load6[free])) / energy_scale,
            float(np.linalg.norm(T.T @ state.internal6[free])) / energy_scale,
            1.0,
        )
        gnorm = float(np.linalg.norm(g)) / norm
        history.append(gnorm)
        if gnorm <= gtol:
            status, message, success = "converged", "equilibrium residual below gtol", True
            break
        if gnorm <= _ROUNDING and len(history) > 1 and gnorm >= history[-2]:
            # no longer decreasing, at a level Eq. (20) accepts too: the rounding of the springs'
            # sums (a tiny load's strains against the positions' digits), not a gtol it can reach
            status, message, success = "converged", f"equilibrium residual {gnorm:.1e}, its rounding level", True
            break

        def material(state=state):
            return T.T @ state.material() @ T / energy_scale

        d = None
        if it == 1 and extended_start and cold:
            bilateral = system.state(state.y, law, bilateral=True)
            if bilateral.finite:
                Kb = T.T @ bilateral.tangent() @ T / energy_scale
                d, safe = _direction(Kb, T.T @ bilateral.residual() / energy_scale, material)
                kind = "extended"
                if not (np.isfinite(d).all() and g @ d < 0):
                    d = None  # no descent for the unilateral problem
        if d is None:
            K = T.T @ state.tangent() @ T / energy_scale
            d, safe, kind = _descent(K, g, material)
        kinds.append(kind)
        turn = float(np.linalg.norm((T @ d)[np.asarray(free) >= 3]))
        if turn > _MAX_TURN:  # a near-singular tangent's leap: no local model reaches that far
            d = d * (_MAX_TURN / turn)
        slope = float(g @ d)
        if not (np.isfinite(slope) and slope < 0):
            status, message = "stalled", "no descent direction (a load along a direction no spring resists?)"
            break
        Td = T @ d
        line = _Line(system, law, x, Td, energy_scale, slope)
        alpha, trial, used = _line_search(line, slope, _WOLFE_CURVATURE_SAFE if safe else _WOLFE_CURVATURE)
        if alpha is not None and alpha > 1.0 and alpha * float(np.linalg.norm(Td[np.asarray(free) >= 3])) > _MAX_TURN:
            alpha = np.inf  # a grown step that turns body 2 past a quarter turn: look at the turn closely
        evaluations += used
        if alpha is None:
            status, message = "line_search_failed", "the line search found no acceptable step"
            break
        if not np.isfinite(alpha):  # steps growing fourfold may leap a turn's contact: look closely
            alpha, trial, used = _scan(line, system.free, slope, _WOLFE_CURVATURE_SAFE if safe else _WOLFE_CURVATURE)
            evaluations += used
            if alpha is None:
                status, message = "unbounded", _unbounded(system, Td)
                break
        step = alpha * Td
        x = x + step
        state = trial
        active = state.eps < 0
        settled = previous_active is not None and np.array_equal(active, previous_active)
        previous_active = active
        scaled_step = float(np.linalg.norm(alpha * d))
        size = float(np.linalg.norm(scaled @ (x - x0))) if T.size else 0.0
        if alpha == 1.0 and settled and scaled_step <= xtol * max(size, 1e-300):
            g = T.T @ state.residual() / energy_scale
            norm = max(
                float(np.linalg.norm(T.T @ state.load6[free])) / energy_scale,
                float(np.linalg.norm(T.T @ state.internal6[free])) / energy_scale,
                1.0,
            )
            if float(np.linalg.norm(g)) / norm <= max(gtol, _ROUNDING):
                status, message, success = "converged", "step below xtol (Eq. 20)", True
                break
    if not success and law.bounded_strain and state.eps[state.gaps.valid].min(initial=0.0) < -1 + _CRUSH_WINDOW:
        # what the iterates met, not a verdict on the load: dea_opt.finite.verdict proves one or says so
        status = "crushed"
        message = f"{message}; springs reach eps = {state.eps.min():.6f}, crushed through their thickness on the way"
    return InnerResult(
        x,
        state,
        success,
        status,
        message,
        it,
        time.perf_counter() - start,
        {"residual_history": history, "line_evaluations": evaluations, "directions": kinds},
    )
