"""The 3-D pressure map of a report: the cartilage surface coloured by pressure, for Plotly.

The figure is written as plain data (``{"data", "layout"}``) with its arrays as Plotly's typed
arrays (``{"dtype": "f4", "bdata": base64}``), so the page carries 4 bytes per number rather than
its decimal text. Each face of the surface gets its own three vertices, all with its spring's
pressure: the faces are drawn flat, as the springs are, and hovering a face shows its pressure
(vertex values, which every version of Plotly reports on hover). Faces out of contact are grey.
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


def _surface(layer):
    """``(vertices (P, 3), triangles (T, 3), spring of each triangle (T,))``: the mesh faces the
    springs were cast from, or a triangulation through the springs (then a triangle's value is the
    mean of its three springs', given as -1 and handled by the caller)."""
    if layer.surface is not None and layer.source_face is not None:
        vertices, faces = layer.surface
        return np.asarray(vertices, float), np.asarray(faces, np.int64)[layer.source_face], np.arange(len(layer))
    from ..io.triangulate import point_triangulation

    triangles = point_triangulation(layer)
    if triangles is None or not len(triangles):
        return np.asarray(layer.points, float), np.zeros((0, 3), np.int64), None
    return np.asarray(layer.points, float), np.asarray(triangles, np.int64), None


def _faces(solution):
    """``(corners (T, 3, 3), pressure (T,), in contact (T,), note)`` of the faces drawn."""
    layer = solution.problem.layer
    vertices, triangles, spring = _surface(layer)
    pressure = np.asarray(solution.pressure, float)
    if spring is not None:
        value, touching = pressure[spring], np.asarray(solution.in_contact)[spring]
    else:  # springs on points: a triangle carries its three springs' mean
        value = pressure[triangles].mean(axis=1)
        touching = np.asarray(solution.in_contact)[triangles].any(axis=1)
    note = ""
    if len(triangles) > FACE_LIMIT:
        keep = touching if touching.sum() <= FACE_LIMIT else touching & (np.cumsum(touching) % 2 == 0)
        step = max(1, int(np.ceil(keep.sum() / FACE_LIMIT)))
        keep = np.flatnonzero(keep)[::step]
        note = (
            f"{len(keep)} of the {len(triangles)} faces are drawn (those in contact{', thinned' if step > 1 else ''})"
        )
        triangles, value, touching = triangles[keep], value[keep], touching[keep]
    return vertices[triangles], value, touching, note


def _mesh(corners, values, name, **style) -> dict:
    """A ``mesh3d`` trace of separate triangles ``corners`` (T, 3, 3), each vertex carrying its
    triangle's value."""
    points = corners.reshape(-1, 3)
    count = len(corners)
    index = np.arange(3 * count, dtype=np.int32).reshape(count, 3)
    return {
        "type": "mesh3d",
        "name": name,
        "x": _typed(points[:, 0]),
        "y": _typed(points[:, 1]),
        "z": _typed(points[:, 2]),
        "i": _typed(index[:, 0], "i4"),
        "j": _typed(index[:, 1], "i4"),
        "k": _typed(index[:, 2], "i4"),
        **({"intensity": _typed(np.repeat(values, 3))} if values is not None else {}),
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

    corners, pressure, touching, note = _faces(solution)
    top = float(np.nanmax(pressure, initial=0.0)) or 1.0
    data = []
    if (~touching).any():
        data.append(
            _mesh(
                corners[~touching],
                None,
                "out of contact",
                color="#c8c8c8",
                hovertemplate="out of contact<br>x %{x:.1f}, y %{y:.1f}, z %{z:.1f} mm<extra></extra>",
            )
        )
    if touching.any():
        data.append(
            _mesh(
                corners[touching],
                pressure[touching],
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
