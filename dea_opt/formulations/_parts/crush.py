"""The one test of a crushed layer: springs of a bounded law driven through their thickness.

A law defined only for ``eps > -1`` (Ateshian's) cannot carry a load beyond what the layer
bears before its springs reach ``eps = -1``; a failed solve that ends there is
:attr:`~dea_opt.status.Status.CRUSHED` (``formulations/energy.md``, "Statuses"), a claim about
the problem that every formulation makes by the same test (:func:`crushed`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["CRUSHED_MESSAGE", "CRUSH_WINDOW", "crushed"]


#: A failed solve whose most compressed spring is within this of ``eps = -1`` ran into a
#: bounded law's crushing (formulations/energy.md, "Statuses").
CRUSH_WINDOW = 1e-4


def crushed(law, eps) -> bool:
    """Whether a failed solve ended with springs crushed through their thickness: a law
    defined only for ``eps > -1`` whose most compressed spring is within
    :data:`CRUSH_WINDOW` of -1. The one test every formulation uses for
    :attr:`Status.CRUSHED`."""
    eps = np.asarray(eps, dtype=float)
    eps = eps[np.isfinite(eps)]
    return bool(law.bounded_strain and eps.size and eps.min() < -1 + CRUSH_WINDOW)


CRUSHED_MESSAGE = (
    "springs reach eps = {eps:.6f}, crushed through their thickness before the load is carried: "
    "the load is beyond what this layer can bear"
)
