"""Record what OpenSim 4.6 itself computes on the Grand Challenge DM model: the reference that
tests/opensim/test_opensim_reference.py checks dea_opt.opensim against.

Run it in a venv of its own (the ``opensim`` wheel brings its own CasADi, which cannot share a
process with dea-opt's), from the repository root::

    python3 -m venv /path/opensim46 && /path/opensim46/bin/pip install opensim==4.6 numpy
    /path/opensim46/bin/python tests/data/opensim/make_reference.py [../shared/data/tka]

It writes ``tests/data/opensim/dm_reference.json`` beside itself. Why here and not under
benchmarks/: the file is the provenance of test data, kept next to the data it made.

What it does:

1. reads ``DM.osim`` and removes its two ``Smith2018ArticularContactForce`` and three
   ``Smith2018ContactMesh`` elements, which plain OpenSim 4.6 lacks (nothing else is removed:
   the model as the data's README describes it); a second copy also has every ``PathWrap``
   removed, so the ligaments are the polylines through their path points ("wraps stripped");
2. loads both with OpenSim 4.6 and sets several poses: the model's defaults, fluoroscopy frames
   0, 15, 50 and 70 (their ``dm_knee_*`` columns, the DM.osim knee_r coordinates), and two poses
   that move every coordinate of the pelvis, the right hip, knee, patella and ankle at once;
3. records, per pose: every coordinate's value, each body's pose in ground (4x4, mm) and, for
   every Blankevoort1991Ligament of the wraps-stripped model, its length (mm), strain and total
   force (N, speeds zero); and once: each coordinate's motion type and, with the wrap objects
   kept, every bundle's length at the default pose;
4. does the same for the small model of tests/osim_models.py (a CustomJoint of axes off x, y, z,
   a slope and an intercept, a constant, a MultiplierFunction, axes left to their defaults,
   offset frames on both sides; a bundle with a via point) at its defaults and three poses:
   ``toy`` in the JSON.

The numbers are derived from DM.osim (Apache License 2.0, opensim-jam-org/jam-resources): the
JSON says so, and tests/data/opensim/LICENSE is that licence.
"""

from __future__ import annotations

import csv
import hashlib
import json
import sys
import tempfile
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import opensim as osim

HERE = Path(__file__).resolve().parent
DATA = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE.parents[2] / ".." / "shared" / "data" / "tka"
FRAMES = (0, 15, 50, 70)
STRIPPED = ("Smith2018ArticularContactForce", "Smith2018ContactMesh")
#: Two poses that move the pelvis, right hip, knee, patella and ankle together (OpenSim units).
MOVED = {
    "moved_1": {
        "pelvis_tilt": 0.1,
        "pelvis_list": -0.05,
        "pelvis_rot": 0.2,
        "pelvis_tx": 0.3,
        "pelvis_ty": 0.9,
        "pelvis_tz": -0.1,
        "hip_flex_r": 0.4,
        "hip_add_r": -0.1,
        "hip_rot_r": 0.15,
        "knee_flex_r": 0.6,
        "knee_add_r": -0.05,
        "knee_rot_r": 0.08,
        "knee_tx_r": -0.003,
        "knee_ty_r": 0.012,
        "knee_tz_r": -0.009,
        "pf_flex_r": 0.5,
        "pf_rot_r": 0.02,
        "pf_tilt_r": -0.03,
        "pf_tx_r": 0.05,
        "pf_ty_r": 0.01,
        "pf_tz_r": 0.002,
        "ankle_flex_r": 0.2,
    },
    "moved_2": {
        "pelvis_tilt": -0.2,
        "pelvis_list": 0.1,
        "pelvis_rot": -0.3,
        "pelvis_tx": -0.5,
        "pelvis_ty": 1.0,
        "pelvis_tz": 0.2,
        "hip_flex_r": -0.2,
        "hip_add_r": 0.2,
        "hip_rot_r": -0.3,
        "knee_flex_r": 1.2,
        "knee_add_r": 0.04,
        "knee_rot_r": -0.15,
        "knee_tx_r": 0.002,
        "knee_ty_r": 0.016,
        "knee_tz_r": -0.008,
        "pf_flex_r": 1.0,
        "pf_rot_r": -0.05,
        "pf_tilt_r": 0.04,
        "pf_tx_r": 0.045,
        "pf_ty_r": -0.005,
        "pf_tz_r": -0.003,
        "ankle_flex_r": -0.3,
    },
}


def stripped_copy(source: Path, folder: Path, without_wraps: bool) -> Path:
    tree = ET.parse(source)
    for parent in tree.iter():
        for child in list(parent):
            if child.tag in STRIPPED:
                parent.remove(child)
            elif without_wraps and child.tag == "PathWrap":
                parent.remove(child)
    out = folder / ("DM_no_wraps.osim" if without_wraps else "DM_stripped.osim")
    tree.write(out, encoding="UTF-8", xml_declaration=True)
    return out


def fluoroscopy_poses() -> dict:
    with open(DATA / "fluoroscopy_poses.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    names = ("flex", "add", "rot", "tx", "ty", "tz")
    units = ("rad", "rad", "rad", "m", "m", "m")
    poses = {}
    for k in FRAMES:
        row = rows[k]
        poses[f"fluoroscopy_{k}"] = {f"knee_{n}_r": float(row[f"dm_knee_{n}_r_{u}"]) for n, u in zip(names, units)}
    return poses


def set_pose(model, state, values: dict) -> None:
    coordinates = model.getCoordinateSet()
    for i in range(coordinates.getSize()):
        c = coordinates.get(i)
        c.setValue(state, c.getDefaultValue(), False)
    for name, value in values.items():
        coordinates.get(name).setValue(state, value, False)
    model.realizeVelocity(state)


def transform_mm(T) -> list:
    R, p = T.R(), T.p()
    return [[R.get(i, 0), R.get(i, 1), R.get(i, 2), 1000.0 * p.get(i)] for i in range(3)] + [[0.0, 0.0, 0.0, 1.0]]


def record(model, state, name: str, values: dict) -> dict:
    set_pose(model, state, values)
    coordinates = model.getCoordinateSet()
    bodies = model.getBodySet()
    forces = model.getForceSet()
    ligaments = {}
    for i in range(forces.getSize()):
        lig = osim.Blankevoort1991Ligament.safeDownCast(forces.get(i))
        if lig is not None:
            ligaments[lig.getName()] = [1000.0 * lig.getLength(state), lig.getStrain(state), lig.getTotalForce(state)]
    return {
        "name": name,
        "coordinates": {
            coordinates.get(i).getName(): coordinates.get(i).getValue(state) for i in range(coordinates.getSize())
        },
        "bodies": {
            bodies.get(i).getName(): transform_mm(bodies.get(i).getTransformInGround(state))
            for i in range(bodies.getSize())
        },
        "ligaments": ligaments,
    }


def toy(folder: Path) -> dict:
    sys.path.insert(0, str(HERE.parents[1]))
    from osim_models import ligament, write_model

    via = '<PathPoint name="v"><socket_parent_frame>/bodyset/b</socket_parent_frame><location>0.1 0 0</location></PathPoint>'
    path = write_model(folder, forces=ligament(via=via, slack="<slack_length>0.3</slack_length>"))
    model = osim.Model(str(path))
    state = model.initSystem()
    rng = np.random.default_rng(2024)
    names = [model.getCoordinateSet().get(i).getName() for i in range(model.getCoordinateSet().getSize())]
    poses = {"default": {}}
    for k in range(3):
        poses[f"random_{k}"] = {n: float(rng.uniform(-1.0, 1.0)) for n in names}
    coordinates = model.getCoordinateSet()
    motion = {}
    for i in range(coordinates.getSize()):
        c = coordinates.get(i)
        motion[c.getName()] = {1: "rotational", 2: "translational", 3: "coupled"}.get(
            int(c.getMotionType()), "undefined"
        )
    return {
        "model": "tests/osim_models.py: write_model(forces=ligament(via=..., slack_length 0.3 m))",
        "motion_types": motion,
        "poses": [record(model, state, name, values) for name, values in poses.items()],
    }


def main() -> None:
    source = DATA / "DM.osim"
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        model = osim.Model(str(stripped_copy(source, folder, without_wraps=True)))
        state = model.initSystem()
        poses = {"default": {}, **fluoroscopy_poses(), **MOVED}
        records = [record(model, state, name, values) for name, values in poses.items()]
        coordinates = model.getCoordinateSet()
        motion = {}
        for i in range(coordinates.getSize()):
            c = coordinates.get(i)
            motion[c.getName()] = {1: "rotational", 2: "translational", 3: "coupled"}.get(
                int(c.getMotionType()), "undefined"
            )
        wrapped_model = osim.Model(str(stripped_copy(source, folder, without_wraps=False)))
        wrapped_state = wrapped_model.initSystem()
        wrapped = record(wrapped_model, wrapped_state, "default, wrap objects kept", {})["ligaments"]
        small = toy(folder)
    out = {
        "script": "tests/data/opensim/make_reference.py",
        "opensim": osim.GetVersionAndDate(),
        "model": "DM.osim",
        "model_sha256": hashlib.sha256(source.read_bytes()).hexdigest(),
        "licence": (
            "Apache License 2.0 (tests/data/opensim/LICENSE). Derived from DM.osim of opensim-jam-org/jam-resources "
            "(models/knee_tka/grand_challenge/DM, commit 73306a0f8dce2e31fea2095a27dd449bcd14d9b7): these are "
            "numbers OpenSim 4.6 computed on that model with its Smith2018 contact elements (and, for 'poses', its "
            "PathWraps) removed; no part of the model file is included."
        ),
        "units": "mm for translations and lengths, N for forces, rad and m for coordinates",
        "stripped": list(STRIPPED) + ["PathWrap (poses only)"],
        "motion_types": motion,
        "poses": records,
        "wrapped_length_at_default_mm": {name: values[0] for name, values in wrapped.items()},
        "toy": small,
    }
    target = HERE / "dm_reference.json"
    target.write_text(json.dumps(out, indent=1) + "\n", encoding="utf-8")
    print(
        f"wrote {target}: {len(records)} poses, {len(records[0]['ligaments'])} ligaments, {len(records[0]['bodies'])} bodies"
    )
    np.set_printoptions(precision=4)


if __name__ == "__main__":
    main()
