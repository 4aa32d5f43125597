"""The TKA through its measured gait (``examples/tka_gait.py``), checked from its files.

Every tenth frame of the fluoroscopic gait (``--coarse``), with the femur's flexion prescribed and,
in a second run, its three rotations: each frame certified and inside validity; the prescribed
coordinates are the model's coordinates OpenSim 4.6 found for the same poses (the ``dm_knee_*``
columns of ``fluoroscopy_poses.csv``); each compartment's force in ``frames.csv`` is the sum of its
springs' forces in that frame's ``.vtu`` (medial where the insert's z > 0), summed here; the
ligament table's strains are its lengths over the slack lengths. Skipped cleanly where the data
are absent.
"""

from __future__ import annotations

import csv
import importlib.util
import json
import sys
import tomllib
from pathlib import Path

import meshio
import numpy as np
import pytest
from conftest import SHARED

pytestmark = pytest.mark.slow

TKA = SHARED / "data" / "tka"
EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "tka_gait.py"


def _example():
    spec = importlib.util.spec_from_file_location("example_tka_gait", EXAMPLE)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def _rows(path) -> list:
    with open(path, newline="") as handle:
        return list(csv.DictReader(line for line in handle if not line.startswith("#")))


@pytest.fixture(scope="module", params=[False, True], ids=["flexion", "rotations"])
def gait(request, tmp_path_factory):
    if not all(
        (TKA / f).is_file() for f in ("DM.osim", "tibial_insert.stl", "femoral_component.stl", "fluoroscopy_poses.csv")
    ):
        pytest.skip(f"the DM knee is not in {TKA}")
    out = tmp_path_factory.mktemp("gait")
    args = ["--coarse", "--out", str(out)] + (["--rotations"] if request.param else [])
    outcome = _example().main(args)
    return request.param, out, outcome


def test_every_frame_is_certified_and_valid(gait):
    _, out, outcome = gait
    assert outcome.success and outcome.valid and outcome.exit_code == 0, outcome.message
    frames = _rows(out / "run" / "frames.csv")
    assert len(frames) == 11 and all(r["success"] == "True" and r["valid"] == "True" for r in frames)
    summary = json.loads((out / "run" / "summary.json").read_text())
    assert summary["certified"] == 11 and set(summary["compartments"]["knee_contact"]) == {"lateral", "medial"}
    assert any("medial" in line for line in outcome.regions) and (out / "compartments.png").is_file()


def test_the_prescribed_rotations_are_the_model_s_coordinates_of_the_fluoroscopic_poses(gait):
    rotations, out, _ = gait
    frames = _rows(out / "run" / "frames.csv")
    fluoroscopy = _rows(TKA / "fluoroscopy_poses.csv")[::10]
    prescribed = (("rx", "knee_flex_r"), ("ry", "knee_add_r"), ("rz", "knee_rot_r"))[: 3 if rotations else 1]
    for row, pose in zip(frames, fluoroscopy):
        assert float(row["time_s"]) == float(pose["time_pct_gait"])
        for dof, name in prescribed:
            assert float(row[f"femur_r.{dof}_rad"]) == pytest.approx(float(pose[f"dm_{name}_rad"]), abs=1e-9)
            assert f"femur_r.reaction_{dof}_Nmm" in row
        if not rotations:
            assert "femur_r.reaction_ry_Nmm" not in row  # adduction and rotation found, not prescribed


def test_each_compartment_is_the_sum_of_its_springs_in_the_frame_s_series(gait):
    """The ``.vtu`` of each frame: springs with their pressure, area, normal and label (medial where the
    insert's own z > 0, the insert placed by its frame in the scenario); the forces summed here."""
    _, out, _ = gait
    run = out / "run"
    frames = _rows(run / "frames.csv")
    series = (run / "knee_contact.pvd").read_text()
    scenario = tomllib.loads((out / "dm_gait.toml").read_text())
    insert = np.array(next(f["pose"] for f in scenario["frames"] if f["name"] == "tibia_implant"))
    both = 0
    for k, row in enumerate(frames):
        assert f'file="knee_contact_frames/frame_{k:04d}.vtu"' in series
        mesh = meshio.read(run / "knee_contact_frames" / f"frame_{k:04d}.vtu")
        data = {name: values[0] for name, values in mesh.cell_data.items()}
        cells = mesh.cells[0].data
        centres = mesh.points[cells].mean(axis=1)
        own_z = ((centres - insert[:3, 3]) @ insert[:3, :3])[:, 2]  # the insert's frame: z medial
        push = (data["pressure"] * data["area"])[:, None] * data["normal"]
        medial = own_z > 0
        loaded = data["pressure"] > 0
        # each loaded side carries one label, not the other's (a side may lift off in a frame whose
        # rotations are all prescribed: then it has no loaded spring to name)
        labels = [set(data["label"][side & loaded].tolist()) for side in (medial, ~medial)]
        assert all(len(s) <= 1 for s in labels) and not (labels[0] & labels[1]), labels
        both += bool(labels[0] and labels[1])
        for name, side in (("medial", medial), ("lateral", ~medial)):
            assert float(row[f"knee_contact.{name}.force_N"]) == pytest.approx(
                np.linalg.norm(push[side].sum(axis=0)), rel=1e-6
            )
        assert float(row["knee_contact.force_N"]) == pytest.approx(np.linalg.norm(push.sum(axis=0)), rel=1e-9)
    assert both >= len(frames) // 2  # both condyles in contact through most of the gait


def test_the_ligament_table_has_every_bundle_every_frame(gait):
    _, out, _ = gait
    rows = _rows(out / "run" / "ligaments.csv")
    assert len(rows) == 11 * 89
    slack = {b["name"]: b["slack_length"] for b in tomllib.loads((out / "dm_gait.toml").read_text())["ligaments"]}
    for row in rows[::37]:
        assert float(row["strain"]) == pytest.approx(float(row["length_mm"]) / slack[row["name"]] - 1.0, abs=1e-12)
        assert float(row["force_N"]) >= 0.0
    assert max(float(r["force_N"]) for r in rows) > 1.0  # the bundles take part
