"""Pictures: the pressure map of a solution, and the cycle and exposure plots of a load path.

Drawn on matplotlib's Agg canvas (pyplot and its global state are not touched) and written
atomically. Maps are drawn on the best-fit plane of the springs (:func:`best_fit_frame`).
Units in the labels: mm, mm^2, N, MPa, s, MPa s.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .._optional import require
from .._tolerances import AXIS_ALIGNED
from ..errors import InputError
from .atomic import file_path, write_atomic
from .surface import contact_surface

__all__ = ["best_fit_frame", "plot_cycle", "plot_exposure", "plot_pressure"]


# --- the frame and what every map shares ------------------------------------------------
def best_fit_frame(points, weights=None, normals=None) -> tuple:
    """An orthonormal frame whose first two axes span the best-fit plane of ``points``.

    Parameters
    ----------
    points : ndarray, shape (N, 3)
        In mm.
    weights : ndarray, shape (N,), optional
        E.g. spring areas; default equal.
    normals : ndarray, shape (N, 3), optional
        When given, the third axis points to the same side as their weighted mean.

    Returns
    -------
    origin : ndarray, shape (3,)
        Weighted centroid (mm).
    axes : ndarray, shape (3, 3)
        Rows ``e1, e2, e3``: ``e3`` the plane normal (least spread, by PCA), ``e1`` the
        coordinate axis most nearly in the plane projected onto it (so a plane normal to
        z gives ``e1 = x``), ``e2 = e3 x e1`` (right-handed).
    """
    points = np.asarray(points, dtype=float)
    w = np.ones(len(points)) if weights is None else np.asarray(weights, dtype=float)
    origin = w @ points / w.sum()
    centred = points - origin
    _, vectors = np.linalg.eigh((centred * w[:, None]).T @ centred)  # 3 x 3, ascending spread
    e3 = vectors[:, 0]
    if normals is not None:
        mean = w @ np.asarray(normals, dtype=float)
        if mean @ e3 < 0:
            e3 = -e3
    k = int(np.argmin(np.abs(e3)))  # the coordinate axis most nearly in the plane
    e1 = np.eye(3)[k] - e3[k] * e3
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(e3, e1)
    return origin, np.array([e1, e2, e3])


def _axis_label(name: str, axis) -> str:
    """``x (mm)`` when the projection axis is a coordinate axis, else its direction."""
    k = int(np.argmax(np.abs(axis)))
    if abs(axis[k]) > 1 - AXIS_ALIGNED:
        return f"{'-' if axis[k] < 0 else ''}{'xyz'[k]} (mm)"
    return f"{name} = ({axis[0]:.2f}, {axis[1]:.2f}, {axis[2]:.2f}) (mm)"


def _boundary_edges(triangles: np.ndarray) -> np.ndarray:
    """Edges (E, 2) that belong to one triangle only: the outline of a set of triangles."""
    if len(triangles) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    edges = np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1)
    unique, counts = np.unique(edges, axis=0, return_counts=True)
    return unique[counts == 1]


def _point_triangulation(xy: np.ndarray, areas: np.ndarray):
    """Delaunay triangles of spring points, without those that bridge gaps; None if flat."""
    from matplotlib.tri import Triangulation

    try:
        tri = Triangulation(xy[:, 0], xy[:, 1])
    except (RuntimeError, ValueError):
        return None
    t = tri.triangles
    a, b, c = xy[t[:, 0]], xy[t[:, 1]], xy[t[:, 2]]
    tri_area = 0.5 * np.abs((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))
    tri.set_mask(tri_area > 4.0 * areas[t].max(axis=1))
    return tri


# --- the pressure map of a solution -----------------------------------------------------
def _draw_plane(ax, solution, frame, cmap, norm, grey):
    from matplotlib.collections import LineCollection
    from matplotlib.tri import Triangulation

    layer = solution.problem.layer
    origin, axes = frame
    contact = solution.in_contact
    surface = contact_surface(solution) if layer.surface is not None and layer.source_face is not None else None
    if surface is not None:
        xy = (surface.points - origin) @ axes[:2].T
        tris = surface.cells
        if not contact.all():
            ax.tripcolor(Triangulation(xy[:, 0], xy[:, 1], tris[~contact]), facecolors=np.zeros((~contact).sum()),
                         cmap=grey, vmin=0, vmax=1, edgecolors="none")
        if contact.any():
            ax.tripcolor(Triangulation(xy[:, 0], xy[:, 1], tris[contact]), facecolors=solution.pressure[contact],
                         cmap=cmap, norm=norm, edgecolors="none")
        edges = _boundary_edges(tris[contact])
        ax.add_collection(LineCollection(xy[edges], colors="k", linewidths=0.8))
        return xy, len(edges) > 0
    xy = (layer.points - origin) @ axes[:2].T
    tri = _point_triangulation(xy, layer.areas)
    if tri is None:
        colours = np.where(contact, solution.pressure, np.nan)
        ax.scatter(xy[~contact, 0], xy[~contact, 1], s=4, color=grey(0.5))
        ax.scatter(xy[contact, 0], xy[contact, 1], s=4, c=colours[contact], cmap=cmap, norm=norm)
        return xy, False
    base_mask = tri.mask.copy()
    ax.tripcolor(tri, np.zeros(len(xy)), cmap=grey, vmin=0, vmax=1, shading="gouraud")
    touching = contact[tri.triangles].any(axis=1)
    if touching.any():  # a triangulation of its own: matplotlib reads the mask when drawing
        loaded = Triangulation(xy[:, 0], xy[:, 1], tri.triangles, mask=base_mask | ~touching)
        ax.tripcolor(loaded, solution.pressure, cmap=cmap, norm=norm, shading="gouraud")
    if 0 < contact.sum() < len(contact):
        ax.tricontour(tri, contact.astype(float), levels=[0.5], colors="k", linewidths=0.8)
        return xy, True
    if contact.all():
        edges = _boundary_edges(tri.triangles[~base_mask])
        ax.add_collection(LineCollection(xy[edges], colors="k", linewidths=0.8))
        return xy, True
    return xy, False


def _draw_3d(ax, solution, cmap, norm, grey):
    from matplotlib.ticker import MaxNLocator
    from mpl_toolkits.mplot3d.art3d import Line3DCollection, Poly3DCollection

    layer = solution.problem.layer
    contact = solution.in_contact
    colours = np.asarray(cmap(norm(solution.pressure)))
    colours[~contact] = grey(0.5)
    if layer.surface is not None and layer.source_face is not None:
        surface = contact_surface(solution)
        points, tris = surface.points, surface.cells
        ax.add_collection3d(Poly3DCollection(points[tris], facecolors=colours, edgecolors="none"))
        edges = _boundary_edges(tris[contact])
        if len(edges):
            ax.add_collection3d(Line3DCollection(points[edges], colors="k", linewidths=0.8))
        outlined = len(edges) > 0
    else:
        points = layer.points
        ax.scatter(points[:, 0], points[:, 1], points[:, 2], c=colours, s=4, depthshade=False)
        outlined = False
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


_PICTURE_FORMATS = (".png", ".pdf", ".svg")


def plot_pressure(solution, path, *, view: str = "plane", cmap: str = "viridis", vmax: float | None = None,
                  title: str | None = None, dpi: int = 150, figsize: tuple = (6.4, 5.2),
                  elev: float | None = None, azim: float | None = None) -> Path:
    """Draw a pressure map of the contact surface to a PNG.

    Faces (or springs) in contact are coloured by pressure with a colour bar in MPa; the
    rest of the surface is light grey; the contact edge is outlined in black and the
    centre of pressure marked with a white dot. Layers with ``surface`` and
    ``source_face`` are drawn face by face; other layers by a triangulation of their
    spring points (triangles bridging gaps are dropped) or, failing that, by dots.
    Drawn with matplotlib's Agg canvas: pyplot and its backend are not touched.

    Parameters
    ----------
    solution : Solution
    path : str or os.PathLike
        ``.png`` (or ``.pdf``, ``.svg``).
    view : {"plane", "3d"}
        ``"plane"``: projected on the best-fit plane of the springs (:func:`best_fit_frame`,
        seen from body 2: the plane normal points along the springs' mean normal).
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
    frame = best_fit_frame(layer.points, layer.areas, layer.normals)
    cop = solution.center_of_pressure

    fig = Figure(figsize=figsize, layout="constrained")
    FigureCanvasAgg(fig)
    if view == "plane":
        ax = fig.add_subplot()
        xy, outlined = _draw_plane(ax, solution, frame, colormap, norm, grey)
        if np.isfinite(cop).all():
            c = (cop - frame[0]) @ frame[1][:2].T
            ax.plot(c[0], c[1], "o", mfc="white", mec="k", ms=7, zorder=5)
        low, high = xy.min(axis=0), xy.max(axis=0)
        pad = 0.03 * max(float((high - low).max()), 1e-9)
        ax.set_xlim(low[0] - pad, high[0] + pad)
        ax.set_ylim(low[1] - pad, high[1] + pad)
        ax.set_aspect("equal")
        ax.set_xlabel(_axis_label("e1", frame[1][0]))
        ax.set_ylabel(_axis_label("e2", frame[1][1]))
    else:
        ax = fig.add_subplot(projection="3d", computed_zorder=False)
        outlined = _draw_3d(ax, solution, colormap, norm, grey)
        if np.isfinite(cop).all():
            ax.scatter([cop[0]], [cop[1]], [cop[2]], s=50, c="white", edgecolors="k", depthshade=False,
                       zorder=10)
        tilt = np.radians(40.0)  # look from 40 degrees off the mean normal, toward -e2
        eye = np.cos(tilt) * frame[1][2] - np.sin(tilt) * frame[1][1]
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
        title = (f"{solution.method}: peak {solution.peak_pressure:.4g} MPa, "
                 f"resultant {np.linalg.norm(solution.contact_force):.4g} N, area {solution.contact_area:.4g} mm$^2$")
    ax.set_title(title, fontsize="medium")
    write_atomic(target, lambda tmp: fig.savefig(tmp, format=fmt[1:], dpi=dpi))
    return target


# --- load paths: the cycle and the exposure maps -----------------------------------------
def _figure(figsize):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    # A fixed layout: constrained layout doubles the drawing time, and these pictures
    # are drawn once per run.
    fig = Figure(figsize=figsize)
    FigureCanvasAgg(fig)
    return fig


def _save(fig, path, dpi=120) -> Path:
    path = Path(path)
    fmt = path.suffix.lower().lstrip(".") or "png"
    return write_atomic(path, lambda tmp: fig.savefig(tmp, format=fmt, dpi=dpi))


def plot_cycle(table, path, title: str | None = None) -> Path:
    """Resultant force, peak and mean pressure, and contact area against time (PNG).

    Parameters
    ----------
    table : pandas.DataFrame
        The per-frame table of :class:`~dea_opt.loadpath.PathResult`.
    path : str or Path
        ``.png`` (or ``.pdf``, ``.svg``).
    """
    t = table["time"].to_numpy()
    failed = ~table["success"].to_numpy(dtype=bool)
    fig = _figure((6.4, 6.4))
    axes = fig.subplots(3, 1, sharex=True)
    fig.subplots_adjust(left=0.13, right=0.97, top=0.93, bottom=0.08, hspace=0.12)
    series = (
        (axes[0], [("resultant", "resultant force", "C0")], "force (N)"),
        (axes[1], [("peak_pressure", "peak", "C3"), ("mean_pressure", "mean", "C1")], "pressure (MPa)"),
        (axes[2], [("contact_area", "contact area", "C2")], "area (mm$^2$)"),
    )
    for ax, columns, label in series:
        for column, name, colour in columns:
            values = table[column].to_numpy(dtype=float)
            ax.plot(t, values, "-", color=colour, label=name, marker="." if len(t) <= 30 else None)
            if failed.any():
                ax.plot(t[failed], values[failed], "x", color="k", ms=7,
                        label="failed certificate" if column == columns[0][0] else None)
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        ax.set_ylim(bottom=0)
        if len(columns) > 1 or failed.any():
            ax.legend(fontsize="small", loc="upper right")
    axes[-1].set_xlabel("time (s)")
    axes[0].set_title(title or f"{len(t)} frames: peak {table['peak_pressure'].max():.4g} MPa, "
                               f"largest area {table['contact_area'].max():.4g} mm$^2$", fontsize="medium")
    return _save(fig, path)


def plot_exposure(layer, exposure, path, *, moving: bool = False, title: str | None = None) -> Path:
    """Two maps side by side: pressure-time integral (MPa s) and time above the threshold (s).

    Parameters
    ----------
    layer : SpringLayer
        The springs (or, with ``moving``, a layer whose ``surface`` faces are the sites).
    exposure : Exposure
    path : str or Path
    moving : bool
        Sites are the faces of ``layer.surface`` rather than the springs.
    """
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    fig = _figure((11.0, 4.8))
    axes = fig.subplots(1, 2)
    fig.subplots_adjust(left=0.07, right=0.97, top=0.88, bottom=0.1, wspace=0.3)
    frame = best_fit_frame(layer.points, layer.areas, layer.normals)
    maps = (
        (axes[0], exposure.pressure_time_integral, "pressure-time integral (MPa s)", "magma"),
        (axes[1], exposure.time_above, f"time above {exposure.threshold:g} MPa (s)", "viridis"),
    )
    for ax, values, label, cmap in maps:
        top = float(values.max(initial=0.0))
        norm = Normalize(0.0, top if top > 0 else 1.0)
        _draw_sites(ax, layer, values, frame, moving, cmap, norm)
        ax.set_aspect("equal")
        ax.set_xlabel(_axis_label("e1", frame[1][0]))
        ax.set_ylabel(_axis_label("e2", frame[1][1]))
        fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, label=label, shrink=0.85)
    fig.suptitle(title or f"Contact-stress exposure over {exposure.duration:.3g} s "
                          f"(threshold {exposure.threshold:g} MPa)", fontsize="medium")
    return _save(fig, path)


def _draw_sites(ax, layer, values, frame, moving, cmap, norm):
    from matplotlib.tri import Triangulation

    origin, axes = frame
    if layer.surface is not None and (moving or layer.source_face is not None):
        vertices, faces = layer.surface
        faces = np.asarray(faces) if moving else np.asarray(faces)[layer.source_face]
        xy = (np.asarray(vertices) - origin) @ axes[:2].T
        ax.tripcolor(Triangulation(xy[:, 0], xy[:, 1], faces), facecolors=values, cmap=cmap, norm=norm,
                     edgecolors="none")
        ax.set_xlim(xy[faces].reshape(-1, 2)[:, 0].min(), xy[faces].reshape(-1, 2)[:, 0].max())
        ax.set_ylim(xy[faces].reshape(-1, 2)[:, 1].min(), xy[faces].reshape(-1, 2)[:, 1].max())
        return
    xy = (layer.points - origin) @ axes[:2].T
    triangulation = _point_triangulation(xy, layer.areas)
    if triangulation is None:
        ax.scatter(xy[:, 0], xy[:, 1], c=values, s=6, cmap=cmap, norm=norm)
    else:
        ax.tripcolor(triangulation, values, cmap=cmap, norm=norm, shading="flat")
