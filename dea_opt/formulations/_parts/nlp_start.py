"""The constrained NLP's start from Newton's answer: IPOPT's primal and dual point, and the options
that make IPOPT begin there (``formulations/nlp.md``, "Start from Newton's answer").

From a cold start IPOPT spends 20-odd interior-point iterations on the cubic law at 1e5 springs,
each a factorization of a KKT system as large as the springs. Newton's active set answers the same
energy minimum in a few passes over the springs; given that answer's motion, its strains' ``c``
and the multipliers they imply (the contact rows' ``lambda_i = Vs_i s0 sigma_i``, the block ties'
the force each block's springs carry), IPOPT starts next to its own optimum and needs a handful of
iterations. The answer is still IPOPT's own, to its own tolerance, and certified as any other: the
start only moves where IPOPT begins.
"""

from __future__ import annotations

import numpy as np

from ...status import Status

#: IPOPT's barrier parameter at a start from Newton's answer, and its pushes off the bounds there
#: (the problem is scaled, so one value serves every unit): small enough that IPOPT does not walk
#: away from the answer, large enough that its first steps keep the iterates interior (1e-4 to
#: 1e-8 took 3 to 6 iterations on the box, plate and sphere).
WARM_MU = 1e-6

#: The IPOPT options of a start from a given primal and dual point.
WARM_OPTIONS = {
    "warm_start_init_point": "yes",
    "mu_init": WARM_MU,
    "warm_start_bound_push": WARM_MU,
    "warm_start_slack_bound_push": WARM_MU,
    "warm_start_mult_bound_push": WARM_MU,
}


def block_tie_duals(AT_scaled, s0: float, lam_contact, block, n_blocks: int) -> np.ndarray:
    """The multipliers of the block ties ``X_b - X_1 = 0`` (``b = 2..nb``) at a point whose contact
    rows carry ``lam_contact``: stationarity in ``X_b`` asks ``sum_{i in b} (a_i T / s0)
    lambda_i + lambda^tie_b = 0``, so each block's tie carries minus the force its springs carry.

    Parameters
    ----------
    AT_scaled : ndarray, shape (k, N)
        ``(A T)^T`` of the scaling (1).
    s0 : float
        The strain scale (1).
    lam_contact : ndarray, shape (N,)
        The contact rows' multipliers (scaled energy).
    block : ndarray of int, shape (N,)
        Each spring's block, ``0..n_blocks-1``.
    n_blocks : int

    Returns
    -------
    ndarray, shape (k * (n_blocks - 1),)
        In CasADi's order, ``vec`` of the (k, nb - 1) ties, column by column.
    """
    k = AT_scaled.shape[0]
    force = np.empty((k, n_blocks))
    for j in range(k):
        force[j] = np.bincount(block, weights=AT_scaled[j] * lam_contact, minlength=n_blocks) / s0
    return -force[:, 1:].T.reshape(-1)


def newton_start(system, law, load, start_of, scale, block, n_blocks: int, upper: float) -> dict | None:
    """IPOPT's start ``{"x0", "lam_x0", "lam_g0"}`` from Newton's answer to ``system`` under
    ``load``, or ``None`` where Newton does not converge or its answer lies outside the NLP's
    bounds (a spring compressed to ``upper``, the crush bound): IPOPT then starts cold.

    ``start_of(u_free)`` is the model's own primal start at a motion; ``scale`` its
    :class:`~dea_opt.formulations.energy.Scaling`; ``block`` and ``n_blocks`` its block copies.
    """
    from .. import newton

    try:
        answer = newton.solve(system.with_load(load), law)
    except Exception:  # noqa: BLE001 - any failure of the start is a cold start, not an error
        return None
    if answer.status is not Status.CONVERGED or not np.isfinite(answer.u_free).all():
        return None
    x0 = start_of(answer.u_free)
    c = x0[scale.n_dofs * n_blocks :]
    if not (np.isfinite(answer.stress).all() and (c < upper).all()):
        return None
    lam_contact = answer.stress * scale.volume * scale.strain_scale
    ties = block_tie_duals(scale.AT, scale.strain_scale, lam_contact, block, n_blocks)
    return {"x0": x0, "lam_x0": np.zeros(x0.size), "lam_g0": np.concatenate([lam_contact, ties])}
