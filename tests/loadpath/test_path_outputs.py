"""Validity and compartments in every output of a load path: the table, the JSON, the VTK files.

A plate on a bonded layer labelled in two halves along x is tilted by a moment that changes
sign over the path, so the load moves from one half to the other; the last frame crushes the
layer past the linear law's range. Every regional number is checked against sums written
here over the springs of each half.
"""

from __future__ import annotations

import dataclasses
import json
import warnings

import meshio
import numpy as np
import pandas as pd
import pytest

import dea_opt as d
from dea_opt.anatomy.regions import label_by_axis
from dea_opt.geometry import plate_layer
from dea_opt.loadpath import REGION_COLUMNS, TABLE_COLUMNS, solve_path

H = 10.0
LOADS = np.array(
    [
        [0.0, 0.0, -400.0, 0.0, -1500.0, 0.0],
        [0.0, 0.0, -400.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, -400.0, 0.0, 1500.0, 0.0],
        [0.0, 0.0, -2800.0, 0.0, 0.0, 0.0],  # 2800 N on 400 mm^2: 7 MPa, strain 0.7 > 0.3
    ]
)


@pytest.fixture(scope="module")
def labelled():
    layer = plate_layer(40.0, 10.0, 40, 10, thickness=2.0)
    return dataclasses.replace(layer, labels=label_by_axis(layer, "x", at=0.0, names=("medial", "lateral")))


@pytest.fixture(scope="module")
def path(labelled):
    problem = d.ContactProblem(labelled, d.LinearLaw(H), free=("uz", "ry"))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = solve_path(problem, LOADS, times=[0.0, 0.1, 0.2, 0.3], method="newton")
    result.caught = [w for w in caught if issubclass(w.category, d.ValidityWarning)]
    return result


def test_region_columns_are_the_sums_over_each_half(path, labelled):
    table = path.table
    assert path.regions == {"lateral": "lateral", "medial": "medial"}
    expected = [f"{p}_{c}" for p in ("lateral", "medial") for c in REGION_COLUMNS]
    assert list(table.columns)[-len(expected) :] == expected
    for k, solution in enumerate(path.solutions):
        p, a, n = solution.pressure, labelled.areas, labelled.normals
        total = (p * a) @ n  # the contact force: every spring's force on body 2
        for name in ("medial", "lateral"):
            mask = labelled.labels == name
            force = float(p[mask] @ a[mask])
            vector = (p[mask] * a[mask]) @ n[mask]
            row = table.iloc[k]
            assert [row[f"{name}_force_{c}_N"] for c in "xyz"] == pytest.approx(vector.tolist(), rel=1e-12, abs=1e-9)
            assert row[f"{name}_resultant_N"] == pytest.approx(np.linalg.norm(vector), rel=1e-12)
            assert row[f"{name}_force_magnitude_sum_N"] == pytest.approx(force, rel=1e-12)
            assert row[f"{name}_force_share"] == pytest.approx(vector @ total / (total @ total), rel=1e-12)
            assert row[f"{name}_peak_pressure_MPa"] == p[mask].max()
            contact = mask & (solution.strain < 0)
            assert row[f"{name}_contact_area_mm2"] == pytest.approx(a[contact].sum(), rel=1e-12)
            if force > 0:
                cop = (p[mask] * a[mask]) @ labelled.points[mask] / force
                assert [row[f"{name}_cop_{c}_mm"] for c in "xyz"] == pytest.approx(cop.tolist(), abs=1e-9)
        assert table["medial_force_share"].iloc[k] + table["lateral_force_share"].iloc[k] == pytest.approx(1.0)
    # Closed form of the plate in full contact, p_i = P/A + M x_i / I over the springs at
    # x_i = +-0.5, ..., +-19.5 mm (1 mm apart): I = S sum x_i^2, and the moment adds
    # M sum_{x<0} |x_i| / sum x_i^2 = M 200 / 5330 to one half's force.
    share = table["medial_force_share"].to_numpy()
    x = np.arange(-19.5, 20.0)
    shift = 1500.0 * np.abs(x[x < 0]).sum() / (x**2).sum() / 400.0
    np.testing.assert_allclose(share[:3], [0.5 + shift, 0.5, 0.5 - shift], rtol=1e-9)


def test_validity_per_frame(path):
    table = path.table
    # the linear law's range is 30 % compressive strain: the last frame is outside it
    strain = table["peak_pressure_MPa"] / H  # linear law: p = -H eps
    assert table["valid"].tolist() == [True, True, True, False]
    assert table["validity_failed"].tolist() == ["", "", "", "strain"]
    np.testing.assert_allclose(table["validity_strain"], strain, rtol=1e-12)
    assert path.success and not path.valid and path.frames_outside_validity == [3]
    summary = path.validity_summary()
    assert summary["failed_checks"] == ["strain"] and summary["checks"]["strain"]["frames"] == [3]
    assert summary["checks"]["strain"]["worst"] == pytest.approx(strain.iloc[3])
    assert len(path.caught) == 1 and "1 of 4 frames" in str(path.caught[0].message)


def test_files_carry_validity_and_regions(path, labelled, tmp_path):
    files = path.write(tmp_path, anatomy={"medial": (-1, 0, 0), "proximal": (0, 0, 1), "side": "right"})
    table = pd.read_csv(files["table"], keep_default_na=False, na_values=[""])
    assert list(table.columns)[: len(TABLE_COLUMNS)] == list(TABLE_COLUMNS)
    np.testing.assert_array_equal(table["medial_force_share"], path.table["medial_force_share"])
    assert table["valid"].tolist() == [True, True, True, False]
    summary = json.loads(files["summary"].read_text())
    assert summary["valid"] is False and summary["validity"]["frames_outside_validity"] == [3]
    regions = summary["regions"]
    assert set(regions) == {"medial", "lateral"}
    assert regions["medial"]["max_force_share"] == pytest.approx(path.table["medial_force_share"].max())
    assert regions["lateral"]["peak_frame"] == 3
    assert summary["anatomy"]["side"] == "right"
    # every frame's .vtu carries the label of each spring, and so does the exposure
    codes = {"lateral": 0, "medial": 1}
    frame = meshio.read(next((tmp_path / "series_frames").glob("*.vtu")))
    np.testing.assert_array_equal(frame.point_data["label"], [codes[v] for v in labelled.labels])
    surface = meshio.read(files["exposure_vtk"])
    np.testing.assert_array_equal(surface.point_data["label"], [codes[v] for v in labelled.labels])


def test_regions_given_for_a_path(labelled):
    """A layer without labels, split for the whole path by a function of the layer."""
    bare = dataclasses.replace(labelled, labels=None)
    problem = d.ContactProblem(bare, d.LinearLaw(H), free=("uz", "ry"))
    result = solve_path(
        problem,
        LOADS[:3],
        method="newton",
        outputs=d.PathOutputs(regions=lambda layer: label_by_axis(layer, "x", names=("left", "right"))),
    )
    assert set(result.regions) == {"left", "right"}
    with pytest.raises(d.InputError, match="one label per spring"):
        solve_path(problem, LOADS[:1], outputs=d.PathOutputs(regions=np.zeros(3)))


def test_label_by_axis_in_an_anatomical_frame(labelled):
    anatomy = {"medial": (-1.0, 0.0, 0.0), "proximal": (0.0, 0.0, 1.0), "side": "left"}
    labels = label_by_axis(labelled, "medial", anatomy=anatomy)
    # medial is -x: the springs at x < 0 are the medial half
    np.testing.assert_array_equal(labels, np.where(labelled.points[:, 0] < 0, "medial", "lateral"))
    with pytest.raises(d.InputError, match="direction must be one of"):
        label_by_axis(labelled, "sideways", anatomy=anatomy)
    with pytest.raises(d.InputError, match="at must be"):
        label_by_axis(labelled, "x", at="cop")


def test_frames_written_in_a_thread_are_the_frames_written_in_turn(path, labelled, tmp_path):
    """``solve_path(..., PathOutputs(series=...))`` writes each frame's ``.vtu`` in a thread while
    the next frame solves: the same bytes as :meth:`PathResult.to_pvd` writes from the kept
    solutions in turn, every file there when the path returns, nothing else in the folder."""
    problem = d.ContactProblem(labelled, d.LinearLaw(H), free=("uz", "ry"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        streamed = solve_path(
            problem, LOADS, times=[0.0, 0.1, 0.2, 0.3], method="newton", outputs=d.PathOutputs(series=tmp_path / "s")
        )
    path.to_pvd(tmp_path / "kept.pvd")
    written = sorted(p.name for p in (tmp_path / "s").iterdir())
    assert written == [f"frame_{k:04d}.vtu" for k in range(len(LOADS))]
    for name in written:
        assert (tmp_path / "s" / name).read_bytes() == (tmp_path / "kept_frames" / name).read_bytes(), name
    assert streamed.frame_files is not None and streamed.frame_files._thread is None  # the thread ended


def test_a_frame_that_cannot_be_written_in_the_thread_fails_the_path(labelled, tmp_path):
    """A frame's write that fails in the series' thread raises in the solve, as a write in turn did."""
    from dea_opt.loadpath import FrameSeries

    series = FrameSeries(tmp_path / "blocked", 2, background=True)
    (tmp_path / "blocked").write_text("a file where the folder goes")
    with pytest.raises((d.InputError, OSError)):
        series.write(0, 0.0, labelled)
        series.finish()
    assert series._thread is None
