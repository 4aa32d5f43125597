"""The proximity window at a pose, the springs it drops or rejects, and the targets on mesh 2.

Closed forms on flat layers: a slab (mesh 1, articular face up at z = 0, ``DEPTH`` thick) and
flat, open sheets of mesh 2 facing down at known heights, so that every gap, every drop and
every rejection is known in advance. The tangent-plane gap of the targets is checked against
fresh casts on the curved hip meshes.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh

import dea_opt as d
from dea_opt import geometry
from dea_opt import mesh as M
from dea_opt.validity import assess

DEPTH = 2.0  # the slab's thickness (mm)
NX, NY = 8, 4  # slab cells: 8 x 4 cells of 1 mm, two triangles each


def slab():
    return geometry.slab_mesh(8.0, 4.0, DEPTH, NX, NY)


def sheet(x0, x1, z):
    """An open flat sheet over ``x0 <= x <= x1`` (full width), at height ``z``, facing down."""
    closed = geometry.slab_mesh(x1 - x0, 4.0, 0.5, 4, 4, center=(0.5 * (x0 + x1), 0.0), top=z, facing="down")
    down = closed.face_normals[:, 2] < -0.5
    return trimesh.Trimesh(closed.vertices, closed.faces[down], process=False)


def two_sheets(z_left, z_right):
    """Sheets over x < 0 at ``z_left`` and over x > 0 at ``z_right``, one mesh."""
    return trimesh.util.concatenate([sheet(-4.0, 0.0, z_left), sheet(0.0, 4.0, z_right)])


def top_faces(mesh, side):
    """The slab's articular (top) faces on one side of x = 0."""
    centre = mesh.triangles_center
    top = (mesh.face_normals[:, 2] > 0.5) & np.isclose(centre[:, 2], 0.0)
    return np.flatnonzero(top & ((centre[:, 0] < 0) if side == "left" else (centre[:, 0] > 0)))


def translation(z):
    pose = np.eye(4)
    pose[2, 3] = z
    return pose


def rotation_about(axis, degrees, point):
    from scipy.spatial.transform import Rotation

    R = Rotation.from_rotvec(np.radians(degrees) * np.asarray(axis, dtype=float) / np.linalg.norm(axis)).as_matrix()
    pose = np.eye(4)
    pose[:3, :3] = R
    pose[:3, 3] = np.asarray(point) - R @ np.asarray(point)
    return pose


# --------------------------------------------------------------------------------------------
# Rays back through mesh 1's own layer are rejected; deeper overlaps are counted as dropped
# --------------------------------------------------------------------------------------------
def test_a_ray_back_through_the_layer_is_rejected_and_counted():
    # Right: the sheet overlaps by 0.5 mm, inside the slab. Left: it lies 0.5 mm below the
    # slab's bone side, so the ray from a top face reached it through the whole layer.
    mesh1 = slab()
    cast = M.cast_springs(mesh1, two_sheets(-DEPTH - 0.5, -0.5), thickness2=0.0, max_overlap=3.0)
    left, right = top_faces(mesh1, "left"), top_faces(mesh1, "right")
    np.testing.assert_array_equal(np.sort(cast.layer.source_face), right)
    np.testing.assert_allclose(cast.layer.gap, -0.5, atol=1e-12)
    np.testing.assert_array_equal(cast.dropped.faces["through_layer"], left)
    assert cast.dropped.counts == {"overlap": 0, "through_layer": len(left), "angle": 0, "thickness": 0}
    # no spring overlaps deeper than mesh 1's own layer
    assert (-cast.layer.gap < cast.thickness1).all()


def test_an_overlap_inside_the_layer_is_a_spring():
    mesh1 = slab()
    cast = M.cast_springs(mesh1, two_sheets(-1.5, -0.5), thickness2=0.0, max_overlap=3.0)
    assert len(cast.layer) == 2 * NX * NY and cast.dropped.total == 0
    left = np.isin(cast.layer.source_face, top_faces(mesh1, "left"))
    np.testing.assert_allclose(cast.layer.gap[left], -1.5, atol=1e-12)
    np.testing.assert_allclose(cast.layer.gap[~left], -0.5, atol=1e-12)


def test_an_overlap_deeper_than_the_window_is_counted_as_dropped():
    mesh1 = slab()
    cast = M.cast_springs(mesh1, two_sheets(-1.5, -0.5), thickness2=0.0, max_overlap=1.0)
    left, right = top_faces(mesh1, "left"), top_faces(mesh1, "right")
    np.testing.assert_array_equal(np.sort(cast.layer.source_face), right)
    np.testing.assert_array_equal(cast.dropped.faces["overlap"], left)
    assert cast.dropped["overlap"] == len(left) and cast.dropped.describe() == f"overlap {len(left)}"


def test_every_ray_rejected_is_a_named_error():
    mesh1 = slab()
    with pytest.raises(d.InputError, match="behind mesh1's own far side"):
        M.cast_springs(mesh1, sheet(-4.0, 4.0, -DEPTH - 0.5), thickness2=0.0, max_overlap=3.0)


# --------------------------------------------------------------------------------------------
# The window follows the pose
# --------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def plate():
    pair = geometry.plate_meshes(nx=16, ny=4)
    return pair, M.cast_springs(pair.mesh1, pair.mesh2, **pair.options)


def test_a_recast_keeps_every_spring_when_the_overlap_grows(plate):
    pair, start = plate
    # pushed 1.5 mm in: deeper than max_overlap = 1, inside the 2 mm slab
    with pytest.raises(d.InputError, match="raise max_overlap"):
        M.cast_springs(pair.mesh1, pair.mesh2, pose=translation(-1.5), **pair.options)
    again = M.recast(start, translation(-1.5))
    np.testing.assert_array_equal(again.cast.layer.source_face, start.layer.source_face)
    np.testing.assert_allclose(again.cast.layer.gap, start.layer.gap - 1.5, atol=1e-12)
    assert again.kept == len(start.layer) and len(again.gained) == 0
    assert all(len(f) == 0 for f in again.lost.values())
    assert again.dropped == 0 and again.rejected == 0


def test_a_recast_through_the_whole_layer_is_rejected(plate):
    _, start = plate
    with pytest.raises(d.InputError, match="behind mesh1's own far side"):
        M.recast(start, translation(-2.5))  # the plate below the slab's bone side


def test_a_recast_counts_springs_lost_to_separation(plate):
    _, start = plate
    again = M.recast(start, translation(1.0))
    assert again.kept == len(start.layer)
    np.testing.assert_allclose(again.cast.layer.gap, 1.0, atol=1e-12)
    with pytest.raises(d.InputError, match="smallest distance found between the meshes is 3 mm"):
        M.recast(start, translation(3.0))


def test_a_recast_far_away_says_a_lower_bound_of_the_distance_it_can_prove(plate):
    # 1e6 mm up: the boxes' distance bounds the meshes' from below (the message says "at least")
    _, start = plate
    with pytest.raises(d.InputError, match="between the meshes is at least") as raised:
        M.recast(start, translation(1e6))
    said = float(str(raised.value).split("is at least ")[1].split(" mm")[0])
    assert 0.99e6 < said <= 1e6 + 3.0  # the plate lay 3 mm from facing at 3 mm up (above)


def test_a_recast_counts_springs_that_slid_off(plate):
    _, start = plate
    shifted = np.eye(4)
    shifted[0, 3] = 10.0  # the plate slides a quarter of its length along x
    again = M.recast(start, shifted)
    x = start.layer.points[:, 0]
    off = start.layer.source_face[x < -20.0 + 10.0 - 1e-9]  # cells the plate no longer covers
    np.testing.assert_array_equal(np.sort(again.lost["no_hit"]), np.sort(off))
    assert again.kept == len(start.layer) - len(off)
    assert again.counts["lost_no_hit"] == len(off)


def test_recast_checks_its_arguments(plate):
    _, start = plate
    with pytest.raises(d.InputError, match="SpringCast"):
        M.recast(start.layer, np.eye(4))
    with pytest.raises(d.InputError, match="not rigid"):
        M.recast(start, np.diag([2.0, 1, 1, 1]))


# --------------------------------------------------------------------------------------------
# Re-cast at a solved pose: the force the springs carry there
# --------------------------------------------------------------------------------------------
def test_recast_at_a_translated_solution_carries_the_load_exactly():
    # A pure translation is exact in the small-kinematics model: the re-cast springs carry
    # the load to rounding, and the gained springs (newly inside the window) carry nothing.
    pair = geometry.sphere_on_bed_meshes(radius=25.0, thickness=2.0, extent=6.0, n_bed=24, step=3.0)
    cast = M.cast_springs(pair.mesh1, pair.mesh2, **{**pair.options, "max_gap": 1.0})
    law = d.LinearLaw(10.0)
    problem = d.ContactProblem(cast.layer, law, force=(0, 0, -200.0), reference=pair.reference2, free=("uz",))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        solution = d.solve(problem, "newton")
    assert solution.success and solution.u[8] < -0.3  # pushed deeper than... most of the window
    again = M.recast_at_solution(solution, cast)
    new = again.cast.layer
    same = np.isin(new.source_face, cast.layer.source_face)
    start = dict(zip(cast.layer.source_face, cast.layer.gap))
    np.testing.assert_allclose(new.gap[same], [start[f] + solution.u[8] for f in new.source_face[same]], atol=1e-9)
    force = (law.H * np.maximum(-new.gap, 0.0) / new.thickness * new.areas) @ new.normals
    np.testing.assert_allclose(again.force, force, rtol=1e-12)
    np.testing.assert_allclose(again.force, [0.0, 0.0, 200.0], atol=1e-7)
    assert again.force_error < 1e-9 and again.dropped == 0
    report = assess(problem, solution.u, solution.strain, solution.pressure, dropped=again.dropped)
    assert report["dropped_springs"].passed


def test_recast_at_solution_takes_body_1s_motion_out():
    # The bed (body 1) pushed up into the rigid sphere (body 2, held): the same relative
    # motion as the sphere pushed down, so the same re-cast force on body 2.
    pair = geometry.sphere_on_bed_meshes(radius=25.0, thickness=2.0, extent=6.0, n_bed=24, step=3.0)
    cast = pair.cast(max_gap=1.0)
    law = d.LinearLaw(10.0)
    body1 = d.Body(reference=pair.reference1, free=("uz",), force=(0.0, 0.0, 200.0))
    body2 = d.Body(reference=pair.reference2, free=())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        solution = d.solve(d.ContactProblem(cast.layer, law, body1=body1, body2=body2), "newton")
    assert solution.u[2] > 0.3
    again = M.recast_at_solution(solution, cast)
    np.testing.assert_allclose(again.pose, translation(-solution.u[2]), atol=1e-15)
    np.testing.assert_allclose(again.force, [0.0, 0.0, 200.0], atol=1e-7)
    assert again.force_error < 1e-9


def test_recast_at_solution_needs_the_cast_of_its_layer(plate):
    pair, start = plate
    other = M.cast_springs(pair.mesh1, pair.mesh2, pose=translation(0.5), **pair.options)
    problem = d.ContactProblem(other.layer, d.LinearLaw(10.0), force=(0, 0, -10.0), free=("uz",))
    solution = d.solve(problem, "newton")
    with pytest.raises(d.InputError, match="not the layer of this cast"):
        M.recast_at_solution(solution, start)
    with pytest.raises(d.InputError, match="Solution"):
        M.recast_at_solution("solution", start)


def test_body_pose_is_the_exact_rotation_about_the_reference():
    u6 = np.array([0.1, -0.2, 0.3, 0.02, -0.05, 0.01])
    c = np.array([1.0, 2.0, 3.0])
    T = M.body_pose(u6, c)
    np.testing.assert_allclose(T[:3, :3].T @ T[:3, :3], np.eye(3), atol=1e-15)
    np.testing.assert_allclose(T[:3, :3] @ c + T[:3, 3], c + u6[:3], atol=1e-14)  # the reference moves by t
    axis = u6[3:] / np.linalg.norm(u6[3:])
    np.testing.assert_allclose(T[:3, :3] @ axis, axis, atol=1e-15)  # the axis is fixed
    u = np.concatenate([u6, u6])
    np.testing.assert_allclose(M.relative_pose(u, c, c), np.eye(4), atol=1e-14)


# --------------------------------------------------------------------------------------------
# Targets: kept on the layer, the tangent-plane gap at another pose
# --------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def hip():
    pair = geometry.hip_meshes(step=3.0)
    return pair, M.cast_springs(pair.mesh1, pair.mesh2, max_gap=3.0, max_overlap=3.0)


def test_targets_are_the_hits_in_mesh_2s_own_frame(hip):
    pair, cast = hip
    layer = cast.layer
    assert layer.has_targets
    np.testing.assert_array_equal(layer.target_faces, cast.hit_face)
    np.testing.assert_allclose(layer.target_points, cast.hit_point, atol=1e-12)  # pose = identity
    np.testing.assert_allclose(layer.target_normals, pair.mesh2.face_normals[layer.target_faces], atol=1e-15)
    # each target lies on its face of mesh 2: on its plane and inside its triangle
    tri = pair.mesh2.triangles[layer.target_faces]
    off_plane = np.einsum("ij,ij->i", layer.target_points - tri[:, 0], layer.target_normals)
    assert np.abs(off_plane).max() < 1e-9
    bary = trimesh.triangles.points_to_barycentric(tri, layer.target_points)
    assert bary.min() > -1e-9
    np.testing.assert_allclose(M.tangent_plane_gap(layer, np.eye(4)), layer.gap, atol=1e-12)


def test_targets_are_kept_in_mesh_2s_frame_under_a_pose(hip):
    pair, _ = hip
    pose = rotation_about((1.0, 0.0, 0.0), 2.0, (0.0, 0.0, -0.5))
    cast = M.cast_springs(pair.mesh1, pair.mesh2, pose=pose, max_gap=3.0, max_overlap=3.0)
    layer = cast.layer
    moved = layer.target_points @ pose[:3, :3].T + pose[:3, 3]
    np.testing.assert_allclose(moved, cast.hit_point, atol=1e-12)
    np.testing.assert_allclose(layer.target_normals, pair.mesh2.face_normals[layer.target_faces], atol=1e-15)


# The hip's faces are about 1.2 mm across (3 deg steps on 24 mm spheres); the poses move
# the targets by 0.05-0.1 mm.
POSES = {
    "rotation 0.05 deg about a far point": rotation_about((0.3, 1.0, 0.2), 0.05, (40.0, -30.0, 60.0)),
    "translation 0.05 mm": np.array([[1, 0, 0, 0.03], [0, 1, 0, -0.02], [0, 0, 1, -0.035], [0, 0, 0, 1.0]]),
    "rotation 0.2 deg about the centre plus 0.03 mm": rotation_about((1.0, -1.0, 0.5), 0.2, (0.0, 0.0, -0.5))
    @ np.array([[1, 0, 0, 0], [0, 1, 0, 0.01], [0, 0, 1, -0.03], [0, 0, 0, 1.0]]),
}


@pytest.mark.parametrize("name", POSES)
def test_tangent_plane_gap_equals_a_fresh_cast_where_the_target_stays_on_its_face(hip, name):
    pair, cast = hip
    pose = POSES[name]
    fresh = M.cast_springs(pair.mesh1, pair.mesh2, pose=pose, max_gap=3.0, max_overlap=3.0).layer
    predicted = M.tangent_plane_gap(cast.layer, pose)
    _, i, j = np.intersect1d(cast.layer.source_face, fresh.source_face, return_indices=True)
    same_face = cast.layer.target_faces[i] == fresh.target_faces[j]
    # the pose moves the targets by less than a face: most stay on their face
    assert same_face.mean() > 0.8, same_face.mean()
    np.testing.assert_allclose(predicted[i][same_face], fresh.gap[j][same_face], rtol=0, atol=1e-9)
    # where the hit moved to another face, the tangent plane is only an approximation
    assert np.abs(predicted[i][~same_face] - fresh.gap[j][~same_face]).max() > 1e-9


def test_targets_survive_subset_concatenate_and_with_gap(hip):
    _, cast = hip
    layer = cast.layer
    mask = layer.points[:, 0] > 0
    part = layer.subset(mask)
    for name in ("target_points", "target_normals", "target_faces", "source_face", "gap", "points"):
        np.testing.assert_array_equal(getattr(part, name), getattr(layer, name)[mask])
    by_index = layer.subset(np.flatnonzero(~mask))
    whole = d.SpringLayer.concatenate([part, by_index])
    order = np.concatenate([np.flatnonzero(mask), np.flatnonzero(~mask)])
    for name in ("target_points", "target_normals", "target_faces", "source_face", "areas"):
        np.testing.assert_array_equal(getattr(whole, name), getattr(layer, name)[order])
    assert whole.surface[1].shape == layer.surface[1].shape  # one shared surface, not stacked
    np.testing.assert_array_equal(layer.with_gap(0.0).target_faces, layer.target_faces)
    labelled = d.SpringLayer.concatenate([part, by_index], labels=["medial", "lateral"])
    assert (labelled.labels == np.repeat(["medial", "lateral"], [len(part), len(by_index)])).all()


def test_concatenating_layers_of_two_surfaces_stacks_them():
    pair = geometry.knee_meshes(n_plateau=8, step=6.0)
    a = M.springs_from_meshes(pair.mesh1, pair.mesh2, **pair.options)
    b = M.springs_from_meshes(
        geometry.slab_mesh(4.0, 4.0, 1.0, 2, 2),
        geometry.slab_mesh(4.0, 4.0, 1.0, 2, 2, top=0.5, facing="down"),
        thickness2=0.0,
    )
    both = d.SpringLayer.concatenate([a, b])
    faces = both.surface[1][both.source_face]
    corners = both.surface[0][faces].mean(axis=1)
    np.testing.assert_allclose(corners, both.points, atol=1e-12)  # each spring sits on its face
    assert both.labels is None  # b has no labels
    assert both.has_targets


def test_layers_without_meshes_have_no_targets():
    layer = geometry.plate_layer(4.0, 2.0, 4, 2)
    assert not layer.has_targets and layer.target_points is None
    assert layer.subset([0, 1]).target_faces is None
    with pytest.raises(d.InputError, match="only springs cast from meshes"):
        M.tangent_plane_gap(layer, np.eye(4))


@pytest.mark.parametrize(
    "given, words",
    [
        ({"target_points": np.zeros((8, 3))}, "given together"),
        (
            {
                "target_points": np.zeros((8, 3)),
                "target_normals": np.tile([0, 0, 2.0], (8, 1)),
                "target_faces": np.zeros(8, dtype=int),
            },
            "unit vectors",
        ),
        (
            {
                "target_points": np.zeros((8, 3)),
                "target_normals": np.tile([0, 0, 1.0], (8, 1)),
                "target_faces": np.zeros(8),
            },
            "target_faces must be integers",
        ),
        (
            {
                "target_points": np.zeros((7, 3)),
                "target_normals": np.tile([0, 0, 1.0], (8, 1)),
                "target_faces": np.zeros(8, dtype=int),
            },
            "target_points must have shape",
        ),
    ],
)
def test_bad_targets_are_named(given, words):
    layer = geometry.plate_layer(4.0, 2.0, 4, 2)
    with pytest.raises(d.InputError, match=words):
        d.SpringLayer(layer.points, layer.normals, layer.areas, layer.thickness, **given)


@pytest.mark.parametrize(
    "index, words",
    [
        (np.ones(3, dtype=bool), "boolean index"),
        (np.array([0.5]), "integer indices"),
        (np.array([99]), "lie in"),
    ],
)
def test_bad_subsets_are_named(index, words):
    with pytest.raises(d.InputError, match=words):
        geometry.plate_layer(4.0, 2.0, 4, 2).subset(index)


def test_bad_concatenations_are_named():
    layer = geometry.plate_layer(4.0, 2.0, 4, 2)
    with pytest.raises(d.InputError, match="non-empty sequence"):
        d.SpringLayer.concatenate([])
    with pytest.raises(d.InputError, match="one label per layer"):
        d.SpringLayer.concatenate([layer, layer], labels=["a"])


def test_a_mesh_pair_gives_its_cast_and_the_cast_recasts():
    pair = geometry.knee_meshes(n_plateau=12, step=4.0)
    cast = pair.cast()
    np.testing.assert_array_equal(cast.layer.source_face, pair.layer().source_face)
    assert set(cast.layer.labels) == {"medial", "lateral"}
    again = M.recast(cast, translation(-0.5))
    assert again.kept == len(cast.layer) and again.dropped == 0
    label_of = dict(zip(cast.layer.source_face.tolist(), cast.layer.labels.tolist()))
    assert again.cast.layer.labels.tolist() == [label_of[f] for f in again.cast.layer.source_face.tolist()]
