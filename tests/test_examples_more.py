"""The hip gait, knee and solver-study examples on their coarse setting, checked against closed forms.

``examples/hip_gait.py``, ``examples/knee_from_meshes.py`` and ``examples/solver_study.py``
are run through their ``main``; what they return and write is compared with closed forms
written out here, independently of the examples: a rigid ball in a socket that surrounds its
contact, a sphere pressed into a bonded layer, force and moment balance, compartment shares
that add up to one, and every solver agreeing with Newton. The real knee
(``../shared/data/knee``) is skipped cleanly when it is absent.
"""

from __future__ import annotations

import importlib.util
import json
import math
import sys
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.integrate import fixed_quad
from scipy.optimize import brentq

import dea_opt as d

# Each module runs whole example scripts (seconds each); CI runs them all the same.
pytestmark = pytest.mark.slow

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
KNEE = Path(__file__).resolve().parents[2] / "shared" / "data" / "knee"
KNEE_FILES = ("femoral_cartilage.stl", "medial_tibial_cartilage.stl", "lateral_tibial_cartilage.stl")
PNG = b"\x89PNG\r\n\x1a\n"


def _load(name):
    """Import an example script as a module (examples/ is not a package)."""
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


# --- closed forms, written independently of dea_opt and of the examples -----------------
def ball_in_socket(force, H, R, h, gap):
    """Rigid ball in a linear layer on a socket surrounding the contact, by Gauss quadrature.

    The spring at angle t from the load line is compressed by ``d cos t - gap``, so the load
    carried is ``2 pi R^2 int_{cos t > gap/d} H (d cos t - gap) / h cos t sin t dt``.
    Returns ``(approach d, peak pressure, contact area)``.
    """

    def carried(dd):
        c0 = gap / dd
        # Gauss-Legendre with 4 nodes is exact for this quadratic in c.
        value, _ = fixed_quad(lambda c: H * (dd * c - gap) / h * c, c0, 1.0, n=4)
        return 2 * math.pi * R**2 * value

    dd = brentq(lambda x: carried(x) - force, gap + 1e-12, gap + 10.0, xtol=1e-15, rtol=1e-14)
    return dd, H * (dd - gap) / h, 2 * math.pi * R**2 * (1 - gap / dd)


def bonded_sphere_approach(force, H, R, h):
    """Rigid sphere into a bonded linear layer: ``F = pi H d^2 (R - d/3) / h``, solved for d."""
    return brentq(lambda x: math.pi * H * x * x * (R - x / 3) / h - force, 0.0, R, xtol=1e-15)


# ========================================================================================
# hip_gait
# ========================================================================================
@pytest.fixture(scope="module")
def hip(tmp_path_factory):
    module = _load("hip_gait")
    out = tmp_path_factory.mktemp("hip_gait")
    result = module.main(["--coarse", "--out", str(out)])
    return module, result, out


def test_hip_every_frame_certified_and_balanced(hip):
    _, result, _ = hip
    path = result["path"]
    assert len(path) == 21 and path.success
    loads = result["loads"][["Fx", "Fy", "Fz"]].to_numpy()
    for solution, load in zip(path.solutions, loads):
        # Only translations are free: the springs' resultant is exactly minus the load.
        np.testing.assert_allclose(solution.contact_force, -load, rtol=0, atol=1e-6 * np.linalg.norm(load))
    np.testing.assert_allclose(path.table["resultant_N"], np.linalg.norm(loads, axis=1), rtol=1e-6)
    # The peak pressure follows the peak load, in the first hump of stance.
    table = path.table
    assert table["peak_pressure_MPa"].idxmax() == table["resultant_N"].idxmax()
    assert table.loc[table["peak_pressure_MPa"].idxmax(), "time_s"] < 0.3


def test_hip_frames_match_the_ball_in_socket_where_contact_clears_the_rim(hip):
    module, result, _ = hip
    closed = result["closed_form"]
    clear = closed[closed["inside_rim"] & ~closed["at_rim"]]
    assert len(clear) >= 5  # the swing frames and heel strike
    assert len(clear) < len(closed)  # stance presses the contact against the rim
    for row in clear.itertuples(index=False):
        dd, peak, area = ball_in_socket(row.force_N, module.H_DEFAULT, 25.0, 3.0, 0.1)
        assert row.cf_approach == pytest.approx(dd, rel=1e-9)
        assert row.cf_peak_pressure == pytest.approx(peak, rel=1e-9)
        assert row.cf_contact_area == pytest.approx(area, rel=1e-9)
        # the solution on the coarse socket (432 springs)
        assert row.approach == pytest.approx(dd, rel=5e-3)
        assert row.peak_pressure == pytest.approx(peak, rel=1e-2)
        assert row.contact_area == pytest.approx(area, rel=3e-2)


def test_hip_default_mesh_frame_matches_the_closed_form_tightly(hip):
    """One frame on the demo's 5400-spring socket: the closed form to 0.1 % (peak, approach)."""
    module, result, _ = hip
    load = result["loads"].loc[0, ["Fx", "Fy", "Fz"]].to_numpy(dtype=float)
    s = d.solve(module.hip_problem().with_load(force=load), "newton")
    dd, peak, area = ball_in_socket(np.linalg.norm(load), 10.0, 25.0, 3.0, 0.1)
    assert s.u[6:9] @ (load / np.linalg.norm(load)) == pytest.approx(dd, rel=1e-3)
    assert s.peak_pressure == pytest.approx(peak, rel=1e-3)
    assert s.contact_area == pytest.approx(area, rel=5e-3)


def test_hip_full_contact_socket(hip):
    """No clearance, a hemispherical socket, the gait's peak load on its axis: the whole
    socket touches and the peak is 3 F / (2 pi R^2)."""
    module, result, _ = hip
    force = float(np.linalg.norm(result["loads"][["Fx", "Fy", "Fz"]].to_numpy(), axis=1).max())
    problem = module.hip_problem(gap=0.0, coverage=90.0, n_rings=30, n_sectors=60)
    s = d.solve(problem.with_load(force=(0.0, 0.0, -force)), "newton")
    R = 25.0
    assert s.peak_pressure == pytest.approx(3 * force / (2 * math.pi * R**2), rel=2e-3)
    assert s.contact_area == pytest.approx(2 * math.pi * R**2, rel=1e-9)
    np.testing.assert_allclose(s.contact_force, [0.0, 0.0, force], atol=1e-6 * force)
    cf = module.ball_in_socket(force, gap=0.0)
    assert cf["peak_pressure"] == pytest.approx(3 * force / (2 * math.pi * R**2), rel=1e-12)


def test_hip_exposure_is_the_time_integral_of_pressure(hip):
    _, result, _ = hip
    path = result["path"]
    P = np.array(path.pressures)
    t = path.times
    integral = (0.5 * (P[1:] + P[:-1]) * np.diff(t)[:, None]).sum(axis=0)
    np.testing.assert_allclose(path.exposure.pressure_time_integral, integral, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(path.exposure.peak, P.max(axis=0), rtol=0)
    assert path.exposure.time_above.max() <= t[-1] - t[0]


def test_hip_files(hip):
    import meshio

    _, result, out = hip
    path = result["path"]
    frames = pd.read_csv(out / "frames.csv")
    np.testing.assert_allclose(frames["peak_pressure_MPa"], path.table["peak_pressure_MPa"], rtol=1e-12)
    closed = pd.read_csv(out / "closed_form.csv")
    np.testing.assert_allclose(closed["dev_peak"], result["closed_form"]["dev_peak"], rtol=1e-9, atol=1e-15)
    # The ParaView series: one existing .vtu per frame, at the frame times.
    datasets = ET.parse(out / "series.pvd").getroot().findall(".//DataSet")
    assert len(datasets) == 21
    assert [float(x.get("timestep")) for x in datasets] == pytest.approx(list(path.times))
    for x in datasets:
        assert (out / x.get("file")).is_file()
    # The socket is a generated layer: its files are a surface through the springs, the
    # springs' data on its points.
    last = meshio.read(out / datasets[-1].get("file"))
    assert last.cells[0].type == "triangle"
    np.testing.assert_allclose(last.point_data["pressure"], path.pressures[-1], rtol=1e-12)
    exposure = meshio.read(out / "exposure.vtu")
    np.testing.assert_allclose(
        exposure.point_data["pressure_time_integral"], path.exposure.pressure_time_integral, rtol=1e-12
    )
    for name in ("cycle.png", "exposure.png"):
        assert (out / name).read_bytes()[:8] == PNG
    summary = json.loads((out / "summary.json").read_text())
    assert summary["peak_pressure_MPa"] == pytest.approx(path.table["peak_pressure_MPa"].max())
    assert not list(out.glob(".*.tmp*")), "a temporary file was left behind"


# ========================================================================================
# knee_from_meshes
# ========================================================================================
def _knee_checks(result, load):
    """Force and moment balance, shares that partition the load, for every law."""
    table = result["table"]
    for name, s in result["solutions"].items():
        assert s.success
        # uz free: the springs carry the axial load; ry free: no moment about y is left.
        assert s.contact_force[2] == pytest.approx(load, rel=1e-6)
        assert abs(s.contact_moment[1]) <= 1e-6 * load * 100.0
        layer = s.problem.layer
        force = (s.pressure * layer.areas)[:, None] * layer.normals  # each spring's force on body 2
        total = force.sum(axis=0)
        row = table.set_index("law").loc[name]
        assert row["medial_share"] + row["lateral_share"] == pytest.approx(1.0, abs=1e-12)
        if layer.labels is not None:  # a compartment's share: its resultant along the contact force
            for side in ("medial", "lateral"):
                part = force[layer.labels == side].sum(axis=0) @ total / (total @ total)
                assert row[f"{side}_share"] == pytest.approx(part, rel=1e-10)


@pytest.fixture(scope="module")
def knee(tmp_path_factory):
    if not all((KNEE / name).is_file() for name in KNEE_FILES):
        pytest.skip(f"the knee meshes are not in {KNEE}")
    module = _load("knee_from_meshes")
    out = tmp_path_factory.mktemp("knee")
    result = module.main(["--coarse", "--out", str(out)])
    return module, result, out


def test_knee_balances_the_load_and_splits_it(knee):
    _, result, _ = knee
    assert set(result["solutions"]) == {"linear", "ateshian_b0.05"}
    assert set(result["problem"].layer.labels) == {"medial", "lateral"}
    _knee_checks(result, 1000.0)
    table = result["table"].set_index("law")
    # both compartments carry a real part of the load
    assert 0.2 < table.loc["linear", "medial_share"] < 0.8


def test_knee_linear_against_nonlinear(knee):
    """Eq. (2) with the linear law's H is stiffer in compression: a higher peak on a smaller area."""
    _, result, _ = knee
    table = result["table"].set_index("law")
    lin, ate = table.loc["linear"], table.loc["ateshian_b0.05"]
    assert ate["peak_pressure"] > lin["peak_pressure"]
    assert ate["contact_area"] < lin["contact_area"]
    assert ate["max_strain"] < lin["max_strain"] < 0.3
    assert ate["dev_peak"] == pytest.approx(ate["peak_pressure"] / lin["peak_pressure"] - 1, rel=1e-12)
    assert ate["d_medial_share"] == pytest.approx(100 * (ate["medial_share"] - lin["medial_share"]), rel=1e-12)
    assert lin["dev_peak"] == 0.0


def test_knee_files(knee):
    _, result, out = knee
    assert (out / "knee_pressure_linear.png").read_bytes()[:8] == PNG
    written = pd.read_csv(out / "knee_comparison.csv")
    np.testing.assert_allclose(written["peak_pressure"], result["table"]["peak_pressure"], rtol=1e-12)
    summary = json.loads((out / "knee_linear.json").read_text())
    shares = {
        r["name"]: r["share"]
        for r in (summary["regions"].values() if isinstance(summary["regions"], dict) else summary["regions"])
    }
    assert shares["medial"] == pytest.approx(result["table"]["medial_share"].iloc[0], rel=1e-12)
    for line in result["markdown"].splitlines():
        if line.startswith("| linear |"):
            assert f"{result['table']['peak_pressure'].iloc[0]:.3f}" in line


def test_knee_without_data_exits_cleanly(tmp_path, capsys):
    module = _load("knee_from_meshes")
    with pytest.raises(SystemExit) as exc:
        module.main([str(tmp_path / "nowhere"), "--out", str(tmp_path / "out")])
    assert exc.value.code == 2
    assert "no such mesh file or knee directory" in capsys.readouterr().err
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(FileNotFoundError, match="femoral_cartilage.stl"):
        module.find_meshes([empty])


def test_knee_file_roles(tmp_path):
    module = _load("knee_from_meshes")
    names = ["lat_tib.stl", "femur.stl", "med_tib.stl", "a.stl", "b.stl", "c.stl", "tibia.stl"]
    for name in names:
        (tmp_path / name).write_bytes(b"x")
    p = {name: tmp_path / name for name in names}
    assert module.find_meshes([p["lat_tib.stl"], p["femur.stl"], p["med_tib.stl"]]) == {
        "lateral": p["lat_tib.stl"],
        "femur": p["femur.stl"],
        "medial": p["med_tib.stl"],
    }
    assert module.find_meshes([p["a.stl"], p["b.stl"], p["c.stl"]]) == {
        "femur": p["a.stl"],
        "medial": p["b.stl"],
        "lateral": p["c.stl"],
    }
    assert module.find_meshes([p["tibia.stl"], p["a.stl"]]) == {"tibia": p["tibia.stl"], "femur": p["a.stl"]}
    with pytest.raises(ValueError, match="cannot tell"):
        module.find_meshes([p["femur.stl"], p["med_tib.stl"]])
    with pytest.raises(ValueError, match="2 \\(femur, tibia\\) or 3"):
        module.find_meshes([p["a.stl"]])


@pytest.fixture(scope="module")
def synthetic_knee(tmp_path_factory):
    """Two equal condyles (R = 30 mm) on two slabs, written as STL files: the closed form
    of a sphere pressed into a bonded layer holds in each compartment."""
    from dea_opt.geometry import knee_meshes

    folder = tmp_path_factory.mktemp("synthetic_knee")
    pair = knee_meshes(condyle_radius=(30.0, 30.0))
    labels = pair.options["labels"]
    files = {
        "femur": folder / "femur.stl",
        "medial": folder / "medial.stl",
        "lateral": folder / "lateral.stl",
        "tibia": folder / "tibia.stl",
    }
    pair.mesh2.export(files["femur"])
    pair.mesh1.export(files["tibia"])
    for side in ("medial", "lateral"):
        pair.mesh1.submesh([np.flatnonzero(labels == side)], append=True).export(files[side])
    return pair, files


@pytest.mark.parametrize("mode", ["three files", "femur and one tibia"])
def test_knee_example_on_a_synthetic_knee_matches_the_closed_form(synthetic_knee, tmp_path, mode):
    module = _load("knee_from_meshes")
    pair, files = synthetic_knee
    paths = (
        [files["femur"], files["medial"], files["lateral"]]
        if mode == "three files"
        else [files["tibia"], files["femur"]]
    )
    load = 400.0
    result = module.main([*map(str, paths), "--coarse", "--load", f"{load:g}", "--out", str(tmp_path)])
    _knee_checks(result, load)
    table = result["table"].set_index("law")
    h = pair.info["femoral_thickness"] + pair.info["tibial_thickness"]  # 5 mm through both layers
    # Symmetric knee, load at the midpoint: half the load on each condyle, no tilt.
    assert table.loc["linear", "medial_share"] == pytest.approx(0.5, abs=5e-3)
    assert abs(table.loc["linear", "ry_deg"]) < 1e-2
    dd = bonded_sphere_approach(load / 2, 10.0, 30.0, h)
    assert -table.loc["linear", "uz"] == pytest.approx(dd, rel=1e-2)
    assert table.loc["linear", "peak_pressure"] == pytest.approx(10.0 * dd / h, rel=2e-2)
    assert table.loc["linear", "contact_area"] == pytest.approx(2 * math.pi * (2 * 30.0 * dd - dd * dd), rel=5e-2)


# ========================================================================================
# solver_study
# ========================================================================================
@pytest.fixture(scope="module")
def study(tmp_path_factory):
    module = _load("solver_study")
    out = tmp_path_factory.mktemp("solver_study")
    result = module.main(["--coarse", "--quiet", "--out", str(out)])
    return module, result, out


def test_study_covers_every_method(study):
    module, result, _ = study
    table = result["table"]
    installed = [s for s in ("CLARABEL", "OSQP", "SCS", "PIQP") if s in d.study.installed_qp_solvers()]
    linear = set(table[table["law"] == "linear"]["label"])
    assert linear == {"newton", "nlp-constrained", "nlp-reduced", *(f"qp-{s}" for s in installed)}
    assert set(table[table["law"] == "ateshian"]["label"]) == {"newton", "nlp-constrained", "nlp-reduced"}
    sizes = sorted(set(table["n_springs"]))
    assert len(sizes) == 2
    for target, n in zip((300, 1000), sizes):
        assert abs(n - target) <= 0.05 * target


def test_study_rows_agree_with_newton(study):
    module, result, _ = study
    table = result["table"]
    assert table["success"].all(), table[~table["success"]][["law", "label", "message"]]
    assert (table["d_pressure"] <= 1e-6).all() and (table["d_displacement"] <= 1e-6).all()
    assert (table["worst_residual"] <= 1e-6).all()
    # Recompute every row's peak from an independent Newton solve of the same problem.
    for (law, n), rows in table.groupby(["law", "n_target"]):
        problem = module.study_problem(n, module.make_law(law))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", d.ValidityWarning)
            s = d.solve(problem, "newton")
        np.testing.assert_allclose(s.contact_force, -module.peak_force(), atol=1e-6 * module.PEAK_LOAD)
        np.testing.assert_allclose(rows["peak_pressure_MPa"], s.peak_pressure, rtol=1e-6)
        np.testing.assert_allclose(rows["contact_area_mm2"], s.contact_area, rtol=1e-9)


def test_study_load_and_grid(study):
    module, _, _ = study
    F = module.peak_force()
    assert np.linalg.norm(F) == pytest.approx(2400.0)
    assert math.degrees(math.acos(-F[2] / np.linalg.norm(F))) == pytest.approx(20.0)
    n_rings, n_sectors = module.socket_grid(10_000)
    # cells near mid-cap are about square: 80/n_rings deg of latitude vs 360 sin(40)/n_sectors
    assert (80.0 / n_rings) / (360.0 * math.sin(math.radians(40.0)) / n_sectors) == pytest.approx(1.0, rel=0.05)


def test_study_files_and_summary(study):
    module, result, out = study
    table, summary = result["table"], result["summary"]
    written = pd.read_csv(out / "solver_study.csv")
    assert len(written) == len(table)
    np.testing.assert_allclose(written["wall_time"], table["wall_time"], rtol=1e-12)
    for row in summary.itertuples(index=False):
        runs = table[(table["law"] == row.law) & (table["n_springs"] == row.n_springs) & (table["label"] == row.label)]
        assert row.best_time == pytest.approx(runs["wall_time"].min(), rel=1e-12)
        assert row.success_rate_percent == 100.0
    assert (summary[summary["label"] == "newton"]["relative"] == 1.0).all()
    assert (out / "solver_study.png").read_bytes()[:8] == PNG
    assert (out / "solver_study.md").read_text() == result["markdown"]
    assert set(result["exponents"]["label"]) == set(summary["label"])


# ========================================================================================
def test_gallery_pictures_exist_and_are_small():
    """Every picture the site's gallery shows (``examples/GALLERY_HEADER.rst``) and the README's
    picture are committed, PNGs, and under 150 KB."""
    import re

    header = (EXAMPLES / "GALLERY_HEADER.rst").read_text(encoding="utf-8")
    readme = (EXAMPLES.parent / "README.md").read_text(encoding="utf-8")
    pictures = re.findall(r"\.\. figure:: \.\./\.\./(examples/gallery/[\w.]+\.png)", header)
    pictures += re.findall(r"\]\((examples/gallery/[\w.]+\.png)\)", readme)
    assert len(pictures) >= 6
    for picture in pictures:
        data = (EXAMPLES.parent / picture).read_bytes()
        assert data[:8] == PNG and len(data) < 150_000, picture
