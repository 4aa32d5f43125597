"""The covariance of calibrated parameters: the stated noise (and its correlation) carried through
the Jacobian at the optimum, or the noise estimated from the residuals' scatter.

Written math: ``formulations/sensitivity.md`` ("Standard errors"). The fit of
:func:`~dea_opt.sensitivity.calibrate.calibrate` weights each datum by its standard deviation and
does not decorrelate the data (a generalised least squares would need the inverse of the
correlation, a dense matrix as large as a film map squared); the covariance reported is that of
this estimate under the stated correlation, ``(J^T J)^-1 J^T Rho J (J^T J)^-1``, which is
``(J^T J)^-1`` for independent data. :func:`spatial_correlation` builds a sparse correlation of a
map's neighbouring readings. Units: those of the parameters.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, cast

import numpy as np

from ..errors import InputError

__all__ = ["ParameterCovariance", "check_correlation", "parameter_covariance", "spatial_correlation"]

#: Largest number of data whose correlation is checked to be positive semidefinite (an
#: eigen-decomposition, O(n^3)); larger ones are checked for shape, symmetry and range only.
_CHECKED_SIZE = 3000


def check_correlation(name: str, value, n: int):
    """``value`` as an (n, n) correlation matrix (a float array, or a scipy.sparse matrix kept
    sparse), or an :class:`InputError` naming ``name``: finite, symmetric, ones on the
    diagonal, entries in [-1, 1] and (up to :data:`_CHECKED_SIZE` data) positive semidefinite."""
    import scipy.sparse as sp

    matrix: Any
    if sp.issparse(value):
        matrix = sp.csr_matrix(cast(Any, value), dtype=float)
    else:
        try:
            matrix = np.array(value, dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"{name} must be a square matrix of numbers, got {value!r:.80}") from None
    if matrix.shape != (n, n):
        raise InputError(f"{name} must be a matrix of shape ({n}, {n}), one row per datum, got shape {matrix.shape}")
    if isinstance(matrix, np.ndarray):
        values, diagonal = matrix.reshape(-1), np.diagonal(matrix)
        asymmetry = float(np.abs(matrix - matrix.T).max()) if matrix.size else 0.0
    else:
        values, diagonal = matrix.data, matrix.diagonal()
        asymmetry = float(abs(matrix - matrix.T).max()) if matrix.nnz else 0.0
    if not np.isfinite(values).all():
        raise InputError(f"{name} must be finite; it holds NaN or infinite values")
    if np.any(np.abs(diagonal - 1.0) > 1e-12):
        raise InputError(
            f"{name} must have ones on its diagonal (a correlation), got {diagonal.min():g} to {diagonal.max():g}"
        )
    if values.size and np.abs(values).max() > 1.0 + 1e-12:
        raise InputError(f"{name} must hold values in [-1, 1] (a correlation), got {np.abs(values).max():g}")
    if asymmetry > 1e-12:
        raise InputError(f"{name} must be symmetric, got entries that differ from their transpose by {asymmetry:g}")
    if n <= _CHECKED_SIZE:
        dense = matrix if isinstance(matrix, np.ndarray) else matrix.toarray()
        smallest = float(np.linalg.eigvalsh(dense).min()) if n else 0.0
        if smallest < -1e-9:
            raise InputError(
                f"{name} must be positive semidefinite (a correlation of real noise), got an eigenvalue of {smallest:.3g}"
            )
    return matrix


def spatial_correlation(points, length: float):
    """The correlation of readings that lie within ``length`` (mm) of each other: Wendland's
    compactly supported function ``(1 - d/L)^4 (4 d/L + 1)`` of their distance ``d`` (zero beyond
    ``L``), positive definite in three dimensions (Wendland 1995), as a sparse matrix.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Where the readings were taken (mm), e.g. ``PressureMap.points``.
    length : float
        The distance beyond which readings are independent (mm): a film's grain or a scanner's
        blur, a few pixels.

    Returns
    -------
    scipy.sparse.csr_matrix, shape (n, n)
    """
    import scipy.sparse as sp
    from scipy.spatial import cKDTree

    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 3 or not np.isfinite(points).all():
        raise InputError(f"points must be finite with shape (n, 3) (mm), got shape {points.shape}")
    if isinstance(length, bool) or not isinstance(length, (int, float, np.integer, np.floating)) or not length > 0:
        raise InputError(f"length must be a number > 0 (mm), got {length!r}")
    tree = cKDTree(points)
    distance = tree.sparse_distance_matrix(tree, float(length), output_type="coo_matrix")
    q = distance.data / float(length)
    values = (1.0 - q) ** 4 * (4.0 * q + 1.0)
    n = len(points)
    # the diagonal is not among a distance matrix's stored (nonzero) entries
    off = distance.row != distance.col
    rows = np.concatenate([distance.row[off], np.arange(n)])
    cols = np.concatenate([distance.col[off], np.arange(n)])
    return sp.csr_matrix((np.concatenate([values[off], np.ones(n)]), (rows, cols)), shape=(n, n))


@dataclass(frozen=True)
class ParameterCovariance:
    """What :func:`parameter_covariance` found.

    Attributes
    ----------
    covariance : ndarray, shape (q, q)
        NaN throughout when the standard errors are undefined.
    errors : str
        ``"stated"`` (the data's stated noise carried through the Jacobian) or ``"estimated"``
        (the noise's scale estimated from the residuals' scatter).
    degrees_of_freedom : float
        Residuals taking part less what the fit absorbs (``n - q`` for independent data of full
        rank); what the estimate of the noise rests on.
    note : str
        Why the standard errors are undefined (empty when they are not).
    """

    covariance: np.ndarray
    errors: str
    degrees_of_freedom: float
    note: str = ""


def parameter_covariance(r, J, correlation=None, *, errors: str = "stated") -> ParameterCovariance:
    """The covariance of parameters fitted by least squares on weighted residuals.

    Parameters
    ----------
    r : ndarray, shape (n,)
        The residuals taking part, each divided by its datum's standard deviation.
    J : ndarray, shape (n, q)
        Their derivatives in the parameters.
    correlation : ndarray or scipy.sparse matrix, shape (n, n), optional
        The correlation of the data's noise (identity when None).
    errors : {"stated", "estimated"}
        ``"stated"``: the standard deviations are the noise's, so ``Cov = (J^T J)^-1 J^T Rho J
        (J^T J)^-1``. ``"estimated"``: they are weights known up to a common scale, which the
        residuals give: ``Cov`` times ``|r|^2 / (n - tr((J^T J)^-1 J^T Rho J))``, undefined
        (NaN, with a note) when no degree of freedom is left.

    Returns
    -------
    ParameterCovariance
    """
    r, J = np.asarray(r, dtype=float), np.asarray(J, dtype=float)
    n, q = J.shape
    inverse = np.linalg.pinv(J.T @ J)
    middle = J.T @ J if correlation is None else J.T @ np.asarray(correlation @ J)
    covariance = inverse @ middle @ inverse
    covariance = 0.5 * (covariance + covariance.T)
    absorbed = float(np.trace(inverse @ middle))
    dof = float(n) - absorbed
    if errors == "stated":
        return ParameterCovariance(covariance, "stated", dof)
    if errors != "estimated":
        raise InputError(f"errors must be 'stated' or 'estimated', got {errors!r}")
    if dof <= 1e-9 * max(n, 1):
        note = (
            f"the standard errors are undefined: the noise was not stated, and {n} residual(s) taking part "
            f"for {q} parameter(s) leave no degree of freedom to estimate it from; state each datum's noise "
            f"(PressureMap(noise=...), ForceDisplacement(noise=...), ContactData(area_std=..., center_std=...))"
        )
        return ParameterCovariance(np.full((q, q), np.nan), "estimated", dof, note)
    return ParameterCovariance(float(r @ r) / dof * covariance, "estimated", dof)
