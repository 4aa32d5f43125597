"""Checking and repairing triangle meshes: degenerate faces, inconsistent winding, inside-out surfaces.

Each repair warns with the count of what it changed; a mesh with nothing left to use is an
:class:`~dea_opt.errors.InputError`. Lengths in mm.
"""

from __future__ import annotations

import warnings

import numpy as np

from .._checks.thresholds import DEGENERATE_AREA
from ..errors import InputError

__all__ = ["SIZE_RANGE", "check_size", "clean", "repair"]

#: The sizes (mm) of meshes dea-opt computes with: the bounding-box diagonal at least the
#: first, every coordinate at most the second in magnitude. Below, trimesh's merge tolerance
#: (1e-8) fuses distinct vertices; above, its merge keys overflow 64-bit integers and
#: Embree's float32 loses the faces. Cartilage spans 10-100 mm; a mesh in metres (0.01-0.1)
#: or micrometres (1e4-1e5) is inside, and is then flagged by the validity report.
SIZE_RANGE = (1e-3, 1e9)


def clean(vertices, faces, source: str, scale: float = 1.0):
    """A checked Trimesh from arrays, and ``(input index of each face kept, input face count)``
    when faces were dropped (None when all are kept)."""
    import trimesh

    try:
        vertices = np.array(vertices, dtype=float)
        faces = np.array(faces)
    except (TypeError, ValueError):
        raise InputError(f"{source}: vertices and faces must be numeric arrays") from None
    if faces.size == 0 or vertices.size == 0:
        raise InputError(
            f"{source} is empty: it has no triangle faces ({len(vertices)} vertices); expected a triangle surface"
        )
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise InputError(f"{source}: vertices must have shape (V, 3), got {vertices.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise InputError(f"{source}: faces must be triangles, shape (F, 3), got {faces.shape}")
    if not np.issubdtype(faces.dtype, np.integer):
        if not np.all(np.mod(faces, 1) == 0):
            raise InputError(f"{source}: faces must hold integer vertex indices, got {faces.dtype}")
        faces = faces.astype(np.int64)
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise InputError(
            f"{source}: face indices must lie in [0, {len(vertices) - 1}], got [{faces.min()}, {faces.max()}]"
        )
    finite = np.isfinite(vertices).all(axis=1)
    if finite.all():
        check_size(vertices * scale if scale != 1.0 else vertices, source)
    if not finite.all():
        i = int(np.argmin(finite))
        raise InputError(
            f"{source}: vertices must be finite, found NaN or inf in {int((~finite).sum())} of "
            f"{len(vertices)} vertices (the first is vertex {i}: {vertices[i].tolist()})"
        )
    if scale != 1.0:
        vertices = vertices * scale
    mesh = trimesh.Trimesh(vertices, faces, process=True)  # merges the per-face vertices of STL
    return repair(mesh, source, copy=False)


def check_size(vertices: np.ndarray, source: str) -> None:
    """An InputError when finite ``vertices`` (V, 3) (mm) lie outside :data:`SIZE_RANGE`."""
    if not len(vertices):
        return
    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    top = float(np.abs(np.concatenate([lo, hi])).max())
    span = float(np.linalg.norm((hi - lo) / max(top, 1e-300))) * top  # no overflow near 1e308
    small, large = SIZE_RANGE
    if span < small or top > large:
        what = (
            f"spans only {span:.3g} mm (its bounding-box diagonal)"
            if span < small
            else f"has coordinates up to {top:.3g} mm"
        )
        raise InputError(
            f"{source} {what}, outside the sizes dea-opt computes with (a diagonal of at least "
            f"{small:g} mm, coordinates within +-{large:g} mm): its vertices would merge into "
            f"points or its products overflow; give the mesh in mm (load_mesh(path, scale=...))"
        )


def repair(mesh, source: str, copy: bool):
    """Drop zero-area faces, make winding consistent and closed surfaces outward."""
    bad = ~_nondegenerate(mesh)
    kept = None
    if bad.any():
        if bad.all():
            raise InputError(
                f"{source}: all {len(bad)} faces are degenerate (zero area); expected a "
                f"triangle surface with faces of nonzero area"
            )
        if copy:
            mesh, copy = mesh.copy(), False
        kept = (np.flatnonzero(~bad), len(bad))  # input index of each face kept, input count
        mesh.update_faces(~bad)
        mesh.remove_unreferenced_vertices()
        warnings.warn(f"{source}: dropped {int(bad.sum())} degenerate (zero-area) faces of {len(bad)}", stacklevel=4)
    if not mesh.is_winding_consistent:
        if copy:
            mesh, copy = mesh.copy(), False
        flipped = _fix_winding(mesh)
        if mesh.is_winding_consistent:
            warnings.warn(f"{source}: winding was inconsistent; re-wound {flipped} faces", stacklevel=4)
        else:
            warnings.warn(
                f"{source}: winding is inconsistent and could not be repaired (non-manifold "
                f"edges?); face normals may point either way",
                stacklevel=4,
            )
    if mesh.is_watertight and mesh.is_winding_consistent and _signed_volume(mesh) < 0:
        if copy:
            mesh, copy = mesh.copy(), False
        mesh.invert()
        warnings.warn(f"{source}: the closed surface was inside out; inverted so normals point outward", stacklevel=4)
    return mesh, kept


def _fix_winding(mesh) -> int:
    """Make the winding consistent across every shared edge; returns the faces re-wound.

    Faces sharing an edge must run it in opposite directions. A breadth-first tree over the
    face adjacency gives each face its flip relative to the root of its piece (accumulated
    by pointer jumping, vectorized); each piece then keeps the orientation most of its faces
    already had. (trimesh's own ``fix_winding`` needs networkx.)
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import breadth_first_tree, connected_components

    faces = mesh.faces
    n = len(faces)
    pairs = np.asarray(mesh.face_adjacency)
    if not len(pairs):
        return 0
    edges = np.asarray(mesh.face_adjacency_edges)

    def runs(face, u, v):  # does the face traverse the edge u -> v?
        f = faces[face]
        return ((f == u[:, None]) & (np.roll(f, -1, axis=1) == v[:, None])).any(axis=1)

    # two faces that run their shared edge the same way need opposite flips
    differ = runs(pairs[:, 0], edges[:, 0], edges[:, 1]) == runs(pairs[:, 1], edges[:, 0], edges[:, 1])
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n)).tocsr()
    n_pieces, piece = connected_components(graph, directed=False)
    # a virtual node n joined to one face of each piece makes a single breadth-first tree
    roots = np.unique(piece, return_index=True)[1]
    rows = np.concatenate([pairs[:, 0], np.full(len(roots), n)])
    cols = np.concatenate([pairs[:, 1], roots])
    differ = np.concatenate([differ, np.zeros(len(roots), dtype=bool)])
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n + 1, n + 1)).tocsr()
    tree = breadth_first_tree(graph, n, directed=False).tocoo()
    child = np.arange(n + 1)
    parent = child.copy()
    parent[tree.col] = tree.row
    key = np.minimum(rows, cols) * (n + 1) + np.maximum(rows, cols)
    order = np.argsort(key)
    link = np.minimum(child, parent) * (n + 1) + np.maximum(child, parent)
    found = np.searchsorted(key[order], link).clip(0, len(key) - 1)
    flip = np.where(parent != child, differ[order][found], False)
    while np.any(parent != parent[parent]):  # flip relative to the root: xor along the path
        flip = flip ^ np.where(parent != child, flip[parent], False)
        parent = parent[parent]
    flip = flip[:n]
    # keep each piece's majority orientation
    share = np.bincount(piece, weights=flip.astype(float), minlength=n_pieces) / np.bincount(piece)
    flip ^= share[piece] > 0.5
    if flip.any():
        mesh.faces = np.where(flip[:, None], faces[:, ::-1], faces)
    return int(flip.sum())


def _signed_volume(mesh) -> float:
    """Enclosed volume (mm^3), negative for an inside-out closed surface (cheaper than
    trimesh's mass properties, which also compute the inertia)."""
    tri = mesh.triangles - mesh.vertices.mean(axis=0)  # centred: less cancellation
    return float(np.einsum("ij,ij->", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])) / 6.0)


def _nondegenerate(mesh) -> np.ndarray:
    area = mesh.area_faces
    return mesh.nondegenerate_faces() & (area > DEGENERATE_AREA * max(mesh.scale, 1e-300) ** 2)
