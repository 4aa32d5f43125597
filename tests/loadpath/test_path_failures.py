"""Load paths that finish: a frame without an answer is recorded and the path goes on.

The middle frame of each path pulls body 2 away from the socket (a load the compression-only
springs cannot carry); the frames around it must be exactly the answers of cold solves, the
failed frame must be in every output with its status and NaN results, and the exposure must
bridge it. Equilibrium is checked with sums written here, not with the certificate.
"""

from __future__ import annotations

import json
import math
import xml.etree.ElementTree as ET

import meshio
import numpy as np
import pandas as pd
import pytest

import dea_opt as d
from dea_opt.errors import InputError, LoadNotSupportedError, SolverError
from dea_opt.formulations import newton
from dea_opt.geometry import socket_layer, sphere_on_bed_meshes
from dea_opt.loadpath import exposure, solve_path

PUSH = np.array([[30.0, 10.0, -600.0], [0.0, 0.0, -900.0]])
PULL = np.array([0.0, 0.0, 400.0])  # away from the socket: no compression-only spring can carry it
LOADS = np.array([PUSH[0], PULL, PUSH[1]])
TIMES = np.array([0.0, 0.5, 1.25])


@pytest.fixture(scope="module")
def hip():
    layer = socket_layer(radius=25.0, thickness=3.0, coverage=80.0, n_rings=10, n_sectors=30, gap=0.1)
    return d.ContactProblem(layer, d.LinearLaw(10.0), free=("ux", "uy", "uz"))


def own_equilibrium(solution, force):
    """|sum of the spring forces on body 2 + the load| / |load|, summed here."""
    layer = solution.problem.layer
    springs = ((solution.pressure * layer.areas)[:, None] * layer.normals).sum(axis=0)
    return float(np.linalg.norm(springs + force) / np.linalg.norm(force))


@pytest.mark.parametrize(
    "method, options",
    [("newton", {}), ("auto", {}), ("qp", {"tol": 1e-12}), pytest.param("nlp", {}, marks=pytest.mark.slow)],
)
def test_a_frame_the_springs_cannot_carry_is_recorded_and_the_path_goes_on(hip, method, options):
    result = solve_path(hip, LOADS, times=TIMES, method=method, **options)
    table = result.table
    assert len(table) == 3 and not result.success and result.failed_frames == [1]
    row = table.iloc[1]
    assert not row["success"] and not row["valid"] and row["status"] == "load_not_supported"
    assert "cannot carry" in row["message"] and "frame" not in row["message"][:6]
    assert row["Fz_N"] == 400.0 and row["time_s"] == 0.5  # the load and time are kept
    for column in (
        "peak_pressure_MPa",
        "mean_pressure_MPa",
        "contact_area_mm2",
        "cop_x_mm",
        "resultant_N",
        "max_compressive_strain",
    ):
        assert math.isnan(row[column]), column
    assert np.isnan(result.pressures[1]).all() and result.solutions[1] is None
    # the frames around it are certified answers: equilibrium summed here
    for k in (0, 2):
        assert table["success"].iloc[k] and table["status"].iloc[k] != "load_not_supported"
        assert own_equilibrium(result.solutions[k], LOADS[k]) < 1e-6
        cold = d.solve(hip.with_load(force=LOADS[k]), "newton")
        assert np.abs(result.pressures[k] - cold.pressure).max() <= 1e-6 * cold.peak_pressure
    assert result.failures() == [{"frame": 1, "time_s": 0.5, "status": "load_not_supported", "message": row["message"]}]
    line = result.failure_message()
    assert line.startswith("1 of 3 frames have no certified answer: frame 1 (0.5 s) load_not_supported: ")
    assert "\n" not in line and len(line) < 300


def test_the_frame_after_a_failure_starts_cold(hip, monkeypatch):
    starts = []
    original = newton._solve  # what every Newton solve runs, with the start it was given

    def recording(system, law, *, x0=None, **kw):
        starts.append(None if x0 is None else np.array(x0))
        return original(system, law, x0=x0, **kw)

    monkeypatch.setattr(newton, "_solve", recording)
    loads = np.array([PUSH[0], PUSH[1], PULL, PUSH[1]])
    result = solve_path(hip, loads, method="newton")
    assert result.failed_frames == [2]
    # frame 0 cold, frame 1 warm, frame 2 (failed) warm from frame 1, frame 3 cold again
    assert starts[0] is None and starts[1] is not None and starts[-1] is None
    cold = newton.solve(hip.with_load(force=PUSH[1]).system(), hip.law)
    assert result.table["iterations"].iloc[3] == cold.iterations


def test_stop_on_error_restores_aborting(hip):
    with pytest.raises(LoadNotSupportedError, match=r"frame 1 \(time 0.5 s\)"):
        solve_path(hip, LOADS, times=TIMES, method="newton", stop_on_error=True)
    with pytest.raises(InputError, match="unknown option 'strict'"):  # one name per thing
        solve_path(hip, LOADS, times=TIMES, method="newton", strict=True)


def test_every_output_has_every_frame(hip, tmp_path):
    result = solve_path(
        hip,
        LOADS,
        times=TIMES,
        method="newton",
        outputs=d.PathOutputs(keep_solutions=False, keep_pressures=False, series=tmp_path / "series_frames"),
    )
    assert result.solutions is None and result.pressures is None
    files = result.write(tmp_path)
    table = pd.read_csv(files["table"], keep_default_na=False, na_values=[""])
    assert table["status"].tolist()[1] == "load_not_supported" and table["success"].tolist() == [True, False, True]
    assert math.isnan(table["peak_pressure_MPa"].iloc[1]) and table["peak_pressure_MPa"].iloc[[0, 2]].gt(0).all()
    # the motion found: a number for a certified frame only
    motion = table[["body2_ux_mm", "body2_uy_mm", "body2_uz_mm"]]
    assert motion.iloc[1].isna().all() and np.isfinite(motion.iloc[[0, 2]].to_numpy()).all()
    datasets = ET.parse(files["series"]).getroot().find("Collection").findall("DataSet")
    assert [float(x.get("timestep")) for x in datasets] == TIMES.tolist()
    frames = [meshio.read(tmp_path / x.get("file")) for x in datasets]
    assert all(f.cells[0].type == "triangle" for f in frames)
    assert np.isnan(frames[1].point_data["pressure"]).all()
    assert np.isfinite(frames[0].point_data["pressure"]).all() and frames[2].point_data["pressure"].max() > 0
    summary = json.loads(files["summary"].read_text())
    assert summary["success"] is False and summary["failed_frames"] == [1]
    assert summary["failures"][0]["status"] == "load_not_supported"
    assert summary["validity"]["failed_frames"] == [1] and summary["validity"]["frames_outside_validity"] == []
    for key in ("cycle_plot", "exposure_map"):
        assert files[key].read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_exposure_bridges_a_failed_frame(hip):
    result = solve_path(hip, LOADS, times=TIMES, method="newton")
    p0, p2 = result.pressures[0], result.pressures[2]
    # linear from frame 0 to frame 2: the trapezoid over the whole step
    expected = 0.5 * (p0 + p2) * (TIMES[2] - TIMES[0])
    np.testing.assert_allclose(result.exposure.pressure_time_integral, expected, rtol=1e-12, atol=1e-15)
    np.testing.assert_array_equal(result.exposure.peak, np.maximum(p0, p2))
    assert result.exposure.duration == TIMES[2] - TIMES[0]


def test_uncertified_frames_have_nan_results_and_the_solver_status(hip):
    result = solve_path(hip, LOADS[[0, 2]], method="newton", max_iter=1)
    table = result.table
    assert result.failed_frames == [0, 1] and (table["status"] != "").all()
    assert table["peak_pressure_MPa"].isna().all() and (table["iterations"] == 1).all()
    assert table["message"].str.contains("no certified answer").all()
    assert table["certificate_residual"].gt(1e-6).all()  # how it failed is kept
    summary = result.summary()
    assert math.isnan(summary["peak_pressure_MPa"]) and summary["peak_frame"] is None
    assert not result.solutions[0].success  # the uncertified answer, for inspection
    with pytest.raises(SolverError, match="frame 0") as caught:
        solve_path(hip, LOADS[[0, 2]], method="newton", max_iter=1, stop_on_error=True)
    assert caught.value.solution is not None


def test_a_pose_without_springs_is_a_failed_frame():
    pair = sphere_on_bed_meshes(radius=25.0, thickness=2.0, extent=6.0, n_bed=24, step=4.0)
    problem = pair.problem(d.LinearLaw(10.0), free=("uz",))
    poses = np.tile(np.eye(4), (3, 1, 1))

    def layer_for_pose(pose):
        if len(calls) == 1:
            calls.append(pose)
            raise InputError("no face of mesh 1 meets mesh 2 within the proximity window")
        calls.append(pose)
        return pair.layer(pose=pose)

    calls = []
    result = solve_path(problem, np.tile([0.0, 0.0, -100.0], (3, 1)), poses, layer_for_pose=layer_for_pose)
    assert result.failed_frames == [1] and result.table["status"].iloc[1] == "pose_error"
    assert "proximity window" in result.table["message"].iloc[1]
    assert result.table["success"].iloc[[0, 2]].all()
    with pytest.raises(InputError, match="frame 1"):
        calls.clear()
        solve_path(
            problem, np.tile([0.0, 0.0, -100.0], (3, 1)), poses, layer_for_pose=layer_for_pose, stop_on_error=True
        )


def test_exposure_accumulated_equals_the_dense_computation():
    """Frame by frame, with sites and skipped frames, against every frame x site at once."""
    rng = np.random.default_rng(3)
    n_frames, n_springs, n_sites, threshold = 9, 40, 25, 0.7
    times = np.cumsum(rng.uniform(0.05, 0.4, n_frames))
    pressures = [np.where(rng.random(n_springs) < 0.3, 0.0, rng.uniform(0, 2, n_springs)) for _ in times]
    sites = [rng.integers(0, n_sites, n_springs) for _ in times]
    skipped = {3, 4}
    got = exposure(
        times, [None if k in skipped else p for k, p in enumerate(pressures)], sites, threshold, n_sites=n_sites
    )
    # dense: a frames x sites array of the kept frames, the largest pressure at each site
    keep = [k for k in range(n_frames) if k not in skipped]
    P = np.zeros((len(keep), n_sites))
    for row, k in enumerate(keep):
        for spring, site in enumerate(sites[k]):
            P[row, site] = max(P[row, site], pressures[k][spring])
    t = times[keep]
    np.testing.assert_allclose(got.pressure_time_integral, np.trapezoid(P, t, axis=0), rtol=1e-12)
    np.testing.assert_array_equal(got.peak, P.max(axis=0))
    # time above the threshold and the excess: a fine resampling of the piecewise-linear p(t)
    fine = np.linspace(t[0], t[-1], 200001)
    dense = np.stack([np.interp(fine, t, P[:, j]) for j in range(n_sites)], axis=1)
    dt = fine[1] - fine[0]
    np.testing.assert_allclose(got.time_above, (dense > threshold).sum(axis=0) * dt, atol=4 * dt)
    np.testing.assert_allclose(
        got.exposure_above, np.trapezoid(np.maximum(dense - threshold, 0), fine, axis=0), atol=1e-6
    )
    assert got.duration == times[-1] - times[0]
