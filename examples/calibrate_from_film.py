"""Calibrate H and beta of Ateshian's law to a pressure film, then carry their uncertainty to the answer.
======================================================================================================

A synthetic experiment on the real knee (``../shared/data/knee``; the embedded hip socket when it is
absent or with ``--geometry hip``): the femur pressed onto the tibia with 1000 N (the hip: 2.4 kN
tilted 20 degrees), cartilage following Ateshian's law, Eq. (2), with H = 5 MPa and beta = 0.6.
Its pressures, read at every spring with 5 % multiplicative noise through a Fuji Prescale LLW film
(0.5-2.5 MPa: lower readings say only "below", higher ones "saturated"), are written to
``film.csv`` (x, y, z, p). Then ``dea_opt.calibrate`` fits H and beta to the film from twice the
true values, with the exact Jacobian of ``dea_opt.sensitivities`` (formulations/sensitivity.md),
and reports the fitted values, their standard errors and correlation. Finally the fitted model's
peak pressure, contact area and centre of pressure get standard deviations for 5 % uncertainty in
H and beta, to first order (``dea_opt.propagate``) and by a Monte Carlo sweep on Dask.

Run it with::

    python examples/calibrate_from_film.py --out figures/
    python examples/calibrate_from_film.py --geometry hip --draws 400 --workers 2
    dea-opt calibrate scenario.toml --data figures/film.csv --film LLW      # the same fit from the CLI

``--coarse`` (the tests' setting) uses a coarse hip and 24 draws. ``--workers N`` runs the draws on
a Dask LocalCluster of N processes (default: in this process).

Writes into ``--out`` (default ``examples/output/calibrate_from_film/``): ``film.csv``,
``calibration.png`` (measured vs predicted pressure, censored points at the film's limits, and the
residual map), ``calibration.json`` (fit and uncertainty), ``residuals.csv``.

Units: mm, N, MPa.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

import dea_opt
from dea_opt.files import write_atomic
from dea_opt.geometry import socket_layer
from dea_opt.sensitivity import PressureMap, calibrate, monte_carlo, propagate

NAME = "calibrate_from_film"
DEFAULT_OUT = Path(__file__).resolve().parent / "output" / NAME
KNEE = Path(__file__).resolve().parents[2] / "shared" / "data" / "knee"
KNEE_FILES = ("femoral_cartilage.stl", "medial_tibial_cartilage.stl", "lateral_tibial_cartilage.stl")
TRUE = {"H": 5.0, "beta": 0.6}  # MPa, 1
NOISE = 0.05
FILM = "LLW"


def knee_problem(law) -> dea_opt.ContactProblem:
    """The real knee: springs from the tibial cartilage to the femoral cartilage, 1000 N along -z."""
    from dea_opt import mesh as M

    femur, medial, lateral = (M.load_mesh(KNEE / name) for name in KNEE_FILES)
    tibia, labels = M.concatenate_meshes({"medial": medial, "lateral": lateral})
    layer = M.springs_from_meshes(tibia, femur, labels=labels, max_gap=2.0)
    centre = 0.5 * sum((m.area_faces @ m.triangles_center) / m.area for m in (medial, lateral))
    return dea_opt.ContactProblem(layer, law, force=(0.0, 0.0, -1000.0), reference=tuple(centre), free=("uz", "ry"))


def hip_problem(law, coarse: bool = False) -> dea_opt.ContactProblem:
    """The demo's hip socket with a 0.3 mm clearance, 2.4 kN tilted 20 degrees from its axis."""
    rings, sectors = (30, 80) if coarse else (90, 240)
    layer = socket_layer(radius=25.0, thickness=3.0, coverage=80.0, n_rings=rings, n_sectors=sectors, gap=0.3)
    tilt = np.radians(20.0)
    force = 2400.0 * np.array([np.sin(tilt), 0.0, -np.cos(tilt)])
    return dea_opt.ContactProblem(layer, law, force=force, reference=(0, 0, 0), free=("ux", "uy", "uz"))


def film_reading(solution, seed: int = 0) -> pd.DataFrame:
    """The solution's pressure at every spring with 5 % multiplicative noise: columns x, y, z, p."""
    rng = np.random.default_rng(seed)
    pressure = np.maximum(solution.pressure * (1 + NOISE * rng.standard_normal(len(solution.pressure))), 0.0)
    points = solution.problem.layer.points
    return pd.DataFrame({"x": points[:, 0], "y": points[:, 1], "z": points[:, 2], "p": pressure})


def run(
    geometry: str = "auto", out=DEFAULT_OUT, coarse: bool = False, draws: int = 200, workers: int = 0, seed: int = 0
) -> dict:
    """Make the film, fit it, propagate the uncertainty; returns the summary that is also written."""
    out = Path(out)
    truth_law = dea_opt.AteshianLaw(**TRUE)
    if geometry == "auto":
        geometry = "knee" if not coarse and all((KNEE / n).is_file() for n in KNEE_FILES) else "hip"
    if geometry == "knee" and not all((KNEE / n).is_file() for n in KNEE_FILES):
        raise SystemExit(f"no knee meshes in {KNEE}; use --geometry hip")
    problem = knee_problem(truth_law) if geometry == "knee" else hip_problem(truth_law, coarse)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dea_opt.ValidityWarning)
        truth = dea_opt.solve(problem, "newton")
    film = film_reading(truth, seed)
    film_path = write_atomic(out / "film.csv", lambda tmp: film.to_csv(tmp, index=False))
    data = PressureMap.from_csv(film_path, film=FILM, noise=NOISE)
    start = problem.with_law(dea_opt.AteshianLaw(2 * TRUE["H"], 2 * TRUE["beta"]))
    began = time.perf_counter()
    fit = calibrate(start, data, ("H", "beta"))
    fit_time = time.perf_counter() - began
    fitted = fit.solution
    std = {name: NOISE * value for name, value in fit.values.items()}
    first = propagate(fitted, std)
    client = None
    if workers:
        from distributed import Client, LocalCluster

        client = Client(LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None))
    try:
        mc = monte_carlo(fitted.problem, std, n=24 if coarse else draws, seed=seed, client=client)
    finally:
        if client is not None:
            client.close()
    counts = {
        state: int((data.state == code).sum()) for state, code in (("below", -1), ("within", 0), ("saturated", 1))
    }
    summary = {
        "geometry": geometry,
        "springs": len(problem.layer),
        "true": TRUE,
        "film": FILM,
        "noise": NOISE,
        "readings": counts,
        "fit": fit.summary(),
        "fit_time": fit_time,
        "uncertainty": {
            "std": std,
            "first_order": first.output_std,
            "monte_carlo": mc.std,
            "monte_carlo_mean": mc.mean,
            "draws": len(mc.samples),
            "failed_draws": mc.n_failed,
        },
    }
    write_atomic(out / "calibration.json", lambda tmp: tmp.write_text(json.dumps(summary, indent=2, default=float)))
    table = fit.residual_map()
    write_atomic(out / "residuals.csv", lambda tmp: table.to_csv(tmp, index=False))
    text = ", ".join(f"{k} = {fit.values[k]:.4g} ± {fit.standard_errors[k]:.2g} (true {TRUE[k]:g})" for k in TRUE)
    fit.plot(
        out / "calibration.png",
        title=f"{geometry}: {len(problem.layer)} springs, {FILM} film, 5 % noise, start 2x off: {text}",
    )
    print(f"{geometry}: {len(problem.layer)} springs; film readings {counts}")
    for name in fit.parameters:
        print(
            f"  {name:5s} start {fit.start[name]:8.4g}  fitted {fit.values[name]:8.4g} ± "
            f"{fit.standard_errors[name]:.2g}  (true {TRUE[name]:g}, error "
            f"{100 * (fit.values[name] / TRUE[name] - 1):+.2f} %)"
        )
    print(f"  correlation H-beta {fit.correlation[0, 1]:+.3f}; {fit.nfev} solves in {fit_time:.2f} s")
    print("  5 % uncertainty in H and beta:   first order    Monte Carlo")
    for key in ("peak_pressure", "contact_area", "cop_x", "cop_y"):
        print(f"    sd {key:14s}          {first.output_std[key]:10.4g}   {mc.std[key]:10.4g}")
    print(f"wrote {out}")
    return summary


def parse_args(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--geometry",
        choices=("auto", "knee", "hip"),
        default="auto",
        help="the real knee (default when ../shared/data/knee exists) or the hip socket",
    )
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output folder")
    parser.add_argument("--coarse", action="store_true", help="a coarse hip and 24 draws (the tests)")
    parser.add_argument("--draws", type=int, default=200, help="Monte Carlo draws (default 200)")
    parser.add_argument("--workers", type=int, default=0, help="Dask LocalCluster processes (default: none)")
    parser.add_argument("--seed", type=int, default=0, help="noise and draws")
    return parser.parse_args(argv)


def main(argv=None) -> dict:
    args = parse_args(argv)
    return run(args.geometry, args.out, args.coarse, args.draws, args.workers, args.seed)


if __name__ == "__main__":
    sys.exit(0 if main() else 1)
