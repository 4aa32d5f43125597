"""The cartilage layer as a set of normal springs between two rigid bodies."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._validate import as_float_array, check_range
from .errors import InputError

__all__ = ["SpringLayer"]


def _readonly(arr: np.ndarray) -> np.ndarray:
    arr.setflags(write=False)
    return arr


def _unit_normals(normals: np.ndarray) -> np.ndarray:
    """Each finite row divided by its length, without overflow or underflow: scaled by its
    largest component first (a row of 1e200 would square to inf, one of 1e-200 to 0, and
    either would silently become a zero normal). A zero row is an :class:`InputError`; no
    row is ever dropped."""
    top = np.abs(normals).max(axis=1, initial=0.0)
    if normals.shape[0] and not (top > 0).all():
        i = int(np.argmin(top))
        raise InputError(f"normals must be nonzero vectors, got {normals[i].tolist()} at index {i}")
    scaled = normals / top[:, None] if normals.shape[0] else normals
    unit = scaled / np.linalg.norm(scaled, axis=1)[:, None]
    # Every scaled row has a component of magnitude 1, so its length lies in [1, sqrt(3)].
    assert np.isfinite(unit).all()
    return unit


@dataclass(frozen=True, eq=False)
class SpringLayer:
    """N unilateral springs normal to the articular surface.

    Parameters
    ----------
    points : array_like, shape (N, 3)
        Spring positions in mm (face centroids of the articular surface).
    normals : array_like, shape (N, 3)
        Spring directions, pointing from body 1 to body 2; normalized here.
    areas : array_like, shape (N,) or scalar
        Surface area each spring stands for, in mm^2 (> 0).
    thickness : array_like, shape (N,) or scalar
        Unloaded spring length: the total cartilage thickness, in mm (> 0).
    gap : array_like, shape (N,) or scalar, default 0
        Initial distance between the surfaces along the normal, in mm: 0 for a bonded
        layer, positive where the surfaces do not touch yet, negative where they overlap.
    source_face : array_like of int, shape (N,), optional
        Index of the face of ``surface`` each spring sits on, to map results back.
    surface : tuple (vertices (V, 3), faces (F, 3)), optional
        The triangle surface carrying the springs, for output files and pictures.
    labels : array_like of str or int, shape (N,), optional
        A region label per spring (e.g. ``"medial"``) for regional statistics.
    """

    points: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    thickness: np.ndarray
    gap: np.ndarray = 0.0
    source_face: np.ndarray | None = None
    surface: tuple | None = None
    labels: np.ndarray | None = None

    def __post_init__(self):
        points = as_float_array("points", self.points, (None, 3))
        check_range("points", points, "mm")
        n = points.shape[0]
        normals = _unit_normals(as_float_array("normals", self.normals, (n, 3)))
        areas = as_float_array("areas", self.areas, (n,), allow_scalar_for=n)
        thickness = as_float_array("thickness", self.thickness, (n,), allow_scalar_for=n)
        gap = as_float_array("gap", self.gap, (n,), allow_scalar_for=n)
        for name, arr, unit in (("areas", areas, "mm^2"), ("thickness", thickness, "mm")):
            if n and not (arr > 0).all():
                i = int(np.argmin(arr))
                raise InputError(f"{name} must be > 0 everywhere, got {arr[i]} at index {i}")
            check_range(name, arr, unit, positive=True)
        check_range("gap", gap, "mm")
        set_ = object.__setattr__
        set_(self, "points", _readonly(points))
        set_(self, "normals", _readonly(np.ascontiguousarray(normals)))
        set_(self, "areas", _readonly(areas))
        set_(self, "thickness", _readonly(thickness))
        set_(self, "gap", _readonly(gap))
        if self.source_face is not None:
            face = np.asarray(self.source_face)
            if face.shape != (n,) or not np.issubdtype(face.dtype, np.integer):
                raise InputError(
                    f"source_face must be integers of shape ({n},), got shape {face.shape} "
                    f"and dtype {face.dtype}"
                )
            set_(self, "source_face", _readonly(face.copy()))
        if self.surface is not None:
            try:
                vertices = as_float_array("surface vertices", self.surface[0], (None, 3))
                faces = np.asarray(self.surface[1])
            except (TypeError, IndexError):
                raise InputError("surface must be a tuple (vertices (V, 3), faces (F, 3))") from None
            if faces.ndim != 2 or faces.shape[1] != 3 or not np.issubdtype(faces.dtype, np.integer):
                raise InputError(f"surface faces must be integers of shape (F, 3), got {faces.shape}")
            set_(self, "surface", (_readonly(vertices), _readonly(faces.copy())))
        if self.labels is not None:
            labels = np.asarray(self.labels)
            if labels.shape != (n,):
                raise InputError(f"labels must have shape ({n},), got {labels.shape}")
            set_(self, "labels", _readonly(labels.copy()))

    def __len__(self) -> int:
        return self.points.shape[0]

    @property
    def n_springs(self) -> int:
        """Number of springs N."""
        return self.points.shape[0]

    @classmethod
    def from_meshes(cls, mesh1, mesh2, **options) -> SpringLayer:
        """Springs between two triangle surfaces, by ray casting from mesh 1 onto mesh 2.

        A thin front to :func:`dea_opt.mesh.springs_from_meshes`; ``options`` are its keywords:
        ``thickness1=None, thickness2=None, pose=None, max_gap=2.0, max_overlap=1.0,
        max_angle=60.0, flip=False, labels=None, engine="auto"``.

        Parameters
        ----------
        mesh1, mesh2 : path, trimesh.Trimesh or (vertices (V, 3), faces (F, 3))
            Body 1's cartilage surface (carries the springs) and body 2's, in mm.

        Returns
        -------
        SpringLayer
            With ``source_face`` and ``surface`` set so that results map back to mesh 1.
        """
        from .mesh import springs_from_meshes

        return springs_from_meshes(mesh1, mesh2, **options)

    def with_gap(self, gap) -> SpringLayer:
        """A copy with new initial gaps (shape (N,) or scalar, mm)."""
        from dataclasses import replace

        return replace(self, gap=gap)

    def __repr__(self) -> str:
        return f"SpringLayer(N={len(self)}, total area={self.areas.sum():.4g} mm^2)"
