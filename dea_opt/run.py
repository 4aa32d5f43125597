"""Running scenarios: one static solve or a load path, with every output written; and the demo.

The command line (:mod:`dea_opt.cli`) and the sweep workers (:mod:`dea_opt.sweep`) call
:func:`run_scenario`; ``dea-opt demo`` calls :func:`run_demo`.

Outputs of a static load (in the output folder): ``contact.vtu`` (the contact surface with
pressure, strain, gap, thickness, ...), ``contact.csv`` (one row per spring),
``contact.json`` (summary, regions, certificate) and ``contact.png`` (pressure map).
Outputs of a load path: ``frames.csv`` (one row per frame), ``series.pvd`` with
``series_frames/frame_NNNN.vtu`` (ParaView time series), ``exposure.vtu`` (exposure
fields), ``cycle.png`` (force, pressure and contact area over time), ``exposure.png``
(exposure maps) and ``summary.json``.
"""

from __future__ import annotations

import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import InputError

__all__ = ["RunOutcome", "run_scenario", "solve_options", "run_demo", "DEMO_SCENARIO", "demo_comparison"]


@dataclass(eq=False)
class RunOutcome:
    """What :func:`run_scenario` did.

    Attributes
    ----------
    kind : {"static", "path"}
    success : bool
        Every answer passed its certificate.
    message : str
        One line for the user.
    files : dict {name: Path}
    headline : dict
        The numbers a sweep puts in its table.
    result : Solution or PathResult
    warnings : list of str
        Validity warnings raised while solving.
    """

    kind: str
    success: bool
    message: str
    files: dict
    headline: dict
    result: object = None
    warnings: list = field(default_factory=list)


def solve_options(section, method: str, law) -> dict:
    """Formulation options from ``[solve]`` for ``method`` (only those it accepts).

    The formulation is ``method``, or under ``auto`` the one the registry falls back to for
    ``law`` (:func:`dea_opt.formulations.fallback_for`). ``[solve].tol`` sets the options one
    accuracy setting sets (:func:`~dea_opt.formulations.tolerance_options`), and each other
    key of ``[solve]`` that names one of its options (``solver``, ``form``) is passed as is.
    """
    from . import formulations

    effective = method if method != "auto" else formulations.fallback_for(law)
    if effective is None:
        return {}
    options = {option.name: getattr(section, option.name) for option in formulations.options(effective)
               if not option.tolerance and getattr(section, option.name, None) is not None}
    return options | formulations.tolerance_options(effective, section.tol)


def _check_method(method: str | None, default: str) -> str:
    from .scenario import METHOD_NAMES

    method = default if method is None else method.strip().lower()
    if method not in METHOD_NAMES:
        raise InputError(f"method (--method or [solve].method) must be one of {', '.join(METHOD_NAMES)}, "
                         f"got {method!r}")
    return method


def run_scenario(scenario, output_dir=None, *, method: str | None = None, progress: bool = False) -> RunOutcome:
    """Solve a scenario and write its outputs.

    Parameters
    ----------
    scenario : Scenario
    output_dir : str or Path, optional
        Default ``[output].directory`` (relative to the scenario file).
    method : str, optional
        Overrides ``[solve].method``.
    progress : bool
        Progress bar over the frames of a load path (on a terminal).

    Raises
    ------
    DeaError
        Bad input, a load no spring can carry, a solver that fails outright.
    """
    from .scenario import build_problem

    method = _check_method(method, scenario.solve.method)
    out = scenario.output_dir(output_dir)
    problem = build_problem(scenario)
    options = solve_options(scenario.solve, method, problem.law)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if scenario.load_path is None:
            outcome = _run_static(scenario, problem, method, options, out)
        else:
            outcome = _run_path(scenario, problem, method, options, out, progress)
    outcome.warnings = sorted({str(w.message) for w in caught if issubclass(w.category, UserWarning)})
    return outcome


def _run_static(scenario, problem, method, options, out) -> RunOutcome:
    from . import io
    from .solver import solve

    solution = solve(problem, method, certificate_tol=scenario.solve.certificate_tol, strict=False, **options)
    formats = scenario.output.formats
    files = {}
    if "vtk" in formats:
        files["vtk"] = io.to_vtk(solution, out / "contact.vtu")
    if "csv" in formats:
        files["csv"] = io.to_csv(solution, out / "contact.csv")
    if "json" in formats:
        files["json"] = io.to_json(solution, out / "contact.json")
    if "png" in formats:
        files["png"] = io.plot_pressure(solution, out / "contact.png")
    name, value = solution.certificate.worst()
    headline = {
        "method": solution.method, "success": solution.success, "n_springs": len(solution.pressure),
        "peak_pressure": solution.peak_pressure, "mean_pressure": solution.mean_pressure,
        "contact_area": solution.contact_area, "iterations": solution.iterations,
        "solve_time": solution.solve_time, "worst_residual": value,
    }
    if solution.success:
        message = (f"{solution.method}: peak pressure {solution.peak_pressure:.4g} MPa, contact area "
                   f"{solution.contact_area:.4g} mm^2, {solution.iterations} iterations, certificate passed")
    else:
        message = (f"{solution.method} returned no certified answer (status {solution.status!r}; {name} = "
                   f"{value:.3g} > {scenario.solve.certificate_tol:g}); the outputs hold the uncertified answer")
    return RunOutcome("static", solution.success, message, files, headline, solution)


def _run_path(scenario, problem, method, options, out, progress, extra_summary=None) -> RunOutcome:
    from .loadpath import solve_path
    from .scenario import read_load_path

    data = read_load_path(scenario.load_path)
    layer_for_pose = None
    if data.poses is not None:
        from .scenario import pose_builder

        layer_for_pose = pose_builder(scenario.geometry)

    formats = scenario.output.formats
    result = solve_path(problem, data.load_objects(), data.poses, method=method, times=data.times, body=data.body,
                        certificate_tol=scenario.solve.certificate_tol, keep_solutions="vtk" in formats,
                        layer_for_pose=layer_for_pose, threshold=scenario.output.exposure_threshold,
                        progress=progress, **options)
    files = result.write(out, formats, extra_summary={"title": scenario.title, **(extra_summary or {})})
    summary = result.summary()
    headline = {
        "method": method, "success": result.success, "frames": summary["frames"], "n_springs": summary["n_springs"],
        "failed_frames": len(summary["failed_frames"]), "peak_pressure": summary["peak_pressure"],
        "peak_time": summary["peak_time"], "contact_area": summary["max_contact_area"],
        "iterations": summary["iterations_total"], "solve_time": summary["solve_time_total"],
        "worst_residual": summary["worst_certificate_residual"],
        "max_pressure_time_integral": summary["exposure"]["max_pressure_time_integral"],
    }
    message = (f"{summary['frames']} frames by {method}: peak pressure {summary['peak_pressure']:.4g} MPa at "
               f"{summary['peak_time']:.3g} s, largest contact area {summary['max_contact_area']:.4g} mm^2, "
               f"{summary['solve_time_total']:.2f} s solving")
    if not result.success:
        failed = summary["failed_frames"]
        message += (f"; {len(failed)} frame(s) failed their certificate ({', '.join(map(str, failed[:10]))}"
                    f"{', ...' if len(failed) > 10 else ''}) and are flagged in frames.csv")
    return RunOutcome("path", result.success, message, files, headline, result)


# --- the demo ---------------------------------------------------------------------------

#: The embedded default of ``dea-opt demo`` (also ``examples/scenarios/hip_gait.toml``).
DEMO_SCENARIO = '''\
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

[output]
directory = "dea-opt-demo"
exposure_threshold = 1.0
'''

_DEMO_PEAK = 2400.0  # N, the gait-peak frame of the comparison
_DEMO_TILT = 20.0  # degrees from the socket axis
_DEMO_BETA = 0.3


def demo_scenario(frames: int | None = None, coarse: bool = False):
    """The demo's scenario, optionally with fewer frames and a coarse mesh."""
    from .scenario import parse_scenario

    overrides = {}
    if coarse:
        overrides |= {"geometry.n_rings": 12, "geometry.n_sectors": 36}
        frames = frames or 11
    if frames is not None:
        overrides["load_path.frames"] = frames
    return parse_scenario(DEMO_SCENARIO, name="demo.toml", overrides=overrides)


def demo_comparison(scenario, progress: bool = False) -> list[dict]:
    """One gait-peak frame (2.4 kN tilted 20 degrees) by every method, linear and Ateshian laws."""
    from tqdm.auto import tqdm

    from .laws import AteshianLaw, LinearLaw
    from .scenario import build_problem
    from .solver import solve

    tilt = np.radians(_DEMO_TILT)
    force = _DEMO_PEAK * np.array([np.sin(tilt), 0.0, -np.cos(tilt)])
    base = build_problem(scenario).with_load(force=force)
    H = scenario.law.H
    cases = [(LinearLaw(H), m) for m in ("newton", "qp", "nlp")]
    cases += [(AteshianLaw(H, _DEMO_BETA), m) for m in ("newton", "nlp")]
    # Tight solver tolerances: interior-point duals at the edge of contact need them to pass
    # the certificate's consistency check at 1e-6.
    options = {"qp": {"tol": 1e-12}, "nlp": {"tol": 1e-12}, "newton": {}}
    rows = []
    for law, method in tqdm(cases, desc="comparison", unit="solve", disable=None if progress else True, leave=False):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            s = solve(base.with_law(law), method, strict=False, **options[method])
        name, value = s.certificate.worst()
        rows.append({
            "method": method, "law": law.describe(), "success": s.success, "peak_pressure": s.peak_pressure,
            "contact_area": s.contact_area, "max_strain": s.max_compressive_strain, "iterations": s.iterations,
            "build_time": s.build_time, "solve_time": s.solve_time, "certificate": value,
            "certificate_worst": name, "status": s.status,
        })
    return rows


def run_demo(output_dir=None, *, frames: int | None = None, coarse: bool = False, method: str | None = None,
             compare: bool = True, progress: bool = False, echo=print) -> RunOutcome:
    """``dea-opt demo``: the comparison table at the gait peak, then the whole gait cycle.

    Parameters
    ----------
    output_dir : str or Path, optional
        Default ``./dea-opt-demo``.
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
    """
    import pandas as pd

    from .io import write_data
    from .scenario import build_problem

    scenario = demo_scenario(frames, coarse)
    out = Path(output_dir).resolve() if output_dir is not None else Path.cwd() / "dea-opt-demo"
    method = _check_method(method, scenario.solve.method)
    rows = []
    start = time.perf_counter()
    if compare:
        rows = demo_comparison(scenario, progress)
        table = pd.DataFrame(rows)
        write_data(out / "comparison.csv", table.to_csv(index=False, lineterminator="\n"))
        echo(f"Gait-peak frame: {_DEMO_PEAK:g} N tilted {_DEMO_TILT:g} degrees, "
             f"{len(build_problem(scenario).layer)} springs")
        echo(_format_comparison(table))
        echo("")
    problem = build_problem(scenario)
    options = solve_options(scenario.solve, method, problem.law)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        outcome = _run_path(scenario, problem, method, options, out, progress,
                            extra_summary={"comparison": rows, "scenario": DEMO_SCENARIO})
    outcome.warnings = sorted({str(w.message) for w in caught if issubclass(w.category, UserWarning)})
    if compare:
        outcome.files["comparison"] = out / "comparison.csv"
    echo(f"Gait cycle: {outcome.message}")
    echo(f"Wrote {len(outcome.files)} outputs to {out} in {time.perf_counter() - start:.1f} s:")
    for name, path in outcome.files.items():
        echo(f"  {name:13s} {Path(path).relative_to(out) if Path(path).is_relative_to(out) else path}")
    return outcome


def _format_comparison(table) -> str:
    shown = table[["method", "law", "success", "peak_pressure", "contact_area", "max_strain", "iterations",
                   "build_time", "solve_time", "certificate"]].rename(columns={
                       "peak_pressure": "peak (MPa)", "contact_area": "area (mm^2)", "max_strain": "strain",
                       "build_time": "build (s)", "solve_time": "solve (s)", "certificate": "residual"})
    return shown.to_string(index=False, float_format=lambda v: f"{v:.4g}")
