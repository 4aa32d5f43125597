"""Pictures: the pressure map of a solution (the cycle and exposure plots are in :mod:`~dea_opt.io.cycle`).

Drawn on matplotlib's Agg canvas (pyplot and its global state are not touched) and written
atomically. Maps are drawn in an anatomical frame when one is given (labelled sides, an
anatomical view), else on the best-fit plane of the springs (:mod:`~dea_opt.io.mapframe`);
maps of more than :data:`~dea_opt.io.draw.RASTER_LIMIT` springs are rasterized at screen
resolution (:mod:`~dea_opt.io.draw`). Regions (the layer's labels) are outlined and named.
Units in the labels: mm, mm^2, N, MPa.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .._checks.dependencies import require
from ..errors import InputError
from ..files.atomic import file_path, write_atomic
from .draw import RASTER_LIMIT, boundary_edges, draw_regions, draw_values, map_geometry
from .mapframe import best_fit_frame, map_frame
from .surface import contact_surface

__all__ = ["best_fit_frame", "decorate_map", "note_frame", "plot_pressure"]

_PICTURE_FORMATS = (".png", ".pdf", ".svg")


def save_options(fmt: str) -> dict:
    """savefig's options for ``fmt``: PNGs at zlib's fastest level (a third less time to
    encode, about a tenth larger)."""
    return {"pil_kwargs": {"compress_level": 1}} if fmt == "png" else {}


def decorate_map(ax, frame, geometry) -> None:
    """Limits, equal scale, axis labels and the anatomical side names."""
    low, high = geometry.extent
    pad = 0.03 * max(float((high - low).max()), 1e-9)
    side_pad = 0.1 * max(float((high - low).max()), 1e-9) if frame.sides else 0.0
    ax.set_xlim(low[0] - pad - side_pad, high[0] + pad + side_pad)
    ax.set_ylim(low[1] - pad - side_pad, high[1] + pad + side_pad)
    ax.set_aspect("equal")
    ax.set_xlabel(frame.xlabel)
    ax.set_ylabel(frame.ylabel)
    box = {"boxstyle": "round,pad=0.2", "fc": "white", "ec": "0.6", "alpha": 0.85}
    where = {
        "right": (0.99, 0.5, "right", "center", 90),
        "left": (0.01, 0.5, "left", "center", 90),
        "top": (0.5, 0.99, "center", "top", 0),
        "bottom": (0.5, 0.01, "center", "bottom", 0),
    }
    for side, name in frame.sides.items():
        x, y, ha, va, rotation = where[side]
        ax.text(
            x,
            y,
            name.upper(),
            transform=ax.transAxes,
            ha=ha,
            va=va,
            rotation=rotation,
            fontsize="small",
            fontweight="bold",
            bbox=box,
            zorder=7,
        )


def note_frame(fig, frame) -> None:
    """The frame's note (view, origin) in small grey type under the figure."""
    import textwrap

    fig.supxlabel(textwrap.fill(frame.note, 110), fontsize="x-small", color="0.35")


def _draw_3d(ax, solution, cmap, norm, grey):
    from matplotlib.ticker import MaxNLocator
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    layer = solution.problem.layer
    contact = solution.in_contact
    n = len(layer)
    outlined = False
    if layer.surface is not None and layer.source_face is not None and n <= RASTER_LIMIT:
        colours = np.asarray(cmap(norm(solution.pressure)))
        colours[~contact] = grey(0.5)
        surface = contact_surface(solution)
        points, tris = surface.points, surface.cells
        ax.add_collection3d(Poly3DCollection(points[tris], facecolors=colours, edgecolors="none"))
        edges = boundary_edges(tris[contact])
        if len(edges):
            ax.add_collection3d(Line3DCollection(points[edges], colors="k", linewidths=0.8))
        outlined = len(edges) > 0
    else:
        # Decimated to about as many dots as the picture can show.
        every = max(1, n // RASTER_LIMIT)
        points = layer.points[::every]
        colours = np.asarray(cmap(norm(solution.pressure[::every])))
        colours[~contact[::every]] = grey(0.5)
        ax.scatter(points[:, 0], points[:, 1], points[:, 2], c=colours, s=4, depthshade=False)
        points = layer.points
    low, high = points.min(axis=0), points.max(axis=0)
    span = np.maximum(high - low, 0.1 * max(float((high - low).max()), 1e-9))
    centre = 0.5 * (low + high)
    ax.set_xlim(centre[0] - span[0] / 2, centre[0] + span[0] / 2)
    ax.set_ylim(centre[1] - span[1] / 2, centre[1] + span[1] / 2)
    ax.set_zlim(centre[2] - span[2] / 2, centre[2] + span[2] / 2)
    ax.set_box_aspect(tuple(span))  # equal scale on the three axes
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_zlabel("z (mm)")
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(5))
    return outlined


def plot_pressure(
    solution,
    path,
    *,
    view: str = "plane",
    cmap: str = "viridis",
    vmax: float | None = None,
    title: str | None = None,
    dpi: int = 150,
    figsize: tuple = (6.4, 5.2),
    elev: float | None = None,
    azim: float | None = None,
    anatomy=None,
    regions: bool = True,
) -> Path:
    """Draw a pressure map of the contact surface to a PNG.

    Faces (or springs) in contact are coloured by pressure with a colour bar in MPa; the
    rest of the surface is light grey; the contact edge is outlined in black and the
    centre of pressure marked with a white dot. Layers with ``surface`` and
    ``source_face`` are drawn face by face; other layers on the triangulation through their
    springs (:func:`~dea_opt.io.triangulate.point_triangulation`). Above
    :data:`~dea_opt.io.draw.RASTER_LIMIT` springs the map is a raster at screen resolution
    (each pixel the largest pressure in it). Regions of a labelled layer are outlined
    (dashed white) and named. Drawn with matplotlib's Agg canvas: pyplot and its backend are
    not touched.

    Parameters
    ----------
    solution : Solution
    path : str or os.PathLike
        ``.png`` (or ``.pdf``, ``.svg``).
    view : {"plane", "3d"}
        ``"plane"``: a map in the anatomical frame (``anatomy``) or, without one, on the
        best-fit plane of the springs seen from body 2 (:mod:`~dea_opt.io.mapframe`).
        ``"3d"``: a 3-D view, by default from 40 degrees off the springs' mean normal.
    cmap : str
        A matplotlib colormap name.
    vmax : float, optional
        Top of the colour scale (MPa); default the peak pressure.
    title : str, optional
        Default: method, peak pressure, total force and contact area.
    dpi : int
    figsize : (float, float)
        Inches.
    elev, azim : float, optional
        Camera angles of the 3-D view (degrees).
    anatomy : AnatomicalFrame or dict, optional
        The joint's anatomical directions (:class:`~dea_opt.anatomy.AnatomicalFrame`): the
        map is then drawn in that frame with Medial/Lateral, Anterior/Posterior sides.
    regions : bool
        Outline and name the regions of a labelled layer.

    Returns
    -------
    pathlib.Path

    Raises
    ------
    InputError
        Unknown ``view`` or extension, no springs, or a path that cannot be written.
    """
    target = file_path(path)
    fmt = target.suffix.lower()
    if fmt not in _PICTURE_FORMATS:
        raise InputError(f"path must end in .png, .pdf or .svg, got {str(path)!r}")
    if view not in ("plane", "3d"):
        raise InputError(f"view must be 'plane' or '3d', got {view!r}")
    layer = solution.problem.layer
    if len(layer) == 0:
        raise InputError("solution has no springs to plot")
    require("matplotlib", "plot_pressure")
    import matplotlib
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import ListedColormap, Normalize
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D

    try:
        colormap = matplotlib.colormaps[cmap]
    except KeyError:
        raise InputError(f"cmap must be a matplotlib colormap name, got {cmap!r}") from None
    top = solution.peak_pressure if vmax is None else float(vmax)
    norm = Normalize(0.0, top if top > 0 else 1.0)
    grey = ListedColormap(["0.85"])
    cop = solution.center_of_pressure

    fig = Figure(figsize=figsize, layout="constrained")
    FigureCanvasAgg(fig)
    if view == "plane":
        frame = map_frame(layer.points, layer.areas, layer.normals, anatomy)
        ax = fig.add_subplot()
        geometry = map_geometry(layer, frame)
        outlined = draw_values(
            ax,
            geometry,
            solution.pressure,
            colormap,
            norm,
            contact=solution.in_contact,
            grey=grey,
            edge=solution.strain,
        )
        if regions and layer.labels is not None:
            draw_regions(ax, geometry, layer.labels)
        if np.isfinite(cop).all():
            c = frame.project(cop)
            ax.plot(c[0], c[1], "o", mfc="white", mec="k", ms=7, zorder=5)
        decorate_map(ax, frame, geometry)
        note_frame(fig, frame)
    else:
        ax = fig.add_subplot(projection="3d", computed_zorder=False)
        outlined = _draw_3d(ax, solution, colormap, norm, grey)
        if np.isfinite(cop).all():
            ax.scatter([cop[0]], [cop[1]], [cop[2]], s=50, c="white", edgecolors="k", depthshade=False, zorder=10)
        axes = best_fit_frame(layer.points, layer.areas, layer.normals)[1]
        tilt = np.radians(40.0)  # look from 40 degrees off the mean normal, toward -e2
        eye = np.cos(tilt) * axes[2] - np.sin(tilt) * axes[1]
        ax.view_init(
            elev=float(np.degrees(np.arcsin(np.clip(eye[2], -1, 1)))) if elev is None else elev,
            azim=float(np.degrees(np.arctan2(eye[1], eye[0]))) if azim is None else azim,
        )
    handles = [Line2D([], [], color="k", lw=0.8, label="contact edge")] if outlined else []
    if np.isfinite(cop).all():
        handles.append(Line2D([], [], ls="", marker="o", mfc="white", mec="k", label="centre of pressure"))
    if handles:
        ax.legend(handles=handles, loc="upper right", fontsize="small", framealpha=0.8)
    fig.colorbar(ScalarMappable(norm=norm, cmap=colormap), ax=ax, label="pressure (MPa)", shrink=0.85)
    if title is None:
        title = (
            f"{solution.method}: peak {solution.peak_pressure:.4g} MPa, "
            f"resultant {np.linalg.norm(solution.contact_force):.4g} N, area {solution.contact_area:.4g} mm$^2$"
        )
    ax.set_title(title, fontsize="medium")
    write_atomic(target, lambda tmp: fig.savefig(tmp, format=fmt[1:], dpi=dpi, **save_options(fmt[1:])))
    return target
