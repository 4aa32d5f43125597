"""Every kind of figure dea-opt draws is ready for a talk: its text fits inside it, no panel is
empty, a result outside validity is stamped as such, the scenario's title heads it, and a map
draws each compartment's centre of pressure and contact edge.

A figure is drawn on Matplotlib's Agg canvas and checked with Matplotlib's own measure of each
text's extent (``Text.get_window_extent``): a label cut by the figure's edge lies partly outside
the figure's box. An axes is empty when nothing it holds draws a finite number.
"""

from __future__ import annotations

import dataclasses
import json
import warnings

import matplotlib
import numpy as np
import pandas as pd
import pytest
from matplotlib.collections import Collection
from matplotlib.image import AxesImage
from matplotlib.lines import Line2D
from matplotlib.text import Text

import dea_opt as d
from dea_opt.cli import app
from dea_opt.geometry import plate_layer, socket_layer
from dea_opt.io.cycle import cycle_figure, exposure_figure
from dea_opt.io.plots import pressure_figure

matplotlib.use("Agg")


def problems(fig) -> list[str]:
    """What a reader would miss in ``fig``: text outside the figure (each axes' tight bounding box,
    its tick labels, labels, title and legend included, and the figure's own texts), two axes
    whose boxes so measured overlap (a map's labels over its neighbour's colour bar) or overlap
    the heading or the note, empty axes, unlabelled colour bars."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    box = fig.bbox

    def outside(extent) -> bool:
        return extent.x0 < box.x0 - 1 or extent.y0 < box.y0 - 1 or extent.x1 > box.x1 + 1 or extent.y1 > box.y1 + 1

    def name(ax) -> str:
        return repr(ax.get_ylabel() or ax.get_title() or ax.get_label())

    found = []
    for ax in fig.axes:
        if outside(ax.get_tightbbox(renderer)):
            found.append(f"{name(ax)}: a label is cut by the edge")
    own = [*fig.texts, *(t for t in (fig._suptitle, fig._supxlabel, fig._supylabel) if t is not None)]
    for text in own:
        if text.get_visible() and text.get_text().strip() and outside(text.get_window_extent(renderer)):
            found.append(f"text {text.get_text()[:40]!r} is cut by the figure's edge")
    boxes = [(name(ax), ax.get_tightbbox(renderer)) for ax in fig.axes]
    boxes += [(repr(t.get_text()[:40]), t.get_window_extent(renderer)) for t in (fig._suptitle, fig._supxlabel) if t]
    for k, (one, first) in enumerate(boxes):
        for other, second in boxes[k + 1 :]:
            across = min(first.x1, second.x1) - max(first.x0, second.x0)
            along = min(first.y1, second.y1) - max(first.y0, second.y0)
            if across > 1 and along > 1:
                found.append(f"{one} and {other} overlap")
    for ax in fig.axes:
        if ax.get_label() == "<colorbar>":
            if not ax.get_ylabel() and not ax.get_xlabel():
                found.append("a colour bar without a label")
            continue
        if not _draws_numbers(ax):
            found.append(f"an empty axes: {ax.get_ylabel() or ax.get_title() or ax}")
    return found


def _draws_numbers(ax) -> bool:
    for artist in ax.get_children():
        if isinstance(artist, Line2D) and np.isfinite(np.asarray(artist.get_ydata(), float)).any():
            return True
        if isinstance(artist, AxesImage) and np.isfinite(np.ma.filled(artist.get_array(), np.nan)).any():
            return True
        if isinstance(artist, Collection) and (len(artist.get_paths()) or np.size(artist.get_offsets())):
            return True
    return False


def texts(fig) -> str:
    return "\n".join(t.get_text() for t in fig.findobj(Text))


# --- answers to draw ----------------------------------------------------------------------------


@pytest.fixture(scope="module")
def plate():
    """A plate in two compartments (x < 0 medial), loaded off centre: certified and valid."""
    layer = plate_layer(nx=40, ny=6)
    layer = dataclasses.replace(layer, labels=np.where(layer.points[:, 0] < 0, "medial", "lateral"))
    problem = d.ContactProblem(layer, d.LinearLaw(10.0), force=(0, 0, -400.0), moment=(0, 600.0, 0), free=("uz", "ry"))
    return d.solve(problem)


@pytest.fixture(scope="module")
def crushed(plate):
    """The same plate pressed ten times harder: certified, outside validity (strain past 30 %)."""
    with pytest.warns(d.errors.ValidityWarning, match="strain"):
        return d.solve(plate.problem.with_load(force=(0, 0, -4000.0), moment=(0, 6000.0, 0)))


@pytest.fixture(scope="module")
def socket_solution():
    """Springs on points (a generated socket), in three regions: drawn on a triangulation."""
    layer = socket_layer(radius=25.0, thickness=3.0, coverage=80.0, n_rings=12, n_sectors=36, gap=0.1)
    layer = dataclasses.replace(
        layer, labels=np.where(layer.points[:, 2] < -20, "dome", np.where(layer.points[:, 1] > 0, "front", "back"))
    )
    return d.solve(d.ContactProblem(layer, d.LinearLaw(10.0), force=(300.0, 0, -1500.0), free=("ux", "uy", "uz")))


def path_table(forces, moments=None, failed=()) -> pd.DataFrame:
    """A plate's load path of ``forces`` (N along -z) and ``moments`` (N mm about y)."""
    layer = plate_layer(nx=20, ny=4)
    layer = dataclasses.replace(layer, labels=np.where(layer.points[:, 0] < 0, "medial", "lateral"))
    problem = d.ContactProblem(layer, d.LinearLaw(10.0), free=("uz", "ry"))
    loads = np.zeros((len(forces), 6))
    loads[:, 2] = -np.asarray(forces, float)
    loads[:, 4] = 0.0 if moments is None else moments
    for k in failed:
        loads[k, 2] = 100.0  # pulls the plate off: no certified answer
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the frames outside validity: the figures say so
        return d.solve_path(
            problem, loads, times=np.linspace(0.0, 1.0, len(forces)), outputs=d.PathOutputs(keep_frames=("peak",))
        )


# --- maps ----------------------------------------------------------------------------------------


def test_a_compartment_map_draws_each_centre_of_pressure_and_contact_edge_under_the_scenario_title(plate):
    fig = pressure_figure(plate, title="Plate in two compartments")
    assert problems(fig) == []
    ax = fig.axes[0]
    assert ax.get_title().splitlines()[0] == "Plate in two compartments"  # the scenario's title, not "newton: ..."
    assert "newton" not in ax.get_title()
    legend = [t.get_text() for t in ax.get_legend().get_texts()]
    assert legend == ["centre of pressure (all)", "lateral: edge, centre", "medial: edge, centre"]
    regions = plate.regions()
    markers = {tuple(np.round(line.get_xydata()[0], 9)) for line in ax.get_lines() if line.get_marker() == "D"}
    # each compartment's centre of pressure is where its own pressure-weighted centroid lies (plane z = 0)
    for stats in regions.values():
        weight = plate.pressure * plate.problem.layer.areas
        mask = plate.problem.layer.labels == stats.name
        own = weight[mask] @ plate.problem.layer.points[mask] / weight[mask].sum()
        assert any(np.allclose(m, own[:2], atol=1e-9) for m in markers), stats.name
    assert "OUTSIDE VALIDITY" not in texts(fig)


def test_a_map_outside_validity_is_stamped_with_its_reason(crushed):
    assert crushed.success and not crushed.validity.valid
    fig = pressure_figure(crushed, title="Plate pressed too hard")
    assert problems(fig) == []
    assert "OUTSIDE VALIDITY" in [t.get_text() for t in fig.texts]
    title = fig.axes[0].get_title()
    assert "OUTSIDE VALIDITY: strain" in title and "> 0.3" in title


def test_a_title_wider_than_its_room_is_wrapped_to_fit(plate):
    long = "Real knee over a synthetic stance, from an OpenSim JointReaction file: peak frame 36, 0.432 s"
    fig = pressure_figure(plate, title=long)
    assert problems(fig) == []
    lines = fig.axes[0].get_title().splitlines()
    assert len(lines) >= 3 and " ".join(lines[:-1]) == long
    assert pressure_figure(plate, title="A plate").axes[0].get_title().splitlines()[0] == "A plate"
    path = path_table([1000.0, 3000.0, 2000.0])
    fig = cycle_figure(path.table, f"{long} {long}")
    assert problems(fig) == [] and fig._suptitle.get_text().replace("\n", " ").startswith(f"{long} {long}")


def test_maps_on_points_and_in_3d_fit(socket_solution):
    for view in ("plane", "3d"):
        fig = pressure_figure(socket_solution, view=view, title="A socket")
        assert problems(fig) == [], view
        labels = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
        assert {"dome: edge, centre", "front: edge, centre", "back: edge, centre"} <= set(labels)


# --- a load path's figures ---------------------------------------------------------------------


def test_the_cycle_plot_fits_five_digit_forces_and_draws_no_empty_panel():
    result = path_table([2000.0, 25000.0, 40000.0, 12000.0, 3000.0])  # no moment at any frame
    fig = cycle_figure(result.table, "A heavy plate", regions=result.regions)
    assert problems(fig) == []
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert not any("moment" in label for label in labels)  # an all-zero moment is no panel
    assert labels[0] == "applied force (N)" and "share of the\ncontact force (%)" in labels
    assert (
        fig._suptitle.get_text().startswith("A heavy plate\n5 frames")
        and "no moment applied" in fig._suptitle.get_text()
    )
    assert max(abs(t) for t in fig.axes[0].get_yticks()) >= 10000  # five-digit ticks, and they fit


def test_a_path_outside_validity_is_stamped_on_its_cycle_and_exposure_plots():
    # five-digit negative moments: the labels a fixed layout cut
    result = path_table([500.0, 4000.0, 8000.0], moments=[-30000.0, -45000.0, 0.0], failed=[1])
    table = result.table
    assert not table["success"].iloc[1] and (~table["valid"]).any()
    fig = cycle_figure(table, "A plate")
    assert problems(fig) == []
    assert any("moment" in ax.get_ylabel() for ax in fig.axes)
    assert "OUTSIDE VALIDITY" in [t.get_text() for t in fig.texts]
    from dea_opt.io.marks import path_verdict

    fig = exposure_figure(result.problem.layer, result.exposure, title="A plate", verdict=path_verdict(table))
    assert problems(fig) == [] and "OUTSIDE VALIDITY" in [t.get_text() for t in fig.texts]


@pytest.mark.parametrize("scale", [0.8, 1.5])
def test_a_figure_resized_before_it_is_saved_is_placed_again_at_its_new_size(plate, scale):
    """A reader sizes a picture for a slide or a paper: ``set_size_inches`` and then ``savefig``.
    Each kind of picture (a map, a load path's cycle and exposure, stamped outside validity) is
    placed again when drawn at another size, its texts inside it (from 0.8 to 1.5 times the size
    it was drawn at; a cycle plot's five panels are too short for their labels much below), the
    stamp sized again; drawn at its own size, nothing moves."""
    from matplotlib.layout_engine import LayoutEngine

    from dea_opt.io.marks import path_verdict

    result = path_table([500.0, 4000.0, 8000.0], moments=[-30000.0, -45000.0, 0.0], failed=[1])
    makers = {
        "map": lambda: pressure_figure(plate, title="Plate in two compartments"),
        "cycle": lambda: cycle_figure(result.table, "A plate", regions=result.regions),
        "exposure": lambda: exposure_figure(
            result.problem.layer, result.exposure, title="A plate", verdict=path_verdict(result.table)
        ),
    }
    for kind, make in makers.items():
        fig = make()
        assert isinstance(fig.get_layout_engine(), LayoutEngine)
        placed = [ax.get_position().bounds for ax in fig.axes]
        fig.canvas.draw()
        assert [ax.get_position().bounds for ax in fig.axes] == placed, kind  # its own size: as placed
        marks = [t for t in fig.texts if t.get_text() == "OUTSIDE VALIDITY"]
        before = [mark.get_fontsize() for mark in marks]
        fig.set_size_inches(*(scale * fig.get_size_inches()))
        assert problems(fig) == [], (kind, scale)
        assert len(marks) == (kind != "map")
        for mark, font in zip(marks, before):  # sized again: smaller on a smaller figure, at most 48 pt
            assert mark.get_fontsize() < font if scale < 1 else font <= mark.get_fontsize() <= 48.0


def test_a_path_without_a_certified_frame_draws_only_its_loads():
    result = path_table([1.0, 2.0], failed=[0, 1])
    fig = cycle_figure(result.table)
    assert problems(fig) == []
    assert [ax.get_ylabel() for ax in fig.axes] == ["applied force (N)"]
    assert "NO CERTIFIED ANSWER" in [t.get_text() for t in fig.texts]


def test_the_peak_frame_is_kept_and_drawn(tmp_path):
    result = path_table([1000.0, 3000.0, 2000.0])
    k, solution = result.kept["peak"]
    assert k == 1 == int(result.table["peak_pressure_MPa"].idxmax())
    assert solution.peak_pressure == result.table["peak_pressure_MPa"].iloc[1]
    files = result.write(tmp_path, ["png"], title="A plate", maps=[0])
    assert {"peak_map", "map_frame_0"} <= set(files)
    assert files["peak_map"].name == "peak.png" and files["map_frame_0"].name == "map_frame_0000.png"


# --- a run's pictures, and the calibration's ---------------------------------------------------

SCENARIO = """
title = "Plate under a path"
[geometry]
kind = "plate"
nx = 20
ny = 4
[law]
kind = "linear"
H = 10.0
[body2]
free = ["uz", "ry"]
[regions]
split = "x"
[load_path]
file = "path.csv"
[output]
formats = ["csv", "json", "png"]
maps = [0, 2]
"""


def test_a_run_of_a_load_path_writes_its_peak_map_and_the_maps_it_asks_for(tmp_path):
    from typer.testing import CliRunner

    (tmp_path / "path.csv").write_text(
        "time,Fx,Fy,Fz,Mx,My,Mz\n0,0,0,-300,0,0,0\n0.5,0,0,-900,0,500,0\n1,0,0,-600,0,0,0\n"
    )
    (tmp_path / "plate.toml").write_text(SCENARIO)
    result = CliRunner().invoke(app, ["run", str(tmp_path / "plate.toml"), "-o", str(tmp_path / "out")])
    assert result.exit_code == 0, result.stdout + result.stderr
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert {"peak.png", "map_frame_0000.png", "map_frame_0002.png", "cycle.png"} <= set(manifest["files"])
    (tmp_path / "bad.toml").write_text(SCENARIO.replace("maps = [0, 2]", "maps = [7]"))
    refused = CliRunner().invoke(app, ["run", str(tmp_path / "bad.toml"), "-o", str(tmp_path / "bad")])
    assert refused.exit_code == 2 and "[output] maps names frame 7, but the load path has 3 frames" in refused.stderr


def test_the_calibration_picture_names_h_s_unit_and_labels_its_colour_bar(plate, tmp_path, monkeypatch):
    from dea_opt.sensitivity import PressureMap, calibrate

    start = plate.problem.with_law(d.LinearLaw(20.0))
    data = PressureMap(plate.problem.layer.points, np.maximum(plate.pressure, 0.02), noise=0.05)
    fit = calibrate(start, data, ("H",))
    figures = []
    from matplotlib.figure import Figure

    save = Figure.savefig
    monkeypatch.setattr(Figure, "savefig", lambda self, *a, **k: figures.append(self) or save(self, *a, **k))
    fit.plot(tmp_path / "calibration.png")
    (fig,) = figures
    assert problems(fig) == []
    assert "H = " in fig._suptitle.get_text() and " MPa" in fig._suptitle.get_text()
    (bar,) = [ax for ax in fig.axes if ax.get_label() == "<colorbar>"]
    assert "residual" in bar.get_ylabel()
