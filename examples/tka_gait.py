"""A total knee replacement through its measured gait: flexion from fluoroscopy, the rest of the femur found.
===========================================================================================================

The Grand Challenge DM knee of ``../shared/data/tka`` (Apache 2.0; see its README), read from its
OpenSim model (``DM.osim``, by :func:`dea_opt.opensim.read_model`) and written as a joint scenario
by the writer of ``dea-opt import-osim``: the tibia fixed (``--fixed tibia_r``), the femur moving by
the model's own ``knee_r`` coordinates (``knee_flex_r``, ``knee_add_r``, ``knee_rot_r``,
``knee_tx_r``, ``knee_ty_r``, ``knee_tz_r``), the tibial insert on the femoral component
(``knee_contact``, JAM's lumped linear law, H = 214 MPa over 5 + 5 mm; its springs cast from the
insert, split at the insert's z = 0: z > 0 is medial) and the model's 88 femur-tibia bundles and its
iliotibial band as straight lines with their stiffness and slack length.

The gait, 101 frames: ``[load_path] poses`` is the fluoroscopic pose of the femoral component on the
insert per frame (``fluoroscopy_poses.csv``); the femur's flexion (``knee_flex_r``) is prescribed
from it, found as the model's coordinates of each pose, and its five other coordinates are free
(with ``--rotations``, all three rotations are prescribed and the translations free). The load is a
compressive force along the insert's long axis (-y), at the femoral component's origin, fixed in
space: a **synthetic** double-hump profile shaped like the knee contact forces measured with
instrumented implants in walking (Kutzner et al., J Biomech 2010: peaks near 2.6 and 2.4 body
weights at 15 and 47 % of the cycle, about 0.3 in swing), scaled to ``--body-weight`` (700 N). It is
not this subject's measured load.

**Left out, and why.** The patella: the fluoroscopy gives no patellar pose, and DM's patellar
coordinates are not measured, so the patellofemoral pair and the 60 patellar bundles (patellar
tendon, medial and lateral patellofemoral ligaments) are left out (``--leave-out patella_r``).
Wrapping: the 83 bundles OpenSim wraps are straight lines here, shorter (slacker) than OpenSim's.
Muscles, friction and inertia: none; each frame is a quasi-static equilibrium. The ITB runs to the
pelvis, held where the model's default pose puts it.

It runs ``dea-opt run`` on the scenario it writes (finite kinematics; each frame starts from the
previous answer, its springs carried from frame to frame and cast again at each answer) and writes
into ``--out`` (default ``examples/output/tka_gait/``): the scenario, the run's folder ``run/``
(``frames.csv``: per frame the femur's coordinates, the reaction at its prescribed flexion, the
contact's and each compartment's force, share, peak pressure and area; ``ligaments.csv``: every
bundle's force, strain and length per frame; ``knee_contact.pvd`` with one ``.vtu`` per frame;
``summary.json``; the run's log and manifest) and two figures: the medial and lateral forces over
the cycle and the bundles that carry most. ``--coarse`` solves every tenth frame (the gallery's
build).

Run it with::

    python examples/tka_gait.py --out figures/tka_gait
    python examples/tka_gait.py --rotations        # flexion, adduction and rotation prescribed

Units: mm, N, MPa, rad; time in per cent of the gait cycle.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

NAME = "tka_gait"
DEFAULT_OUT = Path(__file__).resolve().parent / "output" / NAME
DEFAULT_TKA = Path(__file__).resolve().parents[2] / "shared" / "data" / "tka"
#: Knee contact force in body weights over the gait cycle (per cent): a synthetic double hump shaped
#: like Kutzner et al. (2010), not measured data.
PROFILE = (
    (0, 0.4),
    (5, 1.2),
    (15, 2.6),
    (25, 1.9),
    (35, 1.7),
    (47, 2.4),
    (55, 1.6),
    (62, 0.6),
    (75, 0.3),
    (90, 0.3),
    (100, 0.4),
)
ROTATIONS = ("knee_flex_r", "knee_add_r", "knee_rot_r")


def write_scenario(
    folder: Path, tka: Path = DEFAULT_TKA, body_weight: float = 700.0, rotations: bool = False, every: int = 1
) -> Path:
    """Write the gait's scenario (and its load table) into ``folder``; return the scenario's path."""
    from dea_opt.opensim import read_model
    from dea_opt.opensim.export import write_scenario as write

    folder.mkdir(parents=True, exist_ok=True)
    model = read_model(tka / "DM.osim")
    scenario = folder / "dm_gait.toml"
    write(
        model,
        scenario,
        meshes={"tibia_implant": tka / "tibial_insert.stl", "femur_implant": tka / "femoral_component.stl"},
        fixed=("tibia_r",),
        leave_out=("patella_r",),
        free={"femur_r": "all"},
        regions={"knee_contact": {"split": "z", "at": 0.0, "names": ["lateral", "medial"]}},
    )
    poses = model.poses()
    insert = poses["tibia_r"] @ model.frame_in_body("/bodyset/tibia_r/tibia_implant")
    component = poses["femur_r"] @ model.frame_in_body("/bodyset/femur_r/femur_implant")
    down = -insert[:3, 1]  # the insert's long axis: y is superior
    rows = list(csv.DictReader(open(tka / "fluoroscopy_poses.csv", newline="")))[::every]
    table = folder / "fluoroscopy.csv"  # the frames solved (every one, or every tenth)
    with open(table, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    percent = np.array([float(r["time_pct_gait"]) for r in rows])
    magnitude = body_weight * np.interp(percent, *zip(*PROFILE))
    with open(folder / "load.csv", "w", newline="") as handle:
        handle.write("# SYNTHETIC knee compression (a double hump shaped like Kutzner et al. 2010), N, ground frame\n")
        handle.write("time,femur_r.Fx,femur_r.Fy,femur_r.Fz\n")
        for t, g in zip(percent, magnitude):
            handle.write(",".join(repr(float(v)) for v in (t, *(g * down))) + "\n")
    text = scenario.read_text().replace(
        'name = "femur_r"\n', f'name = "femur_r"\npoint = [{", ".join(repr(float(v)) for v in component[:3, 3])}]\n', 1
    )
    # JAM's window casts only the overlapping triangles: 2 mm of gap lets the springs close as the femur moves
    text = text.replace("max_gap = 0.0\n", "max_gap = 2.0\n", 1)
    prescribe = ROTATIONS if rotations else ROTATIONS[:1]
    text += (
        "\n[load_path]\n"
        'file = "load.csv"\n'
        f'poses = "{table.name}"\n'
        'moving = "femur_implant"\n'
        'reference = "tibia_implant"\n'
        f"prescribe = [{', '.join(repr(p).replace(chr(39), chr(34)) for p in prescribe)}]\n"
        "\n[output]\n"
        'directory = "run"\n'
        'formats = ["csv", "json", "vtk", "html"]\n'
    )
    scenario.write_text(text)
    return scenario


def plot_compartments(run: Path, path: Path) -> Path:
    """The medial and lateral compartments' forces over the cycle (N), with the total."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    rows = list(csv.DictReader(open(run / "frames.csv", newline="")))
    t = [float(r["time_s"]) for r in rows]
    figure = Figure(figsize=(6.4, 3.6))
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    for key, label in (
        ("knee_contact.force_N", "total"),
        ("knee_contact.medial.force_N", "medial"),
        ("knee_contact.lateral.force_N", "lateral"),
    ):
        axes.plot(t, [float(r[key]) for r in rows], label=label)
    axes.set_xlabel("gait cycle (%)")
    axes.set_ylabel("contact force (N)")
    axes.legend()
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    return path


def plot_ligaments(run: Path, path: Path, count: int = 8) -> Path:
    """The ``count`` bundles with the largest force over the cycle (N)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    rows = list(csv.DictReader(open(run / "ligaments.csv", newline="")))
    series: dict = {}
    for r in rows:
        series.setdefault(r["name"], []).append((float(r["time_s"]), float(r["force_N"])))
    top = sorted(series, key=lambda n: -max(f for _, f in series[n]))[:count]
    figure = Figure(figsize=(6.4, 3.6))
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    for name in top:
        t, f = zip(*series[name])
        axes.plot(t, f, label=name)
    axes.set_xlabel("gait cycle (%)")
    axes.set_ylabel("bundle force (N)")
    axes.legend(fontsize=7, ncol=2)
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    return path


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("tka", nargs="?", default=str(DEFAULT_TKA), help="the folder of the TKA data")
    parser.add_argument("--out", default=str(DEFAULT_OUT))
    parser.add_argument("--body-weight", type=float, default=700.0, help="N: the load profile's scale")
    parser.add_argument("--rotations", action="store_true", help="prescribe all three rotations, not flexion alone")
    parser.add_argument("--coarse", action="store_true", help="every tenth frame (11 of 101)")
    args = parser.parse_args(argv)
    from dea_opt.run.runner import run_scenario
    from dea_opt.scenario import load_scenario

    out = Path(args.out)
    scenario = write_scenario(out, Path(args.tka), args.body_weight, args.rotations, 10 if args.coarse else 1)
    outcome = run_scenario(load_scenario(scenario), force=True)
    plot_compartments(outcome.folder, out / "compartments.png")
    plot_ligaments(outcome.folder, out / "ligaments.png")
    print(outcome.message)
    for line in (*outcome.regions, *outcome.validity):
        print(f"  {line}")
    return outcome


if __name__ == "__main__":
    sys.exit(main().exit_code)
