"""Load paths: warm starts, per-frame table, exposure, poses, and the files they write."""

from __future__ import annotations

import re
import xml.etree.ElementTree as ET

import numpy as np
import pandas as pd
import pytest

import dea_opt as d
from dea_opt.errors import InputError, LoadNotSupportedError, SolverError
from dea_opt.gait import BODY_WEIGHT, HIP_GAIT_CSV, hip_gait_load, load_hip_gait
from dea_opt.geometry import socket_layer
from dea_opt.loadpath import TABLE_COLUMNS, exposure, solve_path


@pytest.fixture(scope="module")
def hip():
    layer = socket_layer(radius=25.0, thickness=3.0, coverage=80.0, n_rings=10, n_sectors=30, gap=0.1)
    return d.ContactProblem(layer, d.LinearLaw(10.0), free=("ux", "uy", "uz"))


@pytest.fixture(scope="module")
def gait():
    return hip_gait_load(n_frames=9)


@pytest.fixture(scope="module")
def newton_path(hip, gait):
    return solve_path(hip, gait, method="newton")


# --- the synthetic gait load ------------------------------------------------------------


def test_shipped_gait_is_reproducible_and_labelled():
    shipped = load_hip_gait()
    assert list(shipped.columns) == ["time", "Fx", "Fy", "Fz", "Mx", "My", "Mz"]
    assert len(shipped) == 101
    assert np.allclose(shipped.to_numpy(), hip_gait_load().to_numpy(), atol=1e-6)
    assert "SYNTHETIC" in HIP_GAIT_CSV.read_text().splitlines()[0]


def test_gait_is_a_double_hump_peaking_near_2_4_bw():
    table = hip_gait_load()
    bw = np.linalg.norm(table[["Fx", "Fy", "Fz"]].to_numpy(), axis=1) / BODY_WEIGHT
    assert bw.max() == pytest.approx(2.4, rel=0.01)
    stance = bw[:62]
    peaks = [i for i in range(1, 61) if stance[i] >= stance[i - 1] and stance[i] >= stance[i + 1] and stance[i] > 2]
    assert len(peaks) == 2
    assert stance[peaks[0] : peaks[1]].min() < 0.8 * stance[peaks].min()  # a valley between the humps
    assert bw[70:].max() < 0.5  # swing
    assert (table["Fz"] < 0).all()


# --- solving a path ---------------------------------------------------------------------


def test_newton_path_table(newton_path, gait):
    table = newton_path.table
    # the fixed columns first, the motion of each free dof, then one per validity check (no
    # labels: no region columns)
    assert list(table.columns)[: len(TABLE_COLUMNS)] == list(TABLE_COLUMNS)
    extra = list(table.columns)[len(TABLE_COLUMNS) :]
    assert extra[:3] == ["body2_ux_mm", "body2_uy_mm", "body2_uz_mm"]
    assert all(c.startswith("validity_") for c in extra[3:])
    found = np.array([s.u[6:9] for s in newton_path.solutions])
    assert np.array_equal(table[["body2_ux_mm", "body2_uy_mm", "body2_uz_mm"]].to_numpy(), found)
    assert (table["body2_uz_mm"] < 0).all()  # the head sinks into the socket under every frame's load
    assert table["valid"].all() and (table["message"] == "").all()
    assert len(table) == len(gait) and newton_path.success
    assert np.allclose(table["time_s"], gait["time"])
    assert np.allclose(table["resultant_N"], np.linalg.norm(gait[["Fx", "Fy", "Fz"]].to_numpy(), axis=1), rtol=1e-8)
    assert (table["certificate_residual"] <= 1e-6).all()
    assert table["peak_pressure_MPa"].idxmax() == table["resultant_N"].idxmax()


def test_warm_start_matches_cold_solves_with_fewer_iterations(hip, gait, newton_path):
    cold = [d.solve(hip.with_load(force=row[["Fx", "Fy", "Fz"]].to_numpy()), "newton") for _, row in gait.iterrows()]
    for solution, pressure in zip(cold, newton_path.pressures):
        assert np.allclose(pressure, solution.pressure, rtol=1e-9, atol=1e-12)
    assert newton_path.table["iterations"].iloc[1:].sum() < sum(s.iterations for s in cold[1:])


@pytest.mark.parametrize("method, options", [("qp", {"tol": 1e-12}), ("nlp", {})])
def test_constrained_paths_reuse_one_model(hip, gait, newton_path, monkeypatch, method, options):
    from dea_opt.formulations import nlp, qp

    cls = qp.QPModel if method == "qp" else nlp.NLPModel
    built = []
    original = cls.__init__

    def counting(self, *args, **kwargs):
        built.append(1)
        original(self, *args, **kwargs)

    monkeypatch.setattr(cls, "__init__", counting)
    result = solve_path(hip, gait.iloc[:4], method=method, **options)
    assert len(built) == 1
    assert result.success
    assert result.table["build_time_s"].iloc[1:].eq(0).all()
    for pressure, reference in zip(result.pressures, newton_path.pressures):
        assert np.abs(pressure - reference).max() <= 1e-6 * reference.max()


def test_loads_as_arrays_and_load_objects(hip, newton_path, gait):
    forces = gait[["Fx", "Fy", "Fz"]].to_numpy()
    by_array = solve_path(hip, forces, times=gait["time"], outputs=d.PathOutputs(keep_solutions=False))
    by_loads = solve_path(hip, [d.Load(force=f) for f in forces], times=gait["time"].to_numpy())
    assert by_array.solutions is None
    for a, b, c in zip(by_array.pressures, by_loads.pressures, newton_path.pressures):
        assert np.allclose(a, c) and np.allclose(b, c)


def test_ateshian_path_by_newton(hip, gait):
    result = solve_path(hip.with_law(d.AteshianLaw(10.0, 0.3)), gait.iloc[:3], method="newton")
    assert result.success and result.table["peak_pressure_MPa"].gt(0).all()


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"loads": []}, "empty"),
        ({"loads": np.zeros((3, 4))}, "shape"),
        ({"loads": np.zeros((3, 3)), "times": [0, 2, 1]}, "increase"),
        ({"loads": np.zeros((3, 3)), "times": [0, 1]}, "one per frame"),
        ({"loads": pd.DataFrame({"Fx": [0.0], "Fy": [0.0]})}, "missing Fz"),
        ({"loads": np.zeros((2, 3)), "method": "simplex"}, "method must be one of"),
        ({"loads": np.zeros((2, 3)), "body": 3}, "body must be 1 or 2"),
        ({"loads": np.zeros((2, 3)), "poses": np.zeros((3, 4, 4))}, r"shape \(2, 4, 4\)"),
        ({"loads": np.zeros((2, 3)), "poses": np.tile(np.eye(4), (2, 1, 1))}, "not built from meshes"),
    ],
)
def test_bad_path_input(hip, kwargs, match):
    loads = kwargs.pop("loads")
    with pytest.raises(InputError, match=match):
        solve_path(hip, loads, **kwargs)


def test_qp_with_nonlinear_law_is_refused(hip):
    with pytest.raises(InputError, match="nlp"):
        solve_path(hip.with_law(d.AteshianLaw(10.0, 0.3)), np.zeros((2, 3)) - 1, method="qp")


def test_unsupported_frame_is_named_with_stop_on_error(hip):
    loads = np.array([[0.0, 0.0, -500.0], [0.0, 0.0, 400.0]])
    with pytest.raises(LoadNotSupportedError, match="frame 1") as caught:
        solve_path(hip, loads, method="newton", stop_on_error=True)
    assert caught.value.direction  # the unbalanced part is kept


def test_uncertified_frames_are_flagged_or_raised(hip, gait):
    # One Newton iteration cannot finish: every frame fails its certificate.
    result = solve_path(hip, gait.iloc[:3], method="newton", max_iter=1)
    assert not result.success and result.failed_frames == [0, 1, 2]
    with pytest.raises(SolverError, match="frame 0"):
        solve_path(hip, gait.iloc[:3], method="newton", max_iter=1, stop_on_error=True)


# --- exposure ---------------------------------------------------------------------------


def test_exposure_is_exact_for_piecewise_linear_pressure():
    times = [0.0, 1.0, 3.0]
    pressures = [np.array([2.0, 0.0, 1.0]), np.array([2.0, 2.0, 3.0]), np.array([2.0, 0.0, 1.0])]
    e = exposure(times, pressures, threshold=1.0)
    assert np.allclose(e.pressure_time_integral, [6.0, 1.0 + 2.0, 2.0 + 4.0])
    # spring 1: 0 -> 2 over 1 s is above 1 MPa for 0.5 s, 2 -> 0 over 2 s for 1 s
    assert np.allclose(e.time_above, [3.0, 1.5, 3.0])
    assert np.allclose(e.exposure_above, [3.0, 0.25 + 0.5, 1.0 + 2.0])
    assert np.allclose(e.peak, [2.0, 2.0, 3.0])
    assert e.duration == 3.0


def test_exposure_on_sites():
    e = exposure(
        [0.0, 1.0], [np.array([1.0]), np.array([1.0, 3.0])], [np.array([2]), np.array([2, 0])], threshold=0.0, n_sites=4
    )
    assert np.allclose(e.pressure_time_integral, [1.5, 0.0, 1.0, 0.0])
    with pytest.raises(InputError, match="threshold"):
        exposure([0.0], [np.zeros(1)], threshold=-1)


def test_path_exposure_matches_the_table(newton_path):
    e = newton_path.exposure
    P = np.array(newton_path.pressures)
    assert np.allclose(e.peak, P.max(axis=0))
    assert np.allclose(e.pressure_time_integral, np.trapezoid(P, newton_path.times, axis=0))
    assert e.summary()["max_pressure_time_integral_MPa_s"] == pytest.approx(e.pressure_time_integral.max())


# --- files ------------------------------------------------------------------------------


def test_writes_table_series_plots_and_exposure(newton_path, tmp_path):
    import meshio

    files = newton_path.write(tmp_path, extra_summary={"note": "test"})
    assert set(files) == {"table", "series", "exposure_vtk", "cycle_plot", "exposure_map", "summary"}
    table = pd.read_csv(files["table"])
    assert len(table) == len(newton_path) and np.allclose(
        table["peak_pressure_MPa"], newton_path.table["peak_pressure_MPa"]
    )
    datasets = ET.parse(files["series"]).getroot().find("Collection").findall("DataSet")
    assert len(datasets) == len(newton_path)
    assert np.allclose([float(x.get("timestep")) for x in datasets], newton_path.times)
    # The socket is a generated layer: a surface through its springs, the data on its points.
    frame = meshio.read(tmp_path / datasets[-1].get("file"))
    assert frame.cells[0].type == "triangle"
    assert np.array_equal(frame.point_data["pressure"], newton_path.pressures[-1])
    surface = meshio.read(files["exposure_vtk"])
    assert surface.cells[0].type == "triangle"
    assert np.array_equal(surface.point_data["pressure_time_integral"], newton_path.exposure.pressure_time_integral)
    for key in ("cycle_plot", "exposure_map"):
        assert files[key].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    import json

    summary = json.loads(files["summary"].read_text())
    assert summary["frames"] == len(newton_path) and summary["note"] == "test" and summary["success"]
    assert not list(tmp_path.rglob(".*tmp*"))  # atomic writes leave no temporary files


def test_pvd_needs_solutions(hip, gait, tmp_path):
    result = solve_path(hip, gait.iloc[:2], outputs=d.PathOutputs(keep_solutions=False))
    with pytest.raises(InputError, match="keep_solutions"):
        result.to_pvd(tmp_path / "s.pvd")
    files = result.write(tmp_path, formats=("csv", "png"))
    assert set(files) == {"table", "cycle_plot", "exposure_map"}


@pytest.mark.parametrize(
    "outputs, words",
    [
        (lambda: {"keep_solutions": False}, "outputs must be a PathOutputs, got dict"),
        (lambda: d.PathOutputs(keep_solutions=0), "PathOutputs.keep_solutions must be True or False, got 0"),
        (lambda: d.PathOutputs(keep_pressures="no"), "PathOutputs.keep_pressures must be True or False"),
        (lambda: d.PathOutputs(series=3), "PathOutputs.series must be a folder"),
    ],
    ids=["dict", "int", "str", "series"],
)
def test_bad_outputs_are_named(hip, gait, outputs, words):
    with pytest.raises(InputError, match=re.escape(words)):
        solve_path(hip, gait.iloc[:1], outputs=outputs())


# --- moving meshes ----------------------------------------------------------------------


def test_poses_recast_the_springs_each_frame():
    from dea_opt.geometry import sphere_on_bed_meshes

    pair = sphere_on_bed_meshes(radius=25.0, thickness=2.0, extent=6.0, n_bed=24, step=4.0)
    problem = pair.problem(d.LinearLaw(10.0), free=("uz",))
    shifts = np.array([0.0, 1.0, 2.0])
    poses = np.tile(np.eye(4), (3, 1, 1))
    poses[:, 0, 3] = shifts
    calls = []

    def layer_for_pose(pose):
        calls.append(pose)
        return pair.layer(pose=pose)

    result = solve_path(problem, np.tile([0.0, 0.0, -100.0], (3, 1)), poses, layer_for_pose=layer_for_pose)
    assert len(calls) == 3 and result.success and result.moving
    # The contact follows the sphere: the centre of pressure moves with the pose.
    assert np.allclose(result.table["cop_x_mm"], shifts, atol=0.15)
    n_faces = len(problem.layer.surface[1])
    assert result.exposure.pressure_time_integral.shape == (n_faces,)
