"""Pictures of a load path: quantities over the cycle, and exposure maps on the contact surface.

Drawn on matplotlib's Agg canvas (pyplot and its global state are not touched), written
atomically. Units in the labels: s, N, MPa, mm^2, MPa s.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .io import _point_triangulation, write_atomic


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
        The per-frame table of :class:`~dea_opt.path.PathResult`.
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

    from .io import best_fit_frame

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


def _axis_label(name: str, axis) -> str:
    """``x (mm)`` when the projection axis is a coordinate axis, else its direction."""
    k = int(np.argmax(np.abs(axis)))
    if abs(axis[k]) > 1 - 1e-9:
        return f"{'-' if axis[k] < 0 else ''}{'xyz'[k]} (mm)"
    return f"{name} = ({axis[0]:.2f}, {axis[1]:.2f}, {axis[2]:.2f}) (mm)"


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


