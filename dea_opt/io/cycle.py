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
from .layout import colorbar_axes, place_maps, place_panels
from .mapframe import map_frame
from .marks import path_verdict, stamp, verdict_lines
from .plots import decorate_map, note_frame, save_options

__all__ = ["cycle_figure", "exposure_figure", "plot_cycle", "plot_exposure"]


def _figure(figsize):
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    # No layout engine: the axes are placed by dea_opt/io/layout.py, with the room their texts
    # take measured (the labels of five-digit ticks, the legends outside the axes).
    fig = Figure(figsize=figsize, layout=None)
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
        return [(name.split("_")[0], vectors[:, i]) for i, name in enumerate(names)]
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

    A panel is drawn only when it has something to show: the moment panel when a moment is
    applied, the pressure and area panels when a frame has a certified answer, the regions'
    panel when the layer has regions. Frames without a certified answer are marked with a black
    cross on the time axis, certified frames outside validity with an orange triangle, and a
    path with such frames is stamped (:func:`~dea_opt.io.marks.stamp`).

    Parameters
    ----------
    table : pandas.DataFrame
        The per-frame table of :class:`~dea_opt.loadpath.PathResult`.
    path : str or Path
        ``.png`` (or ``.pdf``, ``.svg``).
    title : str, optional
        The figure's heading, e.g. the scenario's title; a line with the frames, the peak
        pressure and the largest area follows it.
    regions : dict {name: column prefix}, optional
        The regions whose force share to plot; default every ``<prefix>_force_share`` column.
    anatomy : AnatomicalFrame or dict, optional
        Draw the force and moment components along medial, anterior and proximal.
    """
    return _save(cycle_figure(table, title, regions=regions, anatomy=anatomy), path)


def _finite(values) -> bool:
    values = np.asarray(values, dtype=float)
    return bool(np.isfinite(values).any())


def cycle_figure(table, title: str | None = None, *, regions: dict | None = None, anatomy=None):
    """The :class:`matplotlib.figure.Figure` :func:`plot_cycle` saves (same parameters)."""
    t = table["time_s"].to_numpy(dtype=float)
    failed = ~table["success"].to_numpy(dtype=bool)
    outside = ~failed & ~table["valid"].to_numpy(dtype=bool) if "valid" in table else np.zeros(len(t), bool)
    prefixes = _region_prefixes(table, regions)
    moments = table[["Mx_Nmm", "My_Nmm", "Mz_Nmm"]].to_numpy(dtype=float)
    panels = ["force"]
    if np.nan_to_num(moments).any():
        panels.append("moment")
    if _finite(table["peak_pressure_MPa"]):
        panels += ["pressure", "area"]
        if prefixes and any(_finite(table[f"{p}_force_share"]) for p in prefixes.values()):
            panels.append("regions")
    fig = _figure((7.4, 2.0 * len(panels) + 1.0))
    axes = np.atleast_1d(fig.subplots(len(panels), 1, sharex=True))
    ax = dict(zip(panels, axes))
    marker = "." if len(t) <= 30 else None
    colours = ("C0", "C1", "C2")
    for k, (name, values) in enumerate(_components(table, ("Fx_N", "Fy_N", "Fz_N"), anatomy)):
        ax["force"].plot(t, values, "-", color=colours[k], label=name, marker=marker)
    ax["force"].plot(
        t, table["resultant_N"].to_numpy(dtype=float), "-", color="k", lw=1.5, label="|contact force|", marker=marker
    )
    ax["force"].set_ylabel("applied force (N)")
    if "moment" in ax:
        for k, (name, values) in enumerate(_components(table, ("Mx_Nmm", "My_Nmm", "Mz_Nmm"), anatomy)):
            ax["moment"].plot(t, values, "-", color=colours[k], label=name, marker=marker)
        ax["moment"].set_ylabel("applied moment\n(N mm)")
    if "pressure" in ax:
        pressure = ax["pressure"]
        pressure.plot(t, table["peak_pressure_MPa"].to_numpy(dtype=float), "-", color="C3", label="peak", marker=marker)
        pressure.plot(t, table["mean_pressure_MPa"].to_numpy(dtype=float), "-", color="C1", label="mean", marker=marker)
        pressure.set_ylabel("pressure (MPa)")
        area = ax["area"]
        area.plot(
            t, table["contact_area_mm2"].to_numpy(dtype=float), "-", color="C2", label="contact area", marker=marker
        )
        area.set_ylabel("contact area (mm$^2$)")
        for one in (pressure, area):
            one.set_ylim(bottom=0)
    if "regions" in ax:
        shares = []
        for k, (name, prefix) in enumerate(prefixes.items()):
            share = 100.0 * table[f"{prefix}_force_share"].to_numpy(dtype=float)
            shares.append(share)
            ax["regions"].plot(t, share, "-", color=f"C{k}", label=str(name), marker=marker)
        ax["regions"].set_ylabel("share of the\ncontact force (%)")
        low, high = (float(f(np.nan_to_num(np.concatenate(shares)))) for f in (np.min, np.max))
        ax["regions"].set_ylim(min(0.0, low), max(100.0, high))  # a region may push against the total
    for one in axes:
        one.grid(alpha=0.3)
        if failed.any():
            one.plot(
                t[failed],
                np.zeros(failed.sum()),
                "x",
                color="k",
                ms=7,
                clip_on=False,
                transform=one.get_xaxis_transform(),
                label="no certified answer",
            )
        if outside.any():
            one.plot(
                t[outside],
                np.zeros(outside.sum()),
                "^",
                color="C1",
                ms=6,
                clip_on=False,
                transform=one.get_xaxis_transform(),
                label="outside validity",
            )
        one.legend(fontsize="x-small", loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    axes[-1].set_xlabel("time (s)")
    peak = np.nanmax(table["peak_pressure_MPa"].to_numpy(dtype=float), initial=-np.inf)
    area = np.nanmax(table["contact_area_mm2"].to_numpy(dtype=float), initial=-np.inf)
    numbers = f"{len(t)} frames" + (
        f": peak {peak:.4g} MPa, largest contact area {area:.4g} mm$^2$" if np.isfinite(peak) else ""
    )
    numbers += f", {int(failed.sum())} without a certified answer" if failed.any() else ""
    numbers += "; no moment applied" if "moment" not in ax else ""
    verdict = path_verdict(table)
    heading = fig.suptitle((f"{title}\n{numbers}" if title else numbers) + verdict_lines(verdict), fontsize="medium")
    place_panels(fig, list(axes), heading)
    stamp(fig, verdict)
    return fig


def plot_exposure(
    layer, exposure, path, *, moving: bool = False, title: str | None = None, anatomy=None, verdict=None
) -> Path:
    """Two maps side by side: pressure-time integral (MPa s) and time above the threshold (s).

    Parameters
    ----------
    layer : SpringLayer
        The springs (or, with ``moving``, a layer whose ``surface`` faces are the sites).
    exposure : Exposure
    path : str or Path
    moving : bool
        Sites are the faces of ``layer.surface`` rather than the springs.
    title : str, optional
        The figure's heading, e.g. the scenario's title; a line naming the measures follows it.
    anatomy : AnatomicalFrame or dict, optional
        Draw the maps in the anatomical frame (:func:`~dea_opt.io.mapframe.map_frame`).
    verdict : (str, str), optional
        The path's verdict (:func:`~dea_opt.io.marks.path_verdict`), stamped on the maps.
    """
    return _save(exposure_figure(layer, exposure, moving=moving, title=title, anatomy=anatomy, verdict=verdict), path)


def exposure_figure(layer, exposure, *, moving: bool = False, title: str | None = None, anatomy=None, verdict=None):
    """The :class:`matplotlib.figure.Figure` :func:`plot_exposure` saves (same parameters)."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import Normalize

    fig = _figure((11.0, 5.6))
    axes = fig.subplots(1, 2)
    frame = map_frame(layer.points, layer.areas, layer.normals, anatomy)
    geometry = map_geometry(layer, frame, sites="faces" if moving else "springs")
    maps = (
        (axes[0], exposure.pressure_time_integral, "pressure-time integral (MPa s)", "magma"),
        (axes[1], exposure.time_above, f"time above {exposure.threshold:g} MPa (s)", "viridis"),
    )
    bars = []
    for ax, values, label, cmap in maps:
        top = float(values.max(initial=0.0))
        norm = Normalize(0.0, top if top > 0 else 1.0)
        draw_values(ax, geometry, values, cmap, norm)
        if not moving and layer.labels is not None:
            draw_regions(ax, geometry, layer.labels)
        decorate_map(ax, frame, geometry)
        bars.append(fig.colorbar(ScalarMappable(norm=norm, cmap=cmap), cax=colorbar_axes(fig), label=label))
    note = note_frame(fig, frame)
    numbers = f"Contact-stress exposure over {exposure.duration:.3g} s (threshold {exposure.threshold:g} MPa)"
    heading = fig.suptitle(
        (f"{title}\n{numbers}" if title else numbers) + verdict_lines(verdict, 120), fontsize="medium"
    )
    place_maps(fig, list(zip(axes, bars)), heading, note)
    stamp(fig, verdict)
    return fig
