"""A whole joint in a scenario file: ``[[bodies]]``, ``[[contacts]]``, ``[[ligaments]]``, run and compared.

The outputs are read back with ``csv`` and ``json`` and compared with the joint solved here in
Python; the chain's force through each layer is checked by its closed form; every bad input is a
``ScenarioError`` (exit 2, one paragraph) naming the key.
"""

from __future__ import annotations

import csv
import json
import textwrap
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import dea_opt as d
from dea_opt.cli import app
from dea_opt.scenario import load_scenario, parse_scenario
from dea_opt.scenario.joint_build import build_joint
from dea_opt.scenario.joint_path import read_joint_path
from dea_opt.scenario.joint_schema import JointScenario

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "scenarios" / "joint"
runner = CliRunner()


def _rows(path):
    with open(path, newline="") as handle:
        return list(csv.DictReader(handle))


def test_the_example_joint_runs_and_writes_each_layer_and_the_ligament_table(tmp_path):
    result = runner.invoke(app, ["run", str(EXAMPLE / "chain.toml"), "-o", str(tmp_path)])
    assert result.exit_code == 0, result.stdout + result.stderr
    scenario = load_scenario(EXAMPLE / "chain.toml")
    assert isinstance(scenario, JointScenario)
    joint, casts = build_joint(scenario)
    assert casts == [None, None] and [c.name for c in joint.contacts] == ["lower", "upper"]
    solution = d.solve(joint)
    manifest = json.loads((tmp_path / "manifest.json").read_text())
    assert manifest["status"] == "ok"
    for name in ("lower", "upper"):
        for ext in ("vtu", "csv", "json", "png"):
            assert (tmp_path / f"{name}.{ext}").stat().st_size > 0
    for i, name in enumerate(("lower", "upper")):
        summary = json.loads((tmp_path / f"{name}.json").read_text())
        assert summary["peak_pressure_MPa"] == pytest.approx(solution.contacts[i].peak_pressure, rel=1e-12)
    rows = _rows(tmp_path / "ligaments.csv")
    assert list(rows[0]) == ["name", "body1", "body2", "force_N", "strain", "length_mm", "slack_length_mm"]
    assert [r["name"] for r in rows] == ["front", "back"]
    for row, force, strain, length in zip(
        rows, solution.ligaments.force, solution.ligaments.strain, solution.ligaments.length
    ):
        assert (float(row["force_N"]), float(row["strain"]), float(row["length_mm"])) == (force, strain, length)
    joint_json = json.loads((tmp_path / "joint.json").read_text())
    assert joint_json["certificate"]["passed"] and joint_json["validity"]["valid"]
    assert set(joint_json["bodies"]) == {"ground", "middle", "top"}
    # small kinematics: each bundle pulls along its line at the start pose, 20 mm across in 25 mm
    total = sum(float(r["force_N"]) * 20.0 / 25.0 for r in rows)
    assert total == pytest.approx(5.0, rel=1e-6)


def test_a_load_path_writes_one_row_per_frame_and_per_bundle_and_frame(tmp_path):
    result = runner.invoke(app, ["run", str(EXAMPLE / "chain_cycle.toml"), "-o", str(tmp_path), "-q"])
    assert result.exit_code == 0, result.stdout + result.stderr
    scenario = load_scenario(EXAMPLE / "chain_cycle.toml")
    joint, _ = build_joint(scenario)
    path = read_joint_path(scenario, joint)
    frames = _rows(tmp_path / "frames.csv")
    bundles = _rows(tmp_path / "ligaments.csv")
    assert len(frames) == len(path) == 11 and len(bundles) == 2 * 11
    assert {"time_s", "top.uz_mm", "top.ry_rad", "lower.peak_pressure_MPa", "upper.force_N"} <= set(frames[0])
    assert list(bundles[0]) == ["frame", "time_s", "name", "body1", "body2", "force_N", "strain", "length_mm"]
    for k in (0, 5, 10):
        frame = path.frame(joint, k)
        assert frame.bodies["middle"].prescribed["rz"] == pytest.approx(0.001 * k / 10)
        s = d.solve(frame)
        assert float(frames[k]["top.uz_mm"]) == pytest.approx(s.bodies["top"].u[2], rel=1e-9)
        assert float(frames[k]["middle.rz_rad"]) == pytest.approx(0.001 * k / 10)
        # the lower layer carries the frame's compressive load and the bundles' pull down (15 of 25 mm)
        assert float(frames[k]["lower.force_N"]) == pytest.approx(np.linalg.norm(s.contacts[0].contact_force), rel=1e-9)
        pull = 0.6 * float(s.ligaments.force.sum())
        assert s.contacts[0].contact_force[2] == pytest.approx(-frame.bodies["top"].force[2] + pull, rel=1e-9)
        assert float(bundles[2 * k]["force_N"]) == pytest.approx(s.ligaments.force[0], rel=1e-9, abs=1e-12)
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["frames"] == summary["certified"] == 11


def test_a_joint_path_s_report_has_every_frame_and_shows_the_frame_of_the_largest_force(tmp_path):
    result = runner.invoke(app, ["run", str(EXAMPLE / "chain_cycle.toml"), "-o", str(tmp_path), "-q"])
    assert result.exit_code == 0, result.stdout + result.stderr
    html = (tmp_path / "report.html").read_text()
    frames = _rows(tmp_path / "frames.csv")
    # the frame shown: the largest force of the two layers together, summed here from frames.csv
    forces = [float(r["lower.force_N"]) + float(r["upper.force_N"]) for r in frames]
    shown = int(np.argmax(forces))
    assert f"frame {shown} (time {float(frames[shown]['time_s']):.4g} s)" in html
    assert f"({forces[shown]:.4g} N)" in html
    # one sortable row per frame, the layers' table and one 3-D view per layer, the certificate
    section = html[html.index('id="frames"') :]
    section = section[: section.index("</table>")]
    assert section.count("<tr") == 1 + len(frames) and "sortable" in section
    for name in ("Contact layers", "Validity", "Certificate"):
        assert name in html
    assert html.count('id="view3d_') == 2


def test_compare_solves_the_joint_by_each_method(tmp_path):
    result = runner.invoke(app, ["compare", str(EXAMPLE / "chain.toml"), "-o", str(tmp_path)])
    assert result.exit_code == 0, result.stdout + result.stderr
    rows = _rows(tmp_path / "compare.csv")
    assert [r["method"] for r in rows] == ["newton", "nlp"] and all(r["success"] == "True" for r in rows)
    assert float(rows[0]["displacement_difference"]) < 1e-8
    assert "skipped: qp" in result.stdout
    linear = d.compare(_linear_chain(), methods=("newton", "qp", "nlp"))
    assert set(linear.solutions) == {"newton", "qp", "nlp"} and linear.displacement < 1e-7


def _linear_chain():
    from dea_opt.geometry import plate_layer

    bodies = {"g": d.Body(free=()), "b": d.Body(reference=(0, 0, 5.0), free=("uz",), force=(0, 0, -10.0))}
    return d.Joint(bodies, [d.Contact(plate_layer(nx=4, ny=4), d.LinearLaw(1.0), body1="g", body2="b")])


BASE = """
[[bodies]]
name = "g"
[[bodies]]
name = "b"
free = ["uz"]
force = [0, 0, -10]
[[contacts]]
body1 = "g"
body2 = "b"
geometry = { kind = "plate", nx = 4, ny = 4 }
law = { kind = "linear", H = 1.0 }
"""


@pytest.mark.parametrize(
    "extra, words",
    [
        ('[[bodies]]\nname = "g"\n', "different names"),
        (
            '[[ligaments]]\nbody1 = "g"\npoint1 = [0, 0, 0]\nbody2 = "femur"\npoint2 = [0, 0, 1]\nstiffness = 1.0\nslack_length = 1.0\n',
            "'femur', not a body",
        ),
        (
            '[[ligaments]]\nbody1 = "g"\npoint1 = [0, 0, 0]\nbody2 = "b"\npoint2 = [0, 0, 1]\nstiffness = 1.0\n',
            "exactly one of slack_length",
        ),
        (
            '[[ligaments]]\nbody1 = "g"\npoint1 = [0, 0, 0]\nbody2 = "b"\npoint2 = [0, 0, 1]\nstiffness = -1.0\nslack_length = 1.0\n',
            "ligaments[0].stiffness",
        ),
        (
            '[[ligaments]]\nbody1 = "g"\npoint1 = [0, 0]\nbody2 = "b"\npoint2 = [0, 0, 1]\nstiffness = 1.0\nslack_length = 1.0\n',
            "ligaments[0].point1",
        ),
        ('[solve]\nkinematics = "finite"\nmethod = "qp"\n', "small-kinematics method"),
        ('[solve]\nmethod = "bfgs"\n', "solve.method"),
        (
            '[[contacts]]\nbody1 = "g"\nbody2 = "b"\ngeometry = { kind = "plate" }\nlaw = { kind = "linear" }\n',
            "contacts[1].law",
        ),
    ],
)
def test_a_bad_joint_scenario_is_a_scenario_error_naming_the_key(extra, words):
    with pytest.raises(d.ScenarioError, match=words.replace("[", r"\[").replace("]", r"\]").replace("(", r"\(")):
        parse_scenario(BASE + extra)


def test_bad_joints_and_paths_are_named_at_the_command_line(tmp_path):
    (tmp_path / "free.toml").write_text(BASE + '[[bodies]]\nname = "lost"\nfree = ["ux"]\n')
    result = runner.invoke(app, ["run", str(tmp_path / "free.toml"), "-o", str(tmp_path / "o1")])
    assert result.exit_code == 2 and "body 'lost' has free dofs" in result.stderr and "Traceback" not in result.stderr
    for header, words in (
        ("time,femur.Fz", "names no body"),
        ("time,b.Fq", "the quantity must be one of"),
        ("t,b.Fz", "time column"),
    ):
        (tmp_path / "p.csv").write_text(f"{header}\n0,1\n")
        (tmp_path / "path.toml").write_text(BASE + '[load_path]\nfile = "p.csv"\n')
        result = runner.invoke(app, ["run", str(tmp_path / "path.toml"), "-o", str(tmp_path / "o2")])
        assert result.exit_code == 2 and words in result.stderr, result.stderr
    result = runner.invoke(app, ["run", str(EXAMPLE / "chain.toml"), "-o", str(tmp_path / "o3"), "--method", "qp"])
    assert result.exit_code == 2 and "needs linear elements" in result.stderr


def test_the_two_body_form_is_still_a_scenario():
    text = textwrap.dedent("""
        [geometry]
        kind = "plate"
        nx = 4
        ny = 4
        [law]
        kind = "linear"
        H = 1.0
        [body2]
        free = ["uz"]
        [load]
        force = [0, 0, -1.0]
    """)
    scenario = parse_scenario(text)
    assert not isinstance(scenario, JointScenario) and scenario.geometry.kind == "plate"
