"""dea_opt.opensim.read_model on small models written here: the CustomJoint transform against an
independent composition (scipy's rotations), offsets, units, contact and ligaments, what is not
modelled, and every bad file as a named error with its line."""

from __future__ import annotations

import numpy as np
import pytest
from osim_models import CONTACT, MESHES, ligament, model_text, write_model
from scipy.spatial.transform import Rotation

import dea_opt as d
from dea_opt.opensim import read_model
from dea_opt.opensim.ligaments import blankevoort_force, segment_crosses_wrap


def _T(R, p) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p
    return T


def _offset(translation, orientation) -> np.ndarray:
    # OpenSim's body-fixed x-y-z sequence is scipy's intrinsic "XYZ"
    return _T(Rotation.from_euler("XYZ", orientation).as_matrix(), 1000.0 * np.asarray(translation))


def _expected_b(values) -> np.ndarray:
    """Body b in ground, composed here without dea_opt: Simbody's R = R1 R2 R3 about the
    normalised axes, p = sum f_k a_k in the parent frame."""
    # j0's axes and q3's name a coordinate but give no function: OpenSim 4.6 moves nothing there
    X_G_a = np.eye(4)
    q1, q2, q4, q5 = (values[f"q{i}"] for i in (1, 2, 4, 5))
    q3 = 0.0
    a1, a2, a3 = np.array([0, 0, 1.0]), np.array([1, 1, 0]) / np.sqrt(2), np.array([0, 1.0, 0])
    R = (
        Rotation.from_rotvec((-q1 + 0.1) * a1) * Rotation.from_rotvec(0.5 * q2 * a2) * Rotation.from_rotvec(q3 * a3)
    ).as_matrix()
    p = 1000.0 * (q4 * np.array([1.0, 0, 0]) + 0.02 * np.array([0, 1.0, 0]) + 2 * q5 * np.array([0, 0.6, 0.8]))
    P = _offset([0.01, -0.4, 0.002], [0.1, -0.2, 0.3])
    C = _offset([-0.003, 0.02, 0.001], [-0.05, 0.02, 0.4])
    return X_G_a @ P @ _T(R, p) @ np.linalg.inv(C)


def test_the_custom_joint_places_the_child_as_simbody_does(tmp_path):
    model = read_model(write_model(tmp_path))
    values = model.default_coordinates()
    assert values == {"g1": 0.7, "g2": 0.9, "q1": 0.3, "q2": -0.2, "q3": 0.4, "q4": 0.01, "q5": -0.015}
    assert np.allclose(model.poses()["b"], _expected_b(values), atol=1e-10, rtol=0)
    rng = np.random.default_rng(7)
    for _ in range(5):
        values = {name: float(rng.uniform(-1, 1)) for name in values}
        assert np.allclose(model.poses(values)["b"], _expected_b(values), atol=1e-10, rtol=0)


def test_offset_frames_units_and_motion_types(tmp_path):
    model = read_model(write_model(tmp_path))
    frame = model.frames["/bodyset/a/a_offset"]
    assert frame.body == "a" and frame.parent == "/bodyset/a"
    assert np.allclose(model.frame_in_body("/bodyset/a/a_offset"), _offset([0.005, -0.41, 0.003], [3.0, 0.01, -3.05]))
    assert {n: c.motion for n, c in model.coordinates.items()} == {
        "g1": "coupled",  # no function given: OpenSim 4.6 calls it coupled (and moves nothing)
        "g2": "coupled",
        "q1": "rotational",  # slope -1 counts as a pure rotation (OpenSim 4.5 and later)
        "q2": "coupled",  # slope 0.5
        "q3": "coupled",
        "q4": "translational",
        "q5": "coupled",  # a MultiplierFunction
    }
    unmoved = sorted(i.name for i in model.not_modelled if i.kind == "property")
    assert unmoved == ["j0/rotation1", "j0/translation2", "j1/rotation3"]
    with pytest.raises(d.OpenSimModelError, match="has no coordinate 'nope'"):
        model.poses({"nope": 1.0})
    with pytest.raises(d.OpenSimModelError, match="finite"):
        model.poses({"q1": float("nan")})


def test_a_joint_walked_from_its_child_uses_the_inverse(tmp_path):
    # j1 with its sockets swapped: its parent frame is on b, its child frame on a, and a is the
    # one joined to ground, so b is reached through j1 backwards
    text = model_text().replace(
        "<socket_parent_frame>a_off</socket_parent_frame>", "<socket_parent_frame>b_off</socket_parent_frame>"
    )
    text = text.replace(
        "<socket_child_frame>b_off</socket_child_frame>", "<socket_child_frame>a_off</socket_child_frame>"
    )
    path = tmp_path / "reversed.osim"
    path.write_text(text)
    model = read_model(path)
    values = model.default_coordinates()
    poses = model.poses()
    forward = _expected_b(values)  # = X_G_a P X_FM inv(C) with P on a, C on b
    P = _offset([0.01, -0.4, 0.002], [0.1, -0.2, 0.3])
    C = _offset([-0.003, 0.02, 0.001], [-0.05, 0.02, 0.4])
    X_FM = np.linalg.inv(P) @ forward @ C  # the joint's transform, from the forward composition (X_G_a = I)
    # now F is on b (C) and M on a (P): X_G_b C X_FM = X_G_a P
    assert np.allclose(poses["a"], np.eye(4))
    assert np.allclose(poses["b"] @ C @ X_FM, poses["a"] @ P, atol=1e-10)


def test_unsupported_joints_and_functions_are_listed_and_block_only_their_bodies(tmp_path):
    joint_ab = """<PinJoint name="pin"><socket_parent_frame>/bodyset/a</socket_parent_frame>
      <socket_child_frame>/bodyset/b</socket_child_frame>
      <coordinates><Coordinate name="angle"/></coordinates></PinJoint>"""
    model = read_model(write_model(tmp_path, joint_ab=joint_ab))
    assert [(i.kind, i.name) for i in model.not_modelled if i.kind != "property"] == [("joint", "pin")]
    assert set(model.poses()) == {"ground", "a"}
    with pytest.raises(d.OpenSimModelError, match="body b has no pose: joint pin .* PinJoint"):
        model.poses(bodies=["b"])
    spline = model_text().replace(
        '<LinearFunction name="function"><coefficients>-1 0.1</coefficients></LinearFunction>',
        '<SimmSpline name="function"><x>0 1</x><y>0 1</y></SimmSpline>',
    )
    (tmp_path / "spline.osim").write_text(spline)
    model = read_model(tmp_path / "spline.osim")
    listed = [(i.kind, i.name, i.line > 0) for i in model.not_modelled if i.kind != "property"]
    assert listed == [("joint_function", "j1/rotation1", True)]
    with pytest.raises(d.OpenSimModelError, match="SimmSpline, which dea-opt does not evaluate"):
        model.poses(bodies=["b"])


def test_forces_constraints_and_path_points_not_modelled_are_listed_by_name(tmp_path):
    via = """<ConditionalPathPoint name="c"><socket_parent_frame>/bodyset/a</socket_parent_frame>
      <location>0 0 0</location></ConditionalPathPoint>
      <PathPoint name="v"><socket_parent_frame>/bodyset/b</socket_parent_frame><location>0.1 0 0</location></PathPoint>"""
    forces = (
        '<Millard2012EquilibriumMuscle name="m1"/><SpringGeneralizedForce name="s1"/>'
        + ligament(name="via", via=via)
        + ligament(name="off").replace("<linear_stiffness>", "<appliesForce>false</appliesForce><linear_stiffness>")
    )
    model = read_model(write_model(tmp_path, forces=forces, constraints='<CoordinateCouplerConstraint name="cc"/>'))
    listed = {(i.kind, i.name) for i in model.not_modelled if i.kind != "property"}
    assert listed == {
        ("muscle", "m1"),
        ("force", "s1"),
        ("constraint", "cc"),
        ("conditional_path_point", "via/c"),
        ("via_points", "via"),
        ("ligament", "off"),
    }
    lig = model.ligaments["via"]
    assert [p.name for p in lig.points] == ["p1", "v", "p2"] and list(model.ligaments) == ["via"]
    report = next(i for i in model.not_modelled if i.kind == "via_points")
    assert report.detail["path_length_mm"] > report.detail["straight_length_mm"] > 0
    assert "via" in model.report() and "m1" in model.report()


def test_ligament_lengths_strains_and_forces_by_hand(tmp_path):
    model = read_model(write_model(tmp_path, forces=ligament(k=1000)))
    lig = model.ligaments["lig"]
    assert (lig.stiffness, lig.slack_length, lig.transition_strain, lig.damping) == (1000.0, 50.0, 0.06, 0.003)
    poses = model.poses()
    x1 = poses["a"][:3, :3] @ [10.0, 20.0, 30.0] + poses["a"][:3, 3]
    x2 = poses["b"][:3, :3] @ [20.0, -30.0, 10.0] + poses["b"][:3, 3]
    state = model.ligament_state()
    L = np.linalg.norm(x2 - x1)
    assert state.length[0] == pytest.approx(L, rel=1e-14) and state.path_length[0] == pytest.approx(L, rel=1e-14)
    e = L / 50.0 - 1.0
    f = 0 if e <= 0 else (1000 * e * e / 0.12 if e < 0.06 else 1000 * (e - 0.03))
    assert state.strain[0] == pytest.approx(e, rel=1e-12) and state.force[0] == pytest.approx(f, rel=1e-12)


def test_the_blankevoort_law_closed_form():
    k, et = 2000.0, 0.05
    e = np.array([-0.1, 0.0, 0.02, 0.05, 0.08])
    f = blankevoort_force(e, k, et)
    assert np.allclose(f, [0.0, 0.0, k * 0.02**2 / (2 * et), k * 0.025, k * (0.08 - 0.025)], rtol=1e-14, atol=0)
    below, above = blankevoort_force([et - 1e-9, et + 1e-9], k, et)
    assert above - below == pytest.approx(k * 2e-9, rel=1e-5)  # continuous, slope k at the transition
    damped = blankevoort_force([0.005, 0.02, 0.02, -0.01], k, et, strain_rate=[1.0, 1.0, -1.0, 1.0], damping=10.0)
    step = 0.5**3 * (10 - 15 * 0.5 + 6 * 0.25)
    assert np.allclose(
        damped - blankevoort_force([0.005, 0.02, 0.02, -0.01], k, et), [10 * step, 10.0, 0.0, 0.0], rtol=1e-12
    )


def test_a_reference_strain_sets_the_slack_length_at_the_default_pose(tmp_path):
    lig = ligament(slack="<reference_strain>0.04</reference_strain>")
    model = read_model(write_model(tmp_path, forces=lig))
    state = model.ligament_state()
    assert model.ligaments["lig"].slack_from == "reference_strain"
    assert state.strain[0] == pytest.approx(0.04, rel=1e-12)


def test_contact_pairs_their_law_and_the_meshes_found_as_opensim_finds_them(tmp_path):
    import trimesh

    (tmp_path / "Geometry").mkdir()

    box = trimesh.creation.box((0.02, 0.02, 0.002))  # metres, as a model's mesh
    box.export(tmp_path / "Geometry" / "a.stl")
    box.export(tmp_path / "b.stl")
    params = dict(file_a="a.stl", file_b="b.stl", E_a=46.3e6, nu_a=0.46, h_a=0.005, E_b=46.3e6, nu_b=0.46, h_b=0.005)
    model = read_model(
        write_model(
            tmp_path, meshes=MESHES.format(**params), forces=CONTACT.format(formulation="linear", lumped="true")
        )
    )
    pair = model.contact_pairs["contact"]
    assert (pair.casting.name, pair.target.name, pair.casting.body, pair.target.body) == ("mesh_a", "mesh_b", "a", "b")
    assert pair.casting.resolved == tmp_path / "Geometry" / "a.stl" and pair.target.resolved == tmp_path / "b.stl"
    assert (pair.min_proximity, pair.max_proximity, pair.window) == (0.0, 20.0, (-0.0, 20.0))
    assert pair.thickness == 10.0
    assert pair.modulus == pytest.approx(0.54 * 46.3 / (1.46 * 0.08), rel=1e-14)  # 214.058 MPa, material.json
    assert pair.law() == d.LinearLaw(pair.modulus)
    assert np.allclose(pair.casting.load().bounds, 1000.0 * box.bounds)  # m -> mm
    # two different layers, not lumped: springs in series over h = h_a + h_b
    params.update(E_b=10e6, nu_b=0.3, h_b=0.002)
    model = read_model(
        write_model(
            tmp_path, meshes=MESHES.format(**params), forces=CONTACT.format(formulation="linear", lumped="false")
        )
    )
    pair = model.contact_pairs["contact"]
    ka, kb = 0.54 * 46.3 / (1.46 * 0.08) / 5.0, 0.7 * 10 / (1.3 * 0.4) / 2.0
    assert pair.modulus == pytest.approx(7.0 * ka * kb / (ka + kb), rel=1e-14)
    model = read_model(
        write_model(
            tmp_path, meshes=MESHES.format(**params), forces=CONTACT.format(formulation="nonlinear", lumped="true")
        )
    )
    assert type(model.contact_pairs["contact"].law()).__name__ == "BlankevoortLaw"
    model = read_model(
        write_model(
            tmp_path, meshes=MESHES.format(**params), forces=CONTACT.format(formulation="nonlinear", lumped="false")
        )
    )
    assert [i.kind for i in model.not_modelled if i.kind != "property"] == ["contact"]
    with pytest.raises(d.OpenSimModelError, match="no dea-opt law"):
        model.contact_pairs["contact"].law()


def test_a_mesh_name_that_leaves_the_model_folder_is_looked_for_nowhere(tmp_path):
    params = dict(file_a="../a.stl", file_b="/etc/passwd", E_a=1e6, nu_a=0.3, h_a=0.005, E_b=1e6, nu_b=0.3, h_b=0.005)
    model = read_model(write_model(tmp_path, meshes=MESHES.format(**params)))
    for mesh in model.contact_meshes.values():
        assert mesh.resolved is None and mesh.searched == ()
        with pytest.raises(d.OpenSimModelError, match="is in none of"):
            mesh.load()


def test_the_straight_line_against_wrap_objects_by_sampling():
    from types import SimpleNamespace

    rng = np.random.default_rng(3)
    shapes = [
        SimpleNamespace(kind="WrapEllipsoid", dimensions={"radii": (10.0, 20.0, 5.0)}),
        SimpleNamespace(kind="WrapSphere", dimensions={"radius": 8.0}),
        SimpleNamespace(kind="WrapCylinder", dimensions={"radius": 6.0, "length": 30.0}),
    ]
    inside = [
        lambda x: ((x / [10.0, 20.0, 5.0]) ** 2).sum(-1) < 1,
        lambda x: (x**2).sum(-1) < 64,
        lambda x: ((x[..., :2] ** 2).sum(-1) < 36) & (np.abs(x[..., 2]) < 15),
    ]
    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_euler("xyz", [0.3, -0.5, 1.1]).as_matrix()
    pose[:3, 3] = [1.0, -2.0, 3.0]
    t = np.linspace(0, 1, 20001)[:, None]
    for shape, test in zip(shapes, inside):
        for _ in range(60):
            a, b = rng.uniform(-30, 30, 3), rng.uniform(-30, 30, 3)
            local = (np.linalg.inv(pose) @ np.c_[a + t * (b - a), np.ones(len(t))].T).T[:, :3]
            sampled = bool(test(local).any())
            assert segment_crosses_wrap(a, b, shape, pose) == sampled
    assert segment_crosses_wrap([0, 0, 0], [1, 1, 1], SimpleNamespace(kind="WrapTorus", dimensions={}), pose) is None


BAD = {
    "billion laughs": (
        model_text(doctype='<!DOCTYPE lolz [<!ENTITY lol "lol"><!ENTITY lol2 "&lol;&lol;">]>'),
        r"line 1: refused, it has a document type declaration",
    ),
    "external entity": (
        model_text(doctype='<!DOCTYPE m [<!ENTITY x SYSTEM "file:///etc/passwd">]>').replace("toy", "&x;"),
        "refused",
    ),
    "undeclared entity": (model_text().replace('name="toy"', 'name="&x;"'), r"line 3, column \d+: not well-formed XML"),
    "truncated": (model_text()[:-40], r"line \d+, column \d+: not well-formed XML"),
    "not a model": ("<html><body/></html>", "root element is <html>, not <OpenSimDocument>"),
    "OpenSim 3": (model_text(version="30000"), "OpenSim 3"),
    "bad number": (
        model_text().replace("0.01 -0.4 0.002", "0.01 abc 0.002"),
        r"line \d+: <translation> of /jointset/j1/a_off must hold 3",
    ),
    "no such frame": (
        model_text().replace("<socket_parent>/bodyset/b</socket_parent>", "<socket_parent>/bodyset/zz</socket_parent>"),
        "names no component",
    ),
    "collinear": (
        model_text().replace("<axis>1 1 0</axis>", "<axis>0 0 -1</axis>"),
        "rotation axes rotation1 and rotation2 are collinear",
    ),
    "zero axis": (
        model_text().replace("<axis>0 1 0</axis></TransformAxis>", "<axis>0 0 0</axis></TransformAxis>", 1),
        "has zero length",
    ),
    "units": (
        model_text().replace("<length_units>m</length_units>", "<length_units>mm</length_units>"),
        "length_units",
    ),
    "slack 0": (model_text(forces=ligament(slack="<slack_length>0</slack_length>")), "slack length > 0"),
    "wrap unknown": (
        model_text(
            forces=ligament(
                wraps="<PathWrapSet><objects><PathWrap><wrap_object>nope</wrap_object></PathWrap></objects></PathWrapSet>"
            )
        ),
        "wrap_object 'nope'",
    ),
    "incompressible": (
        model_text(
            meshes=MESHES.format(file_a="a", file_b="b", E_a=1e6, nu_a=0.5, h_a=0.005, E_b=1e6, nu_b=0.3, h_b=0.005)
        ),
        "incompressible",
    ),
    "empty": ("", "no element found"),
}


@pytest.mark.parametrize("name", sorted(BAD))
def test_bad_files_are_named_errors_with_their_line(tmp_path, name):
    text, expected = BAD[name]
    path = tmp_path / "bad.osim"
    path.write_text(text)
    with pytest.raises(d.OpenSimModelError, match=expected) as info:
        read_model(path)
    assert str(path) in str(info.value)


def test_missing_files_and_directories(tmp_path):
    with pytest.raises(d.OpenSimModelError, match="does not exist"):
        read_model(tmp_path / "nope.osim")
    with pytest.raises(d.OpenSimModelError, match="is a directory"):
        read_model(tmp_path)
    assert issubclass(d.OpenSimModelError, d.InputError)


def test_the_objects_are_immutable(tmp_path):
    model = read_model(write_model(tmp_path, forces=ligament()))
    with pytest.raises(TypeError):
        model.ligaments["x"] = None  # type: ignore[index]
    with pytest.raises(ValueError):
        model.ligaments["lig"].points[0].location[0] = 1.0
    with pytest.raises(AttributeError):
        model.ligaments["lig"].stiffness = 1.0  # type: ignore[misc]
