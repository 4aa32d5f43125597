"""The 3-D pressure map of a report: the cartilage surface coloured by pressure, for Plotly.

The figure is written as plain data (``{"data", "layout"}``) with its arrays as Plotly's typed
arrays (``{"dtype": "f4", "bdata": base64}``), so the page carries 4 bytes per number rather than
its decimal text. Springs cast from a mesh stand for its faces: each face gets its own three
vertices, all with its spring's pressure, so the faces are drawn flat, as the springs are, and
hovering a face shows its spring's pressure (vertex values, which Plotly reports on hover).
Springs on points are the vertices of a triangulation through them, each with its pressure.
Faces out of contact are grey.
Each region's centre of pressure, and the whole contact's, is a marker with its name.
"""

from __future__ import annotations

import base64

import numpy as np

__all__ = ["FACE_LIMIT", "pressure_view"]

#: The most faces the view draws (about 1.5 MB in the page); beyond, the faces out of contact are
#: left out, then every k-th face in contact is kept.
FACE_LIMIT = 60_000


def _typed(values, dtype="f4") -> dict:
    array = np.ascontiguousarray(values, dtype={"f4": np.float32, "i4": np.int32}[dtype])
    return {"dtype": dtype, "bdata": base64.b64encode(array.tobytes()).decode("ascii")}


def _faces(solution):
    """``(vertices (P, 3), triangles (T, 3), values, in contact (T,), per_vertex, note)``.

    Springs cast from a mesh: the mesh's faces, each with its own three vertices carrying its
    spring's pressure (drawn flat, hovered as the spring's). Springs on points: a triangulation
    through them (:func:`~dea_opt.io.triangulate.point_triangulation`), each spring a vertex
    carrying its pressure (drawn smooth between springs, hovered as the nearest spring's)."""
    layer = solution.problem.layer
    pressure = np.asarray(solution.pressure, float)
    contact = np.asarray(solution.in_contact, bool)
    if layer.surface is not None and layer.source_face is not None:
        vertices, faces = layer.surface
        triangles = np.asarray(faces, np.int64)[layer.source_face]
        value, touching, per_vertex = pressure, contact, False
        vertices = np.asarray(vertices, float)
    else:
        from ..io.triangulate import point_triangulation

        triangles = point_triangulation(layer)
        triangles = np.zeros((0, 3), np.int64) if triangles is None else np.asarray(triangles, np.int64)
        vertices, value, per_vertex = np.asarray(layer.points, float), pressure, True
        touching = contact[triangles].any(axis=1)
    note = ""
    if len(triangles) > FACE_LIMIT:
        keep = touching if touching.sum() <= FACE_LIMIT else touching & (np.cumsum(touching) % 2 == 0)
        step = max(1, int(np.ceil(keep.sum() / FACE_LIMIT)))
        keep = np.flatnonzero(keep)[::step]
        note = (
            f"{len(keep)} of the {len(triangles)} faces are drawn (those in contact{', thinned' if step > 1 else ''})"
        )
        triangles, touching = triangles[keep], touching[keep]
        value = value if per_vertex else value[keep]
    return vertices, triangles, value, touching, per_vertex, note


def _mesh(vertices, triangles, values, per_vertex: bool, name: str, **style) -> dict:
    """A ``mesh3d`` trace. ``per_vertex``: ``values`` (one per vertex) on shared vertices; else
    each triangle gets three vertices of its own carrying its value (one per triangle)."""
    if not per_vertex:
        vertices = vertices[triangles].reshape(-1, 3)
        triangles = np.arange(len(vertices)).reshape(-1, 3)
        values = None if values is None else np.repeat(values, 3)
    return {
        "type": "mesh3d",
        "name": name,
        "x": _typed(vertices[:, 0]),
        "y": _typed(vertices[:, 1]),
        "z": _typed(vertices[:, 2]),
        "i": _typed(triangles[:, 0], "i4"),
        "j": _typed(triangles[:, 1], "i4"),
        "k": _typed(triangles[:, 2], "i4"),
        **({"intensity": _typed(values)} if values is not None else {}),
        "flatshading": True,
        # Nearly flat light: the colour is the pressure, not the shading (a fan of thin triangles at a
        # pole would otherwise turn dark).
        "lighting": {"ambient": 0.92, "diffuse": 0.12, "specular": 0.0, "roughness": 1.0},
        **style,
    }


def pressure_view(solution, title: str = "", regions: bool = True) -> tuple[dict, str]:
    """``(figure, note)``: the Plotly figure of ``solution``'s pressure on its surface, and a note
    when not every face is drawn (empty otherwise).

    Parameters
    ----------
    solution : Solution
        A certified answer (its springs' pressure, MPa).
    title : str
    regions : bool
        Mark each labelled region's centre of pressure.
    """
    from ..io.mapframe import best_fit_frame

    vertices, triangles, pressure, touching, per_vertex, note = _faces(solution)
    top = float(np.nanmax(pressure, initial=0.0)) or 1.0
    data = []
    if (~touching).any():
        data.append(
            _mesh(
                vertices,
                triangles[~touching],
                None,
                per_vertex,
                "out of contact",
                color="#c8c8c8",
                hovertemplate="out of contact<br>x %{x:.1f}, y %{y:.1f}, z %{z:.1f} mm<extra></extra>",
            )
        )
    if touching.any():
        data.append(
            _mesh(
                vertices,
                triangles[touching],
                pressure if per_vertex else pressure[touching],
                per_vertex,
                "pressure",
                colorscale="Viridis",
                cmin=0.0,
                cmax=top,
                colorbar={"title": {"text": "pressure (MPa)"}},
                hovertemplate="%{intensity:.3g} MPa<br>x %{x:.1f}, y %{y:.1f}, z %{z:.1f} mm<extra></extra>",
            )
        )
    data += _centres(solution, regions)
    layer = solution.problem.layer
    _, axes = best_fit_frame(layer.points, layer.areas, layer.normals)
    eye = 1.8 * (0.85 * axes[2] - 0.5 * axes[1])  # from body 2's side, tilted
    layout = {
        "title": {"text": title},
        "margin": {"l": 0, "r": 0, "t": 40 if title else 10, "b": 0},
        "legend": {"x": 0.0, "y": 1.0},
        "scene": {
            "aspectmode": "data",
            "camera": {"eye": dict(zip("xyz", eye.tolist())), "up": dict(zip("xyz", axes[1].tolist()))},
            "xaxis": {"title": {"text": "x (mm)"}},
            "yaxis": {"title": {"text": "y (mm)"}},
            "zaxis": {"title": {"text": "z (mm)"}},
        },
    }
    return {"data": data, "layout": layout}, note


def _centres(solution, regions: bool) -> list:
    """Markers: the contact's centre of pressure and each labelled region's."""
    from ..io.marks import region_colours

    points = []
    cop = np.asarray(solution.center_of_pressure, float)
    if np.isfinite(cop).all():
        points.append(("centre of pressure (all)", cop, "white", solution.peak_pressure))
    layer = solution.problem.layer
    if regions and layer.labels is not None and np.isfinite(solution.pressure).all():
        from ..anatomy.regions import regional_statistics

        found = regional_statistics(solution)
        colours = region_colours(found)
        for name, stats in found.items():
            if np.isfinite(stats.center_of_pressure).all():
                points.append(
                    (f"{name}: centre of pressure", stats.center_of_pressure, colours[name], stats.peak_pressure)
                )
    lift = 0.3 * float(np.median(layer.thickness)) if len(layer) else 0.0
    normal = best_normal(layer)
    return [
        {
            "type": "scatter3d",
            "mode": "markers",
            "name": name,
            "x": [float(p[0] + lift * normal[0])],
            "y": [float(p[1] + lift * normal[1])],
            "z": [float(p[2] + lift * normal[2])],
            "marker": {"size": 7, "color": colour, "symbol": "diamond", "line": {"color": "black", "width": 2}},
            "hovertemplate": f"{name}<br>x %{{x:.1f}}, y %{{y:.1f}}, z %{{z:.1f}} mm<br>peak {peak:.3g} MPa<extra></extra>",
        }
        for name, p, colour, peak in points
    ]


def best_normal(layer) -> np.ndarray:
    """The area-weighted mean normal of the springs (unit), toward body 2."""
    mean = np.asarray(layer.areas, float) @ np.asarray(layer.normals, float) if len(layer) else np.zeros(3)
    size = float(np.linalg.norm(mean))
    return mean / size if size > 0 else np.array([0.0, 0.0, 1.0])
