"""Springs from two meshes by ray casting (JAM's elastic foundation), and the checks of a pose.

One spring per articular face of mesh 1, at its centroid, along its normal, with the gap to
mesh 2 and the cartilage thickness measured by ray casting (:mod:`dea_opt.mesh.raycast`).
A ray never takes a hit on the far (back) side of a curved mesh 2: only faces of mesh 2 that
face the ray count, and of those the one nearest the spring. Lengths in mm.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from numbers import Real
from pathlib import Path

import numpy as np

from .._tolerances import ANGLE_SLACK, POSE_LAST_ROW, POSE_ROTATION
from .._validate import number_in_range
from ..errors import InputError
from ..layer import SpringLayer
from .raycast import _caster, _first_per_ray, _self_epsilon, _through, _to_bone
from .readers import _prepare, as_mesh

__all__ = ["MAX_ANGLE", "MAX_GAP", "MAX_OVERLAP", "SpringCast", "cast_springs", "check_pose",
           "springs_from_meshes"]

#: Default proximity window of :func:`springs_from_meshes`: gaps up to 2 mm, overlaps up to
#: 1 mm, normals within 60 degrees of facing each other.
MAX_GAP = 2.0
MAX_OVERLAP = 1.0
MAX_ANGLE = 60.0


def check_pose(pose, name: str = "pose") -> np.ndarray | None:
    """Validate a 4x4 rigid transform (rotation with det +1, last row 0 0 0 1).

    Returns the pose as a float array, or None for None. Raises :class:`InputError`.
    """
    if pose is None:
        return None
    try:
        T = np.array(pose, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a 4x4 rigid transform, got {type(pose).__name__}") from None
    if T.shape != (4, 4):
        raise InputError(f"{name} must be a 4x4 rigid transform, got shape {T.shape}")
    if not np.isfinite(T).all():
        raise InputError(f"{name} must be finite, got NaN or inf")
    if not np.allclose(T[3], [0, 0, 0, 1], rtol=0, atol=POSE_LAST_ROW):
        raise InputError(f"{name} must have last row (0, 0, 0, 1), got {T[3].tolist()}")
    R = T[:3, :3]
    error = float(np.abs(R.T @ R - np.eye(3)).max())
    if error > POSE_ROTATION:
        raise InputError(f"{name} is not rigid: its 3x3 block must be a rotation (R^T R = I), but "
                         f"|R^T R - I| = {error:.3g} (scaling or shear?)")
    det = float(np.linalg.det(R))
    if det < 0:
        raise InputError(f"{name} is not rigid: its 3x3 block is a reflection (det = {det:.3g}), "
                         f"expected a rotation with det +1")
    return T



@dataclass(frozen=True, eq=False)
class SpringCast:
    """The springs cast from mesh 1 onto mesh 2, with what each ray met.

    Attributes
    ----------
    layer : SpringLayer
        The springs (see :func:`springs_from_meshes`).
    hit_face : ndarray of int, shape (N,)
        The face of mesh 2 each spring's ray met.
    hit_point : ndarray, shape (N, 3)
        Where it met it, in mesh 1's frame (mm); ``points + gap * normals``.
    thickness1, thickness2 : ndarray, shape (N,)
        The two cartilage thicknesses whose sum is ``layer.thickness`` (mm).
    mesh1, mesh2 : trimesh.Trimesh
        The checked meshes (mesh 2 in its own frame, before ``pose``).
    pose : ndarray, shape (4, 4)
        The rigid transform applied to mesh 2.
    """

    layer: SpringLayer
    hit_face: np.ndarray
    hit_point: np.ndarray
    thickness1: np.ndarray
    thickness2: np.ndarray
    mesh1: object
    mesh2: object
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))


def _per_face(values, name, mesh, kept) -> np.ndarray:
    """A per-face array given for the mesh as the user gave it, on the checked mesh's faces."""
    n_given = len(mesh.faces) if kept is None else kept[1]
    if values.ndim != 1 or len(values) != n_given:
        raise InputError(f"{name} must have one value per face of the mesh as given, shape "
                         f"({n_given},), got shape {values.shape}")
    return values if kept is None else values[kept[0]]


def _thickness(spec, name, mesh, kept, faces, origins, directions, engine) -> np.ndarray:
    """One side's thickness at the springs from a number, per-face array, bone mesh or None."""
    import trimesh

    if spec is None:
        return _through(mesh, _caster(mesh, engine), origins, directions)
    if isinstance(spec, (trimesh.Trimesh, str, Path)):
        bone = as_mesh(spec, name=f"{name} (bone mesh)")
        return _to_bone(bone, _caster(bone, engine), origins, directions)
    if isinstance(spec, Real) and not isinstance(spec, bool):
        if not math.isfinite(spec) or spec < 0:
            raise InputError(f"{name} must be a finite number >= 0 (mm), got {spec!r}")
        return np.full(len(faces), float(spec))
    try:
        values = np.array(spec, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be None (measure through the closed surface), a number, a "
                         f"per-face array of shape (F,) or a bone mesh, got {type(spec).__name__}") from None
    values = _per_face(values, name, mesh, kept)
    if not np.isfinite(values).all() or (values < 0).any():
        raise InputError(f"{name} must be finite and >= 0 (mm) at every face")
    return values[faces]


def _per_face_labels(labels, mesh, kept) -> np.ndarray | None:
    return None if labels is None else _per_face(np.asarray(labels), "labels", mesh, kept)


def cast_springs(mesh1, mesh2, *, thickness1=None, thickness2=None, pose=None,
                 max_gap: float = MAX_GAP, max_overlap: float = MAX_OVERLAP,
                 max_angle: float = MAX_ANGLE, flip: bool = False, labels=None,
                 engine: str = "auto") -> SpringCast:
    """Like :func:`springs_from_meshes`, also returning what each ray met (:class:`SpringCast`)."""
    m1, kept1 = _prepare(mesh1, "mesh1")
    m2, kept2 = _prepare(mesh2, "mesh2")
    T = check_pose(pose)
    T = np.eye(4) if T is None else T
    max_gap = number_in_range("max_gap", max_gap, 0.0)
    max_overlap = number_in_range("max_overlap", max_overlap, 0.0)
    max_angle = number_in_range("max_angle", max_angle, 0.0, 90.0)
    face_labels = _per_face_labels(labels, m1, kept1)
    R, shift = T[:3, :3], T[:3, 3]

    centroids = m1.triangles_center
    normals = -m1.face_normals if flip else m1.face_normals
    # Rays go to mesh 2's own frame (x2 = R^T (x - shift)) so that its cached ray structures
    # serve every pose of a motion; distances along the rays do not change.
    origins2 = (centroids - shift) @ R
    directions2 = normals @ R
    # Start behind the centroid so that a centroid already inside mesh 2 still finds the face
    # it went through: the line is cast both ways.
    back = max_overlap + _self_epsilon(m2)
    reach = max(max_gap, back) + _self_epsilon(m2)
    ray, face, t = _caster(m2, engine).hits(origins2, directions2, -back, reach)
    # Only faces of mesh 2 that face the ray count (never the back of a curved surface); of
    # those, the nearest to the spring.
    cos = -np.einsum("ij,ij->i", m2.face_normals[face], directions2[ray])
    facing = cos > 0
    ray, face, t, cos = ray[facing], face[facing], t[facing], cos[facing]
    pick = _first_per_ray(ray, np.abs(t), len(centroids))
    has = pick >= 0
    hit = pick[has]
    inside = (t[hit] >= -max_overlap) & (t[hit] <= max_gap)
    aligned = cos[hit] >= math.cos(math.radians(max_angle)) - ANGLE_SLACK
    ok = inside & aligned
    if not ok.any():
        _raise_no_springs(m1, m2, t[hit], cos[hit], inside, origins2, max_gap, max_overlap, max_angle)
    sel = np.flatnonzero(has)[ok]
    hit = hit[ok]
    gap, hit_face = t[hit], face[hit]
    hit_point2 = origins2[sel] + gap[:, None] * directions2[sel]

    h1 = _thickness(thickness1, "thickness1", m1, kept1, sel, centroids[sel], -normals[sel], engine)
    h2 = _thickness(thickness2, "thickness2", m2, kept2, hit_face, hit_point2,
                    -m2.face_normals[hit_face], engine)
    total = h1 + h2
    good = np.isfinite(total) & (total > 0)
    if not good.all():
        _warn_dropped(h1, h2, good, thickness1, thickness2)
        if not good.any():
            raise InputError("no spring has a positive, measurable thickness: thickness1 + thickness2 "
                             "must be > 0 (mm); check that closed surfaces are closed and oriented "
                             "outward, or give the thickness as a number")
        sel, gap, hit_face, hit_point2 = sel[good], gap[good], hit_face[good], hit_point2[good]
        h1, h2, total = h1[good], h2[good], total[good]

    layer = SpringLayer(
        centroids[sel], normals[sel], m1.area_faces[sel], total, gap,
        source_face=sel.astype(np.int64), surface=(m1.vertices, m1.faces),
        labels=None if face_labels is None else face_labels[sel],
    )
    hit_point = hit_point2 @ R.T + shift
    return SpringCast(layer, hit_face, hit_point, h1, h2, m1, m2, T)


def _warn_dropped(h1, h2, good, spec1, spec2) -> None:
    parts = []
    for name, h, spec in (("thickness1", h1, spec1), ("thickness2", h2, spec2)):
        bad = int((~np.isfinite(h)).sum())
        if bad:
            how = ("the inward ray left the surface through a hole or met nothing" if spec is None
                   else "the inward ray never met the bone mesh")
            parts.append(f"{name} could not be measured at {bad} springs ({how})")
    zero = int((np.isfinite(h1 + h2) & (h1 + h2 <= 0)).sum())
    if zero:
        parts.append(f"{zero} springs have zero total thickness")
    warnings.warn("; ".join(parts) + f"; dropped {int((~good).sum())} of {len(good)} springs",
                  stacklevel=4)


def _closest_distance(points: np.ndarray, mesh) -> float:
    """Smallest distance from ``points`` to the surface of ``mesh`` (mm).

    A k-d tree over the mesh's vertices and centroids picks the 64 nearest candidates, whose
    exact closest points on the surface are then computed.
    """
    from scipy.spatial import cKDTree

    tree = cKDTree(np.vstack([mesh.vertices, mesh.triangles_center]))
    rough, _ = tree.query(points)
    best = np.argsort(rough)[:64]
    _, distance, _ = mesh.nearest.on_surface(points[best])
    return float(distance.min())


def _raise_no_springs(m1, m2, t, cos, inside, origins2, max_gap, max_overlap, max_angle):
    window = (f"the proximity window -max_overlap={max_overlap:g} <= gap <= max_gap={max_gap:g} mm "
              f"with max_angle={max_angle:g} deg")
    if len(t):
        if inside.any():
            best = float(np.degrees(np.arccos(np.clip(cos[inside].max(), -1, 1))))
            detail = (f"faces meet within the gap window but their normals are at least {best:.3g} deg "
                      f"from facing each other (raise max_angle)")
        else:
            ahead = t[t > max_gap]
            detail = (f"the smallest distance found along the normals is {ahead.min():.4g} mm "
                      f"(raise max_gap)" if len(ahead) else
                      f"the shallowest overlap found is {-t.max():.4g} mm (raise max_overlap)")
    else:
        detail = (f"no normal of mesh1 meets a face of mesh2 that faces it; the smallest distance "
                  f"found between the meshes is {_closest_distance(origins2, m2):.4g} mm (check pose, "
                  f"flip, units, and that both meshes are in the same frame)")
    raise InputError(f"mesh1 and mesh2 never face each other within {window}: {detail}")


def springs_from_meshes(mesh1, mesh2, *, thickness1=None, thickness2=None, pose=None,
                        max_gap: float = MAX_GAP, max_overlap: float = MAX_OVERLAP,
                        max_angle: float = MAX_ANGLE, flip: bool = False, labels=None,
                        engine: str = "auto") -> SpringLayer:
    """Springs between two cartilage surfaces, by ray casting (JAM's elastic foundation).

    One spring per articular face of mesh 1: a face whose normal ray meets a face of mesh 2
    that faces it inside the proximity window ``-max_overlap <= gap <= max_gap`` with the two
    normals within ``max_angle`` of facing each other.

    Parameters
    ----------
    mesh1, mesh2 : path, trimesh.Trimesh or (vertices, faces)
        Body 1's surface (carries the springs) and body 2's surface, in mm.
    thickness1, thickness2 : None, float, array_like (F,) or mesh, default None
        Each cartilage's thickness (mm): ``None`` measures it through the closed surface itself
        (from the face along the inward normal to the far, bone side: at the spring's face
        for mesh 1, at the point the ray met for mesh 2); a number applies everywhere (0 for a
        rigid body); an array gives one value per face of that mesh as given; a mesh (or
        path) is a bone surface, reached by a ray along the inward normal.
    pose : array_like (4, 4), optional
        Rigid transform applied to mesh 2 (e.g. one frame of a motion), in mesh 1's frame.
    max_gap, max_overlap : float
        Proximity window (mm): the largest gap and the largest initial overlap kept.
    max_angle : float
        Largest angle (deg, in [0, 90]) between a spring's normal and the reversed normal of
        the face of mesh 2 its ray meets.
    flip : bool
        Reverse mesh 1's normals (for an open surface wound away from mesh 2).
    labels : array_like (F,), optional
        A region label per face of mesh 1 (e.g. from :func:`concatenate_meshes`), carried to
        the springs.
    engine : {"auto", "embree", "grid"}
        Ray casting: Embree when importable (auto), or the numpy uniform-grid caster (exact
        float64 ray/triangle tests; slower, no compiled dependency).

    Returns
    -------
    SpringLayer
        ``points`` (N, 3): face centroids (mm); ``normals`` (N, 3): face normals, toward mesh
        2; ``areas`` (N,): face areas (mm^2); ``gap`` (N,): signed distance along the normal
        to mesh 2 (mm, negative where the meshes overlap); ``thickness`` (N,): ``h1 + h2`` (mm);
        ``source_face`` (N,): the face of ``surface`` = mesh 1 (vertices, faces) under each
        spring; ``labels`` as given.

    Raises
    ------
    InputError
        Bad meshes, a pose that is not rigid, a bad window or thickness, or no face of mesh 1
        facing mesh 2 within the window (the message gives the smallest distance found).
    """
    return cast_springs(mesh1, mesh2, thickness1=thickness1, thickness2=thickness2, pose=pose,
                        max_gap=max_gap, max_overlap=max_overlap, max_angle=max_angle, flip=flip,
                        labels=labels, engine=engine).layer
