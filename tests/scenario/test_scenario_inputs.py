"""Scenario inputs: compartments (tables of labelled meshes, [regions], springs tables with labels)
and OpenSim Storage load paths (.sto/.mot), each checked against an independent computation."""

from __future__ import annotations

import json

import numpy as np
import pytest
from conftest import KNEE, scenario_text

from dea_opt.geometry import plate_meshes
from dea_opt.io.tables import read_springs, write_springs
from dea_opt.mesh import springs_from_meshes
from dea_opt.run import run_scenario
from dea_opt.scenario import (
    ScenarioError,
    build_problem,
    parse_scenario,
    pose_matrices,
    read_load_path,
)

PLATE = scenario_text(law=None)


def parse(text, tmp_path):
    return parse_scenario(text, name="case.toml", base_dir=tmp_path)


# --- tables of labelled meshes ------------------------------------------------------------------


def halves(mesh, axis=0):
    """The faces of ``mesh`` with centroid below / above 0 along ``axis``, as two meshes."""
    below = mesh.triangles_center[:, axis] < 0.0
    return mesh.submesh([np.flatnonzero(below)], append=True), mesh.submesh([np.flatnonzero(~below)], append=True)


@pytest.fixture()
def split_plate(tmp_path):
    """The plate pair of dea_opt.geometry with the slab (mesh 1) and the plate (mesh 2) cut at x = 0."""
    pair = plate_meshes(length=40.0, width=10.0, nx=40, ny=10)
    files = {}
    for name, mesh in (("slab", pair.mesh1), ("plate", pair.mesh2)):
        for side, part in zip(("left", "right"), halves(mesh)):
            files[name, side] = tmp_path / f"{name}_{side}.stl"
            part.export(files[name, side])
        files[name] = tmp_path / f"{name}.stl"
        mesh.export(files[name])
    return pair, files


def mesh_scenario(mesh1, mesh2, extra=""):
    return f"""\
[geometry]
kind = "meshes"
mesh1 = {mesh1}
mesh2 = {mesh2}
thickness1 = 1.0
thickness2 = 1.0
max_gap = 1.0
{extra}
[law]
H = 10.0
[body2]
free = ["uz"]
[load]
force = [0.0, 0.0, -400.0]
"""


def test_labels_of_mesh1_parts_reach_the_springs(split_plate, tmp_path):
    _, files = split_plate
    table = f'{{left = "{files["slab", "left"]}", right = "{files["slab", "right"]}"}}'
    layer = build_problem(parse(mesh_scenario(table, f'"{files["plate"]}"'), tmp_path)).layer
    expected = np.where(layer.points[:, 0] < 0.0, "left", "right")
    assert set(layer.labels) == {"left", "right"} and (layer.labels == expected).all()
    # the same springs as from the one mesh: a table only labels them
    whole = springs_from_meshes(files["slab"], files["plate"], thickness1=1.0, thickness2=1.0, max_gap=1.0)
    assert len(whole) == len(layer) and np.isclose(whole.areas.sum(), layer.areas.sum())


def test_labels_of_mesh2_parts_are_those_the_rays_meet(split_plate, tmp_path):
    _, files = split_plate
    plate = f'{{left = "{files["plate", "left"]}", right = "{files["plate", "right"]}"}}'
    layer = build_problem(parse(mesh_scenario(f'"{files["slab"]}"', plate), tmp_path)).layer
    # each spring's normal ray goes straight up (+z): it meets the plate's part above its own x
    assert (layer.labels == np.where(layer.points[:, 0] < 0.0, "left", "right")).all()
    slab = f'{{a = "{files["slab", "left"]}", b = "{files["slab", "right"]}"}}'
    both = build_problem(parse(mesh_scenario(slab, plate), tmp_path)).layer
    assert set(both.labels) == {"a/left", "b/right"}


def test_a_run_reports_the_compartments_and_the_springs_table_keeps_them(split_plate, tmp_path):
    _, files = split_plate
    table = f'{{left = "{files["slab", "left"]}", right = "{files["slab", "right"]}"}}'
    scenario = parse(mesh_scenario(table, f'"{files["plate"]}"'), tmp_path)
    outcome = run_scenario(scenario, tmp_path / "out")
    assert outcome.exit_code == 0
    summary = json.loads((tmp_path / "out" / "contact.json").read_text())
    regions = summary["regions"]
    assert set(regions) == {"left", "right"}
    # a centred load on a symmetric plate: each half carries half of it
    forces = [regions[name]["resultant_N"] for name in ("left", "right")]
    assert np.allclose(forces, 200.0, rtol=1e-9) and np.isclose(sum(forces), 400.0, rtol=1e-12)
    assert [regions[name]["share"] for name in ("left", "right")] == pytest.approx([0.5, 0.5], rel=1e-9)
    layer = outcome.result.problem.layer
    for name in ("springs.csv", "springs.npz"):
        write_springs(layer, tmp_path / name)
        back = read_springs(tmp_path / name)
        assert (back.labels == layer.labels).all() and np.array_equal(back.points, layer.points)


def test_an_empty_table_or_a_missing_part_is_named(split_plate, tmp_path):
    _, files = split_plate
    with pytest.raises(ScenarioError, match="geometry.mesh1.*table of labelled paths"):
        parse(mesh_scenario("{}", f'"{files["plate"]}"'), tmp_path)
    with pytest.raises(ScenarioError, match="labelled 'medial'.*file not found"):
        parse(mesh_scenario('{medial = "nope.stl"}', f'"{files["plate"]}"'), tmp_path)


@pytest.mark.skipif(not (KNEE / "femoral_cartilage.stl").is_file(), reason="the knee meshes are not there")
def test_the_knee_from_two_tibial_meshes_labels_medial_and_lateral(tmp_path):
    text = mesh_scenario(
        f'{{medial = "{KNEE / "medial_tibial_cartilage.stl"}", lateral = "{KNEE / "lateral_tibial_cartilage.stl"}"}}',
        f'"{KNEE / "femoral_cartilage.stl"}"',
    ).replace("thickness1 = 1.0\nthickness2 = 1.0\n", "")
    text = text.replace("max_gap = 1.0", "max_gap = 2.0")
    layer = build_problem(parse(text, tmp_path)).layer
    for label, name in (("medial", "medial_tibial_cartilage.stl"), ("lateral", "lateral_tibial_cartilage.stl")):
        alone = springs_from_meshes(KNEE / name, KNEE / "femoral_cartilage.stl", max_gap=2.0)
        assert (layer.labels == label).sum() == len(alone)
        assert np.isclose(layer.areas[layer.labels == label].sum(), alone.areas.sum(), rtol=1e-12)


# --- [regions]: a split by an axis --------------------------------------------------------------


@pytest.mark.parametrize("at, cut", [("", 0.0), ("at = 5.0", 5.0), ('at = "centroid"', 0.0)])
def test_regions_split_a_single_layer_across_an_axis(tmp_path, at, cut):
    text = PLATE + f'[regions]\nsplit = "x"\n{at}\nnames = ["lateral", "medial"]\n'
    layer = build_problem(parse(text, tmp_path)).layer
    assert (layer.labels == np.where(layer.points[:, 0] < cut, "lateral", "medial")).all()
    flipped = build_problem(parse(text.replace('split = "x"', 'split = "-x"'), tmp_path)).layer
    # "at" is a coordinate along the axis given: along -x, 5.0 is x = -5
    assert (flipped.labels == np.where(-flipped.points[:, 0] < cut, "lateral", "medial")).all()


def test_regions_refuse_springs_that_have_labels(split_plate, tmp_path):
    _, files = split_plate
    table = f'{{left = "{files["slab", "left"]}", right = "{files["slab", "right"]}"}}'
    text = mesh_scenario(table, f'"{files["plate"]}"') + '[regions]\nsplit = "y"\n'
    with pytest.raises(ScenarioError, match="have labels already"):
        build_problem(parse(text, tmp_path))
    with pytest.raises(ScenarioError, match="two different"):
        parse(PLATE + '[regions]\nsplit = "x"\nnames = ["a", "a"]\n', tmp_path)


def test_a_springs_table_with_a_label_column_labels_the_run(tmp_path):
    import dataclasses

    from dea_opt.geometry import plate_layer

    layer = plate_layer(40.0, 10.0, 40, 4, 2.0)
    layer = dataclasses.replace(layer, labels=np.where(layer.points[:, 0] < 0.0, "medial", "lateral"))
    write_springs(layer, tmp_path / "springs.csv")
    header = (tmp_path / "springs.csv").read_text().splitlines()[0]
    assert header.endswith(",label")
    text = PLATE.replace('kind = "plate"\nnx = 40\nny = 4', 'kind = "springs"\nfile = "springs.csv"')
    problem = build_problem(parse(text, tmp_path))
    assert (problem.layer.labels == layer.labels).all()


# --- OpenSim Storage load paths -----------------------------------------------------------------

STO_HEADER = """{name}
version=1
nRows={rows}
nColumns={columns}
inDegrees={degrees}

Units are S.I. units (second, meters, Newtons, ...)
If the header above contains a line with 'inDegrees', this indicates whether rotational values are in \
degrees (yes) or radians (no).

endheader
"""


def write_sto(path, table: dict, degrees="yes", name="knee_JointReaction"):
    labels = list(table)
    rows = np.column_stack([table[c] for c in labels])
    text = STO_HEADER.format(name=name, rows=len(rows), columns=len(labels), degrees=degrees)
    text += "\t".join(labels) + "\n" + "\n".join("\t".join(repr(float(v)) for v in row) for row in rows) + "\n"
    path.write_text(text)


def sto_scenario(geometry: str, columns: str, units: str = "") -> str:
    return f"""\
{geometry}
[law]
H = 10.0
[body2]
free = ["uz"]
[load_path]
file = "path.sto"
{units}
columns = {columns}
"""


RNG = np.random.default_rng(7)
TIME = np.linspace(0.0, 1.0, 6)
FZ = -RNG.uniform(200.0, 900.0, 6)  # N, on the tibia
MX = RNG.uniform(-2.0, 2.0, 6)  # N m
ANGLE = RNG.uniform(-4.0, 4.0, 6)  # degrees
SHIFT = RNG.uniform(-1e-3, 1e-3, 6)  # m


def test_sto_columns_map_to_forces_moments_and_poses_in_mm_and_degrees(tmp_path):
    write_sto(
        tmp_path / "path.sto",
        {"time": TIME, "knee_on_tibia_fz": FZ, "knee_on_tibia_mx": MX, "knee_flexion": ANGLE, "knee_tx": SHIFT},
    )
    columns = (
        '{Fx = "knee_on_tibia_fz", Fy = "knee_on_tibia_fz", Fz = "-knee_on_tibia_fz", '
        'Mx = "-knee_on_tibia_mx", pose_rx = "knee_flexion", pose_tx = "knee_tx"}'
    )
    scenario = parse(sto_scenario('[geometry]\nkind = "plate"', columns), tmp_path)
    data = read_load_path(scenario.load_path)
    assert np.array_equal(data.times, TIME)
    assert np.array_equal(data.loads[:, 2], -FZ) and np.array_equal(data.loads[:, 0], FZ)
    assert np.allclose(data.loads[:, 3], -MX * 1000.0, rtol=1e-15)  # N m -> N mm
    assert (data.loads[:, 4:] == 0.0).all()
    expected = pose_matrices(np.column_stack([SHIFT * 1000.0, 0 * TIME, 0 * TIME, ANGLE, 0 * TIME, 0 * TIME]))
    assert np.allclose(data.poses, expected, rtol=0, atol=1e-12)
    # independently: a rotation by ANGLE degrees about x
    c, s = np.cos(np.radians(ANGLE[2])), np.sin(np.radians(ANGLE[2]))
    assert np.allclose(data.poses[2, :3, :3], [[1, 0, 0], [0, c, -s], [0, s, c]], atol=1e-15)
    # units = "mm": the file is read as it is
    scenario = parse(sto_scenario('[geometry]\nkind = "plate"', columns, 'units = "mm"'), tmp_path)
    data = read_load_path(scenario.load_path)
    assert np.array_equal(data.loads[:, 3], -MX) and np.allclose(data.poses[:, 0, 3], SHIFT, rtol=1e-15)


def test_sto_in_radians_gives_the_same_poses(tmp_path):
    columns = '{Fx = "f", Fy = "f", Fz = "f", pose_rz = "angle"}'
    geometry = '[geometry]\nkind = "plate"'
    write_sto(tmp_path / "path.sto", {"time": TIME, "f": FZ, "angle": ANGLE})
    in_degrees = read_load_path(parse(sto_scenario(geometry, columns), tmp_path).load_path).poses
    write_sto(tmp_path / "path.sto", {"time": TIME, "f": FZ, "angle": np.radians(ANGLE)}, degrees="no")
    in_radians = read_load_path(parse(sto_scenario(geometry, columns), tmp_path).load_path).poses
    assert np.allclose(in_degrees, in_radians, rtol=0, atol=1e-14)


def test_a_run_on_a_sto_load_path_carries_each_frame(tmp_path):
    write_sto(tmp_path / "path.sto", {"time": TIME, "knee_on_tibia_fz": FZ})
    columns = '{Fx = "time", Fy = "time", Fz = "knee_on_tibia_fz"}'  # Fx, Fy on held dofs: reactions
    scenario = parse(sto_scenario('[geometry]\nkind = "plate"\nnx = 20\nny = 2', columns), tmp_path)
    outcome = run_scenario(scenario, tmp_path / "out")
    frames = outcome.result.table
    assert outcome.exit_code == 0 and len(frames) == len(TIME)
    assert np.array_equal(frames["Fz_N"], FZ) and np.array_equal(frames["Fx_N"], TIME)
    # the plate under a centred force: uniform pressure F / A over the 40 x 10 mm plate
    assert np.allclose(frames["mean_pressure_MPa"], -FZ / 400.0, rtol=1e-9)
    assert np.allclose(frames["peak_pressure_MPa"], -FZ / 400.0, rtol=1e-9)


@pytest.mark.parametrize(
    "text, columns, expected",
    [
        ("version=1\ntime\tf\n0\t1\n", None, "no 'endheader'"),
        ("version=1\nendheader\n", None, "no row of column labels"),
        ("nRows=3\nendheader\ntime\tf\n0\t1\n1\t2\n", None, "nRows=3, but it has 2 rows"),
        ("endheader\ntime\tf\n0\t1\n1\tabc\n", None, "line 4, column f: expected a finite number, got 'abc'"),
        ("endheader\ntime\tf\n0\t1\n1\n", None, "line 4: 1 fields"),
        ("endheader\ntime\tf\tf\n0\t1\t1\n", None, "repeated column labels f"),
        (
            "endheader\ntime\tknee_fz\n0\t1\n",
            '{Fx = "knee_fx", Fy = "knee_fz", Fz = "knee_fz"}',
            "load_path.columns.Fx names the column 'knee_fx'.*did you mean 'knee_fz'",
        ),
        (
            "endheader\ntime\tf\ta\n0\t1\t3\n",
            '{Fx = "f", Fy = "f", Fz = "f", pose_rx = "a"}',
            "does not say inDegrees=yes or no",
        ),
    ],
)
def test_bad_sto_files_are_named_errors(tmp_path, text, columns, expected):
    (tmp_path / "path.sto").write_text(text)
    columns = columns or '{Fx = "f", Fy = "f", Fz = "f"}'
    scenario = parse(sto_scenario('[geometry]\nkind = "plate"', columns), tmp_path)
    with pytest.raises(ScenarioError, match=expected):
        read_load_path(scenario.load_path)


def test_sto_keys_are_checked(tmp_path):
    (tmp_path / "path.sto").write_text("endheader\ntime\tf\n0\t1\n")
    with pytest.raises(ScenarioError, match="needs columns"):
        parse(sto_scenario('[geometry]\nkind = "plate"', "{}").replace("columns = {}\n", ""), tmp_path)
    with pytest.raises(ScenarioError, match="missing Fz"):
        parse(sto_scenario('[geometry]\nkind = "plate"', '{Fx = "f", Fy = "f"}'), tmp_path)
    (tmp_path / "path.csv").write_text("time,Fx,Fy,Fz\n0,0,0,-1\n")
    text = sto_scenario('[geometry]\nkind = "plate"', '{Fx = "f", Fy = "f", Fz = "f"}').replace("path.sto", "path.csv")
    with pytest.raises(ScenarioError, match="OpenSim .sto/.mot load paths only"):
        parse(text, tmp_path)


def test_the_example_opensim_scenario_runs(tmp_path):
    from pathlib import Path

    from dea_opt.scenario import load_scenario

    example = Path(__file__).resolve().parents[2] / "examples" / "scenarios" / "hip_opensim.toml"
    scenario = load_scenario(example)
    data = read_load_path(scenario.load_path)
    raw = np.loadtxt(example.with_name("hip_joint_reaction.sto"), skiprows=11)
    assert len(data) == 21 and np.array_equal(data.loads[:, :3], -raw[:, 1:4])
    outcome = run_scenario(scenario, tmp_path / "out")
    assert outcome.exit_code == 0 and outcome.result.success
    # frictionless contact: the springs' resultant on the head balances each frame's force
    assert np.allclose(outcome.result.table["resultant_N"], np.linalg.norm(raw[:, 1:4], axis=1), rtol=1e-6)


@pytest.mark.parametrize(
    "key, value",
    [("load.scale", "inf"), ("load.scale", "nan"), ("law.H", "nan"), ("law.H", "inf"), ("load.force", "[0, 0, nan]")],
)
def test_a_nan_or_inf_is_named_at_its_key_with_what_came(tmp_path, key, value):
    from dea_opt.scenario import parse_set

    path, values = parse_set(f"{key}={value}")
    with pytest.raises(ScenarioError) as info:
        parse_scenario(PLATE, name="case.toml", base_dir=tmp_path, overrides={path: values[0]})
    message = str(info.value)
    shown = "nan" if "nan" in value else "inf"
    where = key + ("[2]" if key == "load.force" else "")
    assert f"{where} (from --set): Input should be a finite number, got {shown}" in message


def test_a_dof_both_free_and_prescribed_is_refused_at_its_key(tmp_path):
    from typer.testing import CliRunner

    from dea_opt.cli import app

    text = PLATE.replace('free = ["uz", "rx", "ry"]', 'free = ["uz", "rx", "ry"]\nprescribed = {uz = -0.1}')
    with pytest.raises(ScenarioError, match=r"body2 \(line 7\): a dof cannot be both free and prescribed: uz"):
        parse(text, tmp_path)
    (tmp_path / "both.toml").write_text(text)
    result = CliRunner().invoke(app, ["run", str(tmp_path / "both.toml"), "-o", str(tmp_path / "out")])
    assert result.exit_code == 2 and "cannot be both free and prescribed: uz" in result.stderr
    assert "Traceback" not in result.stderr and not (tmp_path / "out").exists()
    # free not given: body 2 is free in every dof that is not prescribed
    held = PLATE.replace('free = ["uz", "rx", "ry"]', "prescribed = {uz = -0.1}").replace(
        "[load]\nforce = [0.0, 0.0, -500.0]", "[load]\nforce = [0.0, 0.0, 0.0]"
    )
    assert build_problem(parse(held, tmp_path)).body2.free == ("ux", "uy", "rx", "ry", "rz")
