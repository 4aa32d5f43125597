"""A total knee replacement as one joint: femur and patella free on a fixed tibia, three contact layers, 148 bundles.
=====================================================================================================================

The public OpenSim-JAM Grand Challenge "DM" knee in ``../shared/data/tka`` (Apache 2.0; see its
README): the tibial insert, the femoral component and the patellar button, each in its implant
frame (x posterior, y superior, z medial: y is the compression axis), and the model's
Blankevoort1991Ligament bundles (``ligaments.csv``). The insert frame is the world; the femoral
component sits on it at DM.osim's default pose, the button on the component at DM.osim's default
patellar pose (``frames.json``). Contacts: the insert's medial and lateral halves on the femoral
component (tibiofemoral, medial and lateral), the button on the femoral component
(patellofemoral), springs cast from the insert and the button (JAM's casting meshes), the lumped
linear law of ``material.json`` (H = 214 MPa over 5 + 5 mm). Bundles: every femur-tibia,
femur-patella and patella-tibia bundle as the straight line between its insertions (the ITB, to the
pelvis, is left out; **wrapping is not modelled**: the 83 bundles OpenSim wraps read shorter here,
slacker, than in OpenSim), with DM.osim's stiffness, slack length and transition strain.

Loads: a compressive force on the femur along -y (the body weight's share, ``--load``, 700 N) at
the femoral component's frame origin, its flexion (``rz``, about the medial axis) held at the
default pose, its other five dofs found; a quadriceps pull on the patella (``--quadriceps``, 300 N,
superior and slightly anterior), all six of its dofs found. Finite kinematics: exact poses, the
springs cast again at the solved pose. It writes into ``--out`` (default
``examples/output/tka_joint/``) each layer's ``.vtu`` and ``.json``, ``ligaments.csv`` (one row per
bundle: ``name, body1, body2, force_N, strain, length_mm, slack_length_mm``), ``joint.json``
(the summary: bodies, layers, bundles, certificate, validity), each layer's pressure map
(``<layer>.png``) and ``ligaments.png`` (the bundles that carry most, in N). The solve takes
seconds: the example has no coarse setting, and the gallery runs it as it stands.

Run it with::

    python examples/tka_joint.py --out figures/tka

Units: mm, N, MPa, rad.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import warnings
from pathlib import Path

import numpy as np

import dea_opt as d
from dea_opt.mesh import cast_springs, load_mesh

NAME = "tka_joint"
DEFAULT_OUT = Path(__file__).resolve().parent / "output" / NAME
DEFAULT_TKA = Path(__file__).resolve().parents[2] / "shared" / "data" / "tka"
BODIES = {"tibia_r": "tibia", "femur_r": "femur", "patella_r": "patella"}
QUADRICEPS_DIRECTION = (-0.15, 1.0, 0.0)  # superior, slightly anterior (x is posterior)


def _half(mesh, medial: bool):
    """The faces of ``mesh`` on one side of z = 0 (z medial), as a mesh of their own."""
    keep = (mesh.triangles_center[:, 2] > 0) == medial
    return mesh.submesh([np.flatnonzero(keep)], append=True)


def build(tka: Path = DEFAULT_TKA, load: float = 700.0, quadriceps: float = 300.0, kinematics: str = "finite"):
    """The TKA joint (``dea_opt.Joint``) and the casts of its three layers."""
    frames = json.loads((tka / "frames.json").read_text())
    T_femur = np.array(frames["T_insert_femoral_component_at_dm_defaults_mm"])
    T_patella = T_femur @ np.array(frames["T_femoral_component_patellar_button_at_dm_default_pf_mm"])
    place = {"tibia_r": np.eye(4), "femur_r": T_femur, "patella_r": T_patella}
    insert = load_mesh(tka / "tibial_insert.stl")
    femur = load_mesh(tka / "femoral_component.stl").copy()
    femur.apply_transform(T_femur)
    button = load_mesh(tka / "patellar_button.stl").copy()
    button.apply_transform(T_patella)
    H = json.loads((tka / "material.json").read_text())["tibiofemoral"]["H_MPa"]
    law = d.LinearLaw(H)
    casts = {
        "medial": cast_springs(_half(insert, True), femur, thickness1=5.0, thickness2=5.0, max_gap=3.0),
        "lateral": cast_springs(_half(insert, False), femur, thickness1=5.0, thickness2=5.0, max_gap=3.0),
        "patellofemoral": cast_springs(button, femur, thickness1=5.0, thickness2=5.0, max_gap=5.0),
    }
    finite = kinematics == "finite"
    contacts = [
        d.Contact(casts[n].layer, law, body1=b1, body2="femur", name=n, targets=casts[n] if finite else None)
        for n, b1 in (("medial", "tibia"), ("lateral", "tibia"), ("patellofemoral", "patella"))
    ]
    ligaments = []
    with open(tka / "ligaments.csv", newline="") as handle:
        for row in csv.DictReader(handle):
            if row["body1"] not in BODIES or row["body2"] not in BODIES:
                continue  # the ITB runs to the pelvis
            ends = []
            for k in "12":
                p = np.array([float(row[f"p{k}_implant_{a}_mm"]) for a in "xyz"])
                T = place[row[f"body{k}"]]
                ends.append(T[:3, :3] @ p + T[:3, 3])
            ligaments.append(
                d.Ligament(
                    BODIES[row["body1"]],
                    ends[0],
                    BODIES[row["body2"]],
                    ends[1],
                    stiffness=float(row["linear_stiffness_N_per_strain"]),
                    slack_length=float(row["slack_length_mm"]),
                    transition_strain=float(row["transition_strain"]),
                    name=row["name"],
                )
            )
    pull = np.asarray(QUADRICEPS_DIRECTION) / np.linalg.norm(QUADRICEPS_DIRECTION)
    bodies = {
        "tibia": d.Body(free=()),
        "femur": d.Body(reference=T_femur[:3, 3], free=("ux", "uy", "uz", "rx", "ry"), force=(0.0, -load, 0.0)),
        "patella": d.Body(reference=T_patella[:3, 3], force=quadriceps * pull),
    }
    return d.Joint(bodies, contacts, ligaments, kinematics=kinematics), casts


def write_ligaments(solution, path: Path) -> Path:
    """The ligament table: one row per bundle, units in the column names."""
    rows = solution.ligaments.rows()
    with open(path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    return path


def plot_ligaments(solution, path: Path, count: int = 20) -> Path:
    """A bar chart of the ``count`` bundles that carry most (force in N, strain beside each)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    lig = solution.ligaments
    top = np.argsort(lig.force)[::-1][:count][::-1]
    figure = Figure(figsize=(6.4, 0.22 * len(top) + 1.2))
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    axes.barh([lig.names[i] for i in top], lig.force[top], color="tab:blue")
    for row, i in enumerate(top):
        axes.annotate(
            f"{100 * lig.strain[i]:.1f} %",
            (lig.force[i], row),
            xytext=(3, 0),
            textcoords="offset points",
            va="center",
            fontsize=7,
        )
    axes.set_xlim(0.0, 1.15 * float(lig.force[top].max()))  # room for the strain labels
    axes.set_xlabel("force (N); strain beside each bar")
    axes.set_title(f"the {len(top)} bundles that carry most, of {len(lig.force)}")
    axes.tick_params(axis="y", labelsize=7)
    figure.tight_layout()
    figure.savefig(path, dpi=120)
    return path


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("tka", nargs="?", default=str(DEFAULT_TKA), help="the folder of the TKA data")
    parser.add_argument("--out", default=str(DEFAULT_OUT))
    parser.add_argument("--load", type=float, default=700.0, help="N on the femur, along -y")
    parser.add_argument("--quadriceps", type=float, default=300.0, help="N on the patella")
    args = parser.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    joint, _ = build(Path(args.tka), args.load, args.quadriceps)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)  # the report below says it
        solution = d.solve(joint)
    for contact, layer in zip(joint.contacts, solution.contacts):
        layer.to_vtk(out / f"{contact.name}.vtu")
        layer.to_json(out / f"{contact.name}.json")
        layer.plot_pressure(out / f"{contact.name}.png", title=f"{contact.name}: peak {layer.peak_pressure:.2f} MPa")
    write_ligaments(solution, out / "ligaments.csv")
    plot_ligaments(solution, out / "ligaments.png")
    (out / "joint.json").write_text(json.dumps(solution.summary(), indent=1, default=str))
    print(f"{solution.status} in {solution.iterations} steps; validity: {solution.validity.summary()}")
    for name, body in solution.bodies.items():
        print(f"  {name}: u = {np.round(body.u, 4).tolist()}")
    for contact, layer in zip(joint.contacts, solution.contacts):
        print(
            f"  {contact.name}: force {np.round(layer.contact_force, 1).tolist()} N, peak {layer.peak_pressure:.2f} MPa"
        )
    top = np.argsort(solution.ligaments.force)[::-1][:5]
    print(
        "  strongest bundles: "
        + ", ".join(f"{solution.ligaments.names[i]} {solution.ligaments.force[i]:.1f} N" for i in top)
    )
    return solution


if __name__ == "__main__":
    sys.exit(0 if main().success else 1)
