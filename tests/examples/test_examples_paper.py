"""The paper examples on their coarse setting, checked against closed forms written here.

``examples/paper_figure1.py`` (Fig. 1 and the deviation table) and
``examples/linear_validity.py`` (the 30 % claim under load) are run once each through their
``main``/``run``; the numbers they return, plot and print are compared with Eq. (2), Eq. (3)
and the linear sphere's closed form, all written out independently below.
"""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from scipy.optimize import brentq

# Each module runs whole example scripts (seconds each); CI runs them all the same.
pytestmark = pytest.mark.slow

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
KNEE = Path(__file__).resolve().parents[3] / "shared" / "data" / "knee"
H = 0.6  # MPa, the examples' default
BETAS = (0.05, 0.6)


def _load(name):
    """Import an example script as a module (examples/ is not a package)."""
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses and pickling look modules up by name
    spec.loader.exec_module(module)
    return module


# --- closed forms, written independently of dea_opt and of the examples -----------------
def eq2(eps, beta, h_modulus=H):
    """Eq. (2): sigma = H ((1+e)^2 - 1) / (2 (1+e)^(2 beta + 1)) exp(beta ((1+e)^2 - 1))."""
    lam = 1.0 + np.asarray(eps, dtype=float)
    return h_modulus * (lam**2 - 1) / (2 * lam ** (2 * beta + 1)) * np.exp(beta * (lam**2 - 1))


def eq3(eps, beta, h_modulus=H):
    """Eq. (3): sigma = H/2 (2 e - e^2 + (1 + 4 beta) e^3)."""
    e = np.asarray(eps, dtype=float)
    return h_modulus / 2 * (2 * e - e**2 + (1 + 4 * beta) * e**3)


def taylor_eq2(eps, beta, order, h_modulus=H):
    """Taylor polynomial of Eq. (2) by Cauchy's integral on |z| = 1/2 (FFT), not by series algebra.

    Eq. (2) is analytic for |eps| < 1, so the trapezoidal rule on a circle of radius 1/2
    with 64 nodes gives the coefficients to rounding (aliasing ~ 2^-64).
    """
    n, r = 64, 0.5
    z = r * np.exp(2j * np.pi * np.arange(n) / n)
    lam = 1 + z
    f = h_modulus * (lam**2 - 1) / (2 * lam ** (2 * beta + 1)) * np.exp(beta * (lam**2 - 1))
    c = (np.fft.fft(f) / n).real / r ** np.arange(n)
    e = np.asarray(eps, dtype=float)
    return sum(c[k] * e**k for k in range(1, order + 1))


def sphere_force(d, radius=25.0, h=2.0, h_modulus=H):
    """Linear sphere on a bonded bed: F = pi H d^2 (R - d/3) / h (N)."""
    return math.pi * h_modulus * d**2 * (radius - d / 3) / h


def sphere_approach(force, radius=25.0, h=2.0, h_modulus=H):
    return brentq(lambda d: sphere_force(d, radius, h, h_modulus) - force, 0.0, radius, xtol=1e-15)


# --- the runs ---------------------------------------------------------------------------
@pytest.fixture(scope="module")
def fig1(tmp_path_factory):
    module = _load("paper_figure1")
    out = tmp_path_factory.mktemp("paper_figure1")
    result = module.main(["--coarse", "--out", str(out)])
    return module, result, out


@pytest.fixture(scope="module")
def validity(tmp_path_factory):
    module = _load("linear_validity")
    out = tmp_path_factory.mktemp("linear_validity")
    # The knee (~18 000 springs) has its own test below; this one is the fast study.
    result = module.main(["--coarse", "--no-knee", "--out", str(out)])
    return module, result, out


# --- paper_figure1 ----------------------------------------------------------------------
def test_figure1_eq2_at_30_percent(fig1):
    _, result, _ = fig1
    curves = result["curves"]
    strain = curves["strain"]
    k = int(np.argmin(np.abs(strain + 0.3)))
    assert strain[k] == pytest.approx(-0.3, abs=1e-12)
    value = curves["eq2"][0.05][k]  # sigma / H
    assert value == pytest.approx(eq2(-0.3, 0.05) / H, rel=1e-12)
    assert abs(value) / 0.3 == pytest.approx(1.2266, abs=5e-4)  # "about 1.227 H x 0.3"


def test_figure1_curves_match_eq2_eq3_linear(fig1):
    _, result, _ = fig1
    curves = result["curves"]
    strain = curves["strain"]
    assert strain[0] == pytest.approx(-0.4) and strain[-1] == pytest.approx(0.4)
    np.testing.assert_allclose(curves["linear"], strain, rtol=0, atol=1e-15)
    for beta in BETAS:
        np.testing.assert_allclose(curves["eq2"][beta], eq2(strain, beta) / H, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(curves["eq3"][beta], eq3(strain, beta) / H, rtol=1e-12, atol=1e-15)


def test_figure1_plotted_lines_are_the_curves(fig1):
    """The picture shows Eq. (2) solid, Eq. (3) dashed and the linear law, with these values."""
    module, result, _ = fig1
    fig = module.plot_figure1(result["curves"], result["deviations"])
    try:
        lines = {line.get_label(): line for line in fig.axes[0].get_lines()}
        for beta in BETAS:
            solid, dashed = lines[f"Eq. (2), beta = {beta:g}"], lines[f"Eq. (3), beta = {beta:g}"]
            assert solid.get_linestyle() == "-" and dashed.get_linestyle() == "--"
            x, y = solid.get_xydata().T
            np.testing.assert_allclose(y, eq2(x, beta) / H, rtol=1e-12, atol=1e-15)
            x, y = dashed.get_xydata().T
            np.testing.assert_allclose(y, eq3(x, beta) / H, rtol=1e-12, atol=1e-15)
        x, y = next(v for k, v in lines.items() if k.startswith("linear")).get_xydata().T
        np.testing.assert_allclose(y, x, atol=1e-15)
        assert fig.axes[0].get_xlim() == pytest.approx((-0.4, 0.4))
    finally:
        import matplotlib.pyplot as plt

        plt.close(fig)


def test_figure1_deviation_table(fig1):
    _, result, out = fig1
    table = result["table"]
    assert sorted(set(table["beta"])) == list(BETAS)
    assert sorted(set(table["strain"])) == [-0.4, -0.3, -0.2, -0.1]
    for row in table.itertuples(index=False):
        e, b = row.strain, row.beta
        ref = eq2(e, b)
        assert row.eq2_stress_over_H == pytest.approx(ref / H, rel=1e-12)
        assert row.linear == pytest.approx(H * e / ref - 1, rel=1e-10)
        assert row.cubic == pytest.approx(eq3(e, b) / ref - 1, rel=1e-9, abs=1e-13)
        assert row.order5 == pytest.approx(taylor_eq2(e, b, 5) / ref - 1, rel=1e-6, abs=1e-12)
        assert row.order7 == pytest.approx(taylor_eq2(e, b, 7) / ref - 1, rel=1e-6, abs=1e-12)
        # Remark 2: higher orders come closer to Eq. (2).
        assert abs(row.order7) <= abs(row.order5) <= abs(row.cubic) <= abs(row.linear)
    # The CSV on disk holds the same table.
    written = pd.read_csv(out / "figure1_deviation.csv")
    pd.testing.assert_frame_equal(written, table, check_exact=False, rtol=1e-12)


def test_figure1_files(fig1):
    _, result, out = fig1
    png = out / "figure1.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    curves = pd.read_csv(out / "figure1_curves.csv")
    np.testing.assert_allclose(curves["eq2_beta0.05"], eq2(curves["strain"], 0.05) / H, rtol=1e-12)
    assert not list(out.glob(".*.tmp")), "a temporary file was left behind"


# --- linear_validity --------------------------------------------------------------------
def test_small_load_sphere_matches_linear_closed_form(validity):
    """At the smallest load every law is within 1 % of the linear sphere's closed form."""
    _, result, _ = validity
    frame = result["frames"]["sphere"]
    load = frame["load_N"].min()
    d = sphere_approach(load)
    small = frame[frame["load_N"] == load]
    assert len(small) == 7  # linear, and Ateshian, cubic and 5th order for both betas
    assert small["max_strain"].max() < 0.02
    for row in small.itertuples(index=False):
        assert row.approach_mm == pytest.approx(d, rel=0.01), row.law
        assert row.peak_pressure_MPa == pytest.approx(H * d / 2.0, rel=0.01), row.law
        assert sphere_force(row.approach_mm) == pytest.approx(load, rel=0.01), row.law


def test_linear_sphere_matches_closed_form_at_every_load(validity):
    _, result, _ = validity
    linear = result["frames"]["sphere"].query("law == 'linear'")
    for row in linear.itertuples(index=False):
        d = sphere_approach(row.load_N)
        assert row.approach_mm == pytest.approx(d, rel=2e-3)
        assert row.peak_pressure_MPa == pytest.approx(H * d / 2.0, rel=1e-2)
        assert row.max_strain == pytest.approx(d / 2.0, rel=1e-2)
    # The sweep goes well past the paper's 30 %.
    assert linear["max_strain"].max() > 0.4


def test_small_load_hip_laws_agree(validity):
    _, result, _ = validity
    frame = result["frames"]["hip"]
    small = frame[frame["load_N"] == frame["load_N"].min()]
    linear = small.query("law == 'linear'").iloc[0]
    for row in small.itertuples(index=False):
        assert row.peak_pressure_MPa == pytest.approx(linear.peak_pressure_MPa, rel=0.01), row.law
        assert row.approach_mm == pytest.approx(linear.approach_mm, rel=0.01), row.law
    # Load-controlled: the linear (softest) law always reaches the largest strain.
    for _, rows in frame.groupby("load_N"):
        assert rows.set_index("law").loc["linear", "max_strain"] >= rows["max_strain"].max() - 1e-12


def test_shape_analysis_matches_eq2(validity):
    _, result, _ = validity
    for beta, v in result["shape"].items():
        assert v["deviation_at_claim"] == pytest.approx(H * -0.3 / eq2(-0.3, beta) - 1, rel=1e-10)
        for level, strain in v["departure"].items():
            expected = brentq(
                lambda s, beta=beta, level=level: (1 - H * s / -eq2(-s, beta)) - level, 1e-6, 0.9, xtol=1e-14
            )
            assert strain == pytest.approx(expected, abs=1e-9)
        assert v["departure"][0.05] < v["departure"][0.10] < 0.3
    assert result["shape"][0.05]["deviation_at_claim"] == pytest.approx(-0.1848, abs=1e-4)


def test_departure_strains_monotone(validity):
    _, result, _ = validity
    linear = result["pressure"].query("approximation == 'linear'")
    assert set(linear["geometry"]) == {"sphere", "hip"}
    assert len(linear) == 4
    for row in linear.itertuples(index=False):
        assert np.isfinite(row.strain_ref_5) and np.isfinite(row.strain_ref_10), row
        assert 0 < row.strain_ref_5 < row.strain_ref_10
        assert row.strain_approx_5 < row.strain_approx_10
        assert row.load_N_5 < row.load_N_10
        # The linear model overstates the strain it reaches under the same load.
        assert row.strain_approx_5 >= row.strain_ref_5 - 1e-12
    # Stiffer Eq. (2) (beta 0.6) departs earlier from the linear law.
    for _geometry, rows in linear.groupby("geometry"):
        b = rows.set_index("beta")
        assert b.loc[0.6, "strain_ref_5"] < b.loc[0.05, "strain_ref_5"]


def test_departure_interpolation_brackets_the_level(validity):
    """The interpolated 5 % point lies between two sweep points whose deviations bracket 5 %."""
    module, result, _ = validity
    frame = result["frames"]["sphere"]
    for beta in BETAS:
        ref = frame.query(f"law == 'ateshian_b{beta:g}'").sort_values("load_N")
        lin = frame.query("law == 'linear'").sort_values("load_N")
        dev = np.abs(lin["peak_pressure_MPa"].to_numpy() / ref["peak_pressure_MPa"].to_numpy() - 1)
        found = module.departure(frame, "linear", f"ateshian_b{beta:g}", 0.05)
        k = int(np.flatnonzero(dev >= 0.05)[0])
        s = ref["max_strain"].to_numpy()
        assert dev[k - 1] < 0.05 <= dev[k]
        assert s[k - 1] <= found["strain_reference"] <= s[k]


def _summary_rows(summary: str, first_cell: str) -> list[list[str]]:
    rows = []
    for line in summary.splitlines():
        if line.startswith(f"| {first_cell} |"):
            rows.append([c.strip() for c in line.strip().strip("|").split("|")])
    return rows


def test_summary_numbers_are_the_returned_data(validity):
    _, result, out = validity
    summary = result["summary"]
    assert (out / "validity_summary.md").read_text(encoding="utf-8") == summary
    # Shape table.
    for beta, v in result["shape"].items():
        (cells,) = _summary_rows(summary, f"{beta:g}")
        assert cells[1] == f"{100 * v['deviation_at_claim']:+.2f} %"
        assert cells[2] == f"{v['departure'][0.05]:.3f}"
        assert cells[3] == f"{v['departure'][0.10]:.3f}"
    # Pressure table: one row per geometry and beta, numbers formatted from the data.
    linear = result["pressure"].query("approximation == 'linear'")
    for geometry, rows in linear.groupby("geometry"):
        table = {float(c[1]): c for c in _summary_rows(summary, geometry)}
        for row in rows.itertuples(index=False):
            cells = table[row.beta]
            assert cells[2] == f"up to {row.max_strain_reached:.3f} at {row.max_load_N:.4g} N"
            assert cells[3] == f"{row.load_N_at_claim:.4g} N"
            assert cells[4] == f"{100 * row.dev_peak_at_claim:+.2f} %"
            assert cells[6] == f"{row.strain_ref_5:.3f} [{row.strain_approx_5:.3f}] / {row.load_N_5:.4g} N"
            assert cells[7] == f"{row.strain_ref_10:.3f} [{row.strain_approx_10:.3f}] / {row.load_N_10:.4g} N"
            for level in ("5", "10"):
                strain = getattr(row, f"strain_ref_{level}")
                assert f"{geometry} beta {row.beta:g}: within {level} % up to strain {strain:.3f}" in summary


def test_summary_verdict_follows_the_numbers(validity):
    _, result, _ = validity
    summary = result["summary"]
    linear = result["pressure"].query("approximation == 'linear'")
    for level, verdict in result["verdict"].items():
        tag = f"{round(100 * level):d}"
        shape_ok = all(round(v["departure"][level], 3) >= 0.3 for v in result["shape"].values())
        assert verdict["shape"] == shape_ok
        for geometry, rows in linear.groupby("geometry"):
            ok = bool((np.round(rows[f"strain_ref_{tag}"], 3) >= 0.3).all())
            assert verdict["pressure"][geometry] == ok
        line = next(x for x in summary.splitlines() if x.startswith(f"- **{100 * level:.0f} % tolerance**"))
        assert f"holds for **{verdict['holds_for']}**" in line
        assert ("Shape holds" if shape_ok else "Shape fails") in line
    # What the paper claims for the shape does not survive a 5 % tolerance.
    assert result["verdict"][0.05]["shape"] is False


def test_validity_files(validity):
    module, result, out = validity
    for name in ("validity_sphere.png", "validity_hip.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    sweep = pd.read_csv(out / "validity_sweep.csv")
    assert len(sweep) == sum(len(f) for f in result["frames"].values())
    np.testing.assert_allclose(
        sweep["peak_pressure_MPa"], pd.concat(result["frames"].values())["peak_pressure_MPa"], rtol=1e-12
    )
    departures = pd.read_csv(out / "validity_departures.csv")
    np.testing.assert_allclose(departures["strain_ref_5"], result["pressure"]["strain_ref_5"], rtol=1e-12)
    assert not list(out.glob(".*.tmp")), "a temporary file was left behind"


def test_knee_skip_messages(tmp_path, monkeypatch):
    module = _load("linear_validity")
    problem, note = module._knee_case(module.validity_laws()["linear"], tmp_path / "nowhere")
    assert problem is None and note.startswith("Knee skipped: no knee data")
    monkeypatch.setattr(module, "find_mesh_builder", lambda: None)
    problem, note = module._knee_case(module.validity_laws()["linear"], tmp_path)
    assert problem is None and "springs_from_meshes" in note and "skipped" in note


def test_knee_sweep_when_available():
    """The knee part runs through the same sweep when its data and the mesh builder exist."""
    module = _load("linear_validity")
    if not KNEE.is_dir():
        pytest.skip(f"no knee data at {KNEE}")
    assert module.find_mesh_builder() is not None
    laws = module.validity_laws()
    problem = module.knee_problem(laws["linear"], KNEE)
    assert set(problem.layer.labels) == {"medial", "lateral"}
    frame = module.load_sweep(
        problem,
        {k: laws[k] for k in ("linear", "ateshian_b0.05")},
        np.geomspace(5.0, 100.0, 4),
        geometry="knee",
        check=module.window_check(module.KNEE_MAX_GAP),
    )
    lin = frame.query("law == 'linear'")["peak_pressure_MPa"].to_numpy()
    ate = frame.query("law == 'ateshian_b0.05'")["peak_pressure_MPa"].to_numpy()
    assert np.all(np.diff(lin) > 0) and np.all(ate >= lin)  # Eq. (2) is stiffer in compression
