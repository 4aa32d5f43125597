"""Newton active set: the paper's Eq. (12)-(20), made globally convergent.

Written math: ``formulations/newton.md``. Each iteration evaluates the strains once,
builds the gradient ``g = A^T (V sigma(min(eps, 0))) - r`` (Eq. 12) and the closed-form
tangent ``K = A_act^T diag(V_i sigma'(eps_i)) A_act`` over the compressed springs
(Eq. 15-18, one matrix product), solves ``K d = -g`` (Eq. 19) and backtracks on ``Phi``
(Armijo). The first iteration treats every spring as active (the paper's extended
range), which also starts problems whose gaps are all open; when the active tangent is
singular the all-spring tangent is added, which keeps ``d`` a descent direction.
"""

from __future__ import annotations

import time

import numpy as np

from .base import FormulationResult, SpringSystem

PAGE = "formulations/newton.md"
LINEAR_ONLY = False

_ARMIJO = 1e-4
_SINGULAR = 1e-11  # eigenvalue ratio below which a tangent direction counts as missing


def _energy(law, volume, eps) -> float:
    return float(volume @ law.energy(np.minimum(eps, 0.0)))


def _tangent(AT, weight) -> np.ndarray:
    """``AT diag(weight) AT^T``, shape (m, m): Eq. (16) as one matrix product."""
    return (AT * weight) @ AT.T


def _resisted_basis(K_all) -> np.ndarray:
    """Orthonormal basis (m, k) of the directions some spring resists."""
    vals, vecs = np.linalg.eigh(K_all)
    top = vals[-1] if vals.size else 0.0
    return vecs[:, vals > _SINGULAR * max(top, 0.0)]


def _solve_step(K, g, Q, K_all_fn) -> np.ndarray:
    """``-K^+ g`` within the resisted directions ``Q``.

    Where the active tangent misses one of them (too few springs in contact), ``K + K_all``
    is used instead, which keeps the step a descent direction.
    """
    if Q.shape[1] == 0:
        return np.zeros_like(g)
    Kr, gr = Q.T @ K @ Q, Q.T @ g
    vals = np.linalg.eigvalsh(Kr)
    if vals[-1] <= 0 or vals[0] <= _SINGULAR * vals[-1]:
        Kr = Kr + Q.T @ K_all_fn() @ Q
    try:
        return -(Q @ np.linalg.solve(Kr, gr))
    except np.linalg.LinAlgError:
        return -(Q @ np.linalg.lstsq(Kr, gr, rcond=_SINGULAR)[0])


def solve(
    system: SpringSystem,
    law,
    *,
    x0=None,
    xtol: float = 1e-12,
    gtol: float = 1e-12,
    max_iter: int = 100,
    extended_start: bool = True,
) -> FormulationResult:
    """Minimize ``Phi`` by a damped semismooth Newton method with an active set.

    Parameters
    ----------
    system : SpringSystem
    law : Law
    x0 : ndarray, shape (m,), optional
        Warm start (e.g. the previous frame of a load path); default zeros (Eq. 19).
    xtol : float
        Relative step of Eq. (20) that counts as converged once the contact set is
        unchanged (the paper uses 1e-6).
    gtol : float
        Relative equilibrium residual ``|g| / max(|r|, |A^T V sigma|)`` that counts as
        converged.
    max_iter : int
    extended_start : bool
        Treat every spring as active in the first iteration.
    """
    start = time.perf_counter()
    AT, e0, V, r = system.AT, system.e0, system.volume, system.load
    m = AT.shape[0]
    x = np.zeros(m) if x0 is None else np.array(x0, dtype=float)
    eps = e0 + x @ AT
    if law.bounded_strain and (eps <= -1).any():
        x = np.zeros(m)  # a warm start outside the law's domain is no start
        eps = e0.copy()
    phi = _energy(law, V, eps) - r @ x
    previous_active = None
    Q = None
    status, message, success = "max_iter", f"no convergence in {max_iter} iterations", False
    history = []
    it = 0
    for it in range(1, max_iter + 1):
        compressed = np.minimum(eps, 0.0)
        sigma = law.stress(compressed)
        internal = AT @ (V * sigma)
        g = internal - r
        scale = max(np.linalg.norm(r), np.linalg.norm(internal), 1e-300)
        gnorm = np.linalg.norm(g) / scale
        if not np.isfinite(gnorm):
            status, message = "nan", "the law returned a non-finite stress"
            break
        history.append(gnorm)
        if gnorm <= gtol and it > 1:
            status, message, success = "converged", "equilibrium residual below gtol", True
            break

        def all_springs():
            return _tangent(AT, V * law.tangent(compressed))

        if Q is None:
            # Directions no spring resists carry no load (checked before any method runs
            # or after a failure); leaving them out keeps the Newton steps undamped.
            K_all = all_springs()
            Q = _resisted_basis(K_all)
        if it == 1 and extended_start:
            K = K_all
        else:
            rows = np.flatnonzero(eps < 0)
            K = _tangent(AT[:, rows], V[rows] * law.tangent(compressed[rows])) if rows.size else np.zeros((m, m))
        if not np.isfinite(K).all():
            status, message = "nan", "the law returned a non-finite tangent"
            break
        d = _solve_step(K, g, Q, all_springs)
        slope = g @ d
        if slope >= 0 or not np.any(d):
            # No descent direction is left: the gradient lies in directions nothing resists.
            status, message = "stalled", "no descent direction (unsupported load direction?)"
            break
        Ad = d @ AT
        alpha, accepted = 1.0, False
        rounding = abs(slope) <= 1e-14 * max(abs(phi), 1e-300)
        for _ in range(60):
            trial = eps + alpha * Ad
            phi_trial = _energy(law, V, trial) - r @ (x + alpha * d)
            if np.isfinite(phi_trial) and (
                phi_trial <= phi + _ARMIJO * alpha * slope or (rounding and phi_trial <= phi + 1e-13 * abs(phi))
            ):
                accepted = True
                break
            alpha *= 0.5
        if not accepted:
            if gnorm <= 1e3 * gtol or rounding:
                status, message, success = "converged", "step below rounding of Phi", True
            elif law.bounded_strain and eps.min() < -1 + 1e-6:
                status, message = "crushed", (
                    "the springs reach eps = -1 (crushed through their thickness) before the load "
                    "is carried: the load is beyond what this layer can bear")
            else:
                status, message = "line_search", "the line search found no decrease of Phi"
            break
        step = alpha * d
        x = x + step
        eps = trial
        phi = phi_trial
        new_active = eps < 0
        settled = previous_active is not None and np.array_equal(new_active, previous_active)
        previous_active = new_active
        if alpha == 1.0 and settled and np.linalg.norm(step) <= xtol * max(np.linalg.norm(x), 1e-300):
            # Eq. (20) with the contact set unchanged: one more residual check confirms.
            internal = AT @ (V * law.stress(np.minimum(eps, 0.0)))
            scale = max(np.linalg.norm(r), np.linalg.norm(internal), 1e-300)
            if np.linalg.norm(internal - r) / scale <= max(gtol, 1e-9):
                status, message, success = "converged", "step below xtol (Eq. 20)", True
                break
    if not success and law.bounded_strain and eps.min(initial=0.0) < -1 + 1e-4:
        status, message = "crushed", (
            f"{message}; springs reach eps = {eps.min():.6f}, crushed through their thickness before "
            f"the load is carried: the load is beyond what this layer can bear")
    stress = law.stress(np.minimum(eps, 0.0))
    return FormulationResult(
        x=x,
        stress=stress,
        success=success,
        status=status,
        message=message,
        iterations=it,
        solve_time=time.perf_counter() - start,
        info={"residual_history": history},
    )
