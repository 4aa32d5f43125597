"""dea-opt import-osim: the scenario it writes (read back with tomllib, every number checked
against the model) and its errors (exit 2, one paragraph)."""

from __future__ import annotations

import re
import tomllib

import numpy as np
import pytest
import trimesh
from conftest import SHARED
from osim_models import CONTACT, MESHES, ligament, write_model
from test_cli import invoke, one_paragraph_error

from dea_opt.opensim import read_model

TKA = SHARED / "data" / "tka"


@pytest.fixture
def toy(tmp_path):
    (tmp_path / "model").mkdir()
    box = trimesh.creation.box((0.02, 0.02, 0.002))
    box.export(tmp_path / "model" / "a.stl")
    params = dict(file_a="a.stl", file_b="b.stl", E_a=46.3e6, nu_a=0.46, h_a=0.005, E_b=46.3e6, nu_b=0.46, h_b=0.004)
    forces = CONTACT.format(formulation="linear", lumped="true") + ligament() + '<Thelen2003Muscle name="m"/>'
    return write_model(tmp_path / "model", meshes=MESHES.format(**params), forces=forces)


def test_the_scenario_holds_the_bodies_contacts_and_ligaments_at_the_default_pose(toy, tmp_path):
    out = tmp_path / "out" / "toy.toml"
    result = invoke("import-osim", toy, "-o", out)
    assert result.exit_code == 0, result.stderr
    assert "1 contact pair(s), 1 ligament bundle(s)" in result.stdout and f"wrote {out}" in result.stdout
    assert "not found for mesh_b" in result.stderr
    text = out.read_text()
    scenario = tomllib.loads(text)
    model = read_model(toy)
    poses = model.poses()
    bodies = {b["name"]: b for b in scenario["bodies"]}
    assert set(bodies) == {"a", "b"}
    for name, body in bodies.items():
        assert np.allclose(body["pose"], poses[name], rtol=0, atol=1e-12) and body["free"] == []
        assert np.allclose(body["reference"], poses[name][:3, 3], rtol=0, atol=1e-12)
    (contact,) = scenario["contacts"]
    assert (contact["name"], contact["body1"], contact["body2"]) == ("contact", "a", "b")
    geometry = contact["geometry"]
    assert geometry["kind"] == "meshes"
    assert geometry["mesh1"] == "../model/a.stl" and geometry["mesh2"] == "b.stl"  # found / as named
    assert "# mesh2 (mesh_b): NOT FOUND" in text
    assert (geometry["scale1"], geometry["thickness1"], geometry["thickness2"]) == (1000.0, 5.0, 4.0)
    assert (geometry["max_gap"], geometry["max_overlap"]) == (0.0, 20.0)
    assert contact["law"] == {"kind": "linear", "H": pytest.approx(0.54 * 46.3 / (1.46 * 0.08), rel=1e-15)}
    assert np.allclose(geometry["pose1"], poses["a"] @ model.frame_in_body("/bodyset/a/a_offset"), atol=1e-12)
    assert scenario["solve"] == {"kinematics": "finite"}
    frames = {f["name"]: f for f in scenario["frames"]}
    assert frames["a_offset"]["body"] == "a"
    assert np.allclose(frames["a_offset"]["pose"], geometry["pose1"], atol=1e-12)
    (lig,) = scenario["ligaments"]
    x1 = poses["a"][:3, :3] @ [10.0, 20.0, 30.0] + poses["a"][:3, 3]
    assert (lig["body1"], lig["body2"], lig["law"], lig["transition_strain"]) == ("a", "b", "blankevoort", 0.06)
    assert np.allclose(lig["point1"], x1, atol=1e-12) and (lig["stiffness"], lig["slack_length"]) == (1000.0, 50.0)
    assert "# muscle m (line" in text  # not modelled, as a comment


def test_a_mesh_given_on_the_command_line_is_taken_in_mm(toy, tmp_path):
    stl = tmp_path / "b_mm.stl"
    trimesh.creation.box((20.0, 20.0, 2.0)).export(stl)
    out = tmp_path / "s.toml"
    result = invoke("import-osim", toy, "-o", out, "--mesh", f"mesh_b={stl}")
    assert result.exit_code == 0 and "not found" not in result.stderr
    geometry = tomllib.loads(out.read_text())["contacts"][0]["geometry"]
    assert (geometry["mesh2"], geometry["scale2"]) == ("b_mm.stl", 1.0)


def test_it_keeps_an_existing_file_unless_forced(toy, tmp_path):
    out = tmp_path / "s.toml"
    out.write_text("mine")
    assert "exists" in one_paragraph_error(invoke("import-osim", toy, "-o", out))
    assert out.read_text() == "mine"
    assert invoke("import-osim", toy, "-o", out, "--force").exit_code == 0 and "[[bodies]]" in out.read_text()


@pytest.mark.parametrize(
    "args, expected",
    [
        (["nope.osim"], "does not exist"),
        (["{bad}"], r"line 1, column \d+: not well-formed XML"),
        (["{toy}", "--mesh", "mesh_b"], "--mesh takes NAME=PATH"),
        (["{toy}", "--mesh", "mesh_b=nofile.stl"], "does not exist"),
        (["{toy}", "--mesh", "zz={toy}"], "has no contact mesh zz"),
        (["{toy}", "-o", "{tmp}"], "exists"),
    ],
)
def test_bad_input_is_one_paragraph_with_exit_2(toy, tmp_path, args, expected):
    bad = tmp_path / "bad.osim"
    bad.write_text("<OpenSimDocument")
    args = [a.format(bad=bad, toy=toy, tmp=tmp_path) for a in args]
    if "-o" not in args:
        args += ["-o", str(tmp_path / "new.toml")]
    text = one_paragraph_error(invoke("import-osim", *args))
    assert re.search(expected, text), text


def test_the_dm_knee_imports_with_everything_not_modelled_listed(tmp_path):
    if not (TKA / "DM.osim").is_file():
        pytest.skip(f"the DM model is not in {TKA}")
    out = tmp_path / "dm.toml"
    result = invoke("import-osim", TKA / "DM.osim", "-o", out, "--mesh", f"tibia_implant={TKA / 'tibial_insert.stl'}")
    assert result.exit_code == 0, result.stderr
    text = out.read_text()
    scenario = tomllib.loads(text)
    assert [b["name"] for b in scenario["bodies"]] == ["pelvis", "femur_r", "patella_r", "tibia_r"]
    assert [c["name"] for c in scenario["contacts"]] == ["knee_contact", "pf_contact"]
    assert len(scenario["ligaments"]) == 149
    assert text.count("\n# wrap ") == 83 and "# via_points ITB_r" in text and text.count("\n# muscle ") == 44


def test_help_names_the_command():
    result = invoke("import-osim", "--help")
    assert result.exit_code == 0 and "--mesh" in result.stdout and "Blankevoort1991Ligament" in result.stdout
    assert "import-osim" in invoke("--help").stdout
