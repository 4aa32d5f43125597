"""Uncertainty (formulations/sensitivity.md, "Uncertainty"): first-order propagation against Monte
Carlo on Dask, on the real knee and in closed form."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import KNEE

import dea_opt as d
from dea_opt.geometry import plate_layer
from dea_opt.sensitivity.uncertainty import SCALARS, monte_carlo, propagate

KNEE_FILES = ("femoral_cartilage.stl", "medial_tibial_cartilage.stl", "lateral_tibial_cartilage.stl")


def plate_problem():
    layer = plate_layer(10.0, 10.0, 10, 10, thickness=2.0)
    return d.ContactProblem(layer, d.LinearLaw(20.0), force=(0, 0, -100.0), reference=(0, 0, 0), free=("uz",))


def test_first_order_in_closed_form():
    """A plate on a bonded linear layer: p = -Fz / S everywhere, whatever H and the thickness."""
    problem = plate_problem()
    s = d.solve(problem)
    out = propagate(s, {"Fz": 5.0, "H": 0.1, "thickness_scale": 0.05})
    assert out.output_std["peak_pressure"] == pytest.approx(5.0 / 100.0, rel=1e-12)
    assert out.output_std["mean_pressure"] == pytest.approx(5.0 / 100.0, rel=1e-12)
    assert out.derivatives["peak_pressure"]["H"] == pytest.approx(0.0, abs=1e-15)
    assert out.value["peak_pressure"] == pytest.approx(1.0)
    assert set(out.output_std) == set(SCALARS)
    table = out.table()
    assert list(table.output) == list(SCALARS)


def test_monte_carlo_in_closed_form():
    problem = plate_problem()
    mc = monte_carlo(problem, {"Fz": 5.0, "H": 0.1}, n=64, seed=1, scheduler="threads", chunks=4)
    assert len(mc.samples) == 64 and mc.n_failed == 0
    # the same draws, pushed through p = -Fz / S by hand
    expected = (-mc.samples["Fz"] / 100.0).std(ddof=1)
    assert mc.std["peak_pressure"] == pytest.approx(expected, rel=1e-9)
    assert mc.mean["peak_pressure"] == pytest.approx((-mc.samples["Fz"] / 100.0).mean(), rel=1e-12)
    # the draws are reproducible and independent of the scheduler
    again = monte_carlo(problem, {"Fz": 5.0, "H": 0.1}, n=64, seed=1, scheduler="synchronous", chunks=3)
    np.testing.assert_allclose(np.sort(again.samples["Fz"]), np.sort(mc.samples["Fz"]))


def test_failed_draws_are_rows_not_the_end():
    problem = plate_problem()
    mc = monte_carlo(problem, {"Fz": 200.0}, n=40, seed=2, chunks=2)
    pulled = mc.samples["Fz"] > 0  # a load pulling the plate off: no equilibrium
    assert pulled.any() and not mc.samples.loc[pulled, "success"].any()
    assert mc.n_failed == int(pulled.sum())
    assert mc.samples.loc[pulled, "error"].str.contains("LoadNotSupportedError").all()
    assert np.isfinite(mc.std["peak_pressure"])


def test_bad_inputs_are_named_errors():
    problem = plate_problem()
    s = d.solve(problem)
    with pytest.raises(d.InputError, match="mapping"):
        propagate(s, [1.0])
    with pytest.raises(d.InputError, match=">= 0"):
        propagate(s, {"H": -1.0})
    with pytest.raises(d.InputError, match="per-spring"):
        propagate(s, {"thickness": 0.1})
    with pytest.raises(d.InputError, match="draws"):
        monte_carlo(problem, {"body2.uz": 0.1})
    with pytest.raises(d.InputError, match="n must"):
        monte_carlo(problem, {"H": 0.1}, n=1)


def test_first_order_and_monte_carlo_agree_on_the_knee():
    """5 % uncertainty in H and beta (and the thickness) on the real knee: the standard deviations of
    peak pressure agree within 15 %."""
    if not all((KNEE / name).is_file() for name in KNEE_FILES):
        pytest.skip(f"the knee meshes are not in {KNEE}")
    from dea_opt import mesh as M

    femur, medial, lateral = (M.load_mesh(KNEE / name) for name in KNEE_FILES)
    tibia, labels = M.concatenate_meshes({"medial": medial, "lateral": lateral})
    layer = M.springs_from_meshes(tibia, femur, labels=labels, max_gap=2.0)
    centre = 0.5 * sum((m.area_faces @ m.triangles_center) / m.area for m in (medial, lateral))
    problem = d.ContactProblem(
        layer, d.AteshianLaw(5.0, 0.6), force=(0.0, 0.0, -1000.0), reference=tuple(centre), free=("uz", "ry")
    )
    std = {"H": 0.25, "beta": 0.03, "thickness_scale": 0.05}
    first = propagate(d.solve(problem), std)
    mc = monte_carlo(problem, std, n=200, seed=0, scheduler="synchronous")
    assert mc.n_failed == 0
    ratio = first.output_std["peak_pressure"] / mc.std["peak_pressure"]
    print(
        f"\nknee: first-order sd of peak {first.output_std['peak_pressure']:.4g} MPa, Monte Carlo {mc.std['peak_pressure']:.4g}"
    )
    assert 0.85 < ratio < 1.15, (first.output_std, mc.std)
    assert mc.mean["peak_pressure"] == pytest.approx(first.value["peak_pressure"], rel=0.02)


def test_monte_carlo_on_a_local_cluster():
    from distributed import Client, LocalCluster

    problem = plate_problem()
    with (
        LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster,
        Client(cluster) as client,
    ):
        mc = monte_carlo(problem, {"Fz": 5.0}, n=16, seed=3, client=client, chunks=2)
    here = monte_carlo(problem, {"Fz": 5.0}, n=16, seed=3, chunks=5)
    assert mc.n_failed == 0 and mc.std["peak_pressure"] == pytest.approx(here.std["peak_pressure"], rel=1e-12)
