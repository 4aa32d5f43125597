"""Which directions of the free dofs the springs resist: the one test, decided once per system.

A direction no spring resists can carry no load and takes no motion (``formulations/energy.md``,
"Unresisted directions"). :func:`unresisted` is the one test, with its threshold
:data:`UNRESISTED`; :func:`~dea_opt.formulations._parts.resistance.resistance` applies it to a
:class:`~dea_opt.formulations._parts.system.SpringSystem` (:func:`factor_resistance` to a stiffness given
by its factor, as a joint's), and :class:`Resistance` holds the answer: the resisted basis the
scaling solves in (:mod:`~dea_opt.formulations._parts.scaling`), and the unresisted part of a load or a
motion. Also here :func:`require_finite`, the guard before LAPACK and every compiled solver.
Units: mm, N, N mm, MPa.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ...errors import SolverError
from ...status import Status

__all__ = [
    "UNRESISTED",
    "Resistance",
    "factor_resistance",
    "modulus_scale",
    "require_finite",
    "resistance",
    "unresisted",
]


#: A direction of motion is *unresisted* when the springs' stiffness along it is at most this
#: fraction of the layer's own stiffness scale (formulations/energy.md, "Unresisted
#: directions"). It is 100 times the rounding of a Gram matrix (about 1e-16 of its largest
#: eigenvalue), and a singular value of 1e-7 of the scale: far below the stiffness of any real
#: direction (the tilt of a layer seen from a reference 1e6 layer radii away is about 1e-12).
UNRESISTED = 1e-14


def unresisted(stiffness, scale: float) -> np.ndarray:
    """The one test of "no spring resists this direction": ``stiffness <= UNRESISTED * scale``.

    Parameters
    ----------
    stiffness : array_like
        Stiffnesses along orthonormal directions: eigenvalues of a stiffness matrix, or
        squared singular values of its factor.
    scale : float
        The stiffness the directions are judged against, in the same units: the layer's own
        (:attr:`~dea_opt.formulations._parts.system.SpringSystem.stiffness` times the modulus), or the largest stiffness of the
        same matrix where that is larger (rounding in a matrix is relative to its largest
        entry, so nothing below ``UNRESISTED`` of it can be told from noise).

    Returns
    -------
    ndarray of bool
    """
    return np.asarray(stiffness, dtype=float) <= UNRESISTED * scale


def require_finite(what: str, *arrays) -> None:
    """Raise :class:`SolverError` (status :attr:`Status.NON_FINITE`) before compiled code
    (LAPACK, NNLS, Clarabel, IPOPT) meets a NaN or an infinity, which some of them answer by
    aborting the process rather than by an error."""
    for arr in arrays:
        if not np.isfinite(arr).all():
            raise SolverError(
                f"{what} holds NaN or infinite values (an input near the limits of float64?); "
                f"nothing was passed to the solver",
                status=Status.NON_FINITE,
            )


@dataclass(frozen=True, eq=False)
class Resistance:
    """Which directions of the free dofs the springs resist, decided once by :func:`unresisted`.

    Directions are measured in arc lengths: ``D x`` with ``D`` (:attr:`~dea_opt.formulations._parts.system.SpringSystem.lengths`)
    1 for a translation and the layer's radius about the reference for a rotation, and loads
    as ``r / D`` (moments over that radius), so translations and rotations compare like with
    like.

    Attributes
    ----------
    T1 : ndarray, shape (m, k)
        ``T1^T K0 T1 = I`` for the bonded stiffness ``K0 = A^T diag(V) A`` at unit modulus,
        over the ``k`` resisted directions; no part of its columns lies along ``null`` (in
        arc lengths), so ``x = T1 xi`` is the minimum-norm motion.
    null : ndarray, shape (m, m - k)
        Orthonormal basis (in arc lengths) of the unresisted directions.
    lengths : ndarray, shape (m,)
        ``D``.
    range : ndarray, shape (m, k)
        Orthonormal basis (in arc lengths) of the resisted directions.
    scale : float
        The stiffness they were judged against (:attr:`~dea_opt.formulations._parts.system.SpringSystem.stiffness`, mm).
    """

    T1: np.ndarray
    null: np.ndarray
    lengths: np.ndarray
    range: np.ndarray
    scale: float

    @property
    def n_resisted(self) -> int:
        return self.T1.shape[1]

    def basis(self, modulus: float = 1.0) -> np.ndarray:
        """``T1`` for a law of small-strain stiffness ``modulus``: ``T1^T K0 T1 = I`` with
        ``K0 = A^T diag(V modulus) A``."""
        return self.T1 / np.sqrt(modulus_scale(modulus))

    def load_part(self, r) -> np.ndarray:
        """The part of the generalized load ``r`` (N, N mm) along unresisted directions, in
        the same units: what no spring force can balance."""
        r = np.asarray(r, dtype=float)
        if not self.n_resisted:
            return r.copy()  # all of it, exactly
        D = self.lengths
        return D * (self.null @ (self.null.T @ (r / D)))

    def load_fraction(self, r) -> float:
        """``|P r / D| / |r / D|``: the fraction of the load (moments over the layer radius)
        that acts along unresisted directions; 0 for no load."""
        rD = np.asarray(r, dtype=float) / self.lengths
        top = float(np.abs(rD).max(initial=0.0))
        if top == 0.0 or not self.null.shape[1]:
            return 0.0
        rD = rD / top  # scaled first, so that neither square under- nor overflows
        return float(np.linalg.norm(self.null.T @ rD) / np.linalg.norm(rD))

    def motion_part(self, u_free) -> np.ndarray:
        """The part of the free-dof motion ``u_free`` (mm, rad) along unresisted directions."""
        D = self.lengths
        return (self.null @ (self.null.T @ (np.asarray(u_free, dtype=float) * D))) / D

    def describe(self, names) -> list[str]:
        """The unresisted directions in words: each free dof that lies wholly among them by its
        name (``"body2.rx"``), then any further direction as a combination
        (``"0.707 body2.ux + 0.707 body2.rz"``, in arc lengths)."""
        p = self.null.shape[1]
        if not p:
            return []
        whole = [j for j in range(len(names)) if float(self.null[j] @ self.null[j]) > 1.0 - 1e-9]
        out = [names[j] for j in whole]
        if len(whole) < p:
            rest = self.null.copy()
            rest[whole] = 0.0  # what is left once the whole dofs are named
            u = np.linalg.svd(rest, full_matrices=False)[0]
            for v in u[:, : p - len(whole)].T:
                v = v / v[np.argmax(np.abs(v))]
                big = np.flatnonzero(np.abs(v) >= 1e-6)
                out.append(" + ".join(f"{v[i]:.3g} {names[i]}" for i in big).replace("+ -", "- "))
        return out


def modulus_scale(modulus) -> float:
    """The law's small-strain stiffness, or 1 for a law without one (it only sets a scale)."""
    modulus = float(modulus)
    return modulus if modulus > 0 and np.isfinite(modulus) else 1.0


def resistance(system) -> Resistance:
    """The :class:`Resistance` of ``system``: the one place that decides which directions the
    springs resist (``formulations/energy.md``, "Unresisted directions").

    From the singular value decomposition of ``W D^-1``, ``W^T W = K0`` (unit modulus), rather
    than an eigendecomposition of ``K0``, which would square the condition number: a reference
    point far from the layer makes the dofs nearly dependent, and the tilt of the layer must
    survive that. ``W`` is the system's small ``factor`` when it has one, else the N x m matrix
    ``diag(sqrt(V)) A``. A direction is unresisted when its squared singular value passes
    :func:`unresisted` against the layer's stiffness :attr:`~dea_opt.formulations._parts.system.SpringSystem.stiffness`, which does
    not depend on which dofs are free: when every free dof is unresisted, rounding noise is
    not mistaken for stiffness.
    """
    rows = system.factor if system.factor is not None else (system.AT * np.sqrt(system.volume)).T
    return factor_resistance(rows, system.lengths, system.stiffness)


def factor_resistance(factor, lengths, stiffness: float | None) -> Resistance:
    """The :class:`Resistance` of the bonded stiffness ``factor^T factor`` (at unit modulus) over
    dofs of ``lengths`` (:attr:`~dea_opt.formulations._parts.system.SpringSystem.lengths`), judged against ``stiffness``
    (:attr:`~dea_opt.formulations._parts.system.SpringSystem.stiffness`): :func:`~dea_opt.formulations._parts.resistance.resistance` for a system given by its factor alone
    (a joint's, stacked from its elements' factors: ``formulations/joint.md``)."""
    D = np.asarray(lengths, dtype=float)
    m = D.size
    k_layer = 0.0 if stiffness is None else float(stiffness)
    if not m:
        return Resistance(np.zeros((0, 0)), np.zeros((0, 0)), D, np.zeros((0, 0)), k_layer)
    W = np.asarray(factor, dtype=float) / D
    if not W.size:
        return Resistance(np.zeros((m, 0)), np.eye(m), D, np.zeros((m, 0)), k_layer)
    require_finite("the bonded stiffness of the springs", W)
    _, sigma, vt = np.linalg.svd(W, full_matrices=True)
    values = np.concatenate([sigma**2, np.zeros(m - sigma.size)])
    scale = max(k_layer, float(values.max(initial=0.0)))
    keep = ~unresisted(values, scale) if scale > 0 else np.zeros(m, dtype=bool)
    T1 = vt[keep].T / np.sqrt(values[keep]) / D[:, None]
    return Resistance(T1, vt[~keep].T, D, vt[keep].T, scale)
