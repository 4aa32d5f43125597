"""Meshes 1 and 2 as casts at any pose see them: what does not depend on the pose, measured once.

Written math: ``formulations/finite.md`` ("Re-casting"). Behind each face of mesh 1 its far side
and thickness (:class:`Mesh1`); each face of mesh 2 as a plane and a barycentric map, with a walker
across its edges and Embree's first hits (:class:`Mesh2`); and, per face of mesh 2, the face of
the far side its inward ray met last (:class:`FarSide`), so that a thickness measured again where
a hit moved is followed from there. Each is kept in its mesh's trimesh cache (emptied when the
mesh changes), so that the solves of a load path measure each face once. A cast of a few hundred
faces (:mod:`dea_opt.mesh.facecast`) reads them many times a solve, so they are plain arrays:
reading a trimesh property checks the mesh's hash every time.
"""

from __future__ import annotations

import numpy as np

from .raycast import _caster, _engine, _self_epsilon
from .springs import _thickness
from .walk import Planes, Walker, dot

__all__ = ["FarSide", "Mesh1", "Mesh2"]


def _cached(mesh, key, build):
    """``build()`` kept in ``mesh``'s trimesh cache under ``key`` (built again once the mesh changed)."""
    cache = getattr(mesh, "_cache", None)
    found = cache[key] if cache is not None else None
    if found is None:
        found = build()
        if cache is not None:
            cache[key] = found
    return found


class _FirstHit:
    """The first crossing of a mesh along rays, from their origins on: Embree's first-hit query
    called directly (the scene kept, no check of the mesh's hash per call), the distance taken
    in float64 to the plane of the face it reports; the numpy grid without Embree."""

    def __init__(self, mesh, engine, planes: Planes):
        self.mesh, self.engine, self.planes = mesh, engine, planes
        self._scene()

    def _scene(self) -> None:
        self.scene = None
        if _engine(self.engine) == "embree":
            intersector = _caster(self.mesh, self.engine).intersector
            self.scene = intersector._scene  # trimesh's wrapper: float32, scaled to the mesh's box

    def __getstate__(self) -> dict:
        # an Embree scene does not pickle (a cast is sent to a worker with the meshes' caches)
        return {k: v for k, v in self.__dict__.items() if k != "scene"}

    def __setstate__(self, state) -> None:
        self.__dict__.update(state)
        self.scene = None
        self._scene_wanted = True

    def __call__(self, origins, directions, t_min: float = 0.0):
        """``(face, t)`` of the first crossing with ``t > t_min`` per ray (-1 and NaN where none)."""
        n = len(origins)
        if self.__dict__.pop("_scene_wanted", False):  # unpickled: the scene built again
            self._scene()
        if self.scene is None or not n:
            return _caster(self.mesh, self.engine).nearest(origins, directions, t_min, np.inf)
        start = origins + t_min * directions if t_min else origins
        first = np.asarray(self.scene.run(start, directions.astype(np.float32)), dtype=np.int64)
        face, dist = np.full(n, -1, dtype=np.int64), np.full(n, np.nan)
        found = np.flatnonzero(first >= 0)
        t = self.planes.distance(first[found], origins[found], directions[found])
        good = t > t_min
        face[found[good]], dist[found[good]] = first[found[good]], t[good]
        again = found[~good]  # float32 traversal met the starting face itself: every crossing
        if len(again):
            face[again], dist[again] = _caster(self.mesh, self.engine)._nearest_of_all(
                origins[again], directions[again], t_min, np.inf
            )
        return face, dist


class Mesh1:
    """Mesh 1's faces as a cast sees them, and what lies behind each (measured when first asked).

    :meth:`of` keeps one per mesh and cast options in the mesh's trimesh cache (emptied when the
    mesh changes), so that the solves of a load path measure each face once.
    """

    @classmethod
    def of(cls, cast) -> Mesh1:
        key = f"dea_opt_finite_mesh1_{bool(cast.options['flip'])}_{cast.options['engine']}"
        return _cached(cast.mesh1, key, lambda: cls(cast))

    def __init__(self, cast):
        m1, options = cast.mesh1, cast.options
        self.mesh, self.options = m1, options
        self.centroids = np.array(m1.triangles_center, dtype=float)
        normals = np.array(m1.face_normals, dtype=float)
        self.face_normals = normals  # as the mesh has them (a back face's orientation)
        self.normals = -normals if options["flip"] else normals
        self.areas = np.array(m1.area_faces, dtype=float)
        self.eps = _self_epsilon(m1)
        n = len(m1.faces)
        self.back_face = np.full(n, -2, dtype=np.int64)  # -2: not measured yet
        self.depth = np.full(n, np.nan)  # NaN: not measured yet (inf: nothing behind)
        self._thickness = np.full(n, np.nan)
        self._measured = np.zeros(n, dtype=bool)

    @property
    def neighbours(self) -> np.ndarray:
        """``(F, K)``: the faces sharing an edge with each face (trimesh's ``face_adjacency``), padded
        with -1 (``K`` = 3 on a manifold mesh)."""
        table = getattr(self, "_neighbours", None)
        if table is None:
            n = len(self.areas)
            pairs = np.asarray(self.mesh.face_adjacency, dtype=np.int64).reshape(-1, 2)
            both = np.concatenate([pairs, pairs[:, ::-1]])
            both = both[np.argsort(both[:, 0], kind="stable")]
            start = np.searchsorted(both[:, 0], np.arange(n + 1))
            counts = np.diff(start)
            table = np.full((n, max(int(counts.max(initial=0)), 1)), -1, dtype=np.int64)
            column = np.arange(len(both)) - np.repeat(start[:-1], counts)
            table[both[:, 0], column] = both[:, 1]
            self._neighbours = table
        return table

    def behind(self, faces) -> tuple[np.ndarray, np.ndarray]:
        """``(back_face, depth)`` of ``faces``: the first crossing of mesh 1 behind each, its far side."""
        todo = faces[self.back_face[faces] == -2]
        if len(todo):
            todo = np.unique(todo)
            face, depth = _caster(self.mesh, self.options["engine"]).nearest(
                self.centroids[todo], -self.normals[todo], self.eps, np.inf
            )
            self.back_face[todo] = face
            self.depth[todo] = np.where(face >= 0, depth, np.inf)
        return self.back_face[faces], self.depth[faces]

    def depth_behind(self, faces) -> np.ndarray:
        """The ``depth`` of :meth:`behind` alone (one gather where every face was measured)."""
        depth = self.depth[faces]
        return self.behind(faces)[1] if np.isnan(depth).any() else depth

    def thickness(self, faces) -> np.ndarray:
        """Body 1's cartilage thickness at ``faces`` by the cast's ``thickness1`` (measured once a face)."""
        todo = faces[~self._measured[faces]]
        if len(todo):
            todo = np.unique(todo)
            spec = self.options["thickness1"]
            through = None
            if spec is None:  # the crossing behind the face, where it leaves the layer
                back, depth = self.behind(todo)
                leaves = np.einsum("ij,ij->i", self.face_normals[back.clip(0)], -self.normals[todo]) > 0
                through = np.where((back >= 0) & leaves, depth, np.nan)
            self._thickness[todo] = _thickness(
                spec, self.mesh, todo, self.centroids[todo], -self.normals[todo], self.options["engine"], through
            )
            self._measured[todo] = True
        return self._thickness[faces]


class FarSide:
    """Per face of mesh 2, the face of a surface met along its inward normal: the cartilage's own
    far side (``leaving``: the crossing must leave the surface) or a bone mesh.

    A hit that moved on its face is measured again by intersecting its ray with the plane of
    the far face met last; where that point leaves the far face (or none was met yet) the ray
    is cast. The far side of a cartilage layer is a sheet a few mm away, so nearly every ray
    stays on its far face while its hit moves by less than a face.
    """

    def __init__(self, surface, engine, leaving: bool, n_faces: int, planes: Planes | None = None):
        self.planes = Planes(surface) if planes is None else planes
        self.first = _FirstHit(surface, engine, self.planes)
        self.walker = Walker(self.planes)
        self.leaving = leaving
        self.face = np.full(n_faces, -2, dtype=np.int64)  # -2: none met yet

    def thickness(self, faces, points, directions, guess=None) -> tuple[np.ndarray, np.ndarray]:
        """``(t, far)``: the distance from ``points`` (K, 3) on faces ``faces`` (K,) of mesh 2 along
        ``directions`` (their inward normals) to the far side, NaN where the ray meets none (or
        enters it), and the far face met (-1: none). ``guess`` (K,) are far faces to try first
        (a spring's last one; -2 for none), else the last met from each face."""
        planes = self.planes
        far = self.face[faces] if guess is None else np.where(guess >= -1, guess, self.face[faces])
        t, along = np.full(len(faces), np.nan), np.zeros(len(faces))  # along: n . d at the far face
        known = np.flatnonzero(far >= 0)
        if len(known):
            sel = slice(None) if len(known) == len(faces) else known  # usually all: no copies
            walk = self.walker.follow(far[sel], points[sel], directions[sel])
            on = walk.found & (walk.t > planes.eps)
            t[sel] = np.where(on, walk.t, np.nan)
            far[sel] = np.where(on, walk.face, -2)
            along[sel] = walk.along
        cast = np.flatnonzero(far < 0)
        if len(cast):
            face, d = self.first(points[cast], directions[cast], planes.eps)
            self.face[faces[cast]] = face
            far[cast] = face
            t[cast] = d
            hit = face >= 0
            along[cast[hit]] = dot(np.take(planes.normals, face[hit], axis=0), directions[cast[hit]])
        if self.leaving:
            t = np.where(along > 0, t, np.nan)  # the ray leaves the surface there (and met one)
        return t, far


class Mesh2:
    """Mesh 2 as a cast at any pose sees it, in its own frame: planes, barycentric maps, the
    first-hit query, and what lies behind its faces (:class:`FarSide`). One per mesh and engine,
    kept like :class:`Mesh1`."""

    @classmethod
    def of(cls, cast) -> Mesh2:
        return _cached(cast.mesh2, f"dea_opt_finite_mesh2_{cast.options['engine']}", lambda: cls(cast.mesh2, cast))

    def __init__(self, mesh, cast):
        self.mesh, self.engine = mesh, cast.options["engine"]
        self.planes = Planes(mesh)
        self.first = _FirstHit(mesh, self.engine, self.planes)
        self.walker = Walker(self.planes)
        self._far: dict = {}

    def far_side(self, spec) -> FarSide:
        """The :class:`FarSide` of a ``thickness2`` given as None (through mesh 2) or a bone mesh."""
        key = id(spec)
        found = self._far.get(key)
        if found is None or found[0] is not spec:
            n = len(self.planes.offset)
            side = FarSide(self.mesh, self.engine, True, n, self.planes) if spec is None else None
            found = (spec, side or FarSide(spec, self.engine, False, n))
            self._far[key] = found
        return found[1]

    def thickness(self, spec, faces, points, guess=None) -> tuple[np.ndarray, np.ndarray]:
        """``(h2, far)``: body 2's cartilage thickness at ``points`` (own frame) on ``faces``, by
        ``thickness2``, and the far faces met (:meth:`FarSide.thickness`; -1 where not measured)."""
        if spec is None or not isinstance(spec, (float, np.ndarray)):
            directions = -np.take(self.planes.normals, faces, axis=0)
            return self.far_side(spec).thickness(faces, points, directions, guess)
        far = np.full(len(faces), -1, dtype=np.int64)
        return (np.full(len(faces), spec) if isinstance(spec, float) else spec[faces]), far
