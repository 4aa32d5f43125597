"""Lenhart 2015's native-knee ligament bundles placed on the MRI knee of ``../shared/data/knee``.

Writes ``bundles.csv`` (one row per femur-tibia Blankevoort1991Ligament bundle of the model: its
insertions in the knee's frame, its stiffness, transition strain, and its strain at the model's
default pose) and ``registration.json`` (the similarity transform from the model's knee frame to the
MRI knee's, and how well the two tibial cartilages then agree), from:

- ``lenhart2015.osim`` and ``Geometry/lenhart2015-R-tibia-cartilage.stl`` of the OpenSim-JAM
  repository ``opensim-jam-org/jam-resources`` (``models/knee_healthy/lenhart2015/``, commit
  73306a0f8dce2e31fea2095a27dd449bcd14d9b7), Apache License 2.0: the model of Lenhart, Kaiser,
  Smith and Thelen, "Prediction and validation of load-dependent behavior of the tibiofemoral and
  patellofemoral joints during movement", Ann Biomed Eng 43:2675-2685 (2015);
- the MRI knee's tibial cartilages (``../shared/data/knee``, MIT, see its README).

The model's femur and tibia frames coincide at its default pose (``knee_r``'s coordinates all 0:
full extension), so both bones' insertions are given in one frame: x anterior, y superior, z
lateral (a right knee). The MRI knee's frame is x medial, y posterior, z superior; the model's
tibial cartilage is turned onto it by those axes, then fitted to the MRI knee's tibial cartilages
by iterative closest points with a uniform scale (Umeyama's similarity), and the same transform
carries every insertion. The MRI knee is taken at the model's default pose (extension): each
bundle keeps the strain the model gives it there (its straight line's), so ``reference_strain``
replaces the slack length.

Run from the repository's top (the two model files fetched from the repository above)::

    python tests/data/lenhart/make_knee_bundles.py lenhart2015.osim lenhart2015-R-tibia-cartilage.stl

Modified from the source (Apache-2.0 section 4(b)): the bundles' insertions are transformed into
another frame, their slack lengths replaced by the strain at the model's default pose; nothing of
the source files is included unchanged.
"""

from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

import numpy as np
import trimesh
from scipy.spatial import cKDTree

HERE = Path(__file__).resolve().parent
KNEE = HERE.parents[3] / "shared" / "data" / "knee"
#: The model's axes (anterior, superior, lateral) onto the MRI knee's (medial, posterior, superior).
AXES = np.array([[0.0, 0.0, -1.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def similarity(source, target):
    """Umeyama's least-squares ``(s, R, t)`` with ``target ~ s R source + t``."""
    mu_s, mu_t = source.mean(axis=0), target.mean(axis=0)
    a, b = source - mu_s, target - mu_t
    U, S, Vt = np.linalg.svd(b.T @ a / len(a))
    D = np.eye(3)
    D[2, 2] = np.sign(np.linalg.det(U @ Vt))
    R = U @ D @ Vt
    s = float(np.trace(np.diag(S) @ D) / (a * a).sum(axis=1).mean())
    return s, R, mu_t - s * R @ mu_s


def main(osim, cartilage) -> None:
    sys.path.insert(0, str(HERE.parents[2]))
    from dea_opt.opensim import read_model

    model = read_model(osim)
    source = trimesh.load(cartilage).sample(20000, seed=1) * 1000.0 @ AXES.T  # mm, the MRI knee's axes
    target = np.vstack(
        [
            trimesh.load(KNEE / f).sample(20000, seed=2)
            for f in ("medial_tibial_cartilage.stl", "lateral_tibial_cartilage.stl")
        ]
    )
    tree = cKDTree(target)
    s = np.sqrt(((target - target.mean(0)) ** 2).sum(1).mean() / ((source - source.mean(0)) ** 2).sum(1).mean())
    R, t = np.eye(3), target.mean(0) - s * source.mean(0)
    for _ in range(200):
        moved = s * source @ R.T + t
        distance, index = tree.query(moved)
        s, R, t = similarity(source, target[index])
    distance = tree.query(s * source @ R.T + t)[0]
    place = lambda p: s * (R @ (AXES @ p)) + t  # noqa: E731
    state = model.ligament_state()
    names = list(model.ligaments)
    rows = []
    for name, lig in model.ligaments.items():
        ends = lig.points[0], lig.points[-1]
        if {p.body for p in ends} != {"femur_distal_r", "tibia_proximal_r"} or len(lig.points) != 2:
            continue
        i = names.index(name)
        row = {"name": name}
        for k, p in zip("12", ends):
            row[f"body{k}"] = "femur" if p.body == "femur_distal_r" else "tibia"
            x = place(model.frame_in_body(p.frame)[:3, :3] @ p.location + model.frame_in_body(p.frame)[:3, 3])
            row.update({f"p{k}_{a}_mm": repr(float(v)) for a, v in zip("xyz", x)})
        row["stiffness_N_per_strain"] = repr(float(lig.stiffness))
        row["transition_strain"] = repr(float(lig.transition_strain))
        row["reference_strain"] = repr(float(state.strain[i]))
        row["wraps_in_opensim"] = " ".join(lig.wraps)
        rows.append(row)
    with open(HERE / "bundles.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    report = {
        "source": "opensim-jam-org/jam-resources@73306a0f8dce2e31fea2095a27dd449bcd14d9b7 models/knee_healthy/lenhart2015",
        "licence": "Apache-2.0 (modified: insertions transformed, slack lengths replaced by the default pose's strain)",
        "axes_model_to_knee": AXES.tolist(),
        "scale": s,
        "rotation": R.tolist(),
        "translation_mm": t.tolist(),
        "closest_distance_mm": {
            "rms": float(np.sqrt((distance**2).mean())),
            "median": float(np.median(distance)),
            "max": float(distance.max()),
        },
        "bundles": len(rows),
    }
    (HERE / "registration.json").write_text(json.dumps(report, indent=1) + "\n")
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main(*sys.argv[1:3])
