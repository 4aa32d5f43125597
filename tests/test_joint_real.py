"""Real joints: the pymskt knee held by published bundles with six free dofs, and the three-body TKA.

The knee's cartilage (``../shared/data/knee``) carries no bones: its bundles are the femur-tibia
bundles of OpenSim-JAM's Grand Challenge DM model (``../shared/data/tka/ligaments.csv``, from
DM.osim, Apache 2.0: the collaterals, the posterior cruciate's two bundles, the posterior capsule,
the posteromedial corner and the popliteofibular ligament; a posterior-cruciate-retaining knee, so
no anterior cruciate), their insertions carried onto this knee by the implant frames' anatomical
axes (posterior, superior, medial) and each bone's articular centroid (the tibial insert's onto the
tibial plateaus', the femoral component's onto the femoral cartilage's; their medial-lateral widths
agree to 1 %), each bundle at the strain DM.osim gives it at its default pose. The TKA is
``examples/tka_joint.py``. Both solve with finite kinematics and are checked by the sums of
``tests/joint_checks.py`` at the solved pose. Skipped cleanly where the data are absent.
"""

from __future__ import annotations

import csv
import importlib.util
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest
from joint_checks import assert_balanced_at_pose

import dea_opt as d

pytestmark = pytest.mark.slow

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
KNEE, TKA = DATA / "knee", DATA / "tka"
#: The DM implant frames' axes (posterior, superior, medial) onto the knee's (medial, posterior, superior).
AXES = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])


def _need(folder, *files):
    if not all((folder / f).is_file() for f in files):
        pytest.skip(f"the data are not in {folder}")


def _centroid(mesh, faces=None):
    area, centre = mesh.area_faces, mesh.triangles_center
    if faces is not None:
        area, centre = area[faces], centre[faces]
    return area @ centre / area.sum()


@pytest.fixture(scope="module")
def knee():
    _need(KNEE, "femoral_cartilage.stl", "medial_tibial_cartilage.stl", "lateral_tibial_cartilage.stl")
    _need(TKA, "ligaments.csv", "tibial_insert.stl", "femoral_component.stl")
    from dea_opt.mesh import cast_springs, concatenate_meshes, load_mesh

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        tibia, labels = concatenate_meshes(
            {
                "medial": load_mesh(KNEE / "medial_tibial_cartilage.stl"),
                "lateral": load_mesh(KNEE / "lateral_tibial_cartilage.stl"),
            }
        )
        femur = load_mesh(KNEE / "femoral_cartilage.stl")
        cast = cast_springs(tibia, femur, labels=labels, max_gap=2.0, max_overlap=2.0)
        plateau = _centroid(tibia, np.flatnonzero(tibia.face_normals[:, 2] > 0.5))
        place = {
            "tibia_r": (_centroid(load_mesh(TKA / "tibial_insert.stl")), plateau),
            "femur_r": (_centroid(load_mesh(TKA / "femoral_component.stl")), _centroid(femur)),
        }
    ligaments = []
    with open(TKA / "ligaments.csv", newline="") as handle:
        for row in csv.DictReader(handle):
            if {row["body1"], row["body2"]} != {"femur_r", "tibia_r"}:
                continue
            ends = []
            for k in "12":
                p = np.array([float(row[f"p{k}_implant_{a}_mm"]) for a in "xyz"])
                source, target = place[row[f"body{k}"]]
                ends.append(AXES @ (p - source) + target)
            ligaments.append(
                d.Ligament(
                    row["body1"][:-2],
                    ends[0],
                    row["body2"][:-2],
                    ends[1],
                    stiffness=float(row["linear_stiffness_N_per_strain"]),
                    reference_strain=float(row["strain_at_dm_defaults"]),
                    transition_strain=float(row["transition_strain"]),
                    name=row["name"],
                )
            )
    # 700 N along -z through a point 20 mm above the plateaus, and an extension moment of 4 N m
    # that the posterior structures hold (the flexion is otherwise held by nothing but muscles)
    bodies = {
        "tibia": d.Body(free=()),
        "femur": d.Body(reference=plateau + [0, 0, 20.0], force=(0, 0, -700.0), moment=(4000.0, 0, 0)),
    }
    contact = d.Contact(cast.layer, d.AteshianLaw(10.0, 0.3), body1="tibia", body2="femur", targets=cast)
    return d.Joint(bodies, [contact], ligaments, kinematics="finite")


def test_the_real_knee_with_six_free_dofs_held_by_its_bundles_is_stable_and_certified(knee):
    assert {lig.name[:3] for lig in knee.ligaments} >= {"MCL", "LCL", "PCL"}
    s = d.solve(knee)
    assert s.success and s.status == "converged"
    assert s.validity.valid, s.validity.summary()
    assert s.validity["stability"].value < 0  # every free direction resists a disturbance
    assert s.info["recasts"] >= 1  # the springs were cast again where the femur came to rest
    assert_balanced_at_pose(s, 1e-9)
    assert (s.ligaments.force > 0).sum() >= 20  # the bundles hold it, not only the contact
    layer = s.contacts[0]
    labels = layer.problem.layer.labels
    medial = float((layer.pressure * layer.problem.layer.areas)[labels == "medial"].sum())
    assert 0.2 < medial / layer.total_normal_force < 0.8


def _example():
    path = Path(__file__).resolve().parents[1] / "examples" / "tka_joint.py"
    spec = importlib.util.spec_from_file_location("example_tka_joint", path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_the_three_body_tka_solves_certified_with_its_ligament_table(tmp_path):
    _need(TKA, "ligaments.csv", "tibial_insert.stl", "femoral_component.stl", "patellar_button.stl", "frames.json")
    s = _example().main(["--out", str(tmp_path)])
    assert s.success and s.validity.valid, s.validity.summary()
    assert s.validity["stability"].value < 0
    assert [c.name for c in s.joint.contacts] == ["medial", "lateral", "patellofemoral"]
    assert all(layer.contact_area > 0 for layer in s.contacts)  # each layer carries load
    assert_balanced_at_pose(s, 1e-9)
    # the femur's compression goes through the tibiofemoral layers, with the bundles' pull
    tf = s.contacts[0].contact_force + s.contacts[1].contact_force
    assert tf[1] > 700.0
    with open(tmp_path / "ligaments.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    assert len(rows) == 148 and list(rows[0]) == [
        "name",
        "body1",
        "body2",
        "force_N",
        "strain",
        "length_mm",
        "slack_length_mm",
    ]
    for row, force, strain, length in zip(rows, s.ligaments.force, s.ligaments.strain, s.ligaments.length):
        assert float(row["force_N"]) == force and float(row["strain"]) == strain and float(row["length_mm"]) == length
        assert float(row["strain"]) == pytest.approx(
            float(row["length_mm"]) / float(row["slack_length_mm"]) - 1, abs=1e-12
        )
    for name in ("medial", "lateral", "patellofemoral"):
        assert (tmp_path / f"{name}.vtu").stat().st_size > 0 and (tmp_path / f"{name}.json").stat().st_size > 0
