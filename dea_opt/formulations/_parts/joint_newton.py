"""Newton on a whole joint's energy: the two-body Newton, block by block.

Written math: ``formulations/joint.md`` ("Newton"). The gradient ``g = q - r`` and the tangent
``K = sum_g A_g^T diag(V sigma') A_g`` over the active elements (springs in compression, bundles
in tension) are assembled from each group's rows over its own bodies' dofs
(:func:`~dea_opt.formulations.joint.assemble`), then solved in the joint's scaled variables with
the same step, safe step and Wolfe line search as the two-body Newton
(:mod:`dea_opt.formulations.newton`, whose pieces are reused as they are).
"""

from __future__ import annotations

import time

import numpy as np

from ..._checks.threads import single_threaded_blas
from ..joint import JointResult, JointSystem, assemble, internal_force, joint_scaling
from ..newton import _WOLFE_CURVATURE, _WOLFE_CURVATURE_SAFE, NATIVE_STATUS, _line_search, _solve_step
from .crush import CRUSH_WINDOW
from .options import Option, newton_tolerances, validate
from .resistance import require_finite

#: Newton's options for a joint (the two-body Newton's, checked the same way).
OPTIONS = (
    *newton_tolerances("the active sets are"),
    Option("max_iter", int, 100, "iteration limit", range=(1, None)),
    Option("extended_start", bool, True, "every element two-sided in the first iteration of a cold start"),
)


def _step(K, g, every, stalled: bool) -> tuple[np.ndarray, bool]:
    """The two-body Newton's step; once the residual has stalled, the regularised step
    ``-(K + mu I)^-1 g`` with ``mu`` the scaled residual's size instead.

    In the scaled variables the bonded stiffness is the identity, so ``mu I`` is a fraction of
    every element's stiffness: a descent direction whatever ``K`` misses, and Newton's as the
    residual vanishes. Where an answer leaves springs at exactly zero strain, the safe step can
    rock between two steps without converging (seen on random joints, and by the two-body Newton
    on the same springs); the regularised step converges there.
    """
    if not stalled:
        return _solve_step(K, g, every)
    mu = max(float(np.linalg.norm(g)), 1e-12)
    require_finite("Newton's tangent", K, g)
    return -np.linalg.solve(K + mu * np.eye(K.shape[0]), g), False


#: Newton counts as stalled when its residual fell by less than half over this many iterations.
_STALL = 8


def _stalled(history) -> bool:
    return len(history) > _STALL and history[-1] > 0.5 * min(history[-_STALL - 1 : -1])


class _Line:
    """``phi'(a) = g(x + a d) . d`` along one direction, over every group (energies over E0)."""

    def __init__(self, system: JointSystem, strains, rates, rd: float, E0: float):
        self.system, self.eps, self.rates, self.rd, self.E0 = system, strains, rates, rd, E0

    def phi(self, alpha) -> float:
        with np.errstate(over="ignore", invalid="ignore"):
            value = sum(
                float(g.volume @ g.energy(e + alpha * r)) for g, e, r in zip(self.system.groups, self.eps, self.rates)
            )
        value = (value - alpha * self.rd) / self.E0
        return value if np.isfinite(value) else np.inf

    def touch(self, alpha) -> float | None:
        """The step from which an inactive element whose strain moves toward activity becomes
        active, or None where none does (then the energy falls without bound along the line)."""
        steps = []
        for g, e, r in zip(self.system.groups, self.eps, self.rates):
            size = float(np.abs(r).max(initial=0.0))
            if g.two_sided:
                if size > 0:
                    steps.append(alpha)  # two-sided rows resist the line at once
                continue
            toward = r < -1e-12 * size if g.contact else r > 1e-12 * size
            if toward.any():
                steps.append(float((-e[toward] / r[toward]).min()))
        return max(min(steps), alpha) if steps else None

    def slope(self, alpha):
        trial = [e + alpha * r for e, r in zip(self.eps, self.rates)]
        total = -self.rd
        for g, t, r in zip(self.system.groups, trial, self.rates):
            if g.bounded and t.min(initial=0.0) <= -1.0:
                return np.inf, trial  # beyond the law's domain: an overshoot
            total += float((g.volume * g.stress(t)) @ r)
        total /= self.E0
        return (total if np.isfinite(total) else np.inf), trial


def solve(system: JointSystem, *, x0=None, **options) -> JointResult:
    """Minimise the joint's energy from ``x0`` (mm, rad; default cold) by Newton.

    Options: :data:`OPTIONS` (``xtol``, ``gtol``, ``max_iter``, ``extended_start``).
    """
    checked = validate("newton", OPTIONS, options)
    with single_threaded_blas():
        return _solve(system, x0, **checked)


def _solve(system: JointSystem, x0, *, xtol, gtol, max_iter, extended_start) -> JointResult:
    start = time.perf_counter()
    scale = joint_scaling(system)
    T, E0 = scale.T, scale.energy_scale
    groups = system.groups
    r = system.load
    rt = T.T @ r / E0
    k = T.shape[1]
    xi = np.zeros(k) if x0 is None else scale.to_xi(x0)
    x = T @ xi
    eps = system.strains(x)
    if any(g.bounded and (e <= -1).any() for g, e in zip(groups, eps)):
        xi, x = np.zeros(k), np.zeros(system.n_dofs)  # a start outside a law's domain is no start
        eps = system.strains(x)
    previous = None
    status, message, success = "max_iter", f"no convergence in {max_iter} iterations", False
    history, evaluations, it = [], 0, 0
    for it in range(1, max_iter + 1):
        sigma = [g.stress(e) for g, e in zip(groups, eps)]
        qt = T.T @ internal_force(system, sigma) / E0
        gt = qt - rt
        norm = max(float(np.linalg.norm(rt)), float(np.linalg.norm(qt)), 1.0)
        gnorm = float(np.linalg.norm(gt)) / norm
        if not np.isfinite(gnorm):
            status, message = "nan", "a law returned a non-finite stress"
            break
        history.append(gnorm)
        if gnorm <= gtol:
            status, message, success = "converged", "equilibrium residual below gtol", True
            break

        def every(eps=eps):
            return assemble(system, [g.volume * g.every_tangent(e) for g, e in zip(groups, eps)], T) / E0

        d = None
        if it == 1 and extended_start and x0 is None:
            with np.errstate(over="ignore", invalid="ignore"):
                pairs = [g.bilateral(e) for g, e in zip(groups, eps)]
                bilateral = T.T @ internal_force(system, [p[0] for p in pairs]) / E0 - rt
                K = assemble(system, [g.volume * p[1] for g, p in zip(groups, pairs)], T) / E0
            if np.isfinite(K).all() and np.isfinite(bilateral).all():
                d, safe = _step(K, bilateral, every, False)
                if not (gt @ d < 0):
                    d = None  # the two-sided step is no descent for the one-sided energy
        if d is None:
            K = assemble(system, [g.volume * g.tangent(e) for g, e in zip(groups, eps)], T) / E0
            if not np.isfinite(K).all():
                status, message = "nan", "a law returned a non-finite tangent"
                break
            d, safe = _step(K, gt, every, _stalled(history))
        slope = float(gt @ d)
        if not slope < 0:
            status, message = "stalled", "no descent direction (a load along a direction no element resists?)"
            break
        dx = T @ d
        rates = [g.rate(dx) for g in groups]
        line = _Line(system, eps, rates, float(r @ dx), E0)
        alpha, trial, used = _line_search(line, slope, _WOLFE_CURVATURE_SAFE if safe else _WOLFE_CURVATURE)
        evaluations += used
        if alpha is None or not np.isfinite(alpha):
            status, message = "line_search", "the line search found no acceptable step"
            if alpha is not None:
                message = "the energy decreases without bound along the search direction (the load does work no element resists)"
            break
        step = alpha * d
        xi = xi + step
        eps = trial
        active = [g.active(e) for g, e in zip(groups, eps)]
        settled = previous is not None and all(np.array_equal(a, b) for a, b in zip(active, previous))
        previous = active
        if alpha == 1.0 and settled and np.linalg.norm(step) <= xtol * max(float(np.linalg.norm(xi)), 1e-300):
            sigma = [g.stress(e) for g, e in zip(groups, eps)]
            qt = T.T @ internal_force(system, sigma) / E0
            norm = max(float(np.linalg.norm(rt)), float(np.linalg.norm(qt)), 1.0)
            if np.linalg.norm(qt - rt) / norm <= max(gtol, 1e-9):
                status, message, success = "converged", "step below xtol", True
                break
    crushed = [float(e.min()) for g, e in zip(groups, eps) if g.bounded and e.size and e.min() < -1 + CRUSH_WINDOW]
    if not success and crushed:
        status = "crushed"
        message = (
            f"{message}; springs reach eps = {min(crushed):.6f}, crushed through their thickness before the load "
            f"is carried: the load is beyond what this layer can bear"
        )
    return JointResult(
        x=T @ xi,
        stresses=[g.stress(e) for g, e in zip(groups, eps)],
        success=success,
        status=NATIVE_STATUS[status],
        message=message,
        iterations=it,
        solve_time=time.perf_counter() - start,
        info={"native_status": status, "residual_history": history, "line_evaluations": evaluations},
    )
