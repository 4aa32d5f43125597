"""The certificate's sums over the springs, in one sweep by blocks (:func:`sums`).

:func:`dea_opt.certificate.certify` measures every residual from sums over the springs: the
generalized spring force ``q = A^T (V sigma)``, the force scale without a load ``sum |f_i|``, the
strains' rounding and how far it moves ``q`` (``rho``), tension, complementarity, consistency, and
the tangent over the compressed springs with their stored energy (the Newton decrement). Written
whole-array, each was its own pass over N values with its temporaries (about twenty in all, and
a copy of the compressed springs' columns of ``A^T``); here the springs go by in blocks of
:data:`~dea_opt.formulations._parts.sweeps.BLOCK` whose temporaries stay in the processor's cache,
and every spring array is read once. The definitions are those of ``formulations/energy.md``
("The certificate"); the sums differ from the whole-array ones only in the order of the additions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .formulations._parts.sweeps import BLOCK, blocks
from .formulations._parts.system import ROUNDING
from .problem import ContactProblem


@dataclass
class Sums:
    """The certificate's sums at one answer (``k`` free dofs).

    Attributes
    ----------
    finite : bool
        Every stress, reported stress and ``q`` is finite.
    q : ndarray, shape (k,)
        ``A^T (V sigma)`` (N, N mm).
    force : float
        ``sum_i |f_i|`` (N).
    spread : ndarray, shape (k,)
        ``rho``: how far the strains' rounding can move ``q`` (``inf`` where beyond the law's domain).
    tension, complementarity, consistency : float
        ``sum max(f^rep, 0)``, ``sum |f^rep| max(eps, 0)`` and the consistency excess (N).
    K : ndarray, shape (k, k)
        ``A_act^T diag(V sigma'(eps)) A_act`` over the compressed springs.
    stored : float
        ``sum V w(eps)`` over the compressed springs (N mm).
    compressed : int
        How many springs are compressed.
    """

    finite: bool
    q: np.ndarray
    force: float
    spread: np.ndarray
    tension: float
    complementarity: float
    consistency: float
    K: np.ndarray
    stored: float
    compressed: int


def rounding(problem, u, part: slice, motion: list | None = None) -> np.ndarray:
    """``problem.strain_rounding(u)`` over the springs ``part``: ``ROUNDING`` ulps of the sizes of the
    terms each strain is summed from (formulations/energy.md, "The certificate"). The distance of a
    spring from a body's reference is computed only where that body rotates. ``motion``:
    :func:`_motion` of ``u``, where the caller sweeps block after block."""
    layer = problem.layer
    size = np.abs(layer.gap[part])
    for reference, turn, shift in _motion(problem, u) if motion is None else motion:
        if turn:
            # |p - c| column by column: arithmetic along rows of three values is several times slower
            points = layer.points[part]
            arm = points[:, 0] - reference[0]
            arm *= arm
            for j in (1, 2):
                r = points[:, j] - reference[j]
                r *= r
                arm += r
            np.sqrt(arm, out=arm)
            arm *= turn
            arm += shift
            size += arm
        elif shift:
            size += shift
    size *= ROUNDING * np.finfo(float).eps
    size /= layer.thickness[part]
    return size


def _motion(problem, u) -> list:
    """``[(c_k, |w_k|_1, |t_k|_1)]`` for the two bodies: reference (mm), rotation (rad), translation (mm)."""
    return [
        (
            np.asarray(body.reference, dtype=float),
            float(np.abs(u[6 * k + 3 : 6 * k + 6]).sum()),
            float(np.abs(u[6 * k : 6 * k + 3]).sum()),
        )
        for k, body in enumerate((problem.body1, problem.body2))
    ]


def _finite_or_inf(values: np.ndarray) -> np.ndarray:
    """``values`` with NaN (a bounded law beyond its domain) counted as ``inf``, as ``nan_to_num``
    counts it; checked first, since nearly always nothing is to be replaced."""
    return values if np.isfinite(values).all() else np.nan_to_num(values, nan=np.inf)


def sums(problem, u, eps, reported_stress, tolerance: float, tangent: bool = True) -> Sums:
    """One sweep over ``problem``'s springs at the answer ``u`` (12,), strains ``eps`` (N,) and the
    formulation's ``reported_stress`` (N, MPa): the certificate's :class:`Sums`. ``tangent``: sum the
    compressed springs' tangent and energy too (for the Newton decrement).

    Each block's sums are taken over all its springs, without gathering the compressed or the
    near ones: an open spring, clear of contact by its rounding, adds exactly zero to ``rho``,
    and the tangent's springs are gathered only where some of the block is open."""
    layer, law = problem.layer, problem.law
    system = problem.system()
    AT, V, areas = system.AT, system.volume, layer.areas
    k = AT.shape[0]
    q, spread, K = np.zeros(k), np.zeros(k), np.zeros((k, k))
    finite = True
    force = tension = complementarity = consistency = stored = 0.0
    compressed = 0
    # The consistency window: the certified precision of the answer's compression.
    window = tolerance * float(-min(float(np.min(eps, initial=0.0)), 0.0))
    # A contact problem's rounding is summed here block by block; another problem (a finite
    # kinematics' deformed state) gives its own whole.
    whole = None if type(problem).strain_rounding is ContactProblem.strain_rounding else problem.strain_rounding(u)
    size = min(BLOCK, eps.size)
    weighted = np.empty((k, size))  # a buffer reused block after block
    motion = _motion(problem, u) if whole is None else None
    with np.errstate(invalid="ignore", over="ignore"):
        for part in blocks(eps.size):
            e, v, a, A = eps[part], V[part], areas[part], AT[:, part]
            c = np.minimum(e, 0.0)
            sigma = law.stress(c)
            reported = a * reported_stress[part]
            f = a * sigma
            block_force = float(np.abs(f).sum())
            # (a sum is finite when every term is, short of overflow: the exact test only then)
            if not (math.isfinite(block_force) or np.isfinite(sigma).all()) or not np.isfinite(reported).all():
                finite = False
                break
            force += block_force
            q += A @ (v * sigma)
            delta = rounding(problem, u, part, motion) if whole is None else np.array(whole[part], dtype=float)
            if k and (e < delta).any():
                # sigma moved by the strain's rounding: exactly 0 for a spring clear of contact by it
                moved = np.maximum(
                    np.abs(law.stress(np.minimum(e - delta, 0.0)) - sigma),
                    np.abs(law.stress(np.minimum(e + delta, 0.0)) - sigma),
                )
                spread += np.abs(A, out=weighted[:, : e.size]) @ (v * _finite_or_inf(moved))
            tension += float(np.maximum(reported, 0.0).sum())
            complementarity += float(np.abs(reported) @ np.maximum(e, 0.0))
            delta += window
            low = a * law.stress(np.minimum(e - delta, 0.0))
            high = a * law.stress(np.minimum(e + delta, 0.0))
            low -= reported
            high -= reported
            np.maximum(low, 0.0, out=low)
            np.minimum(high, 0.0, out=high)
            low -= high  # max(low - rep, 0) + max(rep - high, 0)
            consistency += float(_finite_or_inf(low).sum())
            if tangent:
                active = e < 0
                count = int(np.count_nonzero(active))
                if count == e.size:  # every spring compressed (c = e): nothing to gather
                    compressed += count
                    K += np.multiply(A, v * law.tangent(c), out=weighted[:, : e.size]) @ A.T
                    stored += float(v @ law.energy(c))
                elif count:
                    compressed += count
                    cr, vr, Ar = e[active], v[active], A[:, active]
                    K += (Ar * (vr * law.tangent(cr))) @ Ar.T
                    stored += float(vr @ law.energy(cr))
    finite = finite and bool(np.isfinite(q).all())
    return Sums(finite, q, force, spread, tension, complementarity, consistency, K, stored, compressed)
