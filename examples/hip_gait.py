"""The embedded hip over one walking cycle: pressure, contact area, exposure, ParaView series.
===========================================================================================

The hip of ``dea-opt demo``: a femoral head (R = 25 mm, body 2, free to translate) in a
spherical socket (body 1) covering 80 degrees around its pole, 0.1 mm radial clearance,
3 mm of cartilage in all, linear springs with H = 10 MPa. It is loaded frame by frame with
the synthetic 101-frame hip contact force shipped with dea-opt
(``dea_opt/data/hip_gait.csv``: Bergmann-shaped double hump, peaks about 2.4 x 750 N; **not
measured data**) and solved by :func:`dea_opt.solve_path` (warm-started Newton, certified
frame by frame).

Each frame is also compared with the closed form of a rigid ball in a socket that surrounds
the contact (see :func:`ball_in_socket`): it holds exactly while the contact patch stays
inside the socket's rim, which the script checks frame by frame.

Run it with::

    python examples/hip_gait.py --out figures/

(``--coarse``: a 432-spring socket and 21 frames, the tests' setting; ``--method`` to walk
the cycle with ``qp`` or ``nlp``; ``--no-series`` to skip the 101 ParaView frames). It writes,
with :meth:`dea_opt.loadpath.PathResult.write`, ``frames.csv`` (one row per frame),
``series.pvd`` with ``series_frames/frame_NNNN.vtu`` (open the ``.pvd`` in ParaView and press
play), ``exposure.vtu``, ``cycle.png`` (force, peak and mean pressure, contact area over the
cycle), ``exposure.png`` (pressure-time integral and time above 1 MPa) and ``summary.json``;
and ``closed_form.csv`` (each frame against the closed form) into ``--out`` (default
``examples/output/hip_gait/``).

Units: mm, N, MPa, s; exposure in MPa s.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.optimize import brentq

import dea_opt
from dea_opt import formulations
from dea_opt.files import write_atomic
from dea_opt.gait import hip_gait_load, load_hip_gait
from dea_opt.geometry import socket_layer

NAME = "hip_gait"
DEFAULT_OUT = Path(__file__).resolve().parent / "output" / NAME

#: The socket of ``dea-opt demo`` (mm; coverage in degrees).
HIP = {"radius": 25.0, "thickness": 3.0, "coverage": 80.0, "gap": 0.1}
#: Mesh resolution: (default, coarse). The default is the demo's 5400 springs.
MESH = ({"n_rings": 45, "n_sectors": 120}, {"n_rings": 12, "n_sectors": 36})
N_FRAMES = (101, 21)
#: MPa: the stiffness cartilage shows under walking, when the fluid carries much of the
#: load; it keeps the peak strain below the linear law's 30 % (the demo's choice).
H_DEFAULT = 10.0
THRESHOLD = 1.0  # MPa, the pressure the exposure's "time above" counts from


# --- the model --------------------------------------------------------------------------
def hip_problem(
    H: float = H_DEFAULT,
    *,
    radius: float = HIP["radius"],
    thickness: float = HIP["thickness"],
    coverage: float = HIP["coverage"],
    gap: float = HIP["gap"],
    n_rings: int = 45,
    n_sectors: int = 120,
    law: dea_opt.Law | None = None,
) -> dea_opt.ContactProblem:
    """The head in its socket; the load is set frame by frame by :func:`dea_opt.solve_path`.

    The socket opens toward +z around the head's centre at the origin (its pole at
    ``(0, 0, -radius)``), springs on the socket point to the centre; the head may translate,
    not rotate (a frictionless ball carries no moment about its centre).
    """
    layer = socket_layer(
        radius=radius, thickness=thickness, coverage=coverage, n_rings=n_rings, n_sectors=n_sectors, gap=gap
    )
    return dea_opt.ContactProblem(
        layer, law or dea_opt.LinearLaw(H), reference=(0.0, 0.0, 0.0), free=("ux", "uy", "uz")
    )


def gait_loads(n_frames: int = 101) -> pd.DataFrame:
    """The synthetic gait (``time, Fx, Fy, Fz, Mx, My, Mz``): the shipped file for 101
    frames, otherwise the same curve (:func:`dea_opt.gait.hip_gait_load`) resampled."""
    return load_hip_gait() if n_frames == 101 else hip_gait_load(n_frames=n_frames)


# --- the closed form --------------------------------------------------------------------
def ball_in_socket(
    force: float,
    *,
    H: float = H_DEFAULT,
    radius: float = HIP["radius"],
    thickness: float = HIP["thickness"],
    gap: float = HIP["gap"],
) -> dict:
    """A rigid ball pushed by ``force`` (N) into a linear layer on a socket that surrounds it.

    The ball moves by ``d`` along the load; the spring at angle ``theta`` from the load
    direction is compressed by ``d cos(theta) - gap``, so it touches for
    ``cos(theta) > c0 = gap / d`` and carries ``p = H (d cos(theta) - gap) / h``. Summing the
    load components over that cap gives

        F = 2 pi R^2 H / h [d (1 - c0^3) / 3 - gap (1 - c0^2) / 2],

    solved here for ``d``; peak pressure ``H (d - gap) / h`` on the load line, contact area
    ``2 pi R^2 (1 - c0)``. With ``gap = 0`` the whole hemisphere touches and the peak is
    ``3 F / (2 pi R^2)``. Exact for any socket whose rim lies beyond the contact cap.

    Returns
    -------
    dict
        ``approach`` (mm), ``peak_pressure`` (MPa), ``contact_area`` (mm^2),
        ``half_angle`` (deg, of the contact cap about the load line).
    """
    scale = 2.0 * np.pi * radius**2 * H / thickness

    def carried(d):
        c0 = gap / d
        return scale * (d * (1.0 - c0**3) / 3.0 - gap * (1.0 - c0**2) / 2.0)

    if force <= 0:
        return {"approach": 0.0, "peak_pressure": 0.0, "contact_area": 0.0, "half_angle": 0.0}
    if gap == 0:
        d = 3.0 * force / scale
    else:
        # carried(d) rises from 0 at d = gap; bracket the root by doubling.
        hi = 2.0 * gap
        while carried(hi) < force:
            hi *= 2.0
        d = brentq(lambda x: carried(x) - force, gap, hi, xtol=1e-15, rtol=1e-14)
    c0 = gap / d
    return {
        "approach": d,
        "peak_pressure": H * (d - gap) / thickness,
        "contact_area": 2.0 * np.pi * radius**2 * (1.0 - c0),
        "half_angle": float(np.degrees(np.arccos(c0))),
    }


def closed_form_table(result, H: float = H_DEFAULT, coverage: float = HIP["coverage"]) -> pd.DataFrame:
    """Every frame of a hip path (on a :func:`hip_problem` socket) against :func:`ball_in_socket`.

    Columns: ``frame, time, force_N, tilt_deg`` (load angle from the socket axis),
    ``half_angle_deg`` (closed-form contact cap), ``inside_rim`` (``tilt + half_angle <=
    coverage``: the closed-form cap lies inside the rim), ``at_rim`` (the solution touches the
    outermost ring of springs), then ``peak_pressure``, ``contact_area``, ``approach`` for the
    solution and ``cf_...`` for the closed form, and the relative deviations ``dev_peak``,
    ``dev_area``, ``dev_approach``. The closed form holds where ``inside_rim`` and not
    ``at_rim``.
    """
    layer = result.problem.layer
    radius = float(np.linalg.norm(layer.points[0]))
    thickness = float(layer.thickness[0])
    gap = float(layer.gap[0])
    # The outermost ring: the springs farthest from the socket's pole (polar angle from -z).
    polar = np.arccos(np.clip(-layer.points[:, 2] / np.linalg.norm(layer.points, axis=1), -1.0, 1.0))
    rim = polar >= polar.max() - 1e-9
    rows = []
    for k, solution in enumerate(result.solutions):
        load = result.table.loc[k, ["Fx_N", "Fy_N", "Fz_N"]].to_numpy(dtype=float)
        force = float(np.linalg.norm(load))
        direction = load / force
        cf = ball_in_socket(force, H=H, radius=radius, thickness=thickness, gap=gap)
        tilt = float(np.degrees(np.arccos(-direction[2])))
        rows.append(
            {
                "frame": k,
                "time": float(result.times[k]),
                "force_N": force,
                "tilt_deg": tilt,
                "half_angle_deg": cf["half_angle"],
                "inside_rim": tilt + cf["half_angle"] <= coverage,
                "at_rim": bool(solution.in_contact[rim].any()),
                "peak_pressure": solution.peak_pressure,
                "cf_peak_pressure": cf["peak_pressure"],
                "contact_area": solution.contact_area,
                "cf_contact_area": cf["contact_area"],
                "approach": float(solution.u[6:9] @ direction),
                "cf_approach": cf["approach"],
            }
        )
    table = pd.DataFrame(rows)
    for key, column in (("peak", "peak_pressure"), ("area", "contact_area"), ("approach", "approach")):
        table[f"dev_{key}"] = table[column] / table[f"cf_{column}"] - 1.0
    return table


# --- the script -------------------------------------------------------------------------
def run(
    out=DEFAULT_OUT,
    coarse: bool = False,
    H: float = H_DEFAULT,
    method: str = "auto",
    series: bool = True,
    threshold: float = THRESHOLD,
) -> dict:
    """Walk the cycle, compare with the closed form, and write every output into ``out``.

    Returns
    -------
    dict
        ``problem`` (ContactProblem), ``loads`` (DataFrame), ``path``
        (:class:`dea_opt.loadpath.PathResult`), ``summary`` (its :meth:`summary`),
        ``closed_form`` (:func:`closed_form_table`) and ``files`` (name -> path).
    """
    out = Path(out)
    mesh = MESH[1 if coarse else 0]
    problem = hip_problem(H, **mesh)
    loads = gait_loads(N_FRAMES[1 if coarse else 0])
    path = dea_opt.solve_path(problem, loads, method=method, outputs=dea_opt.PathOutputs(threshold=threshold))
    closed = closed_form_table(path, H, HIP["coverage"])
    # solve_path's own writers: the table, the ParaView series, the exposure and both plots.
    formats = ("csv", "json", "vtk", "png") if series else ("csv", "json", "png")
    files = path.write(
        out, formats, extra_summary={"example": "examples/hip_gait.py", "coarse": coarse, "H_MPa": H, **HIP, **mesh}
    )
    files["closed_form"] = write_atomic(
        out / "closed_form.csv", lambda tmp: tmp.write_text(closed.to_csv(index=False), encoding="utf-8")
    )
    return {
        "problem": problem,
        "loads": loads,
        "path": path,
        "summary": path.summary(),
        "closed_form": closed,
        "files": files,
    }


def report(result: dict) -> str:
    """A few lines for the terminal, every number from ``result``."""
    s, table, closed = result["summary"], result["path"].table, result["closed_form"]
    cycle = float(table["time_s"].iloc[-1] - table["time_s"].iloc[0])
    exposure = s["exposure"]
    # Where the closed form holds: its contact cap lies inside the rim, and no spring of the
    # outermost ring (whose centre sits half a ring inside the rim) is touched either.
    inside = closed[closed["inside_rim"] & ~closed["at_rim"]]
    lines = [
        f"{s['frames']} frames, {s['n_springs']} springs, {s['law']}, method {s['method']}: "
        f"{'every frame certified' if s['success'] else 'failed frames ' + str(s['failed_frames'])}",
        f"peak pressure {s['peak_pressure_MPa']:.4g} MPa at {s['peak_time_s']:.3g} s "
        f"({100 * s['peak_time_s'] / cycle:.0f} % of the cycle), under {table['resultant_N'].max():.4g} N",
        f"contact area {table['contact_area_mm2'].min():.4g} to {s['max_contact_area_mm2']:.4g} mm^2; "
        f"largest compressive strain {s['max_compressive_strain']:.3f}",
        f"exposure: up to {exposure['max_pressure_time_integral_MPa_s']:.3g} MPa s, "
        f"{exposure['max_time_above_threshold_s']:.3g} s above {exposure['threshold_MPa']:g} MPa "
        f"({exposure['sites_above_threshold']} springs ever above it)",
        f"solving: {s['solve_time_total_s']:.2f} s, {s['iterations_mean']:.1f} solver iterations a frame",
    ]
    if len(inside):
        lines.append(
            f"closed form (ball in a surrounding socket) at the {len(inside)} frames whose contact stays "
            f"inside the rim: peak within {100 * inside['dev_peak'].abs().max():.2f} %, area within "
            f"{100 * inside['dev_area'].abs().max():.2f} %, approach within "
            f"{100 * inside['dev_approach'].abs().max():.2f} %"
        )
    lines.append(
        f"{len(closed) - len(inside)} frames press the contact against the rim: "
        "there the socket's edge, not the closed form, shapes it"
    )
    return "\n".join(lines)


def parse_args(argv=None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        description=__doc__.split("\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"output directory (default {DEFAULT_OUT})")
    parser.add_argument("--coarse", action="store_true", help="432 springs and 21 frames (the tests use it)")
    parser.add_argument("--H", type=float, default=H_DEFAULT, help="spring modulus in MPa (default 10)")
    parser.add_argument(
        "--method",
        default="auto",
        choices=("auto", *formulations.names()),
        help="solver for every frame (default auto: warm-started Newton)",
    )
    parser.add_argument("--no-series", action="store_true", help="skip the ParaView series (.pvd and .vtu files)")
    return parser.parse_args(argv)


def main(argv=None) -> dict:
    """Command-line entry point; returns what :func:`run` returns."""
    args = parse_args(argv)
    start = time.perf_counter()
    result = run(args.out, coarse=args.coarse, H=args.H, method=args.method, series=not args.no_series)
    print(report(result))
    for name, path in result["files"].items():
        print(f"wrote {name:13s} {path}")
    print(f"{time.perf_counter() - start:.1f} s in all")
    return result


if __name__ == "__main__":
    main()
