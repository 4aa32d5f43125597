"""One-sided derivatives at springs on the edge of contact: a small piecewise-quadratic problem.

Written math: ``formulations/sensitivity.md`` ("One-sided derivatives"). Used by
:mod:`dea_opt.sensitivity`; works in the resisted basis ``xi`` (k <= 12 unknowns), every column
of parameters at once.
"""

from __future__ import annotations

import numpy as np

from ..formulations._parts.resistance import unresisted

__all__ = ["edge_solve", "pinv_solve"]


def pinv_solve(K, rhs):
    """``K^+ rhs`` over the directions :func:`unresisted` keeps, and the columns of ``rhs`` with a
    part outside them (no derivative exists: the motion would jump)."""
    vals, vecs = np.linalg.eigh(K)
    keep = ~unresisted(vals, max(float(vals[-1]) if vals.size else 0.0, 1.0))
    coeff = vecs.T @ rhs
    sol = vecs[:, keep] @ (coeff[keep] / vals[keep, None])
    size = np.maximum(np.linalg.norm(rhs, axis=0), 1e-300)
    lost = np.linalg.norm(coeff[~keep], axis=0) > 1e-9 * size
    return sol, lost


def edge_solve(Ks, c, a, w, b, mode="auto", max_rounds=60):
    """``dxi`` (k, q), the edge springs' states (E, q) and the columns with no derivative.

    Column j solves ``(Ks + sum_{e in S} w_e a_e a_e^T) dxi = -(c_j + sum_{e in S} w_e b_ej a_e)``
    with ``S`` the edge springs whose strain rate ``a_e . dxi + b_ej`` is negative
    (formulations/sensitivity.md, "One-sided derivatives"): the minimizer of the convex
    ``psi(dxi) = dxi^T Ks dxi / 2 + c_j . dxi + sum_e w_e min(a_e . dxi + b_ej, 0)^2 / 2``.
    Active-set rounds from "every edge spring in" (columns grouped by state) settle almost
    every column; a column whose rounds cycle or meet a singular tangent is minimized by a damped
    Newton method. ``mode`` ``"in"``/``"out"`` holds every edge spring in/out instead.
    """
    k, q = c.shape
    E = a.shape[1]
    state = np.full((E, q), mode != "out")

    def solve(state):
        dxi, lost = np.zeros((k, q)), np.zeros(q, dtype=bool)
        patterns, inverse = np.unique(state.T, axis=0, return_inverse=True)
        for p, pattern in enumerate(patterns):
            cols = np.flatnonzero(inverse.reshape(-1) == p)
            aw = a[:, pattern] * w[pattern]
            sol, bad = pinv_solve(Ks + aw @ a[:, pattern].T, c[:, cols] + aw @ b[pattern][:, cols])
            dxi[:, cols], lost[cols] = -sol, bad
        return dxi, lost

    dxi, lost = solve(state)
    if mode != "auto":
        return dxi, state, lost
    for _ in range(max_rounds):
        new = (a.T @ dxi + b) < 0
        changed = np.any(new != state, axis=0) & ~lost
        if not changed.any():
            break
        state = np.where(changed, new, state)
        dxi, lost = solve(state)
    unsettled = np.any(((a.T @ dxi + b) < 0) != state, axis=0) | lost
    if unsettled.any():
        for j in np.flatnonzero(unsettled):
            d = _damped(Ks, c[:, j], a, w, b[:, j])
            state[:, j] = (a.T @ d + b[:, j]) < 0
        dxi, lost = solve(state)
    return dxi, state, lost


def _damped(Ks, c, a, w, b):
    """Minimize the piecewise quadratic ``psi`` of :func:`edge_solve` for one column from 0:
    regularized Newton steps, each with an exact line search (``psi``'s slope along a line is
    increasing and piecewise linear), to the pattern of edge springs in contact."""

    def grad(z):
        return Ks @ z + c + a @ (w * np.minimum(a.T @ z + b, 0.0))

    d = np.zeros(len(c))
    scale = max(float(np.trace(Ks)), float(w @ np.sum(a * a, axis=0)), 1e-300)
    for _ in range(200):
        g = grad(d)
        inside = (a.T @ d + b) < 0
        Hs = Ks + (a[:, inside] * w[inside]) @ a[:, inside].T + 1e-10 * scale * np.eye(len(d))
        step = -np.linalg.solve(Hs, g)
        if not g @ step < 0:
            break
        lo, hi = 0.0, 1.0
        while grad(d + hi * step) @ step < 0 and hi < 1e12:
            lo, hi = hi, 4 * hi
        for _ in range(80):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if grad(d + mid * step) @ step < 0 else (lo, mid)
        d = d + hi * step
    return d
