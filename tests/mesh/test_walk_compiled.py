"""The walk's two loops, compiled (``dea_opt/mesh/_walk.c``) and numpy, against closed forms and each other.

The pass of :meth:`~dea_opt.mesh.walk.Planes.track` (where springs' hits are at a pose, which left
their face and where to) and the scan of :func:`~dea_opt.mesh.walk.window_faces` (the faces whose ray meets the plane of what
it met before within a window) likewise: on a flat grid the gaps are the heights, on the hip the
two scans find the same faces.

On a flat grid the face a ray crosses, and where, are known in closed form; on the embedded hip
turned by large rotations (walks of many steps, rays that leave the mesh, run out of steps, or
meet a face edge-on) the two loops must give the same faces and the same numbers, bit for bit.
Every walk the install has is tested: numpy always, the compiled one where it was built (the
README's install builds it wherever a C compiler is at hand).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import trimesh

from dea_opt import mesh as M
from dea_opt.formulations.finite.rotations import rotation
from dea_opt.geometry import hip_meshes
from dea_opt.mesh.walk import ON_FACE, Planes, Walker, compiled_walk, window_faces

WALKS = ["numpy"] + (["compiled"] if compiled_walk() is not None else [])


def _walker(planes, walk, steps=4):
    return Walker(planes, steps, compiled=walk == "compiled")


def _grid(n=6, size=1.0):
    """A flat n x n grid of squares in z = 0, each cut along its diagonal into two triangles."""
    xs = np.arange(n + 1) * size
    vertices = np.array([(x, y, 0.0) for y in xs for x in xs])
    faces = []
    for j in range(n):
        for i in range(n):
            a, b, c, d = j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i, (j + 1) * (n + 1) + i + 1
            faces += [(a, b, d), (a, d, c)]
    return trimesh.Trimesh(vertices, np.array(faces), process=False)


def _face_at(mesh, x, y):
    """The face of ``_grid`` holding (x, y) strictly inside (closed form: its square, then its side of the diagonal)."""
    n = int(round(np.sqrt(len(mesh.faces) / 2)))
    i, j = int(np.floor(x)), int(np.floor(y))
    if not (0 <= i < n and 0 <= j < n):
        return -1
    return 2 * (j * n + i) + (0 if (x - i) > (y - j) else 1)


@pytest.mark.parametrize("walk", WALKS)
def test_on_a_flat_grid_the_walk_ends_on_the_face_below_the_ray_at_its_height(walk):
    mesh = _grid()
    planes = Planes(mesh)
    rng = np.random.default_rng(3)
    k = 400
    # points inside the grid away from the edges and diagonals, rays tilted downward from above
    cell = rng.integers(0, 6, size=(k, 2))
    local = rng.uniform(0.05, 0.95, size=(k, 2))
    local[:, 1] = np.where(np.abs(local[:, 0] - local[:, 1]) < 0.05, local[:, 0] - 0.1, local[:, 1]).clip(0.02)
    target = np.column_stack([cell + local, np.zeros(k)])
    directions = np.column_stack([rng.uniform(-0.3, 0.3, size=(k, 2)), -np.ones(k)])
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    height = rng.uniform(0.5, 3.0, size=k)
    origins = target - height[:, None] * directions
    expected = np.array([_face_at(mesh, x, y) for x, y, _ in target])
    start = np.array([_face_at(mesh, *np.clip(p[:2] + rng.uniform(-1.0, 1.0, 2), 0.01, 5.99)) for p in target])
    face, t, found, margin, along = _walker(planes, walk, steps=12).follow(start, origins, directions)
    assert found.all()
    assert np.array_equal(face, expected)
    assert np.abs(t - height).max() < 1e-12
    assert np.abs(along - directions[:, 2]).max() < 1e-15  # n = +z: n . d
    assert (margin >= -ON_FACE).all() and (margin <= 1.0 / 3.0 + 1e-12).all()


@pytest.mark.parametrize("walk", WALKS)
def test_rays_that_leave_the_grid_run_out_of_steps_or_lie_in_its_plane_are_not_found(walk):
    mesh = _grid()
    planes = Planes(mesh)
    down = np.array([0.0, 0.0, -1.0])
    origins = np.array(
        [
            [7.5, 3.5, 1.0],  # beyond the grid's edge: the walk stops at the boundary
            [5.5, 0.5, 1.0],  # inside, but 10 faces from the start: out of steps
            [1.5, 1.5, 0.0],  # in the plane, along it: no crossing
            [1.5, 1.5, 1.0],  # a start that names no face
            [2.2, 2.7, 1.0],  # settled where it starts
        ]
    )
    directions = np.array([down, down, [1.0, 0.0, 0.0], down, down])
    start = np.array(
        [_face_at(mesh, 5.5, 3.5), _face_at(mesh, 0.5, 0.5), 0, len(mesh.faces) + 7, _face_at(mesh, 2.2, 2.7)]
    )
    face, t, found, margin, along = _walker(planes, walk, steps=3).follow(start, origins, directions)
    assert found.tolist() == [False, False, False, False, True]
    assert np.isnan(t[:4]).all() and (margin[:4] == 0).all() and (along[:4] == 0).all()
    assert (planes.across[face[0]] < 0).any()  # stopped on a face of the grid's edge
    assert face[3] == len(mesh.faces) + 7  # left as given
    assert t[4] == pytest.approx(1.0, abs=1e-15)


@pytest.fixture(scope="module")
def hip():
    """The embedded hip's meshes and their cast (the springs whose rays the walks follow)."""
    pair = hip_meshes(step=2.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return pair, M.cast_springs(pair.mesh1, pair.mesh2)


def _turned(reference, degrees, axis):
    T = np.eye(4)
    R = rotation(np.radians(degrees) * np.asarray(axis, dtype=float) / np.linalg.norm(axis))
    c = np.asarray(reference, dtype=float)
    T[:3, :3], T[:3, 3] = R, c - R @ c + np.array([0.3, -0.2, 0.1])
    return T


@pytest.mark.parametrize("walk", WALKS)
@pytest.mark.parametrize("degrees", [0.5, 4.0, 15.0, 40.0])
def test_every_walk_gives_the_numpy_walk_s_numbers_bit_for_bit(walk, degrees, hip):
    pair, cast = hip
    layer = cast.layer
    T = _turned(pair.reference2, degrees, (1.0, 0.4, -0.2))
    origins = (layer.points - T[:3, 3]) @ T[:3, :3]
    directions = layer.normals @ T[:3, :3]
    planes = Planes(pair.mesh2)
    for steps in (0, 1, 4, 30):
        mine = _walker(planes, walk, steps).follow(layer.target_faces, origins, directions)
        theirs = _walker(planes, "numpy", steps).follow(layer.target_faces, origins, directions)
        for a, b in zip(mine, theirs):
            assert a.dtype == b.dtype and np.array_equal(a, b, equal_nan=True)
    assert 0.0 < theirs.found.mean() <= 1.0


@pytest.mark.parametrize("walk", WALKS)
def test_the_window_scan_keeps_the_faces_whose_ray_meets_the_plane_it_met_within_the_window(walk):
    """Mesh 2 a flat grid in z = 0 (normals +z); rays from heights 0.5, 1.5, ..., 4.5 mm straight
    down onto face 3: their gap is the height less mesh 2's lift, whatever it turns about z. Rays
    that met nothing (-1), name no face, point away, or were tried are left out."""
    planes = Planes(_grid())
    heights = np.arange(10) + 0.5
    centroids = np.column_stack([np.full(10, 2.0), np.full(10, 3.0), heights])
    normals = np.tile([0.0, 0.0, -1.0], (10, 1))
    met = np.full(10, 3, dtype=np.int64)
    met[6], met[7] = -1, len(planes.records) + 2  # met nothing; names no face
    normals[8] = [0.0, 0.0, 1.0]  # points away from the grid
    tried = np.zeros(10, dtype=bool)
    tried[9] = True
    pose = np.eye(4)
    pose[:3, :3] = rotation(np.radians(35.0) * np.array([0.0, 0.0, 1.0]))
    pose[:3, 3] = [0.4, -0.7, 1.0]  # lifted 1 mm: gaps = heights - 1
    found = window_faces(met, tried, centroids, normals, planes, pose, 1.0, 3.0, compiled=walk == "compiled")
    assert found.dtype == np.int64 and found.tolist() == [2, 3]  # gaps 1.5 and 2.5 (0.5 below, 3.5 above)
    found = window_faces(met, tried, centroids, normals, planes, pose, -1.0, 10.0, compiled=walk == "compiled")
    assert found.tolist() == [0, 1, 2, 3, 4, 5]


@pytest.mark.parametrize("walk", WALKS)
@pytest.mark.parametrize("degrees", [0.5, 4.0, 15.0])
def test_every_window_scan_finds_the_numpy_scan_s_faces(walk, degrees, hip):
    pair, cast = hip
    mesh1 = M.Mesh1.of(cast)
    planes = Planes(pair.mesh2)
    T = _turned(pair.reference2, degrees, (1.0, 0.4, -0.2))
    tried = np.zeros(len(cast.met), dtype=bool)
    tried[::3] = True
    for low, high in ((-4.0, 3.0), (-1.0, 0.5), (0.0, 0.0)):
        mine = window_faces(cast.met, tried, mesh1.centroids, mesh1.normals, planes, T, low, high, walk == "compiled")
        theirs = window_faces(cast.met, tried, mesh1.centroids, mesh1.normals, planes, T, low, high, False)
        assert np.array_equal(mine, theirs)
    assert len(window_faces(cast.met, tried, mesh1.centroids, mesh1.normals, planes, T, -4.0, 3.0)) > 10


def _track(planes, walk, pT, nT, s, faces, tested, clear, measured, pose=None, max_angle=60.0):
    """:meth:`Planes.track` with recast_shift 0.01 mm, max_gap 2 mm, the faces' own normals."""
    pose = np.eye(4) if pose is None else pose
    m = planes.normals[np.clip(faces, 0, len(planes.normals) - 1)]
    limits = (0.01, 2.0, max_angle)
    return planes.track(pT, nT, s, np.isfinite(s), pose, faces, tested, clear, measured, m, limits, walk == "compiled")


@pytest.mark.parametrize("walk", WALKS)
def test_the_track_of_hits_on_a_flat_grid_says_which_stayed_moved_or_left_and_where_to(walk):
    """Springs straight down onto the grid (z = 0) from above, at (x, y): their hits are
    (x, y, 0). A hit inside its face stays (tested and clearance written); one that moved less
    than its clearance is not tested; one outside its face left, to the face across the edge it
    crossed (itself at the grid's boundary); one with no valid gap left; of those that stayed,
    one moved more than 0.01 mm from where it was measured, one lies beyond max_gap."""
    mesh = _grid()
    planes = Planes(mesh)
    xy = np.array([[0.3, 0.1], [0.3, 0.1], [1.1, 0.3], [0.3, 0.1], [0.5, 0.2], [0.5, 0.2], [0.5, -0.1]])
    n = len(xy)
    s = np.array([1.0, 1.0, 1.0, np.nan, 1.0, 3.0, 1.0])  # the sixth 3 mm above the grid
    pT = np.vstack([xy.T, np.where(np.isfinite(s), s, 1.0)])
    nT = np.tile([[0.0], [0.0], [-1.0]], (1, n))
    faces = np.array([_face_at(mesh, 0.3, 0.1)] * n, dtype=np.int64)
    faces[4:6] = _face_at(mesh, 0.5, 0.2)
    hits = np.column_stack([xy, np.zeros(n)])
    tested = hits.copy()
    tested[0] += [0.02, 0.0, 0.0]  # moved 0.02 mm: tested again (clearance 0)
    clear = np.zeros(n)
    clear[1] = 0.5  # tested here before, with room to move: not tested
    tested[1] += [0.2, 0.0, 0.0]
    measured = hits.copy()
    measured[4] += [0.0, 0.05, 0.0]  # measured 0.05 mm away
    track = _track(planes, walk, pT, nT, s, faces, tested, clear, measured)
    assert np.abs(track.own[:, np.isfinite(s)] - hits[np.isfinite(s)].T).max() < 1e-14
    assert track.left.tolist() == [False, False, True, True, False, False, True]
    assert track.moved.tolist() == [False, False, False, False, True, False, False]
    assert track.beyond.tolist() == [False, False, False, False, False, True, False]
    assert not track.turned.any()
    # the first square's lower triangle is left through its edge x = 1, across which lies the next
    # square's upper triangle (which holds the hit); at y < 0 the boundary: the face itself
    assert track.next[2] == _face_at(mesh, 1.1, 0.3) == 3 and track.next[6] == faces[6]
    assert track.next[[0, 1, 4, 5]].tolist() == [-1] * 4 and track.next[3] >= 0  # (no gap: from a face)
    assert np.array_equal(tested[0], hits[0]) and clear[0] > 0.0  # tested: found on its face
    assert clear[1] == 0.5 and np.array_equal(tested[1], hits[1] + [0.2, 0.0, 0.0])  # not tested


@pytest.mark.parametrize("walk", WALKS)
@pytest.mark.parametrize("degrees", [0.5, 4.0, 15.0])
def test_every_track_gives_the_numpy_track_s_numbers_bit_for_bit(walk, degrees, hip):
    pair, cast = hip
    layer = cast.layer
    T = _turned(pair.reference2, degrees, (1.0, 0.4, -0.2))
    own = (layer.points - T[:3, 3]) @ T[:3, :3]
    s = M.Mesh2.of(cast).planes.distance(layer.target_faces, own, layer.normals @ T[:3, :3])
    planes = Planes(pair.mesh2)
    rng = np.random.default_rng(int(degrees * 10))
    clear = np.where(rng.random(len(layer)) < 0.5, rng.uniform(0.0, 0.5, len(layer)), 0.0)
    outs = []
    for kind in (walk, "numpy"):
        tested, room = layer.target_points.copy(), clear.copy()
        track = _track(planes, kind, layer.points.T, layer.normals.T, s, layer.target_faces, tested, room,
                       layer.target_points, T)  # fmt: skip
        outs.append((*track, tested, room))
    for a, b in zip(*outs):
        assert a.dtype == b.dtype and np.array_equal(a, b, equal_nan=True)
    assert 0 < outs[1][1].sum() < len(layer)  # some left their face, some stayed


@pytest.mark.parametrize("walk", WALKS)
def test_a_ray_turned_past_max_angle_on_its_face_is_met_again_there(walk):
    """Springs 1 mm above the grid, tilted 30 and 50 deg from straight down: with max_angle 40 deg
    the second, on its face still, is met again from that face (a cast loses it for its angle)."""
    mesh = _grid()
    planes = Planes(mesh)
    tilt = np.radians([30.0, 50.0])
    nT = np.vstack([np.sin(tilt), np.zeros(2), -np.cos(tilt)])
    s = 1.0 / np.cos(tilt)
    hits = np.array([[2.5, 3.2, 0.0], [2.5, 3.2, 0.0]])
    pT = hits.T - s * nT
    faces = np.array([_face_at(mesh, 2.5, 3.2)] * 2, dtype=np.int64)
    tested, clear = hits.copy(), np.full(2, 0.3)  # not tested again: the angle is looked at anyway
    track = _track(planes, walk, pT, nT, s, faces, tested, clear, hits.copy(), max_angle=40.0)
    assert track.turned.tolist() == [False, True] and track.left.tolist() == [False, True]
    assert track.next.tolist() == [-1, faces[1]] and not track.moved.any()
    assert np.abs(track.own - hits.T).max() < 1e-14
