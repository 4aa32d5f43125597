"""Embedded meshes, made in code: triangle surfaces (``trimesh.Trimesh``) of the demo and the tests.

Closed cartilage volumes (:func:`slab_mesh`, :func:`spherical_shell_mesh`) and pairs of them in
contact (:class:`MeshPair`: :func:`plate_meshes`, :func:`sphere_on_bed_meshes`,
:func:`hip_meshes`, :func:`knee_meshes`), whose springs come from ray casting
(:mod:`dea_opt.mesh`). Units: mm and degrees.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .._checks.inputs import number_in_range, positive_integer
from .._checks.memory import check_memory, format_count
from ..errors import InputError
from ..mesh.budget import BYTES_PER_GENERATED_FACE, PEAK_SHARE

if TYPE_CHECKING:
    import trimesh

    from ..layer import SpringLayer

__all__ = [
    "MeshPair",
    "hip_meshes",
    "knee_meshes",
    "plate_meshes",
    "slab_mesh",
    "sphere_on_bed_meshes",
    "spherical_shell_mesh",
]


def _check_faces(what: str, n_faces: int) -> None:
    """Generated meshes of ``n_faces`` faces in all must fit in memory (checked before building)."""
    check_memory(
        BYTES_PER_GENERATED_FACE * n_faces,
        f"{what} ({format_count(n_faces)} faces)",
        "use a larger step or fewer cells (a joint's cartilage needs 10^4-10^5 faces)",
        share=PEAK_SHARE,
    )


def _step(step) -> float:
    """A grid step in degrees, in (0, 30]."""
    return number_in_range("step", step, 0.0, 30.0, low_open=True)


def _slab_faces(nx: int, ny: int) -> int:
    """Faces of a closed slab of ``nx`` x ``ny`` cells: top, bottom and side walls."""
    return 4 * nx * ny + 4 * (nx + ny)


def _shell_grid(coverage: float, fossa: float, notch: float, step: float) -> tuple[int, int, int]:
    """``(n_polar, n_azimuth, faces)`` of a spherical layer's grid (an upper bound on faces)."""
    n_polar = max(math.ceil((coverage - fossa) / step), 1)
    n_azimuth = max(math.ceil(360.0 / step), 8)
    return n_polar, n_azimuth, 4 * n_polar * n_azimuth + 4 * (n_polar + n_azimuth)


def _shell_faces(coverage: float, step: float, fossa: float = 0.0, notch: float = 0.0) -> int:
    """Faces of :func:`spherical_shell_mesh` with these angles (deg), at most: :func:`_shell_grid`'s."""
    return _shell_grid(coverage, fossa, notch, step)[2]


# --------------------------------------------------------------------------------------------
# Mesh builders: closed cartilage volumes as triangle surfaces, and pairs of them
# --------------------------------------------------------------------------------------------
def _closed_volume(articular: np.ndarray, base: np.ndarray, mask: np.ndarray | None = None, periodic: bool = False):
    """A closed triangle surface around the layer between two grids of points.

    Parameters
    ----------
    articular, base : ndarray, shape (nu + 1, nv + 1, 3) (``(nu + 1, nv, 3)`` when periodic)
        The same grid on the articular skin and on the bone skin (mm).
    mask : ndarray of bool, shape (nu, nv), optional
        The grid cells that belong to the layer (default all).
    periodic : bool
        The grid closes on itself along v (an azimuth).

    Returns
    -------
    trimesh.Trimesh
        Watertight, normals outward: articular faces point away from the base, side walls
        away from the region. Zero-area faces (at a pole) are dropped.
    """
    import trimesh

    nu = articular.shape[0] - 1
    nvv = articular.shape[1]  # vertices along v
    nv = nvv if periodic else nvv - 1
    mask = np.ones((nu, nv), dtype=bool) if mask is None else np.asarray(mask, dtype=bool)
    n_grid = (nu + 1) * nvv

    def vid(i, j):
        return i * nvv + (j % nvv if periodic else j)

    ci, cj = np.nonzero(mask)
    a, b, c, d = vid(ci, cj), vid(ci + 1, cj), vid(ci + 1, cj + 1), vid(ci, cj + 1)
    top = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    caps = [top, top + n_grid]  # the articular and the base faces
    # side walls on every cell edge whose neighbour is outside the region
    inside = np.pad(mask, ((1, 1), (0, 0) if periodic else (1, 1)), constant_values=False)
    off = 0 if periodic else 1

    def neighbour(di, dj):
        jj = (cj + dj) % nv if periodic else cj + dj + off
        return inside[ci + di + 1, jj]

    walls = []
    for (di, dj), (p, q) in (((-1, 0), (a, d)), ((1, 0), (b, c)), ((0, -1), (a, b)), ((0, 1), (d, c))):
        edge = ~neighbour(di, dj)
        p_, q_ = p[edge], q[edge]
        walls.append(np.column_stack([p_, q_, q_ + n_grid]))
        walls.append(np.column_stack([p_, q_ + n_grid, p_ + n_grid]))
    vertices = np.vstack([articular.reshape(-1, 3), base.reshape(-1, 3)])
    faces = np.vstack(caps + walls)
    # Orient each face: articular faces along (articular - base), base faces against it,
    # walls away from the centre of their cell.
    corner = vertices[faces]
    normal = np.cross(corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0])
    lift = articular.reshape(-1, 3) - base.reshape(-1, 3)
    n_top = len(top)
    want = np.empty_like(normal)
    want[:n_top] = lift[top].mean(axis=1)
    want[n_top : 2 * n_top] = -lift[top].mean(axis=1)
    cell_centre = articular.reshape(-1, 3)[np.column_stack([a, b, c, d])].mean(axis=1)
    centres = []
    for di, dj in ((-1, 0), (1, 0), (0, -1), (0, 1)):
        edge = ~neighbour(di, dj)
        centres += [cell_centre[edge]] * 2
    wall_faces = faces[2 * n_top :]
    if len(wall_faces):
        mid = vertices[wall_faces].mean(axis=1)
        want[2 * n_top :] = mid - np.vstack(centres)
    wrong = np.einsum("ij,ij->i", normal, want) < 0
    faces[wrong] = faces[wrong][:, ::-1]
    mesh = trimesh.Trimesh(vertices, faces, process=True)  # merges pole vertices
    mesh.update_faces(mesh.nondegenerate_faces())
    mesh.remove_unreferenced_vertices()
    return mesh


def slab_mesh(
    length: float = 40.0,
    width: float = 40.0,
    thickness: float = 2.0,
    nx: int = 40,
    ny: int = 40,
    *,
    center=(0.0, 0.0),
    top: float = 0.0,
    facing: str = "up",
):
    """A closed flat cartilage slab: the articular face at ``z = top``, the bone face behind it.

    Parameters
    ----------
    length, width : float
        Extent along x and y (mm), centred at ``center`` (x, y).
    thickness : float
        Slab thickness (mm).
    nx, ny : int
        Cells along x and y (each split into two triangles).
    facing : {"up", "down"}
        The articular face's outward normal: +z (the bone below) or -z (the bone above).

    Returns
    -------
    trimesh.Trimesh
        Watertight, outward normals; ``2 nx ny`` articular faces come first.
    """
    nx, ny = positive_integer("nx", nx), positive_integer("ny", ny)
    if facing not in ("up", "down"):
        raise InputError(f"facing must be 'up' or 'down', got {facing!r}")
    for name, value in (("length", length), ("width", width), ("thickness", thickness)):
        number_in_range(name, value, 0.0, low_open=True)
    _check_faces(f"slab_mesh(nx={nx}, ny={ny})", _slab_faces(nx, ny))
    xs = center[0] + np.linspace(-length / 2, length / 2, nx + 1)
    ys = center[1] + np.linspace(-width / 2, width / 2, ny + 1)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    sign = 1.0 if facing == "up" else -1.0
    articular = np.stack([X, Y, np.full_like(X, top)], axis=-1)
    base = np.stack([X, Y, np.full_like(X, top - sign * thickness)], axis=-1)
    return _closed_volume(articular, base)


def _frame(axis) -> np.ndarray:
    """Rows e1, e2, axis: an orthonormal frame whose third row is ``axis``."""
    axis = np.asarray(axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    helper = np.array([1.0, 0.0, 0.0]) if abs(axis[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = np.cross(helper, axis)
    e1 /= np.linalg.norm(e1)
    return np.array([e1, np.cross(axis, e1), axis])


def spherical_shell_mesh(
    radius: float = 25.0,
    thickness: float = 2.0,
    coverage: float = 90.0,
    *,
    center=(0.0, 0.0, 0.0),
    axis=(0.0, 0.0, -1.0),
    articular: str = "outer",
    fossa: float = 0.0,
    notch: float = 0.0,
    step: float = 3.0,
):
    """A closed cartilage layer on a sphere: a cap, or a lunate (horseshoe) with a fossa and notch.

    The articular skin is the sphere of ``radius`` about ``center``; the bone skin lies
    ``thickness`` behind it (inside for ``articular="outer"``, a convex head; outside for
    ``"inner"``, a concave socket). Both are tessellated on the same polar grid, so the
    thickness along a face normal is ``thickness`` to second order in the grid step.

    Parameters
    ----------
    radius, thickness : float
        Articular radius and layer thickness (mm).
    coverage : float
        Polar half-angle of the layer about ``axis`` (deg, up to 180 for a whole sphere).
    axis : array_like, shape (3,)
        Direction from the centre to the pole of the cap.
    articular : {"outer", "inner"}
    fossa : float
        Polar half-angle of a bare region around the pole (deg; the acetabular fossa).
    notch : float
        Azimuthal width of an opening through the rim (deg; the acetabular notch), leaving a
        horseshoe. It is centred on the azimuth ``e1 = x cross axis`` normalized (``+y`` for
        the default ``axis = -z``; ``y cross axis`` when the axis is nearly along x).
    step : float
        Grid step in polar angle and azimuth (deg).

    Returns
    -------
    trimesh.Trimesh
        Watertight, outward normals.
    """
    if articular not in ("outer", "inner"):
        raise InputError(f"articular must be 'outer' or 'inner', got {articular!r}")
    for name, value in (
        ("radius", radius),
        ("thickness", thickness),
        ("coverage", coverage),
        ("fossa", fossa),
        ("notch", notch),
        ("step", step),
    ):
        number_in_range(name, value)
    if not 0 < thickness < radius or not radius > 0:
        raise InputError(f"need 0 < thickness < radius, got thickness={thickness}, radius={radius}")
    if not 0 <= fossa < coverage <= 180:
        raise InputError(f"need 0 <= fossa < coverage <= 180 degrees, got fossa={fossa}, coverage={coverage}")
    if not 0 <= notch < 360:
        raise InputError(f"notch must be in [0, 360) degrees, got {notch}")
    if not 0 < step <= 30:
        raise InputError(f"step must be in (0, 30] degrees, got {step}")
    n_polar, n_azimuth, n_faces = _shell_grid(coverage, fossa, notch, step)
    _check_faces(f"spherical_shell_mesh(step={step:g})", n_faces)
    theta = np.radians(np.linspace(fossa, coverage, n_polar + 1))
    if notch > 0:  # the notch is a gap in azimuth: the grid runs from one side to the other
        phi = np.radians(np.linspace(notch / 2, 360.0 - notch / 2, n_azimuth + 1))
        periodic = False
    else:
        phi = np.radians(np.arange(n_azimuth) * 360.0 / n_azimuth)
        periodic = True
    T, P = np.meshgrid(theta, phi, indexing="ij")
    local = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], axis=-1)
    direction = local @ _frame(axis)
    back = radius - thickness if articular == "outer" else radius + thickness
    centre = np.asarray(center, dtype=float)
    return _closed_volume(centre + radius * direction, centre + back * direction, periodic=periodic)


def _concatenate(meshes):
    import trimesh

    return trimesh.util.concatenate(list(meshes))


@dataclass(frozen=True, eq=False)
class MeshPair:
    """Two cartilage surfaces in contact, made in code, ready for :func:`~dea_opt.mesh.springs_from_meshes`.

    Attributes
    ----------
    name : str
    mesh1, mesh2 : trimesh.Trimesh
        Body 1's surface (carries the springs) and body 2's, closed, normals outward (mm).
    reference1, reference2 : tuple of 3 floats
        The bodies' reference points (mm): rotations and moments are about them.
    options : dict
        Default options of ``springs_from_meshes`` for this pair (e.g. ``thickness2=0`` for
        a rigid body 2, or per-face ``labels``).
    info : dict
        The parameters the pair was built from, for closed-form checks.
    """

    name: str
    mesh1: trimesh.Trimesh
    mesh2: trimesh.Trimesh
    reference1: tuple = (0.0, 0.0, 0.0)
    reference2: tuple = (0.0, 0.0, 0.0)
    options: dict = field(default_factory=dict)
    info: dict = field(default_factory=dict)

    def layer(self, **options) -> SpringLayer:
        """Springs from mesh 1 onto mesh 2; ``options`` override :attr:`options`."""
        return self.cast(**options).layer

    def cast(self, **options):
        """The :class:`~dea_opt.mesh.SpringCast` of :meth:`layer` (for
        :func:`~dea_opt.mesh.recast` and :func:`~dea_opt.mesh.recast_at_solution`)."""
        from ..mesh import cast_springs

        return cast_springs(self.mesh1, self.mesh2, **{**self.options, **options})

    def problem(self, law, force=(0.0, 0.0, 0.0), moment=(0.0, 0.0, 0.0), free=("uz",), **options):
        """A :class:`~dea_opt.problem.ContactProblem`: body 1 fixed, body 2 loaded at ``reference2``."""
        from ..problem import Body, ContactProblem

        body1 = Body(reference=self.reference1, free=())
        body2 = Body(reference=self.reference2, free=free, force=force, moment=moment)
        return ContactProblem(self.layer(**options), law, body1=body1, body2=body2)

    def __repr__(self) -> str:
        return f"MeshPair({self.name!r}, mesh1={len(self.mesh1.faces)} faces, mesh2={len(self.mesh2.faces)} faces)"


def plate_meshes(
    length: float = 40.0,
    width: float = 10.0,
    thickness: float = 2.0,
    nx: int = 80,
    ny: int = 20,
    plate_thickness: float = 5.0,
) -> MeshPair:
    """A rigid plate on a flat cartilage slab, touching at ``z = 0`` (the core plate test).

    Mesh 1 is the slab (``length`` x ``width``, ``thickness`` thick, articular face up at
    ``z = 0``); mesh 2 a rigid plate of the same footprint on top of it (``thickness2=0``).
    A force ``F`` along -z on the plate gives the uniform pressure ``F / (length width)``.
    """
    nx, ny = positive_integer("nx", nx), positive_integer("ny", ny)
    _check_faces(f"plate_meshes(nx={nx}, ny={ny})", 2 * _slab_faces(nx, ny))
    slab = slab_mesh(length, width, thickness, nx, ny)
    plate = slab_mesh(length, width, plate_thickness, nx, ny, top=0.0, facing="down")
    return MeshPair(
        "plate",
        slab,
        plate,
        (0.0, 0.0, -thickness),
        (0.0, 0.0, 0.0),
        {"thickness2": 0.0},
        {"length": length, "width": width, "thickness": thickness},
    )


def sphere_on_bed_meshes(
    radius: float = 25.0, thickness: float = 2.0, extent: float = 8.0, n_bed: int = 32, step: float = 2.0
) -> MeshPair:
    """A rigid sphere touching a flat cartilage bed at the origin (the core sphere-on-bed test).

    Mesh 1 is a square bed ``2 extent`` wide with ``n_bed`` cells a side, articular face up
    at ``z = 0``, ``thickness`` thick (measured through it); mesh 2 the lower cap of the
    sphere of ``radius`` centred at ``(0, 0, radius)``, polar grid step ``step`` (deg), rigid
    (``thickness2=0``). Pressed to a depth ``d`` under a linear law of modulus ``H``:
    ``F = pi H d^2 (R - d/3) / h``, peak pressure ``H d / h``, contact radius
    ``sqrt(2 R d - d^2)``.
    """
    if not 0 < extent * np.sqrt(2) < radius:
        raise InputError(f"extent * sqrt(2) must be smaller than radius={radius}, got extent={extent}")
    n_bed, step = positive_integer("n_bed", n_bed), _step(step)
    reach = min(np.degrees(np.arcsin(extent * np.sqrt(2) / radius)) + 2 * step, 90.0)
    _check_faces(
        f"sphere_on_bed_meshes(n_bed={n_bed}, step={step:g})", _slab_faces(n_bed, n_bed) + _shell_faces(reach, step)
    )
    bed = slab_mesh(2 * extent, 2 * extent, thickness, n_bed, n_bed)
    cap = spherical_shell_mesh(radius, radius / 4, reach, center=(0.0, 0.0, radius), axis=(0.0, 0.0, -1.0), step=step)
    return MeshPair(
        "sphere_on_bed",
        bed,
        cap,
        (0.0, 0.0, -thickness),
        (0.0, 0.0, radius),
        {"thickness2": 0.0},
        {"radius": radius, "thickness": thickness, "extent": extent},
    )


def hip_meshes(
    head_radius: float = 24.0,
    socket_radius: float = 24.5,
    head_thickness: float = 1.5,
    socket_thickness: float = 2.0,
    coverage: float = 85.0,
    fossa: float = 25.0,
    notch: float = 60.0,
    step: float = 3.0,
) -> MeshPair:
    """A hip: a lunate acetabular cartilage (body 1) around a femoral head cartilage (body 2).

    The socket opens upward (+z) about the origin, its pole at ``(0, 0, -socket_radius)``:
    a horseshoe of polar half-angle ``coverage`` with a bare fossa of half-angle ``fossa``
    around the pole and a notch ``notch`` degrees wide at azimuth +y. The head (radius
    ``head_radius`` < ``socket_radius``, the mismatch) touches the socket at its pole, so its
    centre sits at ``(0, 0, head_radius - socket_radius)``; its cartilage covers 20 degrees
    more than the socket's. Both layers are closed, so their thickness is measured through
    them (``thickness1 = thickness2 = None``). Load the head along -z.
    """
    if not 0 < head_radius < socket_radius:
        raise InputError(f"need 0 < head_radius < socket_radius, got {head_radius}, {socket_radius}")
    step = _step(step)
    head_coverage = min(coverage + 20.0, 180.0)
    _check_faces(
        f"hip_meshes(step={step:g})", _shell_faces(coverage, step, fossa, notch) + _shell_faces(head_coverage, step)
    )
    socket = spherical_shell_mesh(
        socket_radius, socket_thickness, coverage, articular="inner", fossa=fossa, notch=notch, step=step
    )
    head_centre = (0.0, 0.0, head_radius - socket_radius)
    head = spherical_shell_mesh(
        head_radius, head_thickness, head_coverage, center=head_centre, articular="outer", step=step
    )
    info = {
        "head_radius": head_radius,
        "socket_radius": socket_radius,
        "head_thickness": head_thickness,
        "socket_thickness": socket_thickness,
        "coverage": coverage,
        "fossa": fossa,
        "notch": notch,
    }
    return MeshPair("hip", socket, head, (0.0, 0.0, 0.0), head_centre, {}, info)


def knee_meshes(
    condyle_radius=(32.0, 28.0),
    spacing: float = 40.0,
    femoral_thickness: float = 2.0,
    tibial_thickness: float = 3.0,
    plateau: float = 24.0,
    n_plateau: int = 48,
    step: float = 2.0,
    coverage: float = 25.0,
) -> MeshPair:
    """A knee-like pair: two femoral condyle cartilage caps (body 2) on a tibial plateau (body 1).

    The plateau is two closed flat slabs ``plateau`` mm square, ``tibial_thickness`` thick,
    articular faces up at ``z = 0``, centred at ``x = +spacing/2`` (labelled ``"medial"``)
    and ``x = -spacing/2`` (``"lateral"``); x is medial-lateral, z points from the tibia to
    the femur, so y is anterior-posterior and varus-valgus is the rotation ``ry``. Each
    condyle is a spherical cap of cartilage (radii ``condyle_radius`` = (medial, lateral),
    half-angle ``coverage``) touching its slab at ``(+-spacing/2, 0, 0)``. The per-face
    labels ride in :attr:`MeshPair.options` (with ``max_gap=3``); thickness is measured
    through both layers (5 mm in all by default).
    """
    r_med, r_lat = condyle_radius
    half = spacing / 2
    if plateau >= spacing:
        raise InputError(f"plateau must be narrower than spacing={spacing} so the slabs stay apart, got {plateau}")
    n_plateau, step = positive_integer("n_plateau", n_plateau), _step(step)
    _check_faces(
        f"knee_meshes(n_plateau={n_plateau}, step={step:g})",
        2 * _slab_faces(n_plateau, n_plateau) + 2 * _shell_faces(coverage, step),
    )
    medial = slab_mesh(plateau, plateau, tibial_thickness, n_plateau, n_plateau, center=(half, 0.0))
    lateral = slab_mesh(plateau, plateau, tibial_thickness, n_plateau, n_plateau, center=(-half, 0.0))
    tibia = _concatenate([medial, lateral])
    labels = np.repeat(np.array(["medial", "lateral"]), [len(medial.faces), len(lateral.faces)])
    condyles = [
        spherical_shell_mesh(r, femoral_thickness, coverage, center=(x, 0.0, r), axis=(0.0, 0.0, -1.0), step=step)
        for x, r in ((half, r_med), (-half, r_lat))
    ]
    femur = _concatenate(condyles)
    reference2 = (0.0, 0.0, max(r_med, r_lat))
    info = {
        "condyle_radius": (r_med, r_lat),
        "spacing": spacing,
        "femoral_thickness": femoral_thickness,
        "tibial_thickness": tibial_thickness,
    }
    return MeshPair(
        "knee", tibia, femur, (0.0, 0.0, -tibial_thickness), reference2, {"labels": labels, "max_gap": 3.0}, info
    )
