"""Newton's passes over the springs, fused: each reads every spring array it needs once.

Written math: ``formulations/newton.md`` (the iteration's residual, tangent and line search).
NumPy evaluates one expression at a time, each a pass over arrays of N values that writes a
temporary of N values and reads it back: the residual ``A^T (V sigma(min(eps, 0)))`` alone made
four such passes, and the tangent over the compressed springs gathered their columns of ``A^T``
into a copy of up to ``8 k N`` bytes. Here the springs go by in blocks of :data:`BLOCK`, small
enough that a block's temporaries stay in the processor's cache: the residual, the tangent over
the compressed springs, the bilateral ones of the extended first iteration and the size of the
compression are summed in one sweep (:func:`state`), and a line-search slope or energy reads
the strains, the direction and the volumes once (:func:`slope`, :func:`energy`). No NumPy
function sums a tangent over a masked subset of columns without copying them, and a compiled
kernel would have to evaluate any law: blocks of NumPy keep every law working.

The sums are the same as the whole-array ones up to the order of the additions (rounding);
``tests/formulations/test_sweeps.py`` compares each with a plain NumPy computation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Springs per block: ``k`` rows of ``A^T`` over a block (6 x 8192 x 8 bytes = 393 kB) and its
#: few temporaries stay in the second-level cache, and the Python per block (a dozen NumPy calls)
#: stays small beside the block's memory time. Twice as many springs ran the sweeps 3-5x slower in
#: some processes (measured at a million springs on a 2-core EPYC): a temporary of one value a
#: spring was then exactly 128 kB, the C library's threshold for mapping fresh pages, which are
#: faulted in anew block after block; 64 kB stays clear of it.
BLOCK = 1 << 13


def blocks(n: int):
    """``slice``s of at most :data:`BLOCK` springs covering ``range(n)``."""
    return (slice(start, min(start + BLOCK, n)) for start in range(0, n, BLOCK))


@dataclass
class State:
    """What one sweep at the strains ``eps`` sums (shapes for ``k`` rows of ``A^T``).

    Attributes
    ----------
    internal : ndarray, shape (k,)
        ``A^T (V sigma(min(eps, 0)))``: the springs' generalized force.
    compression : float
        ``sum_i V_i min(eps_i, 0)^2``.
    K : ndarray, shape (k, k) or None
        ``A_act^T diag(V sigma'(eps)) A_act`` over the compressed springs (``eps < 0``).
    bilateral : ndarray, shape (k,) or None
        ``A^T (V sigma(eps))``, every spring, tension included (the extended range).
    K_all : ndarray, shape (k, k) or None
        ``A^T diag(V sigma'(eps)) A``, every spring.
    """

    internal: np.ndarray
    compression: float
    K: np.ndarray | None = None
    bilateral: np.ndarray | None = None
    K_all: np.ndarray | None = None


def state(AT, V, eps, law, *, tangent: bool = True, extended: bool = False) -> State:
    """One sweep over the springs at strains ``eps`` (N,): the :class:`State` there.

    Parameters
    ----------
    AT : ndarray, shape (k, N)
    V : ndarray, shape (N,)
    eps : ndarray, shape (N,)
    law : Law
    tangent : bool
        Sum the tangent over the compressed springs too.
    extended : bool
        Sum the bilateral residual and tangent over every spring too.
    """
    k, n = AT.shape
    internal = np.zeros(k)
    compression = 0.0
    K = np.zeros((k, k)) if tangent else None
    bilateral = np.zeros(k) if extended else None
    K_all = np.zeros((k, k)) if extended else None
    work = np.empty((k, min(BLOCK, n)))  # the weighted block, one buffer for every block
    with np.errstate(over="ignore", invalid="ignore"):
        for part in blocks(n):
            A, v, e = AT[:, part], V[part], eps[part]
            c = np.minimum(e, 0.0)
            internal += A @ (v * law.stress(c))
            compression += float(v @ (c * c))
            if K is not None:
                active = e < 0
                if active.all():
                    K += np.multiply(A, v * law.tangent(c), out=work[:, : e.size]) @ A.T
                elif active.any():
                    Aa = A[:, active]
                    K += (Aa * (v[active] * law.tangent(c[active]))) @ Aa.T
            if bilateral is not None and K_all is not None:
                bilateral += A @ (v * law.stress(e))
                K_all += np.multiply(A, v * law.tangent(e), out=work[:, : e.size]) @ A.T
    return State(internal, compression, K, bilateral, K_all)


def scaled(raw: State, T, energy_scale: float) -> State:
    """``raw``, summed over the unscaled ``A^T`` and volumes, in the scaled variables ``xi`` of
    :class:`~dea_opt.formulations._parts.scaling.Scaling` (``u = T xi``, energies over ``E0``):
    forces ``T^T q / E0``, tangents ``T^T K T / E0``, the compression over ``E0``. The same sums as
    over ``T^T A^T`` and ``V / E0``, without that copy of ``A^T``."""

    def force(q):
        with np.errstate(over="ignore", invalid="ignore"):  # (non-finite sums stay so: Newton says "nan")
            return None if q is None else (T.T @ q) / energy_scale

    def matrix(K):
        with np.errstate(over="ignore", invalid="ignore"):
            return None if K is None else (T.T @ K @ T) / energy_scale

    internal = force(raw.internal)
    assert internal is not None
    return State(internal, raw.compression / energy_scale, matrix(raw.K), force(raw.bilateral), matrix(raw.K_all))


def tangent(AT, weight) -> np.ndarray:
    """``AT diag(weight) AT^T``, shape (k, k), summed by blocks (no copy of ``AT``)."""
    k, n = AT.shape
    K = np.zeros((k, k))
    work = np.empty((k, min(BLOCK, n)))
    for part in blocks(n):
        A = AT[:, part]
        K += np.multiply(A, weight[part], out=work[:, : A.shape[1]]) @ A.T
    return K


def slope(law, V, eps, Ad, alpha: float, out) -> float:
    """``sum_i V_i sigma(min(eps_i + alpha Ad_i, 0)) Ad_i``, with the trial strains
    ``eps + alpha Ad`` written to ``out`` (N,); ``inf`` where a bounded law's trial reaches
    ``eps <= -1`` (beyond its domain)."""
    total = 0.0
    beyond = False
    with np.errstate(over="ignore", invalid="ignore"):
        for part in blocks(eps.size):
            trial = np.multiply(Ad[part], alpha, out=out[part])
            trial += eps[part]
            if beyond:
                continue
            if law.bounded_strain and trial.min(initial=0.0) <= -1.0:
                beyond = True
                continue
            total += float((V[part] * law.stress(np.minimum(trial, 0.0))) @ Ad[part])
    return np.inf if beyond else total


def energy(law, V, eps, Ad, alpha: float) -> float:
    """``sum_i V_i w(min(eps_i + alpha Ad_i, 0))``: the springs' energy along the line."""
    total = 0.0
    with np.errstate(over="ignore", invalid="ignore"):
        for part in blocks(eps.size):
            trial = eps[part] + alpha * Ad[part]
            total += float(V[part] @ law.energy(np.minimum(trial, 0.0)))
    return total
