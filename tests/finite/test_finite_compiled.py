"""A finite-kinematics system's passes over its springs, compiled (``_finite.c``) and numpy, against
closed forms and each other.

The gap to a plane and the tangent's sum ``G = sum_i w_i a_i v_i^T`` are known in closed form for
a few springs; on the embedded hip's cast springs turned by large rotations the two passes must
agree to rounding (numpy's matrix products group the sums in blocks). Every pass the install has
is tested: numpy always, the compiled one where it was built (the README's install builds it
wherever a C compiler is at hand). A whole Newton solve gives the same answer either way.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import dea_opt as dea
from dea_opt import mesh as M
from dea_opt.formulations.finite import geometry as finite_geometry
from dea_opt.formulations.finite import system as finite_system
from dea_opt.formulations.finite.geometry import MISSED, PlaneRows, Targets, plane_gaps
from dea_opt.formulations.finite.rotations import pose_matrix
from dea_opt.formulations.finite.system import stiffness_sum
from dea_opt.geometry import hip_meshes

PASSES = ["numpy"] + (["compiled"] if finite_geometry.compiled_system() is not None else [])


def _hip():
    pair = hip_meshes(step=2.0)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cast = M.cast_springs(pair.mesh1, pair.mesh2)
    return cast, pair.reference2


@pytest.mark.parametrize("way", PASSES)
def test_the_gap_to_a_turned_and_shifted_plane_is_the_closed_form(way):
    # springs at p along n = -z meet the plane z = 0 of normal +z moved by a rotation about x
    # by a and a lift h: the plane's normal (0, -sin a, cos a), through (0, 0, h), so
    # s = (h - p . m') / (n . m') with n . m' = -cos a; turned past 90 deg it faces away
    points = np.array([[0.0, 0.0, 2.0], [1.0, -2.0, 3.0], [0.5, 4.0, 1.5]])
    normals = np.tile([0.0, 0.0, -1.0], (3, 1))
    targets = Targets.planes(np.zeros((3, 3)), np.tile([0.0, 0.0, 1.0], (3, 1)))
    rows = PlaneRows(targets, points, normals)
    for degrees, lift in ((0.0, 0.0), (20.0, 0.7), (-35.0, -0.4), (100.0, 0.0)):
        a = np.radians(degrees)
        T = pose_matrix([0.0, 0.0, lift, a, 0.0, 0.0], np.zeros(3))
        gaps = plane_gaps(rows, T, compiled=way == "compiled")
        m = np.array([0.0, -np.sin(a), np.cos(a)])
        along = -np.cos(a)
        expected = (lift * np.cos(a) - points @ m) / along if along < 0 else np.full(3, MISSED)
        assert np.allclose(gaps.s, expected, rtol=1e-14, atol=1e-14)
        assert np.allclose(gaps.mT.T, np.tile(m, (3, 1)), atol=1e-15)
        assert np.allclose(gaps.along, along, atol=1e-15)
        assert gaps.valid.all() == (along < 0)


@pytest.mark.parametrize("way", PASSES)
def test_the_tangent_s_sum_is_the_sum_of_each_spring_s_outer_product(way):
    rng = np.random.default_rng(11)
    k = 7
    w = rng.uniform(0.5, 2.0, k)
    w[[1, 4]] = 0.0  # open springs: nothing, whatever their gap
    s = rng.uniform(-0.3, 0.1, k)
    s[4] = np.inf  # a missed target
    pT, nT, mT = (rng.normal(size=(3, k)) for _ in range(3))
    arms = rng.normal(size=(6, k))
    expected = np.zeros((6, 6))
    for i in range(k):
        if w[i]:
            hit = pT[:, i] + s[i] * nT[:, i]
            v = np.concatenate([mT[:, i], np.cross(hit, mT[:, i])])
            expected += w[i] * np.outer(arms[:, i], v)
    G = stiffness_sum(w, s, pT, nT, mT, arms, compiled=way == "compiled")
    assert np.isfinite(G).all()
    assert np.allclose(G, expected, rtol=1e-13, atol=1e-13)
    w[2] = np.nan  # a law's NaN is summed, and shows
    assert np.isnan(stiffness_sum(w, s, pT, nT, mT, arms, compiled=way == "compiled")).all(axis=1).any()


@pytest.mark.parametrize("way", PASSES)
@pytest.mark.parametrize("degrees", [0.5, 10.0, 40.0])
def test_on_the_hip_turned_far_both_passes_agree_to_rounding(way, degrees):
    cast, reference = _hip()
    layer = cast.layer
    targets = Targets.from_layer(layer, cast.pose)
    rows = PlaneRows(targets, layer.points, layer.normals)
    axis = np.array([1.0, 0.4, -0.2]) / np.linalg.norm([1.0, 0.4, -0.2])
    T = pose_matrix([0.3, -0.2, 0.1, *(np.radians(degrees) * axis)], reference) @ targets.frame
    mine = plane_gaps(rows, T, compiled=way == "compiled")
    theirs = plane_gaps(rows, T, compiled=False)
    assert np.array_equal(mine.valid, theirs.valid)
    scale = np.abs(layer.points).max()
    assert np.abs(mine.s[mine.valid] - theirs.s[theirs.valid]).max() <= 1e-12 * scale
    assert np.abs(mine.mT - theirs.mT).max() <= 1e-15 * 4 and np.abs(mine.along - theirs.along).max() <= 1e-15 * 4
    # the tangent's sum on those gaps, weights where the springs are compressed
    w = np.where(mine.valid & (mine.s < 0), layer.areas / layer.thickness, 0.0)
    arms = finite_system.arms_of(rows.pT, rows.nT)
    G = stiffness_sum(w, mine.s, rows.pT, rows.nT, mine.mT, arms, compiled=way == "compiled")
    G0 = stiffness_sum(w, theirs.s, rows.pT, rows.nT, theirs.mT, arms, compiled=False)
    assert w.any() and np.abs(G - G0).max() <= 1e-12 * np.abs(G0).max()


@pytest.mark.parametrize("way", PASSES)
def test_rows_that_are_views_of_longer_buffers_are_read_as_they_are(way):
    # the springs' rows of a solve live in longer buffers: a view of their first columns
    rng = np.random.default_rng(5)
    k = 50
    room = rng.normal(size=(3, 3, k + 30))
    pT, nT, mT = room[0][:, :k], room[1][:, :k], room[2][:, :k]
    mT = mT / np.linalg.norm(mT, axis=0)
    room[2][:, :k] = mT
    mT = room[2][:, :k]
    q = rng.normal(size=(k, 3))
    own = (np.ascontiguousarray(a) for a in (pT, nT, mT))
    contiguous = PlaneRows.of_rows(pT.T, nT.T, *own, np.einsum("ij,ji->i", q, mT))
    viewed = PlaneRows.of_rows(pT.T, nT.T, pT, nT, mT, contiguous.qm)
    T = pose_matrix([0.1, 0.2, 0.3, 0.2, -0.1, 0.3], np.ones(3))
    a = plane_gaps(viewed, T, compiled=way == "compiled")
    b = plane_gaps(contiguous, T, compiled=way == "compiled")
    assert np.array_equal(a.s, b.s) and np.array_equal(a.mT, b.mT) and np.array_equal(a.along, b.along)
    w = np.where(a.valid, rng.uniform(size=k), 0.0)  # nothing where a ray misses its plane
    assert 0 < a.valid.sum() < k
    arms = finite_system.arms_of(np.ascontiguousarray(pT), np.ascontiguousarray(nT))
    wide = np.zeros((6, k + 30))
    wide[:, :k] = arms
    assert np.array_equal(
        stiffness_sum(w, a.s, pT, nT, a.mT, wide[:, :k], compiled=way == "compiled"),
        stiffness_sum(w, a.s, *(np.ascontiguousarray(x) for x in (pT, nT)), a.mT, arms, compiled=way == "compiled"),
    )


def _refuses_arrays_of_the_wrong_shape_or_type():
    kernel = finite_geometry.compiled_system()
    k = 4
    good = [np.zeros(k), np.zeros(k), np.zeros((3, k)), np.zeros((3, k)), np.zeros((3, k)), np.zeros((6, k))]
    for index, bad in ((5, np.zeros((5, k))), (0, np.zeros(k, dtype=np.float32)), (2, np.zeros((3, k + 1)))):
        args = list(good)
        args[index] = bad
        with pytest.raises(ValueError, match="expected"):
            kernel.tangent_sum(k, *args, np.zeros((6, 6)))
    with pytest.raises(ValueError, match="out"):
        kernel.tangent_sum(k, *good, np.zeros((5, 6)))
    with pytest.raises(ValueError, match="C-contiguous"):  # a view of a wider matrix: not one block
        kernel.tangent_sum(k, *good, np.zeros((6, 12))[:, :6])
    with pytest.raises(TypeError):
        kernel.tangent_sum(k, [0.0] * k, *good[1:], np.zeros((6, 6)))
    rows, out = [np.zeros((3, k))] * 3, [np.zeros(k), np.zeros((3, k)), np.zeros(k), np.zeros(k)]
    with pytest.raises(ValueError, match="transform"):
        kernel.plane_gaps(k, 1e-9, np.inf, np.eye(4)[:, :3], *rows, *out)
    with pytest.raises(ValueError, match="negative"):
        kernel.plane_gaps(-1, 1e-9, np.inf, np.eye(4), *rows, *out)


if "compiled" in PASSES:  # split by what the install has: the compiled passes where they were built
    test_the_compiled_passes_refuse_arrays_of_the_wrong_shape_or_type = _refuses_arrays_of_the_wrong_shape_or_type


def test_a_finite_solve_gives_the_same_answer_with_the_numpy_passes(monkeypatch):
    cast, reference = _hip()
    # the head turned 10 deg (prescribed) and pressed into the cup: springs re-cast as it goes
    body2 = dea.Body(
        reference=reference, free=("ux", "uy", "uz"), force=(50.0, -30.0, -400.0), prescribed={"rx": np.radians(10.0)}
    )
    problem = dea.ContactProblem(cast.layer, dea.LinearLaw(10.0), body2=body2, kinematics="finite", targets=cast)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        compiled = dea.solve(problem)
        monkeypatch.setattr(finite_geometry, "compiled_system", lambda: None)
        monkeypatch.setattr(finite_system, "compiled_system", lambda: None)
        plain = dea.solve(problem)
    assert compiled.success and plain.success
    assert compiled.info["recast"]["updates"] >= 1
    assert np.abs(compiled.x - plain.x).max() <= 1e-9
    assert np.abs(compiled.pressure.max() - plain.pressure.max()) <= 1e-9 * plain.pressure.max()
