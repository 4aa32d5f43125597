"""The cartilage layer as a set of normal springs between two rigid bodies."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ._checks.inputs import as_float_array, check_range
from .errors import InputError

__all__ = ["SpringLayer"]

_TARGETS = ("target_points", "target_normals", "target_faces")


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
    target_points : array_like, shape (N, 3), optional
        For springs cast from meshes: where each spring's ray met mesh 2, in mesh 2's own
        frame (before the cast's ``pose``), in mm.
    target_normals : array_like, shape (N, 3), optional
        The unit outward normal of the face of mesh 2 each ray met, in mesh 2's own frame.
        With ``target_points`` it is the target's tangent plane: the gap at another pose is
        where the spring's ray meets that plane moved by the pose
        (:func:`dea_opt.mesh.tangent_plane_gap`).
    target_faces : array_like of int, shape (N,), optional
        The face of mesh 2 (as checked, :attr:`dea_opt.mesh.SpringCast.mesh2`) each ray met.

    The three ``target_*`` arrays are given together or not at all (None for layers not
    made from meshes); they ride along through :meth:`subset`, :meth:`concatenate` and
    :meth:`with_gap` and nothing else reads them.
    """

    points: np.ndarray
    normals: np.ndarray
    areas: np.ndarray
    thickness: np.ndarray
    gap: np.ndarray = field(default_factory=lambda: np.zeros(()))  # 0 for every spring
    source_face: np.ndarray | None = None
    surface: tuple | None = None
    labels: np.ndarray | None = None
    target_points: np.ndarray | None = None
    target_normals: np.ndarray | None = None
    target_faces: np.ndarray | None = None
    #: The cast these springs came from (:attr:`cast`); set by the cast, not a field.
    _cast = None

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
                    f"source_face must be integers of shape ({n},), got shape {face.shape} and dtype {face.dtype}"
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
        self._set_targets(n)

    def _set_targets(self, n: int) -> None:
        given = [getattr(self, name) is not None for name in _TARGETS]
        if not any(given):
            return
        if not all(given):
            missing = [name for name, g in zip(_TARGETS, given) if not g]
            raise InputError(
                f"target_points, target_normals and target_faces are given together or not "
                f"at all; missing {', '.join(missing)}"
            )
        points = as_float_array("target_points", self.target_points, (n, 3))
        check_range("target_points", points, "mm")
        normals = as_float_array("target_normals", self.target_normals, (n, 3))
        length = np.linalg.norm(normals, axis=1)
        if n and np.abs(length - 1.0).max() > 1e-6:
            i = int(np.argmax(np.abs(length - 1.0)))
            raise InputError(f"target_normals must be unit vectors, got length {length[i]:.6g} at index {i}")
        faces = np.asarray(self.target_faces)
        if faces.shape != (n,) or not np.issubdtype(faces.dtype, np.integer) or (n and faces.min() < 0):
            raise InputError(
                f"target_faces must be integers >= 0 of shape ({n},), got shape {faces.shape} and dtype {faces.dtype}"
            )
        set_ = object.__setattr__
        set_(self, "target_points", _readonly(points))
        # rows already unit to rounding are kept bit for bit, so that subsets are exact
        off = np.abs(length - 1.0) > 1e-12
        if off.any():
            normals[off] /= length[off, None]
        set_(self, "target_normals", _readonly(normals))
        set_(self, "target_faces", _readonly(faces.astype(np.int64)))

    @classmethod
    def _checked(cls, points, normals, areas, thickness, gap, source_face, surface, labels, targets) -> SpringLayer:
        """A layer of arrays already checked by a layer or a cast, not checked again (a
        finite-kinematics solve re-casts its springs many times): they are made read-only, not
        copied, so the caller gives arrays nothing else holds. ``surface`` is another layer's
        (checked, read-only); ``targets`` is ``(target_points, target_normals, target_faces)`` or
        None."""
        layer = object.__new__(cls)
        values = {
            "points": points,
            "normals": normals,
            "areas": areas,
            "thickness": thickness,
            "gap": gap,
            "source_face": source_face,
            "labels": labels,
        }
        if targets is not None:
            values.update(zip(_TARGETS, targets))
        for name in ("points", "normals", "areas", "thickness", "gap", "source_face", "labels", *_TARGETS):
            value = values.get(name)
            object.__setattr__(layer, name, None if value is None else _readonly(np.asarray(value)))
        object.__setattr__(layer, "surface", surface)
        return layer

    @property
    def cast(self):
        """The :class:`~dea_opt.mesh.SpringCast` whose rays made these springs
        (:func:`~dea_opt.mesh.springs_from_meshes`, ``cast_springs(...).layer``, and a subset of
        either), else None. With
        ``kinematics="finite"`` and no ``targets``, a layer that is its cast's own is re-cast from
        it as body 2 moves, and a subset's tangent planes are measured against its meshes (the
        ``gap_error`` validity check)."""
        return self._cast

    @property
    def has_targets(self) -> bool:
        """Whether the springs know their targets on mesh 2 (layers cast from meshes)."""
        return self.target_points is not None

    def subset(self, index) -> SpringLayer:
        """The springs ``index`` selects (a boolean mask of shape (N,) or integer indices).

        Every per-spring array (labels, source faces, targets) is subset with them; the
        surface is kept whole, so ``source_face`` still indexes it.
        """
        index = np.asarray(index)
        n = len(self)
        if index.dtype == bool:
            if index.shape != (n,):
                raise InputError(f"a boolean index must have shape ({n},), got {index.shape}")
        elif not np.issubdtype(index.dtype, np.integer) or index.ndim != 1:
            raise InputError(
                f"index must be a boolean mask ({n},) or 1-D integer indices, got "
                f"dtype {index.dtype} and shape {index.shape}"
            )
        elif len(index) and (index.min() < -n or index.max() >= n):
            raise InputError(f"indices must lie in [{-n}, {n - 1}], got [{index.min()}, {index.max()}]")

        def take(arr):
            return None if arr is None else np.asarray(arr)[index]

        subset = SpringLayer(
            self.points[index],
            self.normals[index],
            self.areas[index],
            self.thickness[index],
            self.gap[index],
            source_face=take(self.source_face),
            surface=self.surface,
            labels=take(self.labels),
            target_points=take(self.target_points),
            target_normals=take(self.target_normals),
            target_faces=take(self.target_faces),
        )
        if self._cast is not None:  # its springs came from the same meshes
            object.__setattr__(subset, "_cast", self._cast)
        return subset

    @staticmethod
    def concatenate(layers, labels=None) -> SpringLayer:
        """One layer from several, springs in order (e.g. medial and lateral compartments).

        Parameters
        ----------
        layers : sequence of SpringLayer
        labels : sequence of str, optional
            One label per layer, given to all its springs (overriding their own labels).
            Without it, springs keep their labels when every layer has them (else None).

        Returns
        -------
        SpringLayer
            Surfaces are stacked (``source_face`` offset to index the stacked faces) when
            every layer has one, or kept when all share the same surface; targets are kept
            when every layer has them (their face indices refer to each layer's own mesh 2).
        """
        layers = list(layers) if not isinstance(layers, SpringLayer) else [layers]
        if not layers or not all(isinstance(x, SpringLayer) for x in layers):
            raise InputError(f"layers must be a non-empty sequence of SpringLayer, got {layers!r}")
        if labels is not None:
            labels = list(labels) if not isinstance(labels, str) else [labels]
            if len(labels) != len(layers):
                raise InputError(f"labels must give one label per layer ({len(layers)}), got {len(labels)}")
            spring_labels = np.repeat(np.array([str(x) for x in labels]), [len(x) for x in layers])
        elif all(x.labels is not None for x in layers):
            spring_labels = np.concatenate([x.labels for x in layers])
        else:
            spring_labels = None

        def stack(name):
            parts = [getattr(x, name) for x in layers]
            return None if any(p is None for p in parts) else np.concatenate(parts)

        surface, source_face = _stacked_surfaces(layers)
        targets = {name: stack(name) for name in _TARGETS}
        if any(v is None for v in targets.values()):
            targets = {}
        return SpringLayer(
            stack("points"),
            stack("normals"),
            stack("areas"),
            stack("thickness"),
            stack("gap"),
            source_face=source_face,
            surface=surface,
            labels=spring_labels,
            **targets,
        )

    def __len__(self) -> int:
        return self.points.shape[0]

    @property
    def n_springs(self) -> int:
        """Number of springs N."""
        return self.points.shape[0]

    def with_gap(self, gap) -> SpringLayer:
        """A copy with new initial gaps (shape (N,) or scalar, mm)."""
        from dataclasses import replace

        return replace(self, gap=gap)

    def __repr__(self) -> str:
        return f"SpringLayer(N={len(self)}, total area={self.areas.sum():.4g} mm^2)"


def _stacked_surfaces(layers) -> tuple:
    """``(surface, source_face)`` of concatenated layers: a shared surface kept, distinct
    ones stacked with the faces and source faces offset; ``(None, None)`` when one lacks it."""
    if any(x.surface is None or x.source_face is None for x in layers):
        return None, None
    first = layers[0].surface
    if all(_same(x.surface[0], first[0]) and _same(x.surface[1], first[1]) for x in layers):
        return first, np.concatenate([x.source_face for x in layers])
    vertices, faces, sources, n_vertices, n_faces = [], [], [], 0, 0
    for x in layers:
        vertices.append(x.surface[0])
        faces.append(x.surface[1] + n_vertices)
        sources.append(x.source_face + n_faces)
        n_vertices += len(x.surface[0])
        n_faces += len(x.surface[1])
    return (np.vstack(vertices), np.vstack(faces)), np.concatenate(sources)


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return a is b or (a.shape == b.shape and bool(np.array_equal(a, b)))
