"""An OpenSim model to a run: import-osim writes what dea-opt run takes, an OpenSim joint's coordinates
as a body's dofs, and motions (a table of relative poses, a .sto of the model's coordinates)
prescribing the chosen ones.

The DM knee of ``../shared/data/tka`` is read, imported and run end to end (skipped cleanly where
the data are absent). The coordinates are checked against the OpenSim reader's own joint tree
(itself checked against OpenSim 4.6 in ``tests/test_opensim_reference.py``) and against the
``dm_knee_*`` columns of ``fluoroscopy_poses.csv`` (OpenSim 4.6's numbers, see its README).
"""

from __future__ import annotations

import csv
import re
import tomllib

import numpy as np
import pytest
from conftest import SHARED
from joint_checks import assert_balanced_at_pose
from test_cli import invoke

import dea_opt as d

TKA = SHARED / "data" / "tka"
MESHES = (
    "--mesh",
    f"tibia_implant={TKA / 'tibial_insert.stl'}",
    "--mesh",
    f"femur_implant={TKA / 'femoral_component.stl'}",
)
KNEE = ("knee_tx_r", "knee_ty_r", "knee_tz_r", "knee_flex_r", "knee_add_r", "knee_rot_r")


def _need():
    if not all(
        (TKA / f).is_file() for f in ("DM.osim", "tibial_insert.stl", "femoral_component.stl", "fluoroscopy_poses.csv")
    ):
        pytest.skip(f"the DM knee is not in {TKA}")


@pytest.fixture(scope="module")
def dm():
    _need()
    from dea_opt.opensim import read_model

    return read_model(TKA / "DM.osim")


def _fluoroscopy() -> list:
    with open(TKA / "fluoroscopy_poses.csv", newline="") as handle:
        return list(csv.DictReader(handle))


def _knee(row) -> dict:
    """The DM.osim knee_r coordinates of a fluoroscopy row (OpenSim's units: rad, m)."""
    return {k[3:].rsplit("_", 1)[0]: float(v) for k, v in row.items() if k.startswith("dm_knee")}


def test_the_knee_joint_s_coordinates_move_the_femur_as_the_model_s_joint_tree_does(dm):
    """The femur on a held tibia through knee_r (inverted): its motion at the coordinates of each
    fluoroscopy row is the femur's pose in the tibia's frame from the reader's joint tree, and the
    inverse gives the coordinates back."""
    from dea_opt.opensim.joints import joint_coordinates

    c = joint_coordinates(dm, "knee_r", "femur_r")
    assert c.names == KNEE and c.inverted
    P0 = dm.poses()
    for row in _fluoroscopy()[::20]:
        knee = _knee(row)
        P = dm.poses(knee)
        femur_on_tibia = P0["tibia_r"] @ np.linalg.inv(P["tibia_r"]) @ P["femur_r"]  # the tibia held
        q = np.array([1000.0 * knee[n] if j < 3 else knee[n] for j, n in enumerate(KNEE)])  # mm, rad
        np.testing.assert_allclose(c.motion(q), femur_on_tibia @ np.linalg.inv(P0["femur_r"]), rtol=0, atol=1e-11)
        np.testing.assert_allclose(c.inverse(c.motion(q)), q, rtol=0, atol=1e-10)


def test_import_osim_writes_a_scenario_run_takes_as_it_is_and_with_the_femur_free(tmp_path):
    """DM.osim -> import-osim (the shared STLs are renamed and in mm: --mesh) -> run: every body held
    as written, then with the femur's six knee coordinates free under a compression along the
    insert's axis; the answer balances at its pose by sums written here."""
    _need()
    scenario = tmp_path / "dm.toml"
    result = invoke(
        "import-osim", TKA / "DM.osim", "-o", scenario, "--fixed", "tibia_r", "--leave-out", "patella_r", *MESHES
    )
    assert result.exit_code == 0, result.stderr
    assert "not found" not in result.stderr  # the patellar button is left out, with its pair and bundles
    text = scenario.read_text()
    data = tomllib.loads(text)
    assert [b["name"] for b in data["bodies"]] == ["pelvis", "femur_r", "tibia_r"]
    assert [c["name"] for c in data["contacts"]] == ["knee_contact"]
    assert len(data["ligaments"]) == 89  # 88 femur-tibia bundles and the ITB
    assert re.search(r"# Left out \(--leave-out patella_r\): .*pf_contact, PT1, ", text)
    femur = data["bodies"][1]
    assert femur["coordinates"]["names"] == list(KNEE) and femur["coordinates"]["inverted"] is True
    run = invoke("run", scenario, "-o", tmp_path / "held")
    assert run.exit_code == 0, run.stdout + run.stderr
    assert (tmp_path / "held" / "knee_contact.vtu").is_file() and (tmp_path / "held" / "ligaments.csv").is_file()

    # 700 N along the insert's long axis (-y of tibia_implant) at the femoral component's origin: through
    # the contact, not at the femur's origin (its hip), whose lever arm would fold the knee
    frames = {f["name"]: np.array(f["pose"]) for f in data["frames"]}
    force = -700.0 * frames["tibia_implant"][:3, 1]
    at = frames["femur_implant"][:3, 3]
    load = f"force = [{', '.join(map(repr, map(float, force)))}]\npoint = [{', '.join(map(repr, map(float, at)))}]\n"
    free = text.replace('name = "femur_r"\nreference', f'name = "femur_r"\n{load}reference', 1)
    # flexion held at the model's default (nothing but muscles holds it), the five others free
    free = re.sub(
        r'(name = "femur_r"\n(?:.*\n)*?)free = \[\]', r'\1free = ["ux", "uy", "uz", "ry", "rz"]', free, count=1
    )
    free = free.replace("max_gap = 0.0\n", "max_gap = 2.0\n", 1)
    scenario.write_text(free)
    from dea_opt.scenario import load_scenario
    from dea_opt.scenario.joint_build import build_joint

    joint, _ = build_joint(load_scenario(scenario))
    assert "femur_r" in joint.coordinates
    s = d.solve(joint)
    assert s.success and s.validity.valid, s.validity.summary()
    assert s.validity["stability"].value < 0
    # the free coordinates' twists from the reader's joint tree, by differences written here
    from dea_opt.opensim import read_model

    model = read_model(TKA / "DM.osim")
    q = s.bodies["femur_r"].u
    knee = {n: (v / 1000.0 if j < 3 else v) for j, (n, v) in enumerate(zip(KNEE, q))}
    reference = np.asarray(joint.bodies["femur_r"].reference)

    def femur(values):  # the femur's pose in ground with the tibia held where the defaults put it
        P = model.poses(values)
        return (
            model.poses()["tibia_r"]
            @ np.linalg.inv(P["tibia_r"])
            @ P["femur_r"]
            @ np.linalg.inv(model.poses()["femur_r"])
        )

    T = femur(knee)
    twists = {}
    for j, dof in enumerate(d.DOFS):
        if dof in joint.bodies["femur_r"].free:
            h = 1e-7 if j < 3 else 1e-7  # m or rad
            up, down = dict(knee), dict(knee)
            up[KNEE[j]] += h
            down[KNEE[j]] -= h
            dT = (femur(up) - femur(down)) / (2 * h) / (1000.0 if j < 3 else 1.0)  # per mm or rad
            W = dT @ np.linalg.inv(T)
            w = np.array([W[2, 1], W[0, 2], W[1, 0]])
            twists[dof] = ((dT @ np.append(reference, 1.0))[:3], w)
    assert_balanced_at_pose(s, 1e-7, {"femur_r": twists})
    assert s.contacts[0].contact_force[1] > 300.0  # the insert carries the compression, the bundles the rest
    run = invoke("run", scenario, "-o", tmp_path / "free")
    assert run.exit_code == 0, run.stdout + run.stderr


def _path_scenario(tmp_path, prescribe, motion=None):
    """The imported DM knee with a path: the fluoroscopic poses (or a .sto) prescribing ``prescribe``."""
    from dea_opt.opensim import read_model
    from dea_opt.opensim.export import write_scenario

    scenario = tmp_path / "dm.toml"
    meshes = {"tibia_implant": TKA / "tibial_insert.stl", "femur_implant": TKA / "femoral_component.stl"}
    write_scenario(read_model(TKA / "DM.osim"), scenario, meshes, ("tibia_r",), ("patella_r",), {"femur_r": "all"})
    rows = _fluoroscopy()[:3]
    with open(tmp_path / "poses.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    source = (
        f'motion = "{motion}"'
        if motion
        else 'poses = "poses.csv"\nmoving = "femur_implant"\nreference = "tibia_implant"'
    )
    names = ", ".join(f'"{p}"' for p in prescribe)
    scenario.write_text(scenario.read_text() + f"\n[load_path]\n{source}\nprescribe = [{names}]\n")
    return scenario, rows


def test_a_table_of_relative_poses_prescribes_the_chosen_coordinates(tmp_path):
    """fluoroscopy_poses.csv's 4x4 poses of the femoral component on the insert give, through knee_r
    inverted, the model's coordinates that OpenSim 4.6 found for the same rows (dm_knee_*)."""
    _need()
    from dea_opt.scenario import load_scenario
    from dea_opt.scenario.joint_build import build_joint
    from dea_opt.scenario.joint_path import read_joint_path

    scenario, rows = _path_scenario(tmp_path, ["knee_flex_r", "femur_r.ry", "knee_rot_r"])
    loaded = load_scenario(scenario)
    joint, _ = build_joint(loaded)
    path = read_joint_path(loaded, joint)
    assert sorted(path.prescribed["femur_r"]) == ["rx", "ry", "rz"]
    for k, row in enumerate(rows):
        knee = _knee(row)
        for dof, name in (("rx", "knee_flex_r"), ("ry", "knee_add_r"), ("rz", "knee_rot_r")):
            assert path.prescribed["femur_r"][dof][k] == pytest.approx(knee[name], abs=1e-9)
        frame = path.frame(joint, k)
        assert frame.bodies["femur_r"].free == ("ux", "uy", "uz")  # the others stay free
        assert frame.bodies["femur_r"].prescribed["rx"] == pytest.approx(knee["knee_flex_r"], abs=1e-9)


def test_a_sto_of_the_model_s_coordinates_prescribes_them_in_their_units(tmp_path):
    """A .sto in degrees: rotations made rad, translations (m) made mm; the others stay free."""
    _need()
    from dea_opt.scenario import load_scenario
    from dea_opt.scenario.joint_build import build_joint
    from dea_opt.scenario.joint_path import read_joint_path

    rows = _fluoroscopy()[:3]
    lines = ["motion", "version=1", f"nRows={len(rows)}", "nColumns=4", "inDegrees=yes", "endheader"]
    lines.append("time\tknee_flex_r\t/jointset/knee_r/knee_ty_r/value\tpelvis_tx")
    for row in rows:
        knee = _knee(row)
        lines.append(f"{row['time_pct_gait']}\t{float(np.degrees(knee['knee_flex_r']))!r}\t{knee['knee_ty_r']!r}\t0.5")
    (tmp_path / "ik.sto").write_text("\n".join(lines) + "\n")
    scenario, _ = _path_scenario(tmp_path, ["knee_flex_r", "knee_ty_r"], motion="ik.sto")
    loaded = load_scenario(scenario)
    joint, _ = build_joint(loaded)
    path = read_joint_path(loaded, joint)
    for k, row in enumerate(rows):
        knee = _knee(row)
        assert path.prescribed["femur_r"]["rx"][k] == pytest.approx(knee["knee_flex_r"], rel=1e-12)
        assert path.prescribed["femur_r"]["uy"][k] == pytest.approx(1000.0 * knee["knee_ty_r"], rel=1e-12)
    assert list(path.time) == [float(r["time_pct_gait"]) for r in rows]


@pytest.mark.parametrize(
    ("section", "words"),
    [
        (
            'poses = "poses.csv"\nmoving = "femur_implant"\nreference = "nowhere"',
            "neither a \\[\\[frames\\]\\] name nor a body",
        ),
        (
            'poses = "poses.csv"\nmoving = "femur_implant"\nreference = "tibia_implant"\nprescribe = ["knee_zz"]',
            "does not give",
        ),
        ('poses = "poses.csv"\nmoving = "femur_implant"', "moving and reference"),
        ('prescribe = ["knee_flex_r"]', "give a file"),
    ],
)
def test_bad_motion_paths_are_named(tmp_path, section, words):
    _need()
    scenario, _ = _path_scenario(tmp_path, ["knee_flex_r"])
    text = scenario.read_text()
    text = text[: text.index("\n[load_path]")] + f"\n[load_path]\n{section}\n"
    scenario.write_text(text)
    result = invoke("run", scenario, "-o", tmp_path / "out")
    assert result.exit_code == 2
    assert re.search(words, result.stderr), result.stderr
