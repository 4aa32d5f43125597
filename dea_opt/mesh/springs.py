"""Springs from two meshes by ray casting (JAM's elastic foundation), and the checks of a pose.

One spring per articular face of mesh 1, at its centroid, along its normal, with the gap to
mesh 2 and the cartilage thickness measured by ray casting (:mod:`dea_opt.mesh.raycast`).
A ray never takes a hit on the far (back) side of a curved mesh 2: only faces of mesh 2 that
face the ray count, and of those the one nearest the spring. Lengths in mm.
"""

from __future__ import annotations

import math
import warnings
from numbers import Real
from pathlib import Path

import numpy as np

from .._checks.inputs import number_in_range
from .._checks.thresholds import ANGLE_SLACK
from ..errors import InputError
from ..layer import SpringLayer
from .budget import check_cast_size
from .casts import _SPRING, DROP_REASONS, LOST_REASONS, Dropped, SpringCast, check_pose
from .raycast import _caster, _engine, _first_per_ray, _self_epsilon, _through, _to_bone
from .readers import _prepare, as_mesh

__all__ = [
    "DROP_REASONS",
    "LOST_REASONS",
    "MAX_ANGLE",
    "MAX_GAP",
    "MAX_OVERLAP",
    "Dropped",
    "SpringCast",
    "cast_springs",
    "check_pose",
    "springs_from_meshes",
]

#: Default proximity window of :func:`springs_from_meshes`: gaps up to 2 mm, overlaps up to
#: 1 mm, normals within 60 degrees of facing each other.
MAX_GAP = 2.0
MAX_OVERLAP = 1.0
MAX_ANGLE = 60.0


def _per_face(values, name, mesh, kept) -> np.ndarray:
    """A per-face array given for the mesh as the user gave it, on the checked mesh's faces."""
    n_given = len(mesh.faces) if kept is None else kept[1]
    if values.ndim != 1 or len(values) != n_given:
        raise InputError(
            f"{name} must have one value per face of the mesh as given, shape ({n_given},), got shape {values.shape}"
        )
    return values if kept is None else values[kept[0]]


def _resolve_thickness(spec, name, mesh, kept):
    """A thickness specification on the checked mesh: None, a float, a per-face array or a bone mesh."""
    import trimesh

    if spec is None:
        return None
    if isinstance(spec, (trimesh.Trimesh, str, Path)):
        return as_mesh(spec, name=f"{name} (bone mesh)")
    if isinstance(spec, Real) and not isinstance(spec, bool):
        if not math.isfinite(spec) or spec < 0:
            raise InputError(f"{name} must be a finite number >= 0 (mm), got {spec!r}")
        return float(spec)
    try:
        values = np.array(spec, dtype=float)
    except (TypeError, ValueError):
        raise InputError(
            f"{name} must be None (measure through the closed surface), a number, a "
            f"per-face array of shape (F,) or a bone mesh, got {type(spec).__name__}"
        ) from None
    values = _per_face(values, name, mesh, kept)
    if not np.isfinite(values).all() or (values < 0).any():
        raise InputError(f"{name} must be finite and >= 0 (mm) at every face")
    return values


def _thickness(spec, mesh, faces, origins, directions, engine, through=None) -> np.ndarray:
    """One side's thickness at the springs from a resolved specification.

    ``through`` is the distance through ``mesh`` itself, when already measured.
    """
    if spec is None:
        return _through(mesh, _caster(mesh, engine), origins, directions) if through is None else through
    if isinstance(spec, float):
        return np.full(len(faces), spec)
    if isinstance(spec, np.ndarray):
        return spec[faces]
    return _to_bone(spec, _caster(spec, engine), origins, directions)


def _per_face_labels(labels, mesh, kept) -> np.ndarray | None:
    return None if labels is None else _per_face(np.asarray(labels), "labels", mesh, kept)


def cast_springs(
    mesh1,
    mesh2,
    *,
    thickness1=None,
    thickness2=None,
    pose=None,
    max_gap: float = MAX_GAP,
    max_overlap: float = MAX_OVERLAP,
    max_angle: float = MAX_ANGLE,
    flip: bool = False,
    labels=None,
    engine: str = "auto",
) -> SpringCast:
    """Like :func:`springs_from_meshes`, also returning what each ray met (:class:`SpringCast`)."""
    m1, m2, options = prepare_cast(
        mesh1,
        mesh2,
        thickness1=thickness1,
        thickness2=thickness2,
        max_gap=max_gap,
        max_overlap=max_overlap,
        max_angle=max_angle,
        flip=flip,
        labels=labels,
        engine=engine,
    )
    T = check_pose(pose)
    return _cast(m1, m2, np.eye(4) if T is None else T, options)


def prepare_cast(
    mesh1,
    mesh2,
    *,
    thickness1=None,
    thickness2=None,
    max_gap: float = MAX_GAP,
    max_overlap: float = MAX_OVERLAP,
    max_angle: float = MAX_ANGLE,
    flip: bool = False,
    labels=None,
    engine: str = "auto",
) -> tuple:
    """``(mesh1, mesh2, options)`` of :func:`cast_springs` before any ray: the checked meshes and
    the options resolved on them (what a cast at any pose starts from; a sweep's cache keeps it)."""
    m1, kept1 = _prepare(mesh1, "mesh1")
    m2, kept2 = _prepare(mesh2, "mesh2")
    check_cast_size(len(m1.faces), len(m2.faces), _engine(engine))
    options = {
        "thickness1": _resolve_thickness(thickness1, "thickness1", m1, kept1),
        "thickness2": _resolve_thickness(thickness2, "thickness2", m2, kept2),
        "max_gap": number_in_range("max_gap", max_gap, 0.0),
        "max_overlap": number_in_range("max_overlap", max_overlap, 0.0),
        "max_angle": number_in_range("max_angle", max_angle, 0.0, 90.0),
        "flip": bool(flip),
        "labels": _per_face_labels(labels, m1, kept1),
        "engine": engine,
    }
    return m1, m2, options


def _cast(m1, m2, T, options, allowed=None) -> SpringCast:
    """Cast from every face of the checked mesh 1 onto mesh 2 posed by ``T``.

    ``allowed`` (F1,) is the overlap each face's ray may take (mm); ``max_overlap`` for all
    by default. A ray looks behind its face down to mesh 1's own far side, so that an
    overlap deeper than the window is counted as dropped, not missed, and a hit behind that
    far side (through the spring layer itself) is rejected.
    """
    engine, max_gap = options["engine"], options["max_gap"]
    n_faces = len(m1.faces)
    allowed = np.full(n_faces, options["max_overlap"]) if allowed is None else allowed
    R, shift = T[:3, :3], T[:3, 3]
    centroids = m1.triangles_center
    normals = -m1.face_normals if options["flip"] else m1.face_normals
    # Behind each face, the first crossing of mesh 1 itself: its far (bone) side for a closed
    # layer, none (inf) for an open sheet.
    back_face, depth = _caster(m1, engine).nearest(centroids, -normals, _self_epsilon(m1), np.inf)
    depth = np.where(back_face >= 0, depth, np.inf)
    look = np.where(np.isfinite(depth), np.maximum(depth, allowed), allowed)
    # Rays go to mesh 2's own frame (x2 = R^T (x - shift)) so that its cached ray structures
    # serve every pose of a motion; distances along the rays do not change.
    origins2 = (centroids - shift) @ R
    directions2 = normals @ R
    eps = _self_epsilon(m2)
    # The line is cast both ways (a centroid already inside mesh 2 still finds the face it
    # went through), as far ahead as behind so that the nearest face is the nearest.
    ray, face, t = _caster(m2, engine).hits(origins2, directions2, -(look + eps), np.maximum(max_gap, look) + eps)
    # Only faces of mesh 2 that face the ray count (never the back of a curved surface).
    cos = -np.einsum("ij,ij->i", m2.face_normals[face], directions2[ray])
    keep = cos > 0
    ray, face, t, cos = ray[keep], face[keep], t[keep], cos[keep]
    met = _first_met(m2, engine, ray, face, t, origins2, directions2, np.maximum(max_gap, look) + eps)
    # A hit behind mesh 1's own far side (or on it) went back through the spring layer: rejected.
    through = -t >= depth[ray] - _self_epsilon(m1)
    window = (t >= -allowed[ray]) & (t <= max_gap)
    rejected = np.zeros(n_faces, dtype=bool)
    rejected[ray[through & window]] = True
    # Of the hits inside the window, the nearest to the spring.
    inside = window & ~through
    pick = _first_per_ray(ray[inside], np.abs(t[inside]), n_faces)
    has = np.flatnonzero(pick >= 0)
    hit = np.flatnonzero(inside)[pick[has]]
    aligned = cos[hit] >= math.cos(math.radians(options["max_angle"])) - ANGLE_SLACK
    outcome = _outcomes(n_faces, ray, t, cos, ~through & ~window, rejected, allowed, options)
    outcome[has] = np.where(aligned, _SPRING, LOST_REASONS.index("angle"))
    ok = aligned
    if not ok.any():
        _raise_no_springs(m2, cos[hit], t[~through & ~window], int(rejected.sum()), origins2, options)
    sel, hit = has[ok], hit[ok]
    gap, hit_face = t[hit], face[hit]
    hit_point2 = origins2[sel] + gap[:, None] * directions2[sel]
    through1 = None
    if options["thickness1"] is None:  # the crossing behind the face, where it leaves the layer
        leaves = np.einsum("ij,ij->i", m1.face_normals[back_face[sel].clip(0)], -normals[sel]) > 0
        through1 = np.where((back_face[sel] >= 0) & leaves, depth[sel], np.nan)
    h1 = _thickness(options["thickness1"], m1, sel, centroids[sel], -normals[sel], engine, through1)
    h2 = _thickness(options["thickness2"], m2, hit_face, hit_point2, -m2.face_normals[hit_face], engine)
    total = h1 + h2
    good = np.isfinite(total) & (total > 0)
    if not good.all():
        _warn_dropped(h1, h2, good, options["thickness1"], options["thickness2"])
        if not good.any():
            raise InputError(
                "no spring has a positive, measurable thickness: thickness1 + thickness2 "
                "must be > 0 (mm); check that closed surfaces are closed and oriented "
                "outward, or give the thickness as a number"
            )
        outcome[sel[~good]] = LOST_REASONS.index("thickness")
        sel, gap, hit_face, hit_point2 = sel[good], gap[good], hit_face[good], hit_point2[good]
        h1, h2, total = h1[good], h2[good], total[good]

    return assemble_cast(m1, m2, T, options, sel, gap, hit_face, hit_point2, h1, h2, outcome, met)


#: How far beyond the window a cast looks for what each ray meets first (mm): farther than the
#: springs that follow body 2 move before the whole mesh is cast again (``full_shift``, 5 mm).
_MET_REACH = 10.0


def _first_met(m2, engine, ray, face, t, origins2, directions2, stop) -> np.ndarray:
    """``face (F1,)``: the face of mesh 2 each ray met first facing it (-1: nothing), among the crossings of the cast's range (``ray, face, t``, facing)
    and, for rays with none there, by one first-hit query up to ``_MET_REACH`` beyond ``stop``
    (F1,): where springs that follow body 2 start looking for the faces of mesh 1 near them at
    another pose."""
    n = len(origins2)
    first = _first_per_ray(ray, t, n)
    met = np.where(first >= 0, face[first.clip(0)], -1) if len(face) else np.full(n, -1, dtype=np.int64)
    beyond = np.flatnonzero(met < 0)
    if len(beyond):
        start = origins2[beyond] + stop[beyond, None] * directions2[beyond]
        more, _ = _caster(m2, engine).nearest(start, directions2[beyond], 0.0, _MET_REACH)
        found = more >= 0
        facing = np.zeros(len(beyond), dtype=bool)
        facing[found] = np.einsum("ij,ij->i", m2.face_normals[more[found]], directions2[beyond][found]) < 0
        met[beyond[facing]] = more[facing]
    return met


def assemble_cast(m1, m2, T, options, sel, gap, hit_face, hit_point2, h1, h2, outcome, met=None) -> SpringCast:
    """The :class:`SpringCast` of what the rays found: the faces of mesh 1 with a spring
    (``sel``), their gaps, the faces of mesh 2 met and where (in mesh 2's frame), the two
    thicknesses, and every face's outcome (and, optionally, ``met``: the face of mesh 2 each ray
    met first facing it, :func:`_first_met`). A sweep's cache keeps these arrays and
    nothing else (not ``met``)."""
    normals = -m1.face_normals if options["flip"] else m1.face_normals
    face_labels = options["labels"]
    layer = SpringLayer(
        m1.triangles_center[sel],
        normals[sel],
        m1.area_faces[sel],
        h1 + h2,
        gap,
        source_face=sel.astype(np.int64),
        surface=(m1.vertices, m1.faces),
        labels=None if face_labels is None else face_labels[sel],
        target_points=hit_point2,
        target_normals=m2.face_normals[hit_face],
        target_faces=hit_face,
    )
    hit_point = hit_point2 @ T[:3, :3].T + T[:3, 3]
    dropped = Dropped({r: np.flatnonzero(outcome == i) for i, r in enumerate(DROP_REASONS)})
    met = None if met is None else _readonly(np.asarray(met))
    cast = SpringCast(layer, hit_face, hit_point, h1, h2, m1, m2, T, dropped, options, _readonly(outcome), met)
    object.__setattr__(layer, "_cast", cast)  # the layer knows its meshes (SpringLayer.cast)
    return cast


def _outcomes(n_faces, ray, t, cos, outside, rejected, allowed, options) -> np.ndarray:
    """The outcome of each face whose ray has no hit inside the window (see :data:`LOST_REASONS`).

    ``outside`` marks the hits outside the window that are not behind mesh 1's far side;
    the nearest of them says why the face made no spring.
    """
    outcome = np.full(n_faces, LOST_REASONS.index("no_hit"), dtype=np.int8)
    pick = _first_per_ray(ray[outside], np.abs(t[outside]), n_faces)
    has = np.flatnonzero(pick >= 0)
    hit = np.flatnonzero(outside)[pick[has]]
    aligned = cos[hit] >= math.cos(math.radians(options["max_angle"])) - ANGLE_SLACK
    deep = t[hit] < -allowed[has]
    outcome[has[t[hit] > options["max_gap"]]] = LOST_REASONS.index("gap")
    outcome[has[deep & aligned]] = LOST_REASONS.index("overlap")
    outcome[rejected] = LOST_REASONS.index("through_layer")
    return outcome


def _readonly(arr: np.ndarray) -> np.ndarray:
    arr.setflags(write=False)
    return arr


def _warn_dropped(h1, h2, good, spec1, spec2) -> None:
    parts = []
    for name, h, spec in (("thickness1", h1, spec1), ("thickness2", h2, spec2)):
        bad = int((~np.isfinite(h)).sum())
        if bad:
            how = (
                "the inward ray left the surface through a hole or met nothing"
                if spec is None
                else "the inward ray never met the bone mesh"
            )
            parts.append(f"{name} could not be measured at {bad} springs ({how})")
    zero = int((np.isfinite(h1 + h2) & (h1 + h2 <= 0)).sum())
    if zero:
        parts.append(f"{zero} springs have zero total thickness")
    warnings.warn("; ".join(parts) + f"; dropped {int((~good).sum())} of {len(good)} springs", stacklevel=4)


def _closest_distance(points: np.ndarray, mesh) -> str:
    """The smallest distance from ``points`` to the surface of ``mesh``, as the message says it.

    Where the two bounding boxes lie further apart than the larger box's diagonal, the boxes'
    distance is a lower bound within a factor of two of the answer, and the answer is said as
    "at least" that: a k-d tree's nearest query over points that far out visits nearly every
    node (seconds on a knee, for a message). Otherwise a k-d tree over the mesh's vertices and
    centroids picks the 64 nearest candidates, whose exact closest points on the surface are
    then computed.
    """
    from scipy.spatial import cKDTree

    low, high = points.min(axis=0), points.max(axis=0)
    mesh_low, mesh_high = mesh.bounds
    apart = float(np.linalg.norm(np.maximum(0.0, np.maximum(low - mesh_high, mesh_low - high))))
    size = max(float(np.linalg.norm(high - low)), float(np.linalg.norm(mesh_high - mesh_low)))
    if apart > size:
        return f"at least {apart:.4g} mm"
    tree = cKDTree(np.vstack([mesh.vertices, mesh.triangles_center]))
    rough, _ = tree.query(points)
    best = np.argsort(rough)[:64]
    try:
        _, distance, _ = mesh.nearest.on_surface(points[best])
    except (IndexError, ValueError):  # trimesh's query finds no candidate
        return f"{float(np.min(rough)):.4g} mm"
    return f"{float(distance.min()):.4g} mm"


class NoSpringsError(InputError):
    """A cast that made no spring (an :class:`~dea_opt.errors.InputError`); ``through_layer``
    counts the rays whose only hits in the window lay behind mesh 1's own far side (mesh 2 went
    through mesh 1's layer). A finite-kinematics solve whose pose comes there reports it as a
    failed answer (:mod:`dea_opt.finite.tracker`), not as bad input."""

    def __init__(self, message: str, through_layer: int = 0):
        super().__init__(message)
        self.through_layer = through_layer


def _raise_no_springs(m2, cos_inside, t_outside, n_rejected, origins2, options):
    """The InputError of a cast that made no spring, saying what the rays met instead."""
    max_gap, max_overlap = options["max_gap"], options["max_overlap"]
    window = (
        f"the proximity window -max_overlap={max_overlap:g} <= gap <= max_gap={max_gap:g} mm "
        f"with max_angle={options['max_angle']:g} deg"
    )
    ahead, behind = t_outside[t_outside > max_gap], t_outside[t_outside < 0]
    if len(cos_inside):
        best = float(np.degrees(np.arccos(np.clip(cos_inside.max(), -1, 1))))
        detail = (
            f"faces meet within the gap window but their normals are at least {best:.3g} deg "
            f"from facing each other (raise max_angle)"
        )
    elif n_rejected:
        detail = (
            f"the faces of mesh2 that {n_rejected} rays met within the window lie behind mesh1's own far "
            f"side (the rays went back through mesh1's layer): check the pose and that mesh1's normals "
            f"face mesh2"
        )
    elif len(ahead):
        detail = f"the smallest distance found along the normals is {ahead.min():.4g} mm (raise max_gap)"
    elif len(behind):
        detail = f"the shallowest overlap found is {-behind.max():.4g} mm (raise max_overlap)"
    else:
        detail = (
            f"no normal of mesh1 meets a face of mesh2 that faces it; the smallest distance "
            f"found between the meshes is {_closest_distance(origins2, m2)} (check pose, "
            f"flip, units, and that both meshes are in the same frame)"
        )
    raise NoSpringsError(f"mesh1 and mesh2 never face each other within {window}: {detail}", n_rejected)


def springs_from_meshes(
    mesh1,
    mesh2,
    *,
    thickness1=None,
    thickness2=None,
    pose=None,
    max_gap: float = MAX_GAP,
    max_overlap: float = MAX_OVERLAP,
    max_angle: float = MAX_ANGLE,
    flip: bool = False,
    labels=None,
    engine: str = "auto",
) -> SpringLayer:
    """Springs between two cartilage surfaces, by ray casting (JAM's elastic foundation).

    One spring per articular face of mesh 1: a face whose normal ray meets a face of mesh 2
    that faces it inside the proximity window ``-max_overlap <= gap <= max_gap`` with the two
    normals within ``max_angle`` of facing each other. A face of mesh 2 met behind mesh 1's own
    far (bone) side is never taken: the ray went back through the spring layer itself. Faces
    dropped by the window or rejected are counted in :attr:`SpringCast.dropped`
    (:func:`cast_springs`); :func:`~dea_opt.mesh.recast` re-casts at another pose with the
    window following it.

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
        spring; ``labels`` as given; ``target_points``, ``target_normals`` (N, 3) and
        ``target_faces`` (N,): where each ray met mesh 2 and that face's unit normal, in mesh
        2's own frame (before ``pose``).

    Raises
    ------
    InputError
        Bad meshes, a pose that is not rigid, a bad window or thickness, meshes whose cast
        would not fit in memory, or no face of mesh 1 facing mesh 2 within the window (the
        message gives the smallest distance found).
    """
    return cast_springs(
        mesh1,
        mesh2,
        thickness1=thickness1,
        thickness2=thickness2,
        pose=pose,
        max_gap=max_gap,
        max_overlap=max_overlap,
        max_angle=max_angle,
        flip=flip,
        labels=labels,
        engine=engine,
    ).layer
