"""The DM knee's contact pair as read from DM.osim, at a prescribed fluoroscopic pose: dea-opt's
contact force against a direct sum of JAM's lumped linear law over the same faces.

JAM (Smith2018ArticularContactForce, use_lumped_contact_model, linear) gives each casting
triangle in contact the pressure ``p = H d / h`` with ``H = (1 - nu) E / ((1 + nu)(1 - 2 nu))`` of
the two meshes' mean E and nu, ``h`` the sum of their thicknesses and ``d`` its depth, pushing
the target along the triangle's normal with ``p A n``. The sum below is written from those
words, with the faces' areas and normals taken from the insert's triangles here; the depths are
the springs' of dea-opt's cast of the insert onto the femoral component at that pose.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from conftest import SHARED

import dea_opt as d
from dea_opt.mesh import cast_springs, load_mesh
from dea_opt.opensim import read_model
from dea_opt.opensim.kinematics import rigid_inverse
from dea_opt.opensim.motion import relative_motion

TKA = SHARED / "data" / "tka"


@pytest.fixture(scope="module")
def knee():
    files = ("DM.osim", "tibial_insert.stl", "femoral_component.stl", "fluoroscopy_poses.csv")
    if not all((TKA / f).is_file() for f in files):
        pytest.skip(f"the DM knee is not in {TKA}")
    model = read_model(TKA / "DM.osim")
    return model, load_mesh(TKA / "tibial_insert.stl"), load_mesh(TKA / "femoral_component.stl")


@pytest.mark.parametrize("frame", [50, 70])
def test_the_contact_force_at_a_fluoroscopic_pose_is_jams_lumped_linear_sum(knee, frame):
    model, insert, component = knee
    pair = model.contact_pairs["knee_contact"]
    assert (pair.casting.name, pair.target.name) == ("tibia_implant", "femur_implant")
    # the prescribed pose: the femoral component on the insert at this frame, through the model's frames
    motion = relative_motion(model, TKA / "fluoroscopy_poses.csv", "femur_implant", "tibia_implant")
    poses = {body: motion.poses[body][frame] for body in motion.poses}
    T = rigid_inverse(model.frame_pose(pair.casting.frame, poses=poses)) @ model.frame_pose(
        pair.target.frame, poses=poses
    )
    max_gap, max_overlap = pair.window
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cast = cast_springs(
            insert,
            component,
            thickness1=pair.casting.thickness,
            thickness2=pair.target.thickness,
            pose=T,
            max_gap=max(max_gap, 0.0),
            max_overlap=max_overlap,
        )
    layer = cast.layer
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        solution = d.solve(d.ContactProblem(layer, pair.law(), free=()))

    # JAM's sum, written here
    E = 0.5 * (46.3 + 46.3)  # MPa, each mesh's elastic_modulus in DM.osim
    nu = 0.5 * (0.46 + 0.46)
    h = 5.0 + 5.0  # mm
    H = (1 - nu) * E / ((1 + nu) * (1 - 2 * nu))
    tri = insert.triangles[layer.source_face]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    area = 0.5 * np.linalg.norm(cross, axis=1)
    normal = cross / (2 * area)[:, None]
    assert (np.einsum("ij,ij->i", normal, layer.normals) > 1 - 1e-9).all()  # the winding faces the femur
    depth = np.maximum(-layer.gap, 0.0)
    assert (depth > 0).sum() > 100 and depth.max() > 0.5  # in contact, as the data's README says
    jam = ((H * depth / h) * area) @ normal

    assert np.linalg.norm(solution.contact_force - jam) <= 1e-9 * np.linalg.norm(jam)
    assert np.linalg.norm(jam) > 100.0  # N: a real load, not a graze
    assert jam[1] > 0.9 * np.linalg.norm(jam)  # it pushes the femoral component up (+y of the insert)
