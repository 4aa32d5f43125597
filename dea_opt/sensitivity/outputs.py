"""The outputs' derivatives from the motion rates: pressures, strains, the peak, the contact area's
rate over a band of springs near zero strain, and the per-spring parameters' (N, N) fields.

Written math: ``formulations/sensitivity.md``. :func:`dea_opt.sensitivity.sensitivities` solves
for the motion rates (:mod:`dea_opt.sensitivity.derivatives`); this module turns them into every
output's derivative.
"""

from __future__ import annotations

import numpy as np

__all__ = ["band", "outputs", "peak_set"]


def peak_set(pressure) -> np.ndarray:
    """The springs that share the peak pressure (to rounding)."""
    top = float(pressure.max(initial=0.0))
    return np.flatnonzero(pressure >= top * (1 - 1e-12)) if top > 0 else np.zeros(0, dtype=int)


def band(layer, eps, strict, area_band) -> tuple:
    """``(springs in the band, half-width delta)`` of the contact-area rate: by default the
    ``~ 8 sqrt(pi n)`` springs of strain nearest 0 (``n`` in contact: about four rows on each
    side of a round contact's edge)."""
    n_contact = int(np.count_nonzero(eps < 0))
    if area_band is None:
        count = int(min(len(eps), max(8, round(8 * np.sqrt(np.pi * max(n_contact, 1))))))
        if not count:
            return np.zeros(0, dtype=int), 0.0
        delta = float(np.partition(np.abs(eps), count - 1)[count - 1])
        delta = delta if delta > 0 else 1e-12
    else:
        delta = float(area_band)
    return np.flatnonzero(np.abs(eps) <= delta), delta


def outputs(
    solution, problem, col, dxi, T1, ATk, tangent, strict, edge, state, band, sign, peak_set, dense_limit
) -> dict:
    """Every output's derivative from the motion rates ``dxi`` (k, q) (formulations/sensitivity.md)."""
    layer = problem.layer
    n = len(layer)
    q = dxi.shape[1]
    S = layer.areas
    dx = T1 @ dxi  # (m, q)
    du = col.du.copy() if not col.diagonal else np.zeros((12, q))
    du[problem.free_indices] += dx
    # pressure rate dp = -(sigma' deps + s) over the strict contact, -sigma'(0) deps over the edge springs in
    sig = np.where(strict, tangent, 0.0)

    def strain_rows(rows):
        """deps (len(rows), q) of the given springs."""
        out = ATk[:, rows].T @ dxi
        if col.diagonal:
            out[np.arange(len(rows)), rows] += col.b[rows]
        else:
            out += col.b[rows]
        return out

    def functional(Y):
        """``Y^T dp`` (k_out, q) for Y (N, k_out) without forming dp (N, q)."""
        Ys = Y * sig[:, None]
        out = -(ATk @ Ys).T @ dxi
        if col.diagonal:
            out -= (Ys * col.b[:, None]).T
        else:
            out -= Ys.T @ col.b
            if col.s is not None:
                out -= (Y * strict[:, None]).T @ col.s
        if edge.size:
            rates = strain_rows(edge)
            out -= Y[edge].T @ (tangent[edge, None] * rates * state)
        return out

    arm = layer.points - np.asarray(problem.body2.reference)
    Sn = S[:, None] * layer.normals
    Y = np.column_stack([S, Sn, np.cross(arm, Sn), S[:, None] * layer.points])
    F = functional(Y)  # rows: W, force (3), moment (3), sum S p x (3)
    dW, dforce, dmoment, dSpx = F[0], F[1:4], F[4:7], F[7:10]
    W = float(solution.pressure @ S)
    cop = solution.center_of_pressure
    dcop = (dSpx - np.outer(cop, dW)) / W if W > 0 else np.full((3, q), np.nan)
    rows, delta = band
    if rows.size and delta > 0:
        # The derivative of sum_i S_i ramp(-eps_i), the step smoothed to a C1 ramp over
        # |eps| < delta: a triangular kernel of unit integral (formulations/sensitivity.md).
        kernel = (1.0 - np.abs(solution.strain[rows]) / delta) / delta
        darea = -((S[rows] * kernel) @ strain_rows(rows))
    else:
        darea = np.zeros(q)
    area = solution.contact_area
    dmean = (dW - solution.mean_pressure * darea) / area if area > 0 else np.zeros(q)
    if peak_set.size:
        peaks = _pressure_rows(peak_set, strain_rows, col, sig, strict, tangent, edge, state)
        dpeak = peaks.max(axis=0) if sign > 0 else peaks.min(axis=0)
    else:
        dpeak = np.zeros(q)
    if col.diagonal:
        strain, pressure = _per_spring_fields(n, ATk, dxi, col, sig, tangent, edge, state, dense_limit)
        squeeze = {
            "u": du,
            "peak_pressure": dpeak,
            "mean_pressure": dmean,
            "contact_force": dforce,
            "contact_moment": dmoment,
            "center_of_pressure": dcop,
            "contact_area": darea,
        }
        return {"strain": strain, "pressure": pressure, **squeeze}
    deps = ATk.T @ dxi + col.b
    dp = -sig[:, None] * deps
    if col.s is not None:
        dp -= col.s  # zero outside the strict contact
    if edge.size:
        dp[edge] = -tangent[edge, None] * deps[edge] * state
    return {
        "u": du,
        "strain": deps,
        "pressure": dp,
        "peak_pressure": dpeak,
        "mean_pressure": dmean,
        "contact_force": dforce,
        "contact_moment": dmoment,
        "center_of_pressure": dcop,
        "contact_area": darea,
    }


def _pressure_rows(rows, strain_rows, col, sig, strict, tangent, edge, state):
    """dp (len(rows), q) of the given springs."""
    deps = strain_rows(rows)
    dp = -sig[rows, None] * deps
    if col.s is not None and not col.diagonal:
        dp -= np.where(strict[rows, None], col.s[rows], 0.0)
    if edge.size:
        where = np.searchsorted(edge, rows)
        hit = (where < edge.size) & (edge[np.minimum(where, edge.size - 1)] == rows)
        if hit.any():
            e = where[hit]
            dp[hit] = -tangent[rows[hit], None] * deps[hit] * state[e]
    return dp


def _per_spring_fields(n, ATk, dxi, col, sig, tangent, edge, state, dense_limit):
    """``(d strain, d pressure)`` for a per-spring parameter: (N, N) arrays, or LinearOperators."""
    diag = col.b
    lin = np.where(sig > 0, sig, 0.0)

    def strain_mv(v):
        return ATk.T @ (dxi @ v) + diag * v

    def strain_rmv(y):
        return dxi.T @ (ATk @ y) + diag * y

    def edge_rows():
        if not edge.size:
            return None
        rates = ATk[:, edge].T @ dxi
        rates[np.arange(edge.size), edge] += diag[edge]
        return -tangent[edge, None] * rates * state

    E = edge_rows()
    if n <= dense_limit:
        strain = ATk.T @ dxi + np.diag(diag)
        pressure = -lin[:, None] * strain
        if E is not None:
            pressure[edge] = E
        return strain, pressure
    from scipy.sparse.linalg import LinearOperator

    def pressure_mv(v):
        out = -lin * strain_mv(v)
        if E is not None:
            out[edge] = E @ v
        return out

    def pressure_rmv(y):
        z = np.asarray(y, dtype=float).copy()
        extra = 0.0
        if E is not None:
            extra = E.T @ z[edge]
            z[edge] = 0.0
        return -strain_rmv(lin * z) + extra

    strain = LinearOperator((n, n), matvec=strain_mv, rmatvec=strain_rmv, dtype=float)
    pressure = LinearOperator((n, n), matvec=pressure_mv, rmatvec=pressure_rmv, dtype=float)
    return strain, pressure
