"""dea_opt.opensim against OpenSim 4.6 itself on the Grand Challenge DM knee (../shared/data/tka).

The reference, tests/data/opensim/dm_reference.json, was recorded by OpenSim 4.6 in a venv of its
own (its CasADi cannot share our process) by tests/data/opensim/make_reference.py: body poses
and every Blankevoort1991Ligament's length, strain and force at seven poses, with the wrap
objects removed; the wrapped lengths at the default pose; OpenSim's motion types. The model is
read from ../shared at test time (skipped when absent); only OpenSim's numbers are kept here.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from conftest import SHARED

from dea_opt.opensim import read_model
from dea_opt.opensim.kinematics import rigid_inverse
from dea_opt.opensim.motion import relative_motion

TKA = SHARED / "data" / "tka"
REFERENCE = json.loads((Path(__file__).parents[1] / "data" / "opensim" / "dm_reference.json").read_text())
POSES = {pose["name"]: pose for pose in REFERENCE["poses"]}
#: The left knee's joint functions are SimmSplines, which dea-opt does not evaluate: the bodies below it.
UNPOSED = {"tibia_l", "talus_l", "calcn_l", "toes_l"}


@pytest.fixture(scope="module")
def dm():
    if not (TKA / "DM.osim").is_file():
        pytest.skip(f"the DM model is not in {TKA}")
    return read_model(TKA / "DM.osim")


def test_the_reference_says_what_made_it():
    assert REFERENCE["script"] == "tests/data/opensim/make_reference.py"
    assert REFERENCE["opensim"].startswith("version 4.6")
    assert "Apache License 2.0" in REFERENCE["licence"]
    assert (Path(__file__).parents[1] / "data" / "opensim" / "LICENSE").is_file()
    assert len(POSES) == 7 and all(len(p["ligaments"]) == 149 for p in POSES.values())


@pytest.mark.parametrize("name", sorted(POSES))
def test_body_poses_agree_with_opensim(dm, name):
    pose = POSES[name]
    ours = dm.poses(pose["coordinates"])
    assert set(pose["bodies"]) - set(ours) == UNPOSED
    for body, T in ours.items():
        if body != "ground":
            assert np.abs(np.asarray(pose["bodies"][body]) - T).max() < 1e-9, body  # mm


@pytest.mark.parametrize("name", sorted(POSES))
def test_every_ligament_agrees_with_opensim_without_its_wraps(dm, name):
    pose = POSES[name]
    state = dm.ligament_state(pose["coordinates"])
    length, strain, force = (np.array([pose["ligaments"][n][i] for n in state.names]) for i in range(3))
    assert np.abs(state.path_length / length - 1).max() < 1e-9
    assert np.abs(state.path_strain - strain).max() < 1e-9
    assert np.abs(state.path_force - force).max() < 1e-9 * max(1.0, np.abs(force).max())
    assert force.max() > 10.0  # some bundles are loaded at every pose
    # dea-opt's straight line is OpenSim's path for every bundle of two points
    two = np.array([len(dm.ligaments[n].points) == 2 for n in state.names])
    assert two.sum() == 148 and np.allclose(state.length[two], state.path_length[two], rtol=1e-14, atol=0)


def test_motion_types_agree_with_opensim(dm):
    assert {n: c.motion for n, c in dm.coordinates.items()} == REFERENCE["motion_types"]


def test_the_wrap_report_says_where_opensim_wraps(dm):
    """Where the straight line crosses a wrap object at the default pose OpenSim's path is longer;
    where it stays clear it is the line itself."""
    wrapped = REFERENCE["wrapped_length_at_default_mm"]
    state = dm.ligament_state()
    reports = [item for item in dm.not_modelled if item.kind == "wrap"]
    assert len(reports) == 83
    for item in reports:
        gap = wrapped[item.name] - state.path_length[state.names.index(item.name)]
        crosses = all(text.endswith("crosses") for text in item.detail["line_at_default_pose"])
        assert crosses == (gap > 1e-6), (item.name, gap)
        if not crosses:
            assert abs(gap) < 1e-9
        assert item.detail["straight_length_mm"] == pytest.approx(state.length[state.names.index(item.name)])


def test_fluoroscopy_poses_and_the_model_coordinates_agree(dm):
    """fluoroscopy_poses.csv gives each frame twice, made with OpenSim 4.6: as the femoral component
    in the insert frame (T) and as DM.osim's knee_r coordinates (dm_knee_*)."""
    table = pd.read_csv(TKA / "fluoroscopy_poses.csv")
    motion = relative_motion(dm, TKA / "fluoroscopy_poses.csv", "femur_implant", "tibia_implant")
    assert len(motion) == 101 and np.array_equal(motion.times, table["time_pct_gait"].to_numpy(float))
    names = ("flex", "add", "rot", "tx", "ty", "tz")
    units = ("rad",) * 3 + ("m",) * 3
    worst = 0.0
    for k in range(0, 101, 5):
        row = table.iloc[k]
        coords = {f"knee_{n}_r": row[f"dm_knee_{n}_r_{u}"] for n, u in zip(names, units)}
        poses = dm.poses(coords, bodies=["tibia_r", "femur_r"])
        ours = rigid_inverse(poses["tibia_r"]) @ poses["femur_r"]
        moved = rigid_inverse(motion.poses["tibia_r"][k]) @ motion.poses["femur_r"][k]
        worst = max(worst, float(np.abs(ours - moved).max()))
    assert worst < 1e-8  # mm: the table's 12 digits


def test_the_default_pose_agrees_with_frames_json(dm):
    frames = json.loads((TKA / "frames.json").read_text())
    poses = dm.poses()
    insert = dm.frame_pose("/bodyset/tibia_r/tibia_implant", poses=poses)
    component = dm.frame_pose("/bodyset/femur_r/femur_implant", poses=poses)
    button = dm.frame_pose("/bodyset/patella_r/patella_implant", poses=poses)
    assert np.allclose(
        rigid_inverse(insert) @ component, frames["T_insert_femoral_component_at_dm_defaults_mm"], atol=1e-8
    )
    assert np.allclose(
        rigid_inverse(component) @ button, frames["T_femoral_component_patellar_button_at_dm_default_pf_mm"], atol=1e-8
    )
    for name, frame in frames["implant_frames"].items():
        assert np.allclose(dm.frame_in_body(f"/bodyset/{frame['body']}/{name}"), frame["T_body_implant_mm"], atol=1e-11)


def test_the_contact_material_agrees_with_material_json(dm):
    material = json.loads((TKA / "material.json").read_text())
    for name, pair in dm.contact_pairs.items():
        expected = material["contact_forces"][name]
        assert (
            pair.casting.path == expected["socket_casting_mesh"] and pair.target.path == expected["socket_target_mesh"]
        )
        assert (pair.min_proximity, pair.max_proximity) == (expected["min_proximity_mm"], expected["max_proximity_mm"])
        assert pair.lumped and pair.formulation == "linear" and pair.thickness == material["tibiofemoral"]["h_mm"]
        assert pair.modulus == pytest.approx(material["tibiofemoral"]["H_MPa"], rel=1e-14)
    for name, mesh in dm.contact_meshes.items():
        expected = material["contact_meshes"][name]
        assert (mesh.elastic_modulus, mesh.poissons_ratio, mesh.thickness) == pytest.approx(
            (expected["elastic_modulus_MPa"], expected["poissons_ratio"], expected["thickness_mm"])
        )
        assert mesh.frame == expected["frame"] and mesh.resolved is None  # the shared copies are renamed


def test_what_dm_does_not_model_is_listed(dm):
    summary = dm.summary()
    assert (summary["bodies"], summary["joints"], summary["coordinates"], summary["ligaments"]) == (23, 23, 52, 149)
    assert dict(summary["not_modelled"]) == {
        "joint_function": 5,  # knee_l's SimmSplines
        "muscle": 44,
        "force": 11,  # SpringGeneralizedForce on the knee and patella coordinates
        "component": 1,  # the markers
        "wrap": 83,
        "via_points": 1,  # ITB_r
    }


TOY = REFERENCE["toy"]


@pytest.fixture(scope="module")
def toy(tmp_path_factory):
    from osim_models import ligament, write_model

    via = '<PathPoint name="v"><socket_parent_frame>/bodyset/b</socket_parent_frame><location>0.1 0 0</location></PathPoint>'
    folder = tmp_path_factory.mktemp("toy")
    return read_model(write_model(folder, forces=ligament(via=via, slack="<slack_length>0.3</slack_length>")))


@pytest.mark.parametrize("index", range(len(TOY["poses"])))
def test_a_general_custom_joint_agrees_with_opensim(toy, index):
    """The small model (needs no shared data): axes off x, y, z, a slope and an intercept, a
    constant, a MultiplierFunction, axes without a function, offsets on both sides, a via point."""
    pose = TOY["poses"][index]
    ours = toy.poses(pose["coordinates"])
    for body in ("a", "b"):
        assert np.abs(np.asarray(pose["bodies"][body]) - ours[body]).max() < 1e-9
    state = toy.ligament_state(pose["coordinates"])
    length, strain, force = pose["ligaments"]["lig"]
    assert state.path_length[0] == pytest.approx(length, rel=1e-12) and state.path_strain[0] == pytest.approx(
        strain, rel=1e-12
    )
    assert state.path_force[0] == pytest.approx(force, rel=1e-12) and force > 0


def test_the_small_models_motion_types_agree_with_opensim(toy):
    assert {n: c.motion for n, c in toy.coordinates.items()} == TOY["motion_types"]
