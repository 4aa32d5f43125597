"""The certificate dea_opt computes itself for every answer, of every formulation.

The certificate (:func:`certify`) is a check a reader can redo with the problem's arrays and
``u``; ``formulations/energy.md`` ("The certificate") and the README state the same
definitions. With ``f_i = S_i sigma(min(eps_i, 0))`` the law's spring forces at ``u`` (N,
tension positive), ``f^rep_i`` the forces the formulation reported, ``q = G_free^T f`` the
generalized spring force on the free dofs and ``r`` the load there (N; N mm for rotations),
``L_j`` 1 for a translation and the layer's radius about the body's reference for a
rotation (mm), every force residual is relative to one force scale, what is in equilibrium at
the answer::

    F = max_j |r_j| / L_j        (under a load)
    F = sum_i |f_i|              (without one)

never a quantity of the start (the force of the initial overlap once was, and let answers of a
layer that separates under the load miss up to half of it). The equilibrium residual adds to
``|q_j - r_j|`` how far the rounding of the strains can move it (``rho_j``, from
``problem.strain_rounding(u)``), so that it bounds the imbalance of ``u`` whatever the rounding.
A residual whose numerator is exactly 0 is 0 (also when ``F = 0``).

The certificate says that ``u`` solves the equations; whether they still describe cartilage there
is the validity report's (:mod:`dea_opt.validity`, ``formulations/validity.md``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._checks.threads import single_threaded_blas
from .formulations.resistance import modulus_scale, require_finite, unresisted

__all__ = ["Certificate", "certify"]


@dataclass(frozen=True)
class Certificate:
    """Residuals computed by dea_opt from ``u``, never taken from a solver.

    Notation as in the module docstring (``F`` the force scale, ``L_j`` the dof lengths).

    Attributes
    ----------
    equilibrium : float
        The largest of three parts. (1) Per free dof: ``max_j (|q_j - r_j| + rho_j) / L_j / F``,
        ``rho_j = sum_i |A_ij| V_i max |sigma(eps_i +- delta_i) - sigma(eps_i)|`` the most the
        strains' rounding ``delta`` (``problem.strain_rounding(u)``) can move the spring force on
        the dof. (2) The fraction of the load that acts along directions no spring resists
        (:class:`~dea_opt.formulations.resistance.Resistance`): ``|P r / L| / |r / L|`` with
        ``P`` the orthogonal projector onto those directions (in arc lengths), so a load no
        spring can carry counts in full whatever its size. (3) The spring forces that the
        answer's motion along those directions produces (motion no spring resists changes no
        strain except through rounding): ``sum_i |f_i - f'_i| / F`` with ``f'`` the forces
        with that motion removed.
    tension : float
        ``sum_i max(f^rep_i, 0) / F``: tensile force the formulation reported.
    complementarity : float
        ``sum_i |f^rep_i| max(eps_i, 0) / F``: open springs carry nothing.
    consistency : float
        ``sum_i`` of how far ``f^rep_i`` lies outside ``S_i [sigma(eps_i - d_i), sigma(eps_i + d_i)]``
        (strains clipped at 0), over ``F``, with ``d_i = tolerance * max_i -min(eps_i, 0) +
        delta_i``: the formulation's forces are what the law gives at a strain within the
        certified precision of the answer's compression.
    energy : float
        Energy a further Newton step could still release, ``g^T K^+ g / 2`` with ``g = q - r``
        and ``K`` the tangent of the compressed springs, over the resisted directions (its
        pseudo-inverse drops what :func:`~dea_opt.formulations.resistance.unresisted` calls no
        stiffness), relative to the load's ``r^T K^+ r / 2`` (without a load, the stored energy).
    tolerance : float
        The bound every residual must meet.
    rounding : float
        ``max_j rho_j / L_j / F``: the part of ``equilibrium`` the strains' rounding alone makes.
        Above ``tolerance``, no answer is certified: the load is below what float64 resolves
        against the gaps and motion its strains are summed from.
    """

    equilibrium: float
    tension: float
    complementarity: float
    consistency: float
    energy: float
    tolerance: float = 1e-6
    rounding: float = 0.0

    @property
    def passed(self) -> bool:
        values = (self.equilibrium, self.tension, self.complementarity, self.consistency, self.energy)
        return all(np.isfinite(v) and v <= self.tolerance for v in values)

    def worst(self) -> tuple[str, float]:
        """The name and value of the largest residual."""
        items = self.as_dict()
        for key in ("tolerance", "passed", "rounding"):
            items.pop(key)
        name = max(items, key=lambda k: items[k] if np.isfinite(items[k]) else np.inf)
        return name, items[name]

    def as_dict(self) -> dict:
        return {
            "equilibrium": self.equilibrium,
            "tension": self.tension,
            "complementarity": self.complementarity,
            "consistency": self.consistency,
            "energy": self.energy,
            "tolerance": self.tolerance,
            "passed": self.passed,
            "rounding": self.rounding,
        }


def _ratio(numerator: float, scale: float) -> float:
    """``numerator / scale``, 0 when the numerator is exactly 0 (nothing to measure)."""
    if numerator == 0.0:
        return 0.0
    return numerator / scale if scale > 0 else float("inf")


def certify(problem, u, reported_stress, tolerance: float = 1e-6) -> Certificate:
    """Check ``u`` against the law: equilibrium, sign, complementarity, optimality.

    Every residual is defined in :class:`Certificate`; they use dea_opt's own arrays and
    ``u``, nothing the solver computed except ``reported_stress``.

    Parameters
    ----------
    problem : ContactProblem
    u : ndarray, shape (12,)
    reported_stress : ndarray, shape (N,)
        Spring stress as the formulation reported it (MPa, tension positive).
    tolerance : float
    """
    with single_threaded_blas():
        return _certify(problem, u, reported_stress, tolerance)


def _certify(problem, u, reported_stress, tolerance: float) -> Certificate:
    layer, law = problem.layer, problem.law
    system = problem.system()
    res = system.resistance
    free = problem.free_indices
    u_free = np.asarray(u, dtype=float)[free]
    eps = problem.strain(u)
    compressed = np.minimum(eps, 0.0)
    with np.errstate(invalid="ignore", over="ignore"):
        sigma = law.stress(compressed)
        force = layer.areas * sigma
        reported = layer.areas * np.asarray(reported_stress, dtype=float)
        # A^T (V sigma) = G_free^T (S sigma): the generalized spring force on the free dofs.
        q = system.AT @ (system.volume * sigma)
    if not (np.isfinite(sigma).all() and np.isfinite(reported).all() and np.isfinite(q).all()):
        nan = float("nan")
        return Certificate(nan, nan, nan, nan, nan, tolerance)
    r, L = system.load, system.lengths
    # What is in equilibrium at the answer: the load, or without one the springs' forces there
    # (which make every reaction). Never a force of the start (springs that overlapped there and
    # opened carry nothing), nor, under a load, forces larger than it that would dilute its imbalance.
    F = _force_scale(r, L, force)
    g = q - r
    # How far the strains' rounding can move each generalized force: a load the answer can resolve
    # only below that is not certified (an overlap of gaps and motion cancelling to a tiny strain).
    rounding = np.asarray(problem.strain_rounding(u), dtype=float)
    spread = _rounding_force(system, law, eps, sigma, rounding)
    equilibrium = _ratio(float(((np.abs(g) + spread) / L).max(initial=0.0)), F)
    rounding_part = _ratio(float((spread / L).max(initial=0.0)), F)
    if res.null.shape[1]:
        equilibrium = max(equilibrium, res.load_fraction(r))
        z = res.motion_part(u_free)
        if z.any():
            with np.errstate(invalid="ignore", over="ignore"):
                held = layer.areas * law.stress(np.minimum(eps - z @ system.AT, 0.0))
            equilibrium = max(equilibrium, _ratio(float(np.nan_to_num(np.abs(force - held), nan=np.inf).sum()), F))
    tension = _ratio(float(np.maximum(reported, 0.0).sum()), F)
    complementarity = _ratio(float(np.abs(reported) @ np.maximum(eps, 0.0)), F)
    # A reported force is consistent when the law gives it at a strain within the certified
    # precision of the answer's compression (and the strain's own rounding): springs on the edge
    # of the contact, where interior-point duals are of order sqrt(mu), are judged on what the
    # strain allows.
    delta = tolerance * float(-compressed.min(initial=0.0)) + rounding
    with np.errstate(invalid="ignore", over="ignore"):
        low = layer.areas * law.stress(np.minimum(eps - delta, 0.0))
        high = layer.areas * law.stress(np.minimum(eps + delta, 0.0))
    excess = np.maximum(low - reported, 0.0) + np.maximum(reported - high, 0.0)
    consistency = _ratio(float(np.nan_to_num(excess, nan=np.inf).sum()), F)
    decrement = _energy_residual(system, res, law, eps, g, modulus_scale(law.modulus)) if free.size else 0.0
    return Certificate(equilibrium, tension, complementarity, consistency, decrement, tolerance, rounding_part)


def _force_scale(r, L, force) -> float:
    """``F`` (N): the load's largest component ``max_j |r_j| / L_j`` on the free dofs, or, without a
    load, the springs' total force ``sum_i |f_i|`` at the answer."""
    load = float(np.abs(r / L).max(initial=0.0))
    return load if load > 0 else float(np.abs(force).sum())


def _rounding_force(system, law, eps, sigma, rounding) -> np.ndarray:
    """``rho_j = sum_i |A_ij| V_i max |sigma(eps_i +- delta_i) - sigma(eps_i)|`` (m,): how far
    strains rounded by ``delta`` (N,) can move the generalized spring force on each free dof
    (N, N mm). Only springs within ``delta`` of contact count; NaN (beyond the law's domain) is
    ``inf``."""
    near = np.flatnonzero(eps - rounding < 0)
    if not near.size or not system.n_dofs:
        return np.zeros(system.n_dofs)
    e, d = eps[near], rounding[near]
    with np.errstate(invalid="ignore", over="ignore"):
        low = law.stress(np.minimum(e - d, 0.0))
        high = law.stress(np.minimum(e + d, 0.0))
        spread = np.maximum(np.abs(low - sigma[near]), np.abs(high - sigma[near]))
    spread = np.nan_to_num(spread, nan=np.inf)
    with np.errstate(invalid="ignore", over="ignore"):
        return np.abs(system.AT[:, near]) @ (system.volume[near] * spread)


def _energy_residual(system, res, law, eps, g, H) -> float:
    """``g^T K^+ g / 2`` over the resisted directions, relative to the energy at the answer of what
    ``F`` measures: the load's ``r^T K^+ r / 2`` through the same compliance, or without a load the
    springs' stored energy."""
    rows = np.flatnonzero(eps < 0)
    if not rows.size or not res.n_resisted:
        return 0.0
    compressed = eps[rows]
    with np.errstate(invalid="ignore", over="ignore"):
        weight = system.volume[rows] * law.tangent(compressed)
        stored = float(system.volume[rows] @ law.energy(compressed))
    AT = system.AT[:, rows]
    K = (AT * weight) @ AT.T
    if not (np.isfinite(K).all() and np.isfinite(stored)):
        return float("nan")
    # In the resisted basis (T1^T K0 T1 = I at the law's modulus) the bonded layer's
    # stiffness is the identity: the scale the one test of "unresisted" judges against.
    T1 = res.basis(H)
    Kt = T1.T @ K @ T1
    gt, rt = T1.T @ g, T1.T @ system.load
    require_finite("the certificate's tangent", Kt, gt, rt)
    vals, vecs = np.linalg.eigh(Kt)
    keep = ~unresisted(vals, max(float(vals[-1]), 1.0))
    coeff, load = vecs[:, keep].T @ gt, vecs[:, keep].T @ rt
    decrement = float(coeff @ (coeff / vals[keep]))
    work = float(load @ (load / vals[keep]))
    return _ratio(0.5 * abs(decrement), 0.5 * work if system.load.any() else stored)
