"""Motions from the model's coordinates (.sto/.mot) and from relative 4x4 poses, with their errors."""

from __future__ import annotations

import numpy as np
import pytest
from osim_models import write_model
from scipy.spatial.transform import Rotation

import dea_opt as d
from dea_opt.opensim import read_model
from dea_opt.opensim.motion import coordinate_motion, read_pose_table, relative_motion, resolve_frame


def _sto(path, labels, rows, degrees="no"):
    lines = [
        "motion",
        "version=1",
        f"nRows={len(rows)}",
        f"nColumns={len(labels)}",
        f"inDegrees={degrees}",
        "endheader",
    ]
    lines.append("\t".join(labels))
    lines += ["\t".join(repr(float(v)) for v in row) for row in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture
def model(tmp_path):
    return read_model(write_model(tmp_path))


def test_a_coordinate_motion_poses_the_bodies_frame_by_frame(model, tmp_path):
    rng = np.random.default_rng(11)
    rows = np.c_[np.linspace(0, 1, 6), rng.uniform(-1, 1, (6, 4))]
    labels = ["time", "g1", "/jointset/j1/q1/value", "q4", "/jointset/j1/q3/speed"]
    motion = coordinate_motion(model, _sto(tmp_path / "m.sto", labels, rows), ["a", "b"])
    assert np.array_equal(motion.times, rows[:, 0]) and motion.unused == ("/jointset/j1/q3/speed",)
    assert set(motion.coordinates) == {"g1", "q1", "q4"}
    for k, row in enumerate(rows):
        expected = model.poses({"g1": row[1], "q1": row[2], "q4": row[3]})
        assert np.allclose(motion.poses["a"][k], expected["a"], atol=1e-12)
        assert np.allclose(motion.poses["b"][k], expected["b"], atol=1e-12)


def test_degrees_convert_rotational_coordinates_only(model, tmp_path):
    rows = [[0.0, 30.0, 0.01], [1.0, -45.0, 0.02]]
    motion = coordinate_motion(model, _sto(tmp_path / "deg.mot", ["time", "q1", "q4"], rows, "yes"), ["b"])
    assert np.allclose(motion.coordinates["q1"], np.radians([30.0, -45.0]))
    assert np.array_equal(motion.coordinates["q4"], [0.01, 0.02])  # translational: m as written
    with pytest.raises(d.InputError, match="q2, a coupled coordinate"):
        coordinate_motion(model, _sto(tmp_path / "c.mot", ["time", "q2"], [[0.0, 1.0]], "yes"), ["b"])
    with pytest.raises(d.InputError, match="inDegrees"):
        coordinate_motion(model, _sto(tmp_path / "n.mot", ["time", "q1"], [[0.0, 1.0]], ""), ["b"])


def test_bad_motion_files(model, tmp_path):
    with pytest.raises(d.InputError, match="none of its columns names a coordinate"):
        coordinate_motion(model, _sto(tmp_path / "x.sto", ["time", "hip"], [[0.0, 1.0]]), ["b"])
    bad = tmp_path / "bad.sto"
    bad.write_text("motion\nendheader\ntime\tq1\n0\tabc\n")
    with pytest.raises(d.InputError, match=r"motion .*bad.sto, line 4, column q1"):
        coordinate_motion(model, bad, ["b"])
    with pytest.raises(d.OpenSimModelError, match="has no body 'zz'"):
        coordinate_motion(model, _sto(tmp_path / "ok.sto", ["time", "q1"], [[0.0, 1.0]]), ["zz"])


def test_a_relative_motion_holds_the_reference_and_moves_the_other_body(model):
    rng = np.random.default_rng(5)
    T = np.tile(np.eye(4), (4, 1, 1))
    T[:, :3, :3] = Rotation.from_rotvec(rng.normal(0, 0.3, (4, 3))).as_matrix()
    T[:, :3, 3] = rng.normal(0, 10, (4, 3))
    motion = relative_motion(model, T, "b", "a_offset", times=[0, 1, 2, 3])
    held = model.poses()["a"]
    X_a = held @ model.frame_in_body("/bodyset/a/a_offset")
    for k in range(4):
        assert np.array_equal(motion.poses["a"][k], held)
        # the pose of b in the reference frame is the table's
        assert np.allclose(np.linalg.inv(X_a) @ motion.poses["b"][k], T[k], atol=1e-10)
    assert resolve_frame(model, "a_offset") == "/bodyset/a/a_offset" and resolve_frame(model, "b") == "/bodyset/b"


def test_bad_relative_motions(model, tmp_path):
    with pytest.raises(d.InputError, match="both fixed to a"):
        relative_motion(model, np.eye(4)[None], "a", "a_offset")
    skew = np.eye(4)[None].copy()
    skew[0, 0, 1] = 0.01
    with pytest.raises(d.InputError, match="frame 0: not a rigid transform"):
        relative_motion(model, skew, "b", "a")
    mirror = np.diag([1.0, 1.0, -1.0, 1.0])[None]
    with pytest.raises(d.InputError, match="not a rigid transform"):
        relative_motion(model, mirror, "b", "a")
    with pytest.raises(d.OpenSimModelError, match="has no frame 'zz'"):
        relative_motion(model, np.eye(4)[None], "zz", "a")
    table = tmp_path / "poses.csv"
    table.write_text("t,T00,T01\n0,1,0\n")
    with pytest.raises(d.InputError, match="lacks the columns T02"):
        read_pose_table(table)
    header = "t," + ",".join(f"T{i}{j}" for i in range(4) for j in range(4))
    table.write_text(header + "\n0," + ",".join(["1"] * 15 + ["x"]) + "\n")
    with pytest.raises(d.InputError, match="line 2"):
        read_pose_table(table)
    table.write_text(header + "\n0.5," + ",".join(str(v) for v in np.eye(4).ravel()) + "\n")
    times, T = read_pose_table(table)
    assert times.tolist() == [0.5] and np.array_equal(T[0], np.eye(4))
