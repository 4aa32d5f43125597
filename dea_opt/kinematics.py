"""Rigid-body kinematics of the spring layer: Eq. (7), (9)-(11) of Volokh, Chao & Armand.

``u`` is the 12-vector of Eq. (7): body 1 then body 2, each translations ``(ux, uy, uz)``
then small rotations ``(rx, ry, rz)`` about the body's reference point. The relative
displacement of spring ``i`` is ``delta_i = B_i u`` with ``B_i = [-I, M1, I, M2]`` (Eq. 10),
so that ``n_i . delta_i = G_i u`` with the row

    G_i = [-n_i, -(r1_i x n_i), n_i, r2_i x n_i],   rk_i = x_i - c_k

and the strain of Eq. (11), extended by the initial gap, is ``eps_i = (gap_i + G_i u) / h_i``.
Written math: ``formulations/energy.md`` ("Kinematics").
"""

from __future__ import annotations

import numpy as np

DOFS = ("ux", "uy", "uz", "rx", "ry", "rz")
DOF_NAMES = tuple(f"body{b}.{d}" for b in (1, 2) for d in DOFS)


def normal_operator(points, normals, reference1, reference2) -> np.ndarray:
    """The rows ``n_i^T B_i`` of Eq. (11), shape (N, 12), in mm per unit of ``u``.

    Returned as the transpose of a C-contiguous (12, N) array: products over the springs
    (``G @ u``, ``G.T @ f``) then stream through memory once per dof.
    """
    n = np.asarray(normals, dtype=float)
    p = np.asarray(points, dtype=float)
    GT = np.empty((12, p.shape[0]))
    GT[0:3] = -n.T
    GT[3:6] = -np.cross(p - np.asarray(reference1, dtype=float), n).T
    GT[6:9] = n.T
    GT[9:12] = np.cross(p - np.asarray(reference2, dtype=float), n).T
    return GT.T


def relative_displacement(points, u, reference1, reference2) -> np.ndarray:
    """``delta_i = B_i u`` of Eq. (9), shape (N, 3), in mm."""
    u = np.asarray(u, dtype=float)
    p = np.asarray(points, dtype=float)
    d1 = u[0:3] + np.cross(u[3:6], p - np.asarray(reference1, dtype=float))
    d2 = u[6:9] + np.cross(u[9:12], p - np.asarray(reference2, dtype=float))
    return d2 - d1
