"""The contact surface of a solution as a mesh with its data: what the VTK files and maps show.

Units: mm, mm^2, N, MPa; strain is dimensionless.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError

__all__ = ["SurfaceData", "contact_surface", "label_codes", "layer_surface", "spring_fields"]


@dataclass
class SurfaceData:
    """A mesh with cell data: what :func:`to_vtk` writes and :func:`read_vtk` returns.

    Attributes
    ----------
    points : ndarray, shape (P, 3)
        Vertex coordinates (mm).
    cells : ndarray of int32 or int64, shape (C, 3) or (C, 1)
        Triangles, or one vertex per spring (int32 for a layer triangulated through its
        springs, to halve the memory of the largest).
    cell_type : {"triangle", "vertex"}
    cell_data : dict {name: ndarray, shape (C,) or (C, 3)}
        See :func:`contact_surface` for the names and units.
    point_data : dict {name: ndarray, shape (P,) or (P, 3)}
        The same per-spring arrays when the points are the springs (a layer without a mesh,
        triangulated through its springs); empty otherwise.
    """

    points: np.ndarray
    cells: np.ndarray
    cell_type: str
    cell_data: dict = field(default_factory=dict)
    point_data: dict = field(default_factory=dict)

    @property
    def spring_data(self) -> dict:
        """The per-spring arrays, wherever they sit: point data of a triangulated point
        layer, else cell data."""
        return self.point_data if self.point_data else self.cell_data


def _label_data(labels: np.ndarray) -> np.ndarray:
    """Integer labels as int64; any other labels as codes into ``numpy.unique(labels)``."""
    if np.issubdtype(labels.dtype, np.integer) or labels.dtype == bool:
        return labels.astype(np.int64)
    text = labels.astype(str)
    return np.searchsorted(np.unique(text), text).astype(np.int64)


def label_codes(labels) -> dict:
    """``{label: code}`` of the integer ``label`` field of :func:`to_vtk` for text labels."""
    text = np.asarray(labels).astype(str)
    return {name: i for i, name in enumerate(np.unique(text).tolist())}


def spring_fields(layer, solution=None, static: SurfaceData | None = None) -> dict:
    """The per-spring arrays of :func:`contact_surface`; NaN results without a ``solution``
    (a frame that failed). ``static``: a surface of the same layer made earlier, whose arrays
    of the layer alone (gap, thickness, normal, area, source_face, label) are reused."""
    n = len(layer)
    if solution is None:
        nan = np.full(n, np.nan)
        pressure = strain = force = nan
        contact = np.zeros(n, dtype=np.uint8)
    else:
        pressure = np.asarray(solution.pressure, dtype=float)
        strain = np.asarray(solution.strain, dtype=float)
        force = np.asarray(solution.spring_force, dtype=float)
        contact = solution.in_contact.astype(np.uint8)
    if static is not None:
        data = dict(static.spring_data)
        data.update(pressure=pressure, strain=strain, in_contact=contact, spring_force=force)
        return {name: np.ascontiguousarray(value) for name, value in data.items()}
    data = {
        "pressure": pressure,
        "strain": strain,
        "gap": layer.gap,
        "thickness": layer.thickness,
        "in_contact": contact,
        "spring_force": force,
        "normal": layer.normals,
        "area": layer.areas,
    }
    if layer.source_face is not None:
        data["source_face"] = layer.source_face.astype(np.int64)
    if layer.labels is not None:
        data["label"] = _label_data(layer.labels)
    return {name: np.ascontiguousarray(value) for name, value in data.items()}


def _checked_faces(layer) -> tuple:
    vertices, faces = layer.surface
    faces = faces.astype(np.int64)
    if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
        raise InputError(
            f"layer.surface faces must index its {len(vertices)} vertices, got indices {faces.min()}..{faces.max()}"
        )
    source = layer.source_face.astype(np.int64)
    if source.size and (source.min() < 0 or source.max() >= len(faces)):
        raise InputError(
            f"layer.source_face must index the {len(faces)} surface faces, got {source.min()}..{source.max()}"
        )
    return vertices, faces, source


def contact_surface(solution, *, cells: str = "springs") -> SurfaceData:
    """The contact surface of ``solution`` as a mesh with its data, ready to write.

    Parameters
    ----------
    solution : Solution
    cells : {"springs", "surface"}
        ``"springs"`` (default): when the layer has ``surface`` and ``source_face`` (it came
        from a mesh), one triangle per spring, its source face, in spring order, so cell
        ``i`` is spring ``i`` (vertices not used by them are dropped). Otherwise (a
        generated layer, a springs table) the points are the springs, in spring order, the
        cells the triangles of :func:`~dea_opt.io.triangulate.point_triangulation` through
        them, and the arrays are point data: point ``i`` is spring ``i``. Only a layer that
        cannot be triangulated (fewer than three springs, all on a line) is written as one
        VTK_VERTEX cell per spring.
        ``"surface"``: every face of ``layer.surface``, unused vertices included; faces
        without a spring have ``spring`` -1, ``label`` -1 and 0 in every other field
        (threshold ``spring >= 0`` in ParaView to hide them). Needs ``surface`` and
        ``source_face`` and at most one spring per face.

    Returns
    -------
    SurfaceData
        Per-spring arrays (shape (N,) unless noted), in ``cell_data`` or ``point_data``:

        ==============  ========  =========================================================
        name            unit      meaning
        ==============  ========  =========================================================
        pressure        MPa       contact pressure ``-sigma`` (>= 0)
        strain          1         spring strain ``eps`` (< 0 in compression)
        gap             mm        initial gap along the normal (< 0 for an overlap)
        thickness       mm        unloaded spring length
        in_contact      1         1 where ``strain < 0``, else 0 (uint8)
        spring_force    N         ``-pressure * area``, tension positive (<= 0)
        normal          1         spring direction, body 1 to body 2, shape (N, 3)
        area            mm^2      the area the spring stands for
        source_face     -         index of the face in ``layer.surface`` (when known)
        label           -         integer labels as given; text labels as codes into
                                  their sorted unique values (:func:`label_codes`)
        spring          -         spring index, -1 for none (``cells="surface"`` only)
        ==============  ========  =========================================================
    """
    return layer_surface(solution.problem.layer, spring_fields(solution.problem.layer, solution), cells=cells)


def layer_surface(layer, data: dict, *, cells: str = "springs") -> SurfaceData:
    """The surface of ``layer`` carrying ``data`` (per-spring arrays, shape (N, ...)) as
    :func:`contact_surface` places them (on the springs' faces or points)."""
    has_faces = layer.surface is not None and layer.source_face is not None
    if cells not in ("springs", "surface"):
        raise InputError(f"cells must be 'springs' or 'surface', got {cells!r}")
    if cells == "surface":
        if not has_faces:
            raise InputError("cells='surface' needs a layer with surface and source_face; use cells='springs'")
        return _whole_surface(layer, data)
    if not has_faces:
        from .triangulate import point_triangulation

        triangles = point_triangulation(layer)
        if triangles is None:
            n = len(layer)
            return SurfaceData(layer.points.copy(), np.arange(n, dtype=np.int64)[:, None], "vertex", data)
        return SurfaceData(layer.points, triangles, "triangle", point_data=data)
    vertices, faces, source = _checked_faces(layer)
    triangles = faces[source]
    used, inverse = np.unique(triangles, return_inverse=True)
    return SurfaceData(vertices[used], inverse.reshape(-1, 3).astype(np.int64), "triangle", data)


def _whole_surface(layer, data) -> SurfaceData:
    vertices, faces, source = _checked_faces(layer)
    if len(np.unique(source)) != len(source):
        raise InputError(
            "cells='surface' needs at most one spring per face, but layer.source_face repeats "
            "faces; use cells='springs'"
        )
    n_faces = len(faces)
    spring = np.full(n_faces, -1, dtype=np.int64)
    spring[source] = np.arange(len(source))
    out = {}
    for name, value in data.items():
        if name == "source_face":
            continue
        fill = -1 if name == "label" else 0  # no NaN: VTK cannot read NaN from ASCII files
        full = np.full((n_faces,) + value.shape[1:], fill, dtype=value.dtype)
        full[source] = value
        out[name] = full
    out["source_face"] = np.arange(n_faces, dtype=np.int64)
    out["spring"] = spring
    return SurfaceData(vertices.copy(), faces, "triangle", out)
