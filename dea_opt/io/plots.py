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
from .draw import (
    RASTER_LIMIT,
    _boundary_with_owner,
    boundary_edges,
    draw_contact_edge,
    draw_regions,
    draw_values,
    map_geometry,
)
from .layout import colorbar_axes, place_maps
from .mapframe import best_fit_frame, map_frame
from .marks import region_colours, solution_verdict, stamp, verdict_lines
from .surface import contact_surface

__all__ = ["best_fit_frame", "decorate_map", "note_frame", "plot_pressure", "pressure_figure"]

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


def note_frame(fig, frame):
    """The frame's note (view, origin) in small grey type under the figure: the text (its lines
    fitted to the figure's width when it is placed, :func:`~dea_opt.io.layout.place_maps`)."""
    return fig.supxlabel(frame.note, fontsize="x-small", color="0.35")


def _draw_3d(ax, solution, cmap, norm, grey, parts=None):
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
        if len(edges) and not parts:
            ax.add_collection3d(Line3DCollection(points[edges], colors="k", linewidths=0.8))
        owned, owner = _boundary_with_owner(tris[contact])
        for mask, _, colour in (parts or {}).values():
            own = owned[mask[np.flatnonzero(contact)[owner]]]
            if len(own):
                ax.add_collection3d(Line3DCollection(points[own], colors=colour, linewidths=1.2))
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
    figsize: tuple = (6.4, 5.6),
    elev: float | None = None,
    azim: float | None = None,
    anatomy=None,
    regions: bool = True,
    verdict=None,
) -> Path:
    """Draw a pressure map of the contact surface to a PNG.

    Faces (or springs) in contact are coloured by pressure with a colour bar in MPa; the
    rest of the surface is light grey. Without regions the contact edge is outlined in black
    and the centre of pressure marked with a white dot; a labelled layer's regions
    (compartments) are outlined (dashed white) and named, and each region's contact edge and
    centre of pressure are drawn in its own colour (:data:`~dea_opt.io.marks.REGION_COLOURS`),
    beside the centre of pressure of the whole contact. Layers with ``surface`` and
    ``source_face`` are drawn face by face; other layers on the triangulation through their
    springs (:func:`~dea_opt.io.triangulate.point_triangulation`). Above
    :data:`~dea_opt.io.draw.RASTER_LIMIT` springs the map is a raster at screen resolution
    (each pixel the largest pressure in it). An answer outside validity, or without a
    certificate, is stamped as such (:func:`~dea_opt.io.marks.stamp`) with the reason under the
    title. Drawn with matplotlib's Agg canvas: pyplot and its backend are not touched.

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
        The figure's heading, e.g. the scenario's title; a line with the peak pressure, the
        resultant and the contact area always follows it.
    dpi : int
    figsize : (float, float)
        Inches.
    elev, azim : float, optional
        Camera angles of the 3-D view (degrees).
    anatomy : AnatomicalFrame or dict, optional
        The joint's anatomical directions (:class:`~dea_opt.anatomy.AnatomicalFrame`): the
        map is then drawn in that frame with Medial/Lateral, Anterior/Posterior sides.
    regions : bool
        Outline and name the regions of a labelled layer, with their contact edges and centres
        of pressure.
    verdict : (str, str), optional
        ``(mark, reason)`` to stamp (:data:`~dea_opt.io.marks.CLEAN`: nothing); default the
        solution's own (:func:`~dea_opt.io.marks.solution_verdict`). A load path's frame passes
        its row's, a joint's layer the joint's.

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
    fig = pressure_figure(
        solution,
        view=view,
        cmap=cmap,
        vmax=vmax,
        title=title,
        figsize=figsize,
        elev=elev,
        azim=azim,
        anatomy=anatomy,
        regions=regions,
        verdict=verdict,
    )
    write_atomic(target, lambda tmp: fig.savefig(tmp, format=fmt[1:], dpi=dpi, **save_options(fmt[1:])))
    return target


def pressure_figure(
    solution,
    *,
    view: str = "plane",
    cmap: str = "viridis",
    vmax: float | None = None,
    title: str | None = None,
    figsize: tuple = (6.4, 5.6),
    elev: float | None = None,
    azim: float | None = None,
    anatomy=None,
    regions: bool = True,
    verdict=None,
):
    """The :class:`matplotlib.figure.Figure` :func:`plot_pressure` saves (same parameters)."""
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

    try:
        colormap = matplotlib.colormaps[cmap]
    except KeyError:
        raise InputError(f"cmap must be a matplotlib colormap name, got {cmap!r}") from None
    top = solution.peak_pressure if vmax is None else float(vmax)
    norm = Normalize(0.0, top if top > 0 and np.isfinite(top) else 1.0)
    grey = ListedColormap(["0.85"])
    parts = _regions(solution) if regions and layer.labels is not None else {}
    verdict = solution_verdict(solution) if verdict is None else verdict

    # A map's place is measured from its texts (dea_opt/io/layout.py); a 3-D view's labels lie
    # where its camera puts them, and its few pictures keep matplotlib's constrained layout.
    fig = Figure(figsize=figsize, layout=None if view == "plane" else "constrained")
    FigureCanvasAgg(fig)
    note = None
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
            outline=not parts,
        )
        if parts:
            centres = [stats.center_of_pressure for _, stats, _ in parts.values()] + [solution.center_of_pressure]
            marked = [frame.project(c) for c in centres if np.isfinite(c).all()]
            draw_regions(ax, geometry, layer.labels, avoid=marked)
            for mask, stats, colour in parts.values():
                draw_contact_edge(ax, geometry, solution.in_contact, mask, colour, solution.strain)
                if np.isfinite(stats.center_of_pressure).all():
                    c = frame.project(stats.center_of_pressure)
                    ax.plot(c[0], c[1], "D", mfc=colour, mec="k", ms=7, zorder=8)
        _mark_centre(ax, frame.project, solution.center_of_pressure)
        decorate_map(ax, frame, geometry)
        note = note_frame(fig, frame)
    else:
        ax = fig.add_subplot(projection="3d", computed_zorder=False)
        outlined = _draw_3d(ax, solution, colormap, norm, grey, parts)
        cop = solution.center_of_pressure
        if np.isfinite(cop).all():
            ax.scatter([cop[0]], [cop[1]], [cop[2]], s=50, c="white", edgecolors="k", depthshade=False, zorder=10)
        for _, stats, colour in parts.values():
            c = stats.center_of_pressure
            if np.isfinite(c).all():
                ax.scatter([c[0]], [c[1]], [c[2]], s=40, c=colour, marker="D", edgecolors="k", depthshade=False)
        axes = best_fit_frame(layer.points, layer.areas, layer.normals)[1]
        tilt = np.radians(40.0)  # look from 40 degrees off the mean normal, toward -e2
        eye = np.cos(tilt) * axes[2] - np.sin(tilt) * axes[1]
        ax.view_init(
            elev=float(np.degrees(np.arcsin(np.clip(eye[2], -1, 1)))) if elev is None else elev,
            azim=float(np.degrees(np.arctan2(eye[1], eye[0]))) if azim is None else azim,
        )
    _legend(ax, solution, parts, outlined)
    mappable = ScalarMappable(norm=norm, cmap=colormap)
    if view == "plane":
        bar = fig.colorbar(mappable, cax=colorbar_axes(fig), label="pressure (MPa)")
    else:
        fig.colorbar(mappable, ax=ax, label="pressure (MPa)", shrink=0.85)
    numbers = (
        f"peak {solution.peak_pressure:.4g} MPa, resultant {np.linalg.norm(solution.contact_force):.4g} N, "
        f"contact area {solution.contact_area:.4g} mm$^2$"
    )
    heading = f"{title}\n{numbers}" if title else numbers
    ax.set_title(heading + verdict_lines(verdict, 70), fontsize="medium")
    if view == "plane":
        place_maps(fig, [(ax, bar)], note=note)
    stamp(fig, verdict)
    return fig


def _regions(solution) -> dict:
    """``{name: (mask, RegionStats, colour)}`` of a labelled layer's regions."""
    from ..anatomy.regions import _label_masks, region_statistics

    layer = solution.problem.layer
    masks = _label_masks(layer.labels, len(layer))
    colours = region_colours(masks)
    return {name: (mask, region_statistics(solution, mask, name), colours[name]) for name, mask in masks.items()}


def _mark_centre(ax, project, cop) -> None:
    if np.isfinite(cop).all():
        c = project(cop)
        ax.plot(c[0], c[1], "o", mfc="white", mec="k", ms=7, zorder=9)


def _legend(ax, solution, parts: dict, outlined: bool) -> None:
    """The legend: the contact edge and centre of pressure, of the whole contact and of each region."""
    from matplotlib.lines import Line2D

    handles = [Line2D([], [], color="k", lw=0.8, label="contact edge")] if outlined and not parts else []
    if np.isfinite(solution.center_of_pressure).all():
        label = "centre of pressure (all)" if parts else "centre of pressure"
        handles.append(Line2D([], [], ls="", marker="o", mfc="white", mec="k", label=label))
    for name, (_, _, colour) in parts.items():
        handles.append(
            Line2D([], [], color=colour, lw=1.4, marker="D", mfc=colour, mec="k", label=f"{name}: edge, centre")
        )
    if handles:
        ax.legend(handles=handles, loc="upper right", fontsize="x-small", framealpha=0.8)
