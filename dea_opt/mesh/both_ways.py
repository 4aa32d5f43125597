"""Casting both ways: springs from mesh 1 onto mesh 2 and from mesh 2 onto mesh 1, and how they differ.

Results need not depend on which mesh casts (one of the faults of OpenSim-JAM's elastic
foundation avoided on purpose): the asymmetry between the two casts measures the error of
the discretization. Lengths in mm.
"""

from __future__ import annotations

from dataclasses import dataclass
from numbers import Real
from pathlib import Path

import numpy as np

from ..errors import InputError
from ..layer import SpringLayer
from .readers import _prepare
from .springs import _per_face, check_pose, springs_from_meshes

__all__ = ["TwoWaySprings", "springs_both_ways"]


@dataclass(frozen=True, eq=False)
class TwoWaySprings:
    """Springs cast from mesh 1 onto mesh 2 (``forward``) and from mesh 2 onto mesh 1 (``backward``).

    ``forward`` has body 1 = mesh 1; ``backward`` has body 1 = mesh 2 (in its posed position),
    so its normals point from mesh 2 to mesh 1. ``asymmetry`` compares the two (see
    :func:`springs_both_ways`).
    """

    forward: SpringLayer
    backward: SpringLayer
    asymmetry: dict


def _layer_measures(layer: SpringLayer) -> dict:
    stiffness = layer.areas / layer.thickness  # N/mm per MPa of modulus
    return {
        "n_springs": len(layer),
        "area": float(layer.areas.sum()),
        "stiffness": float(stiffness.sum()),
        "stiffness_vector": stiffness @ layer.normals,
    }


def springs_both_ways(
    mesh1, mesh2, *, thickness1=None, thickness2=None, pose=None, labels1=None, labels2=None, **options
) -> TwoWaySprings:
    """Cast springs from mesh 1 onto mesh 2 and from mesh 2 onto mesh 1 (JAM's ``flip_meshes``).

    With matching meshes the two layers describe the same cartilage contact; how much they
    differ measures the error of the discretization (and of choosing which mesh casts).

    Parameters
    ----------
    mesh1, mesh2, thickness1, thickness2, pose
        As in :func:`springs_from_meshes`; the backward cast uses mesh 2 in its posed position.
    labels1, labels2 : array_like, optional
        Per-face labels of mesh 1 and of mesh 2.
    **options
        ``max_gap``, ``max_overlap``, ``max_angle``, ``engine`` (``flip`` is not allowed).

    Returns
    -------
    TwoWaySprings
        ``asymmetry`` holds, for each direction, the number of springs, the total spring area
        (mm^2) and the stiffness ``sum(A/h)`` (mm, times the modulus in MPa gives N/mm), and
        ``area``, ``stiffness``: the relative differences ``|a - b| / max(a, b)``, and
        ``direction``: ``|s_f + s_b| / max(|s_f|, |s_b|)`` of the stiffness-weighted normal
        sums ``s = sum(A/h n)``, which point opposite ways when the two casts agree.
    """
    if "flip" in options:
        raise InputError("flip is not supported by springs_both_ways; orient both meshes outward")
    m2, kept2 = _prepare(mesh2, "mesh2")
    T = check_pose(pose)
    posed = m2
    if T is not None:
        posed = m2.copy()
        posed.apply_transform(T)
    if kept2 is not None:  # per-face arrays of mesh 2 refer to its faces as given
        thickness2 = _subset(thickness2, "thickness2", m2, kept2)
        labels2 = _subset(labels2, "labels2", m2, kept2)
    forward = springs_from_meshes(mesh1, posed, thickness1=thickness1, thickness2=thickness2, labels=labels1, **options)
    backward = springs_from_meshes(
        posed, mesh1, thickness1=thickness2, thickness2=thickness1, labels=labels2, **options
    )
    f, b = _layer_measures(forward), _layer_measures(backward)

    def rel(a, b):
        return abs(a - b) / max(abs(a), abs(b), 1e-300)

    sf, sb = f.pop("stiffness_vector"), b.pop("stiffness_vector")
    asymmetry = {
        "forward": f,
        "backward": b,
        "area": rel(f["area"], b["area"]),
        "stiffness": rel(f["stiffness"], b["stiffness"]),
        "direction": float(np.linalg.norm(sf + sb) / max(float(np.linalg.norm(sf)), float(np.linalg.norm(sb)), 1e-300)),
    }
    return TwoWaySprings(forward, backward, asymmetry)


def _subset(spec, name, mesh, kept):
    import trimesh

    if spec is None or isinstance(spec, (Real, str, Path, trimesh.Trimesh)):
        return spec
    return _per_face(np.asarray(spec), name, mesh, kept)
