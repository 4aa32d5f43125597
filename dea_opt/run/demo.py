"""``dea-opt demo``: the embedded hip, compared at the gait peak by every method, then a whole gait cycle.

The socket's springs are labelled by region of the acetabulum (:func:`hip_regions`: the
superior dome, and the anterior and posterior walls), and the maps are drawn in the hip's
anatomical frame (``[output] anatomy`` of :data:`DEMO_SCENARIO`); the terminal lists the
validity of the frames and each region's share of the load. The outputs are published like a
run's (:mod:`dea_opt.run.publish`): ``comparison.csv``, ``frames.csv`` (with per-region
columns), ``series.pvd`` (+ ``series_frames/``), ``cycle.png``, ``exposure.png``, ``peak.png``,
``exposure.vtu``, ``summary.json``, ``report.html`` (the run on one page, with the comparison)
and, last, ``manifest.json``.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from .log import captured
from .outcome import RunOutcome
from .path import run_path_outputs
from .runner import check_method, picture_worker, publish_run, run_info, solve_options

__all__ = ["DEMO_DOME", "DEMO_SCENARIO", "demo_comparison", "demo_scenario", "hip_regions", "run_demo"]

#: The embedded default of ``dea-opt demo`` (also ``examples/scenarios/hip_gait.toml``).
DEMO_SCENARIO = """\
title = "Hip under a walking cycle (synthetic load), linear DEA"

# A femoral head (R = 25 mm) in a spherical socket covering 80 degrees around its pole, 0.1 mm
# radial clearance, cartilage 2 x 1.5 mm. Springs sit on the socket; the head is body 2.
[geometry]
kind = "socket"
radius = 25.0
thickness = 3.0
coverage = 80.0
gap = 0.1
n_rings = 45
n_sectors = 120

# H = 10 MPa: the stiffness cartilage shows under a walking cycle, when the interstitial fluid
# carries much of the load. The paper's equilibrium modulus (0.3-0.6 MPa) under these loads would
# crush a 3 mm layer past 80 % strain; 10 MPa keeps the peak strain near 20 %, inside the 30 %
# where Volokh, Chao & Armand find the linear law valid.
[law]
kind = "linear"
H = 10.0

[body2]
free = ["ux", "uy", "uz"]

# The synthetic hip cycle shipped with dea-opt (dea_opt/data/hip_gait.csv): 101 frames, peaks
# about 2.4 x body weight (750 N).
[load_path]
builtin = "hip_gait"

[solve]
method = "auto"

# The synthetic cycle's frame (dea_opt.gait): +x medial, +y anterior, and the socket opens
# toward +z, so its dome (-z) is proximal; a right hip.
[output]
directory = "dea-opt-demo"
exposure_threshold = 1.0
anatomy = {medial = [1.0, 0.0, 0.0], proximal = [0.0, 0.0, -1.0], side = "right"}
"""

#: Half-angle (degrees) of the acetabular dome labelled ``superior`` by :func:`hip_regions`.
DEMO_DOME = 35.0

_DEMO_PEAK = 2400.0  # N, the gait-peak frame of the comparison
_DEMO_TILT = 20.0  # degrees from the socket axis
_DEMO_BETA = 0.3


def demo_scenario(frames: int | None = None, coarse: bool = False):
    """The demo's scenario, optionally with fewer frames and a coarse mesh."""
    from ..scenario import parse_scenario

    overrides: dict[str, object] = {}
    if coarse:
        overrides |= {"geometry.n_rings": 12, "geometry.n_sectors": 36}
        frames = frames or 11
    if frames is not None:
        overrides["load_path.frames"] = frames
    return parse_scenario(DEMO_SCENARIO, name="demo.toml", overrides=overrides)


def hip_regions(layer, anatomy, centre=(0.0, 0.0, 0.0), dome: float = DEMO_DOME) -> np.ndarray:
    """Regions of an acetabular layer: ``superior`` (the dome), ``anterior`` and ``posterior`` (the walls).

    Parameters
    ----------
    layer : SpringLayer
        Springs on the socket.
    anatomy : AnatomicalFrame or dict
        The hip's anatomical frame (:meth:`dea_opt.anatomy.AnatomicalFrame.from_dict`).
    centre : array_like, shape (3,)
        The socket's centre (mm).
    dome : float
        A spring within ``dome`` degrees of the proximal direction, seen from ``centre``, is
        ``superior``; any other is ``anterior`` or ``posterior`` by the side of the frontal
        plane through ``centre`` it lies on.

    Returns
    -------
    ndarray of str, shape (N,)
    """
    from ..anatomy import AnatomicalFrame

    frame = AnatomicalFrame.from_dict(anatomy)
    arm = layer.points - np.asarray(centre, dtype=float)
    cosine = (arm @ frame.proximal) / np.linalg.norm(arm, axis=1)
    wall = np.where(arm @ frame.anterior >= 0.0, "anterior", "posterior")
    return np.where(cosine >= np.cos(np.radians(dome)), "superior", wall)


def demo_comparison(scenario, progress: bool = False) -> list[dict]:
    """One gait-peak frame (2.4 kN tilted 20 degrees) by every method, linear and Ateshian laws."""
    from tqdm.auto import tqdm

    from .. import formulations
    from ..laws import AteshianLaw, LinearLaw
    from ..scenario import build_problem
    from ..solver import solve

    tilt = np.radians(_DEMO_TILT)
    force = _DEMO_PEAK * np.array([np.sin(tilt), 0.0, -np.cos(tilt)])
    base = build_problem(scenario).with_load(force=force)
    H = scenario.law.H
    laws = (LinearLaw(H), AteshianLaw(H, _DEMO_BETA))
    cases = [(law, m) for law in laws for m in formulations.names() if formulations.takes(m, law)]
    # Tight solver tolerances: interior-point duals at the edge of contact need them to pass
    # the certificate's consistency check at 1e-6.
    options = {m: formulations.tolerance_options(m, 1e-12) for m in formulations.names()}
    rows = []
    for law, method in tqdm(cases, desc="comparison", unit="solve", disable=None if progress else True, leave=False):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            s = solve(base.with_law(law), method, strict=False, **options[method])
        name, value = s.certificate.worst()
        rows.append(
            {
                "method": method,
                "law": law.describe(),
                "success": s.success,
                "peak_pressure_MPa": s.peak_pressure,
                "contact_area_mm2": s.contact_area,
                "max_compressive_strain": s.max_compressive_strain,
                "iterations": s.iterations,
                "build_time_s": s.build_time,
                "solve_time_s": s.solve_time,
                "certificate_residual": value,
                "certificate_worst": name,
                "status": s.status,
            }
        )
    return rows


def run_demo(
    output_dir=None,
    *,
    frames: int | None = None,
    coarse: bool = False,
    method: str | None = None,
    compare: bool = True,
    progress: bool = False,
    echo=print,
    force: bool = False,
) -> RunOutcome:
    """``dea-opt demo``: the comparison table at the gait peak, then the whole gait cycle.

    Parameters
    ----------
    output_dir : str or Path, optional
        Default ``./dea-opt-demo``; new, empty or holding an earlier dea-opt run.
    frames : int, optional
        Resample the 101-frame cycle to this many frames.
    coarse : bool
        A coarse socket (432 springs) and 11 frames unless ``frames`` says otherwise: seconds.
    method : str, optional
        Method of the gait path (default ``auto``: warm-started Newton).
    compare : bool
        Solve and print the comparison table.
    echo : callable
        Where the text goes.
    force : bool
        Write into a folder that holds other files.
    """
    import pandas as pd

    from ..files import write_data
    from ..scenario import build_problem
    from .publish import check_output_folder

    scenario = demo_scenario(frames, coarse)
    report: dict = {}
    out = check_output_folder(Path(output_dir) if output_dir is not None else Path.cwd() / "dea-opt-demo", force)
    method = check_method(method, scenario.solve.method)
    start = time.perf_counter()
    with captured() as messages, picture_worker(scenario) as pictures:
        problem = build_problem(scenario)
        problem = problem.with_layer(replace(problem.layer, labels=hip_regions(problem.layer, scenario.output.anatomy)))
        options = solve_options(scenario.solve, method, problem.law)

        def solve_and_write(folder):
            rows = []
            if compare:
                rows = demo_comparison(scenario, progress)
                table = pd.DataFrame(rows)
                comparison = write_data(folder / "comparison.csv", table.to_csv(index=False, lineterminator="\n"))
                echo(f"Gait-peak frame: {_DEMO_PEAK:g} N tilted {_DEMO_TILT:g} degrees, {len(problem.layer)} springs")
                echo(_format_comparison(table))
                echo("")
            outcome = run_path_outputs(
                scenario,
                problem,
                method,
                options,
                folder,
                progress,
                extra_summary={"comparison": rows, "scenario": DEMO_SCENARIO},
                pictures=pictures,
            )
            if compare:
                outcome.files["comparison"] = comparison
                report["comparison"] = rows
            return outcome

        outcome = publish_run(
            scenario,
            out,
            solve_and_write,
            messages,
            force=force,
            info=run_info(scenario, "demo", method),
            started=start,
            report_extra=report,
        )
    out = outcome.folder or out
    echo(f"Gait cycle: {outcome.message}")
    for line in outcome.validity + outcome.regions:
        echo(line)
    echo(f"Wrote {len(outcome.files) + 1} outputs to {out} in {time.perf_counter() - start:.1f} s:")
    for name, path in {**outcome.files, "manifest": out / "manifest.json"}.items():
        echo(f"  {name:13s} {Path(path).relative_to(out) if Path(path).is_relative_to(out) else path}")
    return outcome


def _format_comparison(table) -> str:
    shown = table[
        [
            "method",
            "law",
            "success",
            "peak_pressure_MPa",
            "contact_area_mm2",
            "max_compressive_strain",
            "iterations",
            "build_time_s",
            "solve_time_s",
            "certificate_residual",
        ]
    ].rename(
        columns={
            "peak_pressure_MPa": "peak (MPa)",
            "contact_area_mm2": "area (mm^2)",
            "max_compressive_strain": "strain",
            "build_time_s": "build (s)",
            "solve_time_s": "solve (s)",
            "certificate_residual": "residual",
        }
    )
    return shown.to_string(index=False, float_format=lambda v: f"{v:.4g}")
