"""Sensitivity and calibration benchmark (formulations/sensitivity.md).

Run::

    python benchmarks/bench_sensitivity.py                 # 1e5 springs, and the knee's calibration
    python benchmarks/bench_sensitivity.py --springs 1e4

Targets of the sensitivity issue: the derivatives of every output with respect to 10 parameters
cost less than 3 Newton solves at 1e5 springs (the box: springs on six faces, 6 free dofs,
Ateshian's law); a calibration of H and beta on the real knee (a film reading, start 2x off)
finishes in under 2 s. Prints the rows and writes ``benchmarks/results/sensitivity.csv``.
"""

from __future__ import annotations

import argparse
import os
import time
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
KNEE = HERE.parents[1] / "shared" / "data" / "knee"
KNEE_FILES = ("femoral_cartilage.stl", "medial_tibial_cartilage.stl", "lateral_tibial_cartilage.stl")
#: The 10 parameters: the law's two, the thickness scale, the six load components, a prescribed dof.
WRT = ("H", "beta", "thickness_scale", "Fx", "Fy", "Fz", "Mx", "My", "Mz", "body1.uz")
COLUMNS = [
    "case",
    "n_springs",
    "n_parameters",
    "newton_s",
    "newton_formulation_s",
    "sensitivities_s",
    "ratio",
    "calibration_s",
    "solves",
    "H",
    "beta",
    "success",
    "status",
    "peak_rss_mb",
    "load_1m",
]


def sensitivity_case(n_springs: float = 1e5, repeats: int = 5) -> dict:
    """Best-of-``repeats`` wall time of ``dea.solve(problem, "newton")`` and of ``sensitivities``
    of every output to :data:`WRT` on the box at about ``n_springs``."""
    import sys

    sys.path.insert(0, str(HERE))
    from common import box_problem, peak_rss_mb

    import dea_opt as dea
    from dea_opt.sensitivity import sensitivities

    base = box_problem(int(n_springs))
    body1 = dea.Body(reference=base.body1.reference, free=(), prescribed={"uz": 0.0})
    problem = dea.ContactProblem(base.layer, dea.AteshianLaw(base.law.modulus, 0.3), body1=body1, body2=base.body2)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", dea.ValidityWarning)
        dea.solve(problem, "newton")  # imports and caches warm
        walls, inner = [], []
        for _ in range(repeats):
            start = time.perf_counter()
            solution = dea.solve(problem, "newton")
            walls.append(time.perf_counter() - start)
            inner.append(solution.solve_time)
    sensitivities(solution, WRT)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        sens = sensitivities(solution, WRT)
        times.append(time.perf_counter() - start)
    ok = bool(solution.success and np.isfinite(sens.u["Fz"]).all())
    return {
        "case": "box, Ateshian",
        "n_springs": len(problem.layer),
        "n_parameters": len(WRT),
        "newton_s": min(walls),
        "newton_formulation_s": min(inner),
        "sensitivities_s": min(times),
        "ratio": min(times) / min(walls),
        "success": ok,
        "status": "ok" if ok else "failed",
        "peak_rss_mb": peak_rss_mb(),
        "load_1m": os.getloadavg()[0],
    }


def calibration_case(seed: int = 0) -> dict:
    """A fit of H and beta to the real knee's pressures read through an LLW film (5 % noise), from
    twice the true values (H = 5 MPa, beta = 0.6); the wall time of ``dea.calibrate`` alone."""
    import sys

    sys.path.insert(0, str(HERE))
    if not all((KNEE / name).is_file() for name in KNEE_FILES):
        return {"case": "knee calibration", "status": f"skipped: no knee meshes in {KNEE}", "success": False}
    from common import peak_rss_mb

    import dea_opt as dea
    from dea_opt import mesh as M
    from dea_opt.sensitivity import PressureMap, calibrate

    femur, medial, lateral = (M.load_mesh(KNEE / name) for name in KNEE_FILES)
    tibia, labels = M.concatenate_meshes({"medial": medial, "lateral": lateral})
    layer = M.springs_from_meshes(tibia, femur, labels=labels, max_gap=2.0)
    centre = 0.5 * sum((m.area_faces @ m.triangles_center) / m.area for m in (medial, lateral))
    problem = dea.ContactProblem(
        layer, dea.AteshianLaw(5.0, 0.6), force=(0.0, 0.0, -1000.0), reference=tuple(centre), free=("uz", "ry")
    )
    truth = dea.solve(problem, "newton")
    rng = np.random.default_rng(seed)
    reading = np.maximum(truth.pressure * (1 + 0.05 * rng.standard_normal(len(layer))), 0.0)
    data = PressureMap(layer.points, reading, film="LLW")
    start_problem = problem.with_law(dea.AteshianLaw(10.0, 1.2))
    calibrate(start_problem.with_law(dea.AteshianLaw(5.5, 0.65)), data, ("H", "beta"), max_nfev=2)  # warm imports
    start = time.perf_counter()
    fit = calibrate(start_problem, data, ("H", "beta"))
    wall = time.perf_counter() - start
    return {
        "case": "knee calibration",
        "n_springs": len(layer),
        "n_parameters": 2,
        "calibration_s": wall,
        "solves": fit.nfev,
        "H": fit.values["H"],
        "beta": fit.values["beta"],
        "success": bool(fit.success),
        "status": fit.message,
        "peak_rss_mb": peak_rss_mb(),
        "load_1m": os.getloadavg()[0],
    }


def main(argv=None):
    import sys

    sys.path.insert(0, str(HERE))
    from common import write_csv

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--springs", type=float, default=1e5)
    args = parser.parse_args(argv)
    rows = [sensitivity_case(args.springs), calibration_case()]
    write_csv(HERE / "results" / "sensitivity.csv", rows, COLUMNS)
    for row in rows:
        print("  ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in row.items()))


if __name__ == "__main__":
    main()
