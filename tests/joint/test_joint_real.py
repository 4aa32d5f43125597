"""Real joints: the MRI knee held by published native-knee bundles with six free dofs, and the three-body TKA.

The knee's cartilage (``../shared/data/knee``) carries no bones: its bundles are the collateral and
cruciate bundles of Lenhart et al. 2015's native knee model (OpenSim-JAM's ``lenhart2015.osim``,
Apache 2.0: the medial collateral's superficial, deep and posterior oblique bundles, the lateral
collateral, the anterior cruciate's anteromedial and posterolateral bundles and the posterior
cruciate's anterolateral and posteromedial ones), their published insertions carried onto this
knee by the model's tibial cartilage fitted to this knee's (``tests/data/lenhart/``: the
insertions, and ``make_knee_bundles.py`` that made them), each at the strain the model gives it at
its default pose (extension). The TKA is ``examples/tka_joint.py``. Both solve with finite
kinematics and are checked by the sums of ``tests/joint_checks.py`` at the solved pose. Skipped
cleanly where the data are absent.
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

DATA = Path(__file__).resolve().parents[3] / "shared" / "data"
KNEE, TKA = DATA / "knee", DATA / "tka"
BUNDLES = Path(__file__).resolve().parents[1] / "data" / "lenhart" / "bundles.csv"
#: The collateral and cruciate bundles of the model (not its posterior capsule nor popliteofibular ligament).
HELD_BY = ("MCLs", "MCLd", "MCLp", "LCL", "ACLam", "ACLpl", "PCLal", "PCLpm")
#: A reflection across the sagittal plane (x is medial-lateral): the mirrored knee.
MIRROR = np.diag([-1.0, 1.0, 1.0])


def _need(folder, *files):
    if not all((folder / f).is_file() for f in files):
        pytest.skip(f"the data are not in {folder}")


def _knee(mirror: bool = False) -> d.Joint:
    """The MRI knee with six free dofs under 700 N of compression and an extension moment of 4 N m
    (held by the posterior structures: nothing but muscles holds the knee in flexion); with
    ``mirror``, all of it reflected across the sagittal plane."""
    _need(KNEE, "femoral_cartilage.stl", "medial_tibial_cartilage.stl", "lateral_tibial_cartilage.stl")
    from dea_opt.mesh import cast_springs, concatenate_meshes, load_mesh

    S = MIRROR if mirror else np.eye(3)
    T = np.eye(4)
    T[:3, :3] = S
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        parts = {side: load_mesh(KNEE / f"{side}_tibial_cartilage.stl") for side in ("medial", "lateral")}
        femur = load_mesh(KNEE / "femoral_cartilage.stl")
        for mesh in (*parts.values(), femur):
            mesh.apply_transform(T)  # a reflection: trimesh turns the faces' winding back outward
        tibia, labels = concatenate_meshes(parts)
        cast = cast_springs(tibia, femur, labels=labels, max_gap=2.0, max_overlap=2.0)
    up = np.flatnonzero(np.nan_to_num(tibia.face_normals[:, 2]) > 0.5)
    plateau = tibia.area_faces[up] @ tibia.triangles_center[up] / tibia.area_faces[up].sum()
    ligaments = []
    with open(BUNDLES, newline="") as handle:
        for row in csv.DictReader(handle):
            if not row["name"].startswith(HELD_BY):
                continue
            ends = [S @ [float(row[f"p{k}_{a}_mm"]) for a in "xyz"] for k in "12"]
            ligaments.append(
                d.Ligament(
                    row["body1"],
                    ends[0],
                    row["body2"],
                    ends[1],
                    stiffness=float(row["stiffness_N_per_strain"]),
                    reference_strain=float(row["reference_strain"]),
                    transition_strain=float(row["transition_strain"]),
                    name=row["name"],
                )
            )
    # a moment is a pseudovector: reflected, it is -S M (here unchanged, about the medial-lateral axis)
    moment = -S @ [4000.0, 0.0, 0.0] if mirror else np.array([4000.0, 0.0, 0.0])
    bodies = {
        "tibia": d.Body(free=()),
        "femur": d.Body(reference=plateau + [0, 0, 20.0], force=(0, 0, -700.0), moment=moment),
    }
    contact = d.Contact(cast.layer, d.AteshianLaw(10.0, 0.3), body1="tibia", body2="femur", targets=cast)
    return d.Joint(bodies, [contact], ligaments, kinematics="finite")


@pytest.fixture(scope="module")
def knee():
    return _knee()


def test_the_real_knee_with_six_free_dofs_held_by_published_bundles_is_stable_and_certified(knee):
    assert {lig.name.rstrip("0123456789") for lig in knee.ligaments} == set(HELD_BY)
    s = d.solve(knee)
    assert s.success and s.status == "converged"
    assert s.validity.valid, s.validity.summary()
    assert s.validity["stability"].value < 0  # every free direction resists a disturbance
    assert s.info["recasts"] >= 1  # the springs were cast again where the femur came to rest
    assert_balanced_at_pose(s, 1e-9)
    taut = {name.rstrip("0123456789") for name, f in zip(s.ligaments.names, s.ligaments.force) if f > 0}
    assert {"PCLal", "LCL"} <= taut  # the femur slides forward on the tibia: the posterior cruciate holds it
    layer = s.contacts[0]
    labels = layer.problem.layer.labels
    medial = float((layer.pressure * layer.problem.layer.areas)[labels == "medial"].sum())
    assert 0.2 < medial / layer.total_normal_force < 0.8


def test_the_mirrored_knee_gives_the_mirrored_answer(knee):
    """Reflected across the sagittal plane (meshes, insertions, reference and loads), the knee must
    come to the reflected pose: translations ``S t``, rotation vectors ``-S theta`` (a pseudovector),
    the same forces in the mirrored bundles."""
    s = d.solve(knee)
    m = d.solve(_knee(mirror=True))
    assert m.success
    u, v = s.bodies["femur"].u, m.bodies["femur"].u
    np.testing.assert_allclose(v[:3], MIRROR @ u[:3], rtol=0, atol=1e-6 * max(1.0, np.abs(u[:3]).max()))
    np.testing.assert_allclose(v[3:], -MIRROR @ u[3:], rtol=0, atol=1e-8)
    np.testing.assert_allclose(m.ligaments.force, s.ligaments.force, rtol=1e-5, atol=1e-6 * s.ligaments.force.max())


def _example():
    path = Path(__file__).resolve().parents[2] / "examples" / "tka_joint.py"
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


def test_the_springs_that_follow_the_femur_only_steer_the_steps_the_answer_s_are_a_fresh_cast(knee):
    """On the way the springs near contact follow the femur to the faces under them without a cast;
    the answer's springs are a cast at the solved pose all the same: each spring's gap is the one a
    cast of the two meshes made there from scratch gives it, every spring that such a cast finds
    compressed is one of them, and the forces balance. A start moved by 1e-12 comes to the same
    answer (no result hinges on rounding)."""
    from dea_opt.mesh import cast_springs

    s = d.solve(knee)
    assert s.success and s.info["follows"] >= 1 and s.info["casts"] >= 1
    assert_balanced_at_pose(s, 1e-9)
    cast = knee.contacts[0].targets
    fresh = cast_springs(cast.mesh1, cast.mesh2, pose=s.bodies["femur"].pose, max_gap=2.0, max_overlap=2.0).layer
    layer = s.contacts[0].problem.layer
    at = {int(f): i for i, f in enumerate(layer.source_face)}
    common = [(at[int(f)], j) for j, f in enumerate(fresh.source_face) if int(f) in at]
    assert len(common) > 0.9 * len(fresh)
    mine, theirs = np.array(common).T
    np.testing.assert_allclose(layer.gap[mine], fresh.gap[theirs], rtol=0, atol=1e-9)
    compressed = {int(f) for f, g in zip(fresh.source_face, fresh.gap) if g < 0}
    assert compressed and compressed <= set(at)
    moved = d.solve(knee, x0=np.full(len(knee.free_index), 1e-12))
    assert moved.success
    np.testing.assert_allclose(moved.bodies["femur"].u, s.bodies["femur"].u, rtol=0, atol=1e-9)
    force = np.linalg.norm(s.contacts[0].contact_force)
    np.testing.assert_allclose(moved.contacts[0].contact_force, s.contacts[0].contact_force, rtol=0, atol=1e-8 * force)
