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
from .certificate_sums import sums
from .formulations._parts.resistance import modulus_scale, require_finite, unresisted

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
        (:class:`~dea_opt.formulations._parts.resistance.Resistance`): ``|P r / L| / |r / L|`` with
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
        pseudo-inverse drops what :func:`~dea_opt.formulations._parts.resistance.unresisted` calls no
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


def certify(problem, u, reported_stress, tolerance: float = 1e-6, strain=None) -> Certificate:
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
    strain : ndarray, shape (N,), optional
        ``problem.strain(u)``, where the caller has it already (computed here otherwise).
    """
    with single_threaded_blas():
        return _certify(problem, u, reported_stress, tolerance, strain)


def _certify(problem, u, reported_stress, tolerance: float, strain=None) -> Certificate:
    layer, law = problem.layer, problem.law
    system = problem.system()
    res = system.resistance
    free = problem.free_indices
    u = np.asarray(u, dtype=float)
    u_free = u[free]
    eps = problem.strain(u) if strain is None else np.asarray(strain, dtype=float)
    # Every sum over the springs in one sweep (dea_opt/certificate_sums.py).
    total = sums(problem, u, eps, np.asarray(reported_stress, dtype=float), tolerance, tangent=bool(free.size))
    if not total.finite:
        nan = float("nan")
        return Certificate(nan, nan, nan, nan, nan, tolerance)
    r, L = system.load, system.lengths
    # What is in equilibrium at the answer: the load, or without one the springs' forces there
    # (which make every reaction). Never a force of the start (springs that overlapped there and
    # opened carry nothing), nor, under a load, forces larger than it that would dilute its imbalance.
    load = float(np.abs(r / L).max(initial=0.0))
    F = load if load > 0 else total.force
    g = total.q - r
    # How far the strains' rounding can move each generalized force: a load the answer can resolve
    # only below that is not certified (an overlap of gaps and motion cancelling to a tiny strain).
    spread = total.spread
    equilibrium = _ratio(float(((np.abs(g) + spread) / L).max(initial=0.0)), F)
    rounding_part = _ratio(float((spread / L).max(initial=0.0)), F)
    if res.null.shape[1]:
        equilibrium = max(equilibrium, res.load_fraction(r))
        z = res.motion_part(u_free)
        if z.any():
            with np.errstate(invalid="ignore", over="ignore"):
                force = layer.areas * law.stress(np.minimum(eps, 0.0))
                held = layer.areas * law.stress(np.minimum(eps - z @ system.AT, 0.0))
            equilibrium = max(equilibrium, _ratio(float(np.nan_to_num(np.abs(force - held), nan=np.inf).sum()), F))
    tension = _ratio(total.tension, F)
    complementarity = _ratio(total.complementarity, F)
    # A reported force is consistent when the law gives it at a strain within the certified
    # precision of the answer's compression (and the strain's own rounding): springs on the edge
    # of the contact, where interior-point duals are of order sqrt(mu), are judged on what the
    # strain allows.
    consistency = _ratio(total.consistency, F)
    decrement = _energy_residual(system, res, law, total, g, modulus_scale(law.modulus)) if free.size else 0.0
    return Certificate(equilibrium, tension, complementarity, consistency, decrement, tolerance, rounding_part)


def _energy_residual(system, res, law, total, g, H) -> float:
    """``g^T K^+ g / 2`` over the resisted directions, relative to the energy at the answer of what
    ``F`` measures: the load's ``r^T K^+ r / 2`` through the same compliance, or without a load the
    springs' stored energy. ``K`` and the stored energy are the sweep's (``total``,
    :class:`~dea_opt.certificate_sums.Sums`)."""
    if not total.compressed or not res.n_resisted:
        return 0.0
    K, stored = total.K, total.stored
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
