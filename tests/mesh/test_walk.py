"""Rays followed across a mesh's edges, and the casts of some faces that start from them.

The walk (``dea_opt.mesh.walk``) must give the face and distance Embree's first hit gives, to
rounding, wherever it settles a ray; a thickness measured by following the far side must be the
one a ray cast measures; the clearance a hit may move and stay on its face must hold for random
points; the casts of chosen faces (``cast_faces``, ``follow_faces``) must judge every face as a
whole cast at the same pose does, on the embedded hip turned by large rotations.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from dea_opt import mesh as M
from dea_opt.formulations.finite.rotations import rotation
from dea_opt.geometry import hip_meshes
from dea_opt.mesh import facecast, raycast
from dea_opt.mesh.walk import Planes, Walker


@pytest.fixture(scope="module")
def hip():
    pair = hip_meshes(step=2.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cast = M.cast_springs(pair.mesh1, pair.mesh2)
    return pair, cast


def _turned(reference, degrees, axis, shift=(0.0, 0.0, 0.0)):
    T = np.eye(4)
    R = rotation(np.radians(degrees) * np.asarray(axis, dtype=float) / np.linalg.norm(axis))
    c = np.asarray(reference, dtype=float)
    T[:3, :3], T[:3, 3] = R, c - R @ c + np.asarray(shift)
    return T


def test_the_faces_across_each_edge_are_trimesh_s_face_adjacency(hip):
    pair, _ = hip
    for mesh in (pair.mesh1, pair.mesh2):
        across = Planes(mesh).across
        mine = {tuple(sorted((f, g))) for f, row in enumerate(across) for g in row if g >= 0}
        theirs = {tuple(sorted(p)) for p in np.asarray(mesh.face_adjacency).tolist()}
        assert mine == theirs
        # each face's edge k is opposite its corner k: the neighbour shares the other two corners
        faces = np.asarray(mesh.faces)
        for f in range(0, len(faces), 37):
            for k in range(3):
                g = across[f, k]
                if g >= 0:
                    shared = set(faces[f]) - {faces[f, k]}
                    assert shared <= set(faces[g])


@pytest.mark.parametrize("degrees, settled", [(0.5, 0.9), (3.0, 0.3), (8.0, 0.0)])
def test_a_walk_from_the_face_met_before_settles_on_embree_s_first_hit(hip, degrees, settled):
    pair, cast = hip
    layer = cast.layer
    T = _turned(pair.reference2, degrees, (1.0, 0.4, -0.2), (0.1, -0.2, 0.05))
    origins = (layer.points - T[:3, 3]) @ T[:3, :3]
    directions = layer.normals @ T[:3, :3]
    face, t, found, _, _ = Walker(Planes(pair.mesh2)).follow(layer.target_faces, origins, directions)
    assert found.mean() >= settled and found.any()  # a few faces at most: beyond, a ray is cast
    first, dist = raycast._caster(pair.mesh2, "auto").nearest(origins - 5 * directions, directions, 0.0, np.inf)
    dist = dist - 5
    assert np.array_equal(face[found], first[found])
    assert np.abs(t[found] - dist[found]).max() < 1e-9


def test_the_thickness_followed_across_the_far_side_is_the_one_a_ray_measures(hip):
    pair, cast = hip
    m2 = pair.mesh2
    rng = np.random.default_rng(4)
    faces = rng.integers(0, len(m2.faces), 400)
    tri = np.asarray(m2.triangles)[faces]
    b = rng.dirichlet(np.ones(3), len(faces))
    points = np.einsum("ki,kij->kj", b, tri)
    directions = -np.asarray(m2.face_normals)[faces]
    expected = raycast._through(m2, raycast._caster(m2, "auto"), points, directions)
    side = facecast.FarSide(m2, "auto", True, len(m2.faces))
    first, far = side.thickness(faces, points, directions)  # every ray cast (nothing known yet)
    again, _ = side.thickness(faces, points, directions, far)  # every ray walked from its far face
    # elsewhere on the same faces: the far point moves as much, the walk follows it
    moved = np.einsum("ki,kij->kj", rng.dirichlet(np.ones(3), len(faces)), tri)
    moved_expected = raycast._through(m2, raycast._caster(m2, "auto"), moved, directions)
    walked, _ = side.thickness(faces, moved, directions, far)
    for got, want in ((first, expected), (again, expected), (walked, moved_expected)):
        both = np.isfinite(want)
        assert np.array_equal(np.isfinite(got), both)
        assert np.abs(got[both] - want[both]).max() < 1e-9


def test_a_point_moving_less_than_its_clearance_stays_on_its_face(hip):
    pair, _ = hip
    planes = Planes(pair.mesh2)
    rng = np.random.default_rng(7)
    faces = rng.integers(0, len(pair.mesh2.faces), 2000)
    tri = np.asarray(pair.mesh2.triangles)[faces]
    b = rng.dirichlet(np.ones(3), len(faces))
    points = np.einsum("ki,kij->kj", b, tri)
    clearance = planes.clearance(faces, planes.barycentric(points, faces).min(axis=0))
    assert (clearance > 0).mean() > 0.99
    # any move in the face's plane shorter than the clearance stays inside
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    direction = rng.normal(size=(len(faces), 2))
    step = direction[:, :1] * e1 + direction[:, 1:] * e2
    step *= (0.999 * clearance / np.linalg.norm(step, axis=1))[:, None]
    assert planes.inside(points + step, faces).all()


@pytest.mark.parametrize("degrees", [2.0, 6.0])
def test_casts_of_chosen_faces_judge_every_face_as_a_whole_cast(hip, degrees):
    pair, cast = hip
    T = _turned(pair.reference2, degrees, (0.3, 1.0, 0.2), (0.05, 0.05, -0.1))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        whole = M.cast_springs(pair.mesh1, pair.mesh2, pose=T)
    mesh1, mesh2 = M.Mesh1.of(cast), M.Mesh2.of(cast)
    faces = np.arange(len(pair.mesh1.faces))
    allowed = np.full(len(faces), cast.options["max_overlap"])
    by_cast = M.cast_faces(cast, T, faces, allowed, mesh1, mesh2)
    met = np.where(cast.met >= 0, cast.met, 0)  # every ray starts a walk somewhere
    by_walk = M.follow_faces(cast, T, faces, met, allowed, mesh1, mesh2)
    expected = np.asarray(whole.outcome)
    for got in (by_cast, by_walk):
        assert np.array_equal(got.outcome, expected)
        springs = np.flatnonzero(got.spring)
        assert np.array_equal(springs, np.asarray(whole.layer.source_face))
        assert np.array_equal(got.faces2[springs], np.asarray(whole.layer.target_faces))
        assert np.abs(got.gap[springs] - whole.layer.gap).max() < 1e-9
    M.measure(by_walk, mesh1, mesh2)
    springs = by_walk.spring
    assert np.abs((by_walk.h1 + by_walk.h2)[springs] - whole.layer.thickness).max() < 1e-9


def _springs_of(n, seed):
    """Springs of ``n`` made-up faces, every array numbered by face (as a layer and its cast)."""
    from types import SimpleNamespace

    from dea_opt.finite.springs import Springs

    rng = np.random.default_rng(seed)
    faces = rng.permutation(10 * n)[:n]
    layer = SimpleNamespace(
        source_face=faces,
        points=faces[:, None] + np.array([0.1, 0.2, 0.3]),
        normals=faces[:, None] * np.array([1.0, -1.0, 2.0]),
        areas=faces + 0.5,
        target_points=faces[:, None] + np.array([1.1, 1.2, 1.3]),
        target_normals=faces[:, None] * np.array([2.0, 0.0, 1.0]),
        target_faces=faces + 7,
        gap=faces - 0.25,
    )
    return Springs(layer, faces * 0.01, faces * 0.02), faces


def _rows_agree(springs):
    """The rows a system passes over, kept up to date, are those built afresh from the arrays."""
    from dea_opt.formulations.finite import FiniteSystem, Targets

    fresh = FiniteSystem(
        springs.points,
        springs.normals,
        springs.areas,
        springs.h1 + springs.h2,
        Targets.cast_planes(springs.q, springs.m, np.eye(4), springs.faces2),
        np.zeros(3),
        np.array([2]),
        np.zeros(6),
        np.zeros(3),
        np.zeros(3),
    )
    for kept, built in (
        (springs.pT, fresh.planes.pT),
        (springs.nT, fresh.planes.nT),
        (springs.arms, fresh.arms),
        (springs.mT, fresh.planes.mT),
        (springs.qm, fresh.planes.qm),
    ):
        assert kept.shape == built.shape and np.allclose(kept, built, rtol=0, atol=1e-9 * np.abs(built).max())


def _consistent(springs):
    """Every array of every spring still belongs to its face (whatever the order)."""
    _rows_agree(springs)
    f = springs.faces1
    assert np.array_equal(springs.points, f[:, None] + np.array([0.1, 0.2, 0.3]))
    assert np.array_equal(springs.normals, f[:, None] * np.array([1.0, -1.0, 2.0]))
    assert np.array_equal(springs.areas, f + 0.5) and np.array_equal(springs.gap, f - 0.25)
    assert np.array_equal(springs.h1, f * 0.01) and np.array_equal(springs.h2, f * 0.02)
    assert np.array_equal(springs.q, f[:, None] + np.array([1.1, 1.2, 1.3]))
    assert np.array_equal(springs.measured, springs.q) and np.array_equal(springs.tested, springs.q)
    assert np.array_equal(springs.faces2, f + 7)


@pytest.mark.parametrize("seed", range(4))
def test_springs_lost_and_gained_keep_their_arrays_together_and_say_where_they_stood(seed):
    from types import SimpleNamespace

    springs, faces = _springs_of(500, seed)
    rng = np.random.default_rng(100 + seed)
    held = springs.points  # the cast's, read-only: never written
    assert not held.flags.writeable
    present = list(faces)
    for step in range(6):
        kept = rng.random(len(springs)) > rng.choice([0.0, 0.02, 0.5])
        before = np.array(springs.faces1)
        where = springs.keep(kept)
        assert np.array_equal(springs.faces1, before[where])  # each spring from where it stood
        assert sorted(springs.faces1) == sorted(before[kept])  # the kept ones, each once
        _consistent(springs)
        # some meet mesh 2 anew: another normal there (the rows follow), the hit numbered by face
        moved = rng.choice(len(springs), min(len(springs), 40), replace=False)
        f = springs.faces1[moved]
        springs.retarget(moved, f[:, None] + np.array([1.1, 1.2, 1.3]), f[:, None] * np.array([0.0, 3.0, 1.0]))
        assert np.array_equal(springs.m[moved], f[:, None] * np.array([0.0, 3.0, 1.0]))
        _consistent(springs)
        # gained: more than the room left, now and then
        k = int(rng.choice([0, 3, 400]))
        new_faces = 10_000 + 1000 * step + np.arange(k)
        fresh = SimpleNamespace(
            faces=new_faces,
            h1=new_faces * 0.01,
            h2=new_faces * 0.02,
            q=new_faces[:, None] + np.array([1.1, 1.2, 1.3]),
            m=new_faces[:, None] * np.array([2.0, 0.0, 1.0]),
            faces2=new_faces + 7,
            gap=new_faces - 0.25,
            far2=np.full(k, -2),
        )
        mesh1 = SimpleNamespace(
            centroids=np.arange(20_000)[:, None] + np.array([0.1, 0.2, 0.3]),
            normals=np.arange(20_000)[:, None] * np.array([1.0, -1.0, 2.0]),
            areas=np.arange(20_000) + 0.5,
        )
        count = len(springs)
        springs.extend(mesh1, fresh, np.ones(k, dtype=bool))
        assert len(springs) == count + k and np.array_equal(springs.faces1[count:], new_faces)
        _consistent(springs)
        present = list(springs.faces1)
    assert len(set(present)) == len(present)
    assert np.array_equal(held, faces[:, None] + np.array([0.1, 0.2, 0.3]))  # the cast's arrays untouched


def test_rows_put_whole_are_a_fancy_assignment():
    from dea_opt.finite.springs import put_rows

    rng = np.random.default_rng(3)
    # contiguous, the head of a longer array (as the tracker keeps them), a transposed view, a
    # column and no rows at all; values transposed, an index repeated (the last value wins, as in
    # a fancy assignment), a mask and a row broadcast
    for rows in (
        rng.normal(size=(50, 3)),
        rng.normal(size=(60, 3))[:50],
        rng.normal(size=(3, 50)).T,
        rng.normal(size=50),
        np.zeros((0, 3)),
    ):
        n = len(rows)
        for index in (
            rng.choice(n, min(n, 17), replace=False),
            np.array([4, 9, 4][: min(n, 3)], dtype=np.int64)[:n],
            rng.uniform(size=n) < 0.3,
        ):
            k = int(index.sum()) if index.dtype == bool else len(index)
            for values in (rng.normal(size=(k, *rows.shape[1:])), rng.normal(size=(*rows.shape[1:], k)).T):
                expected = np.array(rows)
                expected[index] = values
                put_rows(rows, index, values)
                assert np.array_equal(rows, expected)
        if rows.ndim == 2 and n:
            expected = np.array(rows)
            expected[[1, 2]] = rows[0]
            put_rows(rows, [1, 2], rows[0].copy())
            assert np.array_equal(rows, expected)
