"""The exact spring layers of the closed-form checks: a plate, a sphere on a bed, a ball in a socket.

Each builds a :class:`~dea_opt.layer.SpringLayer` directly, with exact cell areas, normals and
gaps (no meshes, no ray casting), for the reference problems of the tests, the paper's examples
and the benchmarks. :mod:`dea_opt.geometry` exports them beside its mesh builders
(:mod:`dea_opt.geometry.meshes`).
"""

from __future__ import annotations

import math

import numpy as np

from .._checks.inputs import as_float_array, positive_integer
from .._checks.memory import check_memory, format_count
from ..errors import InputError
from ..layer import SpringLayer
from ..mesh.budget import BYTES_PER_LAYER_SPRING, PEAK_SHARE

__all__ = ["plate_layer", "socket_layer", "sphere_on_bed_layer"]

_FEWER = "use fewer cells (a coarser grid) for a joint-sized layer"


def _cells(builder: str, **counts) -> tuple[int, ...]:
    """The grid's cell counts (``nx=..., ny=...`` or ``n_rings=..., n_sectors=...``), each checked to
    be a positive whole number, once the layer of their product's springs is known to fit in memory
    (checked before any array is made)."""
    checked = {name: positive_integer(name, value) for name, value in counts.items()}
    n = math.prod(checked.values())
    what = f"{builder}({', '.join(f'{name}={value}' for name, value in checked.items())})"
    check_memory(BYTES_PER_LAYER_SPRING * n, f"{what} ({format_count(n)} springs)", _FEWER, share=PEAK_SHARE)
    return tuple(checked.values())


def _by_sectors(per_ring: np.ndarray, n_sectors: int) -> tuple[np.ndarray, np.ndarray]:
    """``(ring, angle)`` (n_rings, n_sectors): each ring's value beside each sector's mid-angle (rad)
    of ``n_sectors`` equal sectors, as for a polar grid's cells."""
    angle = 2 * np.pi * (np.arange(n_sectors) + 0.5) / n_sectors
    ring, angle = np.meshgrid(per_ring, angle, indexing="ij")
    return ring, angle


def _per_spring(name: str, value, n: int) -> np.ndarray:
    """``value`` (mm) as one per spring: a number is broadcast to all ``n``."""
    return as_float_array(name, value, (n,), allow_scalar_for=n)


def plate_layer(
    length: float = 40.0, width: float = 10.0, nx: int = 400, ny: int = 10, thickness: float = 2.0
) -> SpringLayer:
    """A rigid plate on a flat bonded layer: an ``nx`` x ``ny`` grid in the plane z = 0.

    Springs sit at the cell centres, normals +z (body 1 below, body 2 above), x along the
    ``length`` (mm) and y along the ``width`` (mm); the plate is centred at the origin.
    """
    nx, ny = _cells("plate_layer", nx=nx, ny=ny)
    dx, dy = length / nx, width / ny
    xs = -length / 2 + dx * (np.arange(nx) + 0.5)
    ys = -width / 2 + dy * (np.arange(ny) + 0.5)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    points = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    normals = np.tile([0.0, 0.0, 1.0], (X.size, 1))
    n = len(points)
    return SpringLayer(points, normals, np.full(n, dx * dy), _per_spring("thickness", thickness, n))


def sphere_on_bed_layer(
    radius: float = 25.0, thickness: float = 2.0, extent: float = 8.0, n_rings: int = 200, n_sectors: int = 128
) -> SpringLayer:
    """A rigid sphere of ``radius`` touching a flat bed at the origin, springs on the bed.

    Polar cells out to radius ``extent`` (mm) with exact ring areas; each spring's gap is the
    sphere's height above the bed at the cell's centroid radius, ``R - sqrt(R^2 - rho^2)``.
    Normals +z: body 1 is the bed, body 2 the sphere (centre at ``(0, 0, radius)``).
    """
    n_rings, n_sectors = _cells("sphere_on_bed_layer", n_rings=n_rings, n_sectors=n_sectors)
    if extent >= radius:
        raise InputError(f"extent must be smaller than radius={radius}, got {extent}")
    edges = np.linspace(0.0, extent, n_rings + 1)
    r0, r1 = edges[:-1], edges[1:]
    ring_area = np.pi * (r1**2 - r0**2) / n_sectors
    rho = np.sqrt(0.5 * (r0**2 + r1**2))  # the radius that halves the ring's area
    R, T = _by_sectors(rho, n_sectors)
    points = np.column_stack([(R * np.cos(T)).ravel(), (R * np.sin(T)).ravel(), np.zeros(R.size)])
    normals = np.tile([0.0, 0.0, 1.0], (R.size, 1))
    areas = np.repeat(ring_area, n_sectors)
    gap = radius - np.sqrt(radius**2 - R.ravel() ** 2)
    n = len(points)
    return SpringLayer(points, normals, areas, _per_spring("thickness", thickness, n), gap)


def socket_layer(
    radius: float = 25.0,
    thickness: float = 2.0,
    coverage: float = 90.0,
    n_rings: int = 90,
    n_sectors: int = 180,
    gap: float = 0.0,
) -> SpringLayer:
    """A ball in a spherical socket: springs on the socket, a cap of half-angle ``coverage``.

    The socket opens upward (+z) around the ball's centre at the origin; its pole is at
    ``(0, 0, -radius)``. Cells are exact spherical patches; normals point from the socket
    (body 1) to the ball (body 2), i.e. toward the centre.
    """
    n_rings, n_sectors = _cells("socket_layer", n_rings=n_rings, n_sectors=n_sectors)
    if not 0 < coverage <= 180:
        raise InputError(f"coverage must be in (0, 180] degrees, got {coverage}")
    edges = np.radians(np.linspace(0.0, coverage, n_rings + 1))
    t0, t1 = edges[:-1], edges[1:]
    area = 2 * np.pi * radius**2 * (np.cos(t0) - np.cos(t1)) / n_sectors
    polar = np.arccos(0.5 * (np.cos(t0) + np.cos(t1)))  # the angle that halves the patch
    P, F = _by_sectors(polar, n_sectors)
    direction = np.column_stack(
        [(np.sin(P) * np.cos(F)).ravel(), (np.sin(P) * np.sin(F)).ravel(), (-np.cos(P)).ravel()]
    )
    n = len(direction)
    return SpringLayer(
        radius * direction,
        -direction,
        np.repeat(area, n_sectors),
        _per_spring("thickness", thickness, n),
        _per_spring("gap", gap, n),
    )
