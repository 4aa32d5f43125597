"""A load path's centre of pressure and found motion along the joint's anatomical axes: the columns
of PathResult.anatomical_table and frames.csv, summary.json's ranges, and the terminal line of
dea-opt run; checked against the meshes'-frame columns projected on the axes in the test."""

from __future__ import annotations

import dataclasses
import json
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import COARSE_SOCKET, KNEE, KNEE_FILES
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

import dea_opt as d
from dea_opt.anatomy import AnatomicalFrame
from dea_opt.cli import app
from dea_opt.geometry import plate_layer
from dea_opt.loadpath import solve_path
from dea_opt.loadpath.anatomical import anatomical_columns, anatomical_frame_table

runner = CliRunner()

#: A frame turned away from every coordinate axis: the columns of a rotation matrix (a left limb:
#: medial x anterior = proximal makes anterior x proximal = medial, the subject's right).
AXES = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_matrix().T  # rows: medial, anterior, proximal
TURNED = {"medial": AXES[0].tolist(), "anterior": AXES[1].tolist(), "proximal": AXES[2].tolist()}
#: Where the plate is moved to, so that the layer's centroid is not the coordinates' origin.
OFFSET = np.array([5.0, -3.0, 2.0])
H, THICKNESS = 10.0, 2.0
#: Loads (Fx, Fy, Fz, Mx, My, Mz; N, N mm about body 2's reference); frame 2 pulls the plate off
#: its layer, which no spring can carry: it fails, and its numbers are NaN.
LOADS = np.array(
    [
        [0.0, 0.0, -100.0, 50.0, -200.0, 0.0],
        [0.0, 0.0, -300.0, -100.0, 300.0, 0.0],
        [0.0, 0.0, 200.0, 0.0, 0.0, 0.0],
        [0.0, 0.0, -200.0, 20.0, 0.0, 0.0],
    ]
)
CERTIFIED = [0, 1, 3]
TRANSLATION = [f"body2_translation_{a}_mm" for a in ("medial", "anterior", "proximal")]
ROTATION = [f"body2_rotation_{a}_rad" for a in ("medial", "anterior", "proximal")]
COP = ["cop_medial_mm", "cop_anterior_mm", "cop_proximal_mm"]


def invoke(*args):
    return runner.invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def plate_path():
    """A flat plate, moved to OFFSET, sinking (uz) and tilting (rx, ry) about its centre over LOADS."""
    layer = plate_layer(40.0, 10.0, 40, 10, thickness=THICKNESS)
    layer = dataclasses.replace(layer, points=layer.points + OFFSET)
    problem = d.ContactProblem(layer, d.LinearLaw(H), reference=OFFSET, free=("uz", "rx", "ry"))
    return solve_path(problem, LOADS, method="newton")


def closed_form_motion(layer) -> np.ndarray:
    """``(uz, rx, ry)`` per frame of LOADS (mm, rad) while every spring is in compression: the
    uniform sink ``F h / (H A)`` and the tilts ``M h / (H I)`` with ``I`` the springs' second
    moment of area about the plate's centre (``sum a y^2`` about x, ``sum a x^2`` about y)."""
    x, y = (layer.points - OFFSET)[:, 0], (layer.points - OFFSET)[:, 1]
    a = layer.areas
    stiffness = H / THICKNESS
    return np.column_stack(
        [
            LOADS[:, 2] / (stiffness * a.sum()),
            LOADS[:, 3] / (stiffness * (a @ y**2)),
            LOADS[:, 4] / (stiffness * (a @ x**2)),
        ]
    )


def expected_columns(table, origin) -> dict:
    """The anatomical columns worked out here: the meshes'-frame columns dotted with the axes."""
    cop = table[["cop_x_mm", "cop_y_mm", "cop_z_mm"]].to_numpy() - origin
    translation = np.column_stack([np.zeros((len(table), 2)), table["body2_uz_mm"]])
    rotation = np.column_stack([table["body2_rx_rad"], table["body2_ry_rad"], np.zeros(len(table))])
    return {
        **{c: cop @ axis for c, axis in zip(COP, AXES)},
        **{c: translation @ axis for c, axis in zip(TRANSLATION, AXES)},
        **{c: rotation @ axis for c, axis in zip(ROTATION, AXES)},
    }


@pytest.mark.parametrize(
    "anatomy, origin",
    [
        pytest.param({**TURNED, "origin": [1.0, 2.0, -4.0]}, np.array([1.0, 2.0, -4.0]), id="given-origin"),
        pytest.param(AnatomicalFrame(*AXES), None, id="centroid-origin"),
    ],
)
def test_the_plate_s_columns_are_its_table_along_the_turned_axes(plate_path, anatomy, origin):
    layer = plate_path.problem.layer
    origin = layer.areas @ layer.points / layer.areas.sum() if origin is None else origin
    assert not np.allclose(origin, 0.0)  # the subtraction shows
    table = plate_path.table
    columns = anatomical_frame_table(table, plate_path.problem, anatomy)
    assert list(columns) == COP + TRANSLATION + ROTATION
    assert list(columns) == list(anatomical_columns(plate_path.problem))
    for column, values in expected_columns(table, origin).items():
        np.testing.assert_allclose(columns[column], values, rtol=1e-12, atol=1e-12, err_msg=column)
    # the found motion is the plate's closed form, so each axis carries its share of it
    found = closed_form_motion(layer)[CERTIFIED]
    np.testing.assert_allclose(
        table.loc[CERTIFIED, ["body2_uz_mm", "body2_rx_rad", "body2_ry_rad"]], found, rtol=1e-9, atol=1e-15
    )
    np.testing.assert_allclose(columns.loc[CERTIFIED, TRANSLATION], np.outer(found[:, 0], AXES[:, 2]), rtol=1e-9)
    rotation = np.column_stack([found[:, 1], found[:, 2], np.zeros(len(found))]) @ AXES.T
    np.testing.assert_allclose(columns.loc[CERTIFIED, ROTATION], rotation, rtol=1e-9, atol=1e-15)
    # the failed frame stays NaN in every anatomical column
    assert plate_path.failed_frames == [2]
    assert columns.loc[2].isna().all() and columns.loc[CERTIFIED].notna().all().all()


def test_the_anatomical_table_appends_the_columns_and_keeps_the_table(plate_path):
    table = plate_path.anatomical_table(TURNED)
    assert list(table.columns) == [*plate_path.table.columns, *COP, *TRANSLATION, *ROTATION]
    pd.testing.assert_frame_equal(table[list(plate_path.table.columns)], plate_path.table)


def test_the_summary_gives_the_ranges_over_the_certified_frames(plate_path):
    summary = plate_path.summary(TURNED)
    assert {"center_of_pressure_anatomical", "motion_anatomical"} <= set(summary)
    assert "motion_anatomical" not in plate_path.summary()  # only with a frame
    layer = plate_path.problem.layer
    centroid = layer.areas @ layer.points / layer.areas.sum()
    assert summary["anatomy"]["origin_used_mm"] == pytest.approx(centroid.tolist())
    expected = expected_columns(plate_path.table, centroid)
    peak = int(plate_path.table["peak_pressure_MPa"].idxmax())  # NaN of the failed frame skipped
    assert peak == 1
    ranges = {**summary["center_of_pressure_anatomical"], **summary["motion_anatomical"]}
    assert list(summary["center_of_pressure_anatomical"]) == COP
    assert list(summary["motion_anatomical"]) == TRANSLATION + ROTATION
    for column, values in expected.items():
        certified = values[CERTIFIED]
        unit = "rad" if column in ROTATION else "mm"
        assert ranges[column]["unit"] == unit
        assert ranges[column]["min"] == pytest.approx(certified.min(), rel=1e-12, abs=1e-15)
        assert ranges[column]["max"] == pytest.approx(certified.max(), rel=1e-12, abs=1e-15)
        assert ranges[column]["at_peak"] == pytest.approx(values[peak], rel=1e-12, abs=1e-15)


def test_write_puts_the_columns_in_frames_csv_and_the_ranges_in_summary_json(plate_path, tmp_path):
    plate_path.write(tmp_path / "with", formats=("csv", "json"), anatomy=TURNED)
    plate_path.write(tmp_path / "without", formats=("csv", "json"))
    frames = pd.read_csv(tmp_path / "with" / "frames.csv")
    plain = pd.read_csv(tmp_path / "without" / "frames.csv")
    assert list(frames.columns) == [*plain.columns, *COP, *TRANSLATION, *ROTATION]
    np.testing.assert_array_equal(
        frames[COP + TRANSLATION + ROTATION], plate_path.anatomical_table(TURNED)[COP + TRANSLATION + ROTATION]
    )
    summary = json.loads((tmp_path / "with" / "summary.json").read_text())
    assert summary["motion_anatomical"]["body2_translation_proximal_mm"]["unit"] == "mm"
    assert set(summary["center_of_pressure_anatomical"]) == set(COP)
    assert summary["anatomy"]["side"] == "left" and len(summary["anatomy"]["origin_used_mm"]) == 3
    without = json.loads((tmp_path / "without" / "summary.json").read_text())
    assert "motion_anatomical" not in without and "anatomy" not in without


# --- dea-opt run --------------------------------------------------------------------------------

SOCKET_PATH = (
    COARSE_SOCKET
    + """\
[load_path]
file = "path.csv"
[output]
formats = ["csv", "json"]
anatomy = {anatomy}
"""
)


def socket_scenario(tmp_path, anatomy: str):
    rows = [(0.0, 50.0, -30.0, -500.0), (0.1, -80.0, 20.0, -900.0), (0.2, 0.0, 0.0, 800.0)]
    (tmp_path / "path.csv").write_text("time,Fx,Fy,Fz\n" + "".join(f"{t},{x},{y},{z}\n" for t, x, y, z in rows))
    (tmp_path / "path.toml").write_text(SOCKET_PATH.format(anatomy=anatomy))
    return tmp_path / "path.toml"


def test_a_run_projects_every_free_translation_and_says_it(tmp_path):
    anatomy = "{" + ", ".join(f"{axis} = {vector}" for axis, vector in TURNED.items()) + "}"
    result = invoke("run", socket_scenario(tmp_path, anatomy), "-o", tmp_path / "out")
    assert result.exit_code == 1, result.stderr  # frame 2 pulls the head out: no certified answer
    frames = pd.read_csv(tmp_path / "out" / "frames.csv")
    translation = frames[["body2_ux_mm", "body2_uy_mm", "body2_uz_mm"]].to_numpy()
    for column, axis in zip(TRANSLATION, AXES):
        np.testing.assert_allclose(frames[column], translation @ axis, rtol=1e-12, atol=1e-15)
    assert not any(c.startswith("body2_rotation") for c in frames.columns)  # no rotation is free
    assert frames.loc[2, COP + TRANSLATION].isna().all()
    motion = json.loads((tmp_path / "out" / "summary.json").read_text())["motion_anatomical"]
    low, high = motion["body2_translation_proximal_mm"]["min"], motion["body2_translation_proximal_mm"]["max"]
    assert f"body2 translation medial {motion['body2_translation_medial_mm']['min']:.3g} to" in result.stdout
    assert f"proximal {low:.3g} to {high:.3g} mm" in result.stdout


def test_a_bad_anatomy_of_a_path_names_its_key(tmp_path):
    anatomy = '{medial = [1.0, 0.0, 0.0], proximal = [0.9, 0.1, 0.0], side = "right"}'
    result = invoke("run", socket_scenario(tmp_path, anatomy), "-o", tmp_path / "out")
    assert result.exit_code == 2 and "output.anatomy.proximal and output.anatomy.medial" in result.stderr
    assert "Traceback" not in result.stderr and not (tmp_path / "out").exists()


needs_knee = pytest.mark.skipif(not all((KNEE / f).is_file() for f in KNEE_FILES), reason="no knee meshes")


@needs_knee
def test_the_real_knee_s_stance_along_its_anatomical_axes(tmp_path):
    # The knee's frame (x medial-lateral, z tibia to femur) turned 10 degrees about proximal, with
    # its origin at body 2's reference: no axis is a coordinate axis but proximal.
    turn = np.radians(10.0)
    medial = np.array([np.cos(turn), np.sin(turn), 0.0])
    proximal = np.array([0.0, 0.0, 1.0])
    anterior = np.cross(medial, proximal)  # a right knee: anterior x proximal = -medial
    reference = np.array([-69.0242, -5.9006, -18.8433])
    walk = (Path(__file__).resolve().parents[1] / "examples" / "scenarios" / "knee" / "knee_walk.csv").as_posix()
    femur, medial_plateau, lateral_plateau = ((KNEE / name).as_posix() for name in KNEE_FILES)
    anatomy = (
        f'medial = {medial.tolist()}, proximal = {proximal.tolist()}, side = "right", origin = {reference.tolist()}'
    )
    scenario = tmp_path / "knee.toml"
    scenario.write_text(
        textwrap.dedent(f"""
            [geometry]
            kind = "meshes"
            mesh1 = {{ medial = "{medial_plateau}", lateral = "{lateral_plateau}" }}
            mesh2 = "{femur}"
            max_gap = 2.0
            [law]
            kind = "linear"
            H = 10.0
            [body2]
            reference = {reference.tolist()}
            free = ["uz", "ry"]
            # four frames of the example stance at half its load: quick, and inside the linear
            # law's validity
            [load_path]
            file = "{walk}"
            frames = 4
            scale = 0.5
            [output]
            formats = ["csv", "json"]
            anatomy = {{ {anatomy} }}
        """)
    )
    result = invoke("run", scenario, "-o", tmp_path / "out")
    assert result.exit_code == 0, result.stderr
    frames = pd.read_csv(tmp_path / "out" / "frames.csv")
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert list(frames.columns)[-9:] == COP + TRANSLATION + ROTATION
    assert np.allclose(summary["anatomy"]["anterior"], anterior) and summary["anatomy"]["side"] == "right"
    axes = np.array([medial, anterior, proximal])
    cop = (frames[["cop_x_mm", "cop_y_mm", "cop_z_mm"]].to_numpy() - reference) @ axes.T
    np.testing.assert_allclose(frames[COP], cop, rtol=1e-9, atol=1e-9)
    translation = np.outer(frames["body2_uz_mm"], proximal) @ axes.T
    np.testing.assert_allclose(frames[TRANSLATION], translation, rtol=1e-12, atol=1e-15)
    rotation = np.outer(frames["body2_ry_rad"], [0.0, 1.0, 0.0]) @ axes.T
    np.testing.assert_allclose(frames[ROTATION], rotation, rtol=1e-12, atol=1e-15)
    # the femur sinks along proximal under every frame, and tilts about medial and anterior
    assert (frames["body2_translation_proximal_mm"] < 0).all()
    motion, cop_ranges = summary["motion_anatomical"], summary["center_of_pressure_anatomical"]
    assert set(motion) == set(TRANSLATION + ROTATION) and set(cop_ranges) == set(COP)
    peak = frames["peak_pressure_MPa"].idxmax()
    for column in ROTATION + COP:
        ranges = {**motion, **cop_ranges}[column]
        assert ranges["min"] == pytest.approx(frames[column].min(), rel=1e-12, abs=1e-15)
        assert ranges["max"] == pytest.approx(frames[column].max(), rel=1e-12, abs=1e-15)
        assert ranges["at_peak"] == pytest.approx(frames.loc[peak, column], rel=1e-12, abs=1e-15)
    assert "motion found along the anatomical axes: body2 translation proximal" in result.stdout
    assert "rotation about medial" in result.stdout and "about anterior" in result.stdout
