"""Pictures of a load path: the cycle plot (loads, moments, pressure, area and regions over time)
and the exposure maps.

Drawn on matplotlib's Agg canvas and written atomically. Frames without a certified answer
are marked with a black cross on the time axis; certified frames outside the model's
validity with an orange triangle. Units in the labels: N, N mm, MPa, mm^2, s, MPa s.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..files.atomic import write_atomic
from .draw import draw_regions, draw_values, map_geometry
from .mapframe import map_frame
from .plots import decorate_map, note_frame, save_options

__all__ = ["plot_cycle", "plot_exposure"]


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
    return write_atomic(path, lambda tmp: fig.savefig(tmp, format=fmt, dpi=dpi, **save_options(fmt)))


def _components(table, names, anatomy):
    """The three components of the load's force or moment, in the anatomical frame when given."""
    vectors = table[list(names)].to_numpy(dtype=float)
    if anatomy is None:
        return [(name, vectors[:, i]) for i, name in enumerate(names)]
    from ..anatomy import AnatomicalFrame

    frame = AnatomicalFrame.from_dict(anatomy)
    return [(f"{names[0][0]} {axis}", vectors @ frame.direction(axis)) for axis in ("medial", "anterior", "proximal")]


def _region_prefixes(table, regions) -> dict:
    if regions is not None:
        return dict(regions)
    suffix = "_force_share"
    return {c[: -len(suffix)]: c[: -len(suffix)] for c in table.columns if c.endswith(suffix)}


def plot_cycle(table, path, title: str | None = None, *, regions: dict | None = None, anatomy=None) -> Path:
    """The load path over time: applied force and moment, pressure, contact area, regions' shares.

    Parameters
    ----------
    table : pandas.DataFrame
        The per-frame table of :class:`~dea_opt.loadpath.PathResult`.
    path : str or Path
        ``.png`` (or ``.pdf``, ``.svg``).
    title : str, optional
    regions : dict {name: column prefix}, optional
        The regions whose force share to plot; default every ``<prefix>_force_share`` column.
    anatomy : AnatomicalFrame or dict, optional
        Draw the force and moment components along medial, anterior and proximal.
    """
    t = table["time"].to_numpy(dtype=float)
    failed = ~table["success"].to_numpy(dtype=bool)
    outside = ~failed & ~table["valid"].to_numpy(dtype=bool) if "valid" in table else np.zeros(len(t), bool)
    prefixes = _region_prefixes(table, regions)
    rows = 5 if prefixes else 4
    fig = _figure((6.8, 2.0 * rows + 0.6))
    axes = fig.subplots(rows, 1, sharex=True)
    fig.subplots_adjust(left=0.14, right=0.78, top=0.95, bottom=0.06, hspace=0.15)
    marker = "." if len(t) <= 30 else None
    colours = ("C0", "C1", "C2")
    for k, (name, values) in enumerate(_components(table, ("Fx", "Fy", "Fz"), anatomy)):
        axes[0].plot(t, values, "-", color=colours[k], label=name, marker=marker)
    axes[0].plot(
        t, table["resultant"].to_numpy(dtype=float), "-", color="k", lw=1.5, label="|contact force|", marker=marker
    )
    axes[0].set_ylabel("applied force (N)")
    for k, (name, values) in enumerate(_components(table, ("Mx", "My", "Mz"), anatomy)):
        axes[1].plot(t, values, "-", color=colours[k], label=name, marker=marker)
    axes[1].set_ylabel("applied moment\n(N mm)")
    axes[2].plot(t, table["peak_pressure"].to_numpy(dtype=float), "-", color="C3", label="peak", marker=marker)
    axes[2].plot(t, table["mean_pressure"].to_numpy(dtype=float), "-", color="C1", label="mean", marker=marker)
    axes[2].set_ylabel("pressure (MPa)")
    axes[3].plot(t, table["contact_area"].to_numpy(dtype=float), "-", color="C2", label="contact area", marker=marker)
    axes[3].set_ylabel("area (mm$^2$)")
    if prefixes:
        for k, (name, prefix) in enumerate(prefixes.items()):
            axes[4].plot(
                t,
                100.0 * table[f"{prefix}_force_share"].to_numpy(dtype=float),
                "-",
                color=f"C{k}",
                label=str(name),
                marker=marker,
            )
        axes[4].set_ylabel("share of the\ncontact force (%)")
        shares = [100.0 * table[f"{prefix}_force_share"].to_numpy(dtype=float) for prefix in prefixes.values()]
        low, high = (float(f(np.nan_to_num(np.concatenate(shares)))) for f in (np.min, np.max))
        axes[4].set_ylim(min(0.0, low), max(100.0, high))  # a region may push against the total
    for ax in axes:
        ax.grid(alpha=0.3)
        if failed.any():
            ax.plot(
                t[failed],
                np.zeros(failed.sum()),
                "x",
                color="k",
                ms=7,
                clip_on=False,
                transform=ax.get_xaxis_transform(),
                label="no certified answer",
            )
        if outside.any():
            ax.plot(
                t[outside],
                np.zeros(outside.sum()),
                "^",
                color="C1",
                ms=6,
                clip_on=False,
                transform=ax.get_xaxis_transform(),
                label="outside validity",
            )
        ax.legend(fontsize="x-small", loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    for ax in axes[2:4]:
        ax.set_ylim(bottom=0)
    axes[-1].set_xlabel("time (s)")
    peak = table["peak_pressure"].max()
    area = table["contact_area"].max()
    axes[0].set_title(
        title
        or f"{len(t)} frames: peak {peak:.4g} MPa, largest area {area:.4g} mm$^2$"
        + (f", {int(failed.sum())} failed" if failed.any() else ""),
        fontsize="medium",
    )
    return _save(fig, path)


def plot_exposure(layer, exposure, path, *, moving: bool = False, title: str | None = None, anatomy=None) -> Path:
    """Two maps side by side: pressure-time integral (MPa s) and time above the threshold (s).

    Parameters
    ----------
    layer : SpringLayer
        The springs (or, with ``moving``, a layer whose ``surface`` faces are the sites).
    exposure : Exposure
    path : str or Path
    moving : bool
        Sites are the faces of ``layer.surface`` rather than the springs.
    anatomy : AnatomicalFrame or dict, optional
        Draw the maps in the anatomical frame (:func:`~dea_opt.io.mapframe.map_frame`).
    """
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    fig = _figure((11.0, 5.2))
    axes = fig.subplots(1, 2)
    fig.subplots_adjust(left=0.07, right=0.97, top=0.88, bottom=0.14, wspace=0.3)
    frame = map_frame(layer.points, layer.areas, layer.normals, anatomy)
    geometry = map_geometry(layer, frame, sites="faces" if moving else "springs")
    maps = (
        (axes[0], exposure.pressure_time_integral, "pressure-time integral (MPa s)", "magma"),
        (axes[1], exposure.time_above, f"time above {exposure.threshold:g} MPa (s)", "viridis"),
    )
    for ax, values, label, cmap in maps:
        top = float(values.max(initial=0.0))
        norm = Normalize(0.0, top if top > 0 else 1.0)
        draw_values(ax, geometry, values, cmap, norm)
        if not moving and layer.labels is not None:
            draw_regions(ax, geometry, layer.labels)
        decorate_map(ax, frame, geometry)
        fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), ax=ax, label=label, shrink=0.85)
    note_frame(fig, frame)
    fig.suptitle(
        title or f"Contact-stress exposure over {exposure.duration:.3g} s (threshold {exposure.threshold:g} MPa)",
        fontsize="medium",
    )
    return _save(fig, path)
