"""Scenario files: validation with key paths and lines, overrides, load and springs tables."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest

from dea_opt.errors import InputError
from dea_opt.geometry import plate_layer
from dea_opt.io.tables import read_numeric_csv
from dea_opt.layer import SpringLayer
from dea_opt.scenario import (
    Scenario,
    ScenarioError,
    apply_overrides,
    build_problem,
    load_scenario,
    parse_scenario,
    parse_set,
    pose_matrices,
    read_load_path,
    read_springs,
    schema_text,
    write_springs,
)

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "scenarios"

BASE = """\
title = "socket"
[geometry]
kind = "socket"
radius = 25.0
n_rings = 8
n_sectors = 24
[law]
kind = "linear"
H = 10.0
[body2]
free = ["ux", "uy", "uz"]
[load]
force = [0.0, 0.0, -1000.0]
"""


def parse(text, tmp_path=None):
    return parse_scenario(text, name="case.toml", base_dir=tmp_path)


def error_of(text, tmp_path=None) -> str:
    with pytest.raises(ScenarioError) as info:
        parse(text, tmp_path)
    message = str(info.value)
    assert "\n" not in message
    return message


@pytest.mark.parametrize("path", sorted(EXAMPLES.glob("*.toml")), ids=lambda p: p.stem)
def test_example_scenarios_validate(path):
    scenario = load_scenario(path)
    assert scenario.title
    assert scenario.source == str(path.resolve())


def test_example_hip_gait_is_the_demo_scenario():
    from dea_opt.run.demo import DEMO_SCENARIO

    example = load_scenario(EXAMPLES / "hip_gait.toml")
    demo = parse(DEMO_SCENARIO)
    assert example.model_dump(exclude={"output"}) == demo.model_dump(exclude={"output"})


def test_defaults_and_problem():
    scenario = parse(BASE)
    assert scenario.solve.method == "auto" and scenario.output.formats == ["csv", "json", "vtk", "png", "html"]
    problem = build_problem(scenario)
    assert len(problem.layer) == 8 * 24
    assert problem.free_names == ("body2.ux", "body2.uy", "body2.uz")
    assert problem.body2.force == (0.0, 0.0, -1000.0)
    assert problem.body1.free == ()


def test_load_scale_and_point():
    scenario = parse(
        BASE.replace("force = [0.0, 0.0, -1000.0]", "force = [0.0, 0.0, -100.0]\npoint = [1.0, 0.0, 0.0]\nscale = 2")
    )
    problem = build_problem(scenario)
    assert problem.body2.force == (0.0, 0.0, -200.0)
    assert problem.body2.moment == pytest.approx((0.0, 200.0, 0.0))


def test_output_dir_resolves_against_the_scenario(tmp_path):
    (tmp_path / "s.toml").write_text(BASE + '[output]\ndirectory = "out/here"\n')
    scenario = load_scenario(tmp_path / "s.toml")
    assert scenario.output_dir() == (tmp_path / "out" / "here").resolve()
    assert scenario.output_dir("elsewhere") == Path("elsewhere").resolve()


def test_malformed_toml_names_the_line():
    message = error_of(BASE.replace("H = 10.0", "H = "))
    assert "not valid TOML" in message and "line 9" in message


def test_unknown_key_names_key_path_line_and_allowed_keys():
    message = error_of(BASE.replace("H = 10.0", "H = 10.0\nHH = 2"))
    assert "law.HH (line 10)" in message and "unknown key 'HH'" in message and "beta" in message


def test_unknown_key_in_a_geometry_kind():
    message = error_of(BASE.replace("radius = 25.0", "radiuss = 25.0"))
    assert "geometry.radiuss" in message and "coverage" in message


def test_string_where_a_number_belongs():
    message = error_of(BASE.replace("H = 10.0", 'H = "10"'))
    assert "law.H (line 9)" in message and "valid number" in message and "string" in message


def test_list_element_of_the_wrong_type():
    message = error_of(BASE.replace("[0.0, 0.0, -1000.0]", '[0.0, "x", -1000.0]'))
    assert "load.force[1]" in message


def test_missing_files_are_named(tmp_path):
    text = BASE.replace(
        'kind = "socket"\nradius = 25.0\nn_rings = 8\nn_sectors = 24',
        'kind = "meshes"\nmesh1 = "a.stl"\nmesh2 = "b.stl"',
    )
    message = error_of(text, tmp_path)
    assert "geometry.mesh1" in message and str(tmp_path / "a.stl") in message and "geometry.mesh2" in message


def test_unknown_geometry_kind():
    message = error_of(BASE.replace('kind = "socket"', 'kind = "sockett"'))
    assert "geometry.kind" in message and "'socket'" in message


def test_law_parameters_must_fit_the_kind():
    assert "needs beta" in error_of(BASE.replace('kind = "linear"', 'kind = "ateshian"'))
    assert "takes no beta" in error_of(BASE.replace("H = 10.0", "H = 10.0\nbeta = 0.3"))


def test_exactly_one_load():
    assert "exactly one" in error_of(BASE + '[load_path]\nbuiltin = "hip_gait"\n')
    assert "exactly one" in error_of(BASE.replace("[load]\nforce = [0.0, 0.0, -1000.0]\n", ""))


def test_missing_table():
    assert "law: required table is missing" in error_of(BASE.replace('[law]\nkind = "linear"\nH = 10.0\n', ""))


def test_bad_dof_name():
    assert "body2.free[2]" in error_of(BASE.replace('"uz"]', '"wz"]'))


def test_parse_set():
    assert parse_set("law.H=0.3,0.45,0.6") == ("law.H", [0.3, 0.45, 0.6])
    assert parse_set("load.force=[0,0,-1],[0,0,-2]") == ("load.force", [[0, 0, -1], [0, 0, -2]])
    assert parse_set("law.kind=linear,'ateshian'") == ("law.kind", ["linear", "ateshian"])
    for bad in ("lawH", "=3", "law.H=", "law.H=1,,2", "law..H=1"):
        with pytest.raises(ScenarioError):
            parse_set(bad)


def test_overrides_are_validated_like_the_file():
    data = {"law": {"H": 1.0}}
    assert apply_overrides(data, {"law.H": 2.0, "solve.method": "qp"}) == {"law": {"H": 2.0}, "solve": {"method": "qp"}}
    assert data == {"law": {"H": 1.0}}
    assert parse(BASE, None).law.H == 10.0
    assert parse_scenario(BASE, overrides={"law.H": 0.45}).law.H == 0.45
    with pytest.raises(ScenarioError, match="law.nope"):
        parse_scenario(BASE, overrides={"law.nope": 1})
    with pytest.raises(ScenarioError, match="is a value, not a table"):
        parse_scenario(BASE, overrides={"law.H.x": 1})


def test_schema_documents_every_table_and_key():
    text = schema_text()
    for table in ("[geometry]", "[law]", "[body1]", "[body2]", "[load]", "[load_path]", "[solve]", "[output]"):
        assert table in text
    for model in (Scenario,):
        for name in model.model_fields:
            assert name in text
    assert "(MPa)" in text and "(mm)" in text
    json.dumps(Scenario.model_json_schema())


# --- load paths -------------------------------------------------------------------------


def path_scenario(tmp_path, csv_text, extra=""):
    (tmp_path / "loads.csv").write_text(csv_text)
    text = BASE.replace("[load]\nforce = [0.0, 0.0, -1000.0]\n", f'[load_path]\nfile = "loads.csv"\n{extra}')
    return parse(text, tmp_path)


def test_load_path_reads_comments_defaults_and_scale(tmp_path):
    scenario = path_scenario(tmp_path, "# a comment\ntime,Fx,Fy,Fz\n0,0,0,-100\n# mid\n1,0,0,-200\n", "scale = 2\n")
    data = read_load_path(scenario.load_path)
    assert data.times.tolist() == [0.0, 1.0]
    assert data.loads[:, 2].tolist() == [-200.0, -400.0]
    assert data.loads[:, 3:].tolist() == [[0, 0, 0], [0, 0, 0]]
    assert data.poses is None
    assert len(data.load_objects()) == 2


def test_load_path_resamples(tmp_path):
    scenario = path_scenario(tmp_path, "time,Fx,Fy,Fz\n0,0,0,-100\n1,0,0,-200\n", "frames = 5\n")
    data = read_load_path(scenario.load_path)
    assert np.allclose(data.times, [0, 0.25, 0.5, 0.75, 1])
    assert np.allclose(data.loads[:, 2], [-100, -125, -150, -175, -200])


def test_load_path_without_fz(tmp_path):
    scenario = path_scenario(tmp_path, "time,Fx,Fy\n0,0,0\n")
    with pytest.raises(InputError, match="missing column Fz"):
        read_load_path(scenario.load_path)


def test_load_path_non_numeric_cell_names_line_and_column(tmp_path):
    scenario = path_scenario(tmp_path, "# header comment\ntime,Fx,Fy,Fz\n0,0,0,-1\n1,0,abc,-1\n")
    with pytest.raises(InputError, match=r"line 4, column Fy: expected a finite number, got 'abc'"):
        read_load_path(scenario.load_path)


def test_load_path_empty_cell(tmp_path):
    scenario = path_scenario(tmp_path, "time,Fx,Fy,Fz\n0,0,,-1\n")
    with pytest.raises(InputError, match="line 2, column Fy: .*empty cell"):
        read_load_path(scenario.load_path)


@pytest.mark.parametrize(
    "text, match",
    [
        ("", "is empty"),
        ("time,Fx,Fy,Fz\n", "no rows"),
        ("time,Fx,Fy,Fz,Fq\n0,0,0,-1,0\n", "unknown column Fq"),
        ("time,Fx,Fy,Fz\n1,0,0,-1\n0,0,0,-1\n", "must increase"),
        ("time,Fx,Fy,Fz,pose_tx\n0,0,0,-1,0\n", "pose columns must come all six"),
    ],
)
def test_load_path_bad_tables(tmp_path, text, match):
    scenario = path_scenario(tmp_path, text)
    with pytest.raises(InputError, match=match):
        read_load_path(scenario.load_path)


def test_pose_columns_make_rigid_transforms(tmp_path):
    scenario = path_scenario(
        tmp_path, "time,Fx,Fy,Fz,pose_tx,pose_ty,pose_tz,pose_rx,pose_ry,pose_rz\n0,0,0,-1,1,2,3,0,0,90\n"
    )
    poses = read_load_path(scenario.load_path).poses
    assert poses.shape == (1, 4, 4)
    assert np.allclose(poses[0] @ [1, 0, 0, 1], [1, 3, 3, 1])
    assert np.allclose(pose_matrices(np.zeros(6))[0], np.eye(4))


def test_builtin_gait_load_path():
    scenario = parse(BASE.replace("[load]\nforce = [0.0, 0.0, -1000.0]\n", '[load_path]\nbuiltin = "hip_gait"\n'))
    data = read_load_path(scenario.load_path)
    assert len(data) == 101 and (data.loads[:, 2] < 0).all()


# --- springs tables ---------------------------------------------------------------------


def test_springs_csv_round_trip(tmp_path):
    layer = plate_layer(4.0, 2.0, 4, 2, thickness=2.0).with_gap(np.linspace(-0.1, 0.1, 8))
    back = read_springs(write_springs(layer, tmp_path / "springs.csv"))
    for name in ("points", "normals", "areas", "thickness", "gap"):
        assert np.allclose(getattr(back, name), getattr(layer, name), rtol=1e-9, atol=1e-12)


def test_springs_csv_round_trip_is_exact(tmp_path):
    """Every number of a springs table reads back bit for bit, at every magnitude."""
    rng = np.random.default_rng(12)
    n = 400
    scale = 10.0 ** rng.integers(-9, 5, (n, 1))
    layer = SpringLayer(
        rng.standard_normal((n, 3)) * scale,
        rng.standard_normal((n, 3)),
        rng.uniform(1e-6, 3.0, n) / 3.0,
        1.0 / 3.0 + rng.uniform(0.1, 5.0, n),
        rng.standard_normal(n) * 1e-3 / 7.0,
    )
    columns = {
        "x": layer.points[:, 0],
        "y": layer.points[:, 1],
        "z": layer.points[:, 2],
        "nx": layer.normals[:, 0],
        "ny": layer.normals[:, 1],
        "nz": layer.normals[:, 2],
        "area": layer.areas,
        "thickness": layer.thickness,
        "gap": layer.gap,
    }
    # ten significant digits, as a %.10g writer keeps, would not be enough for these numbers
    assert any(float(f"{v:.10g}") != v for v in layer.gap)
    path = write_springs(layer, tmp_path / "springs.csv")
    with open(path, newline="") as handle:
        rows = list(csv.reader(handle))
    assert rows[0] == list(columns)
    text = np.array(rows[1:], dtype=object)
    for k, (name, values) in enumerate(columns.items()):
        assert [float(cell) for cell in text[:, k]] == values.tolist(), name  # the file itself, read by Python
    table = read_numeric_csv(path, tuple(columns))
    for name, values in columns.items():
        np.testing.assert_array_equal(table[name].to_numpy(), values, err_msg=name)
    back = read_springs(path)
    for name in ("points", "areas", "thickness", "gap"):
        np.testing.assert_array_equal(getattr(back, name), getattr(layer, name), err_msg=name)
    # normals are normalised again on reading: equal up to that rounding
    np.testing.assert_allclose(back.normals, layer.normals, rtol=0, atol=4e-16)


def test_springs_npz(tmp_path):
    layer = plate_layer(4.0, 2.0, 4, 2, thickness=2.0)
    np.savez(
        tmp_path / "s.npz",
        x=layer.points[:, 0],
        y=layer.points[:, 1],
        z=layer.points[:, 2],
        nx=layer.normals[:, 0],
        ny=layer.normals[:, 1],
        nz=layer.normals[:, 2],
        area=layer.areas,
        thickness=layer.thickness,
    )
    assert np.allclose(read_springs(tmp_path / "s.npz").points, layer.points)
    np.savez(tmp_path / "bad.npz", x=layer.points[:, 0])
    with pytest.raises(InputError, match="missing arrays"):
        read_springs(tmp_path / "bad.npz")


def test_springs_table_with_bad_values(tmp_path):
    (tmp_path / "s.csv").write_text("x,y,z,nx,ny,nz,area,thickness\n0,0,0,0,0,1,-1,2\n")
    with pytest.raises(InputError, match="areas must be > 0"):
        read_springs(tmp_path / "s.csv")


def test_generator_mesh_pair_supplies_references():
    text = BASE.replace(
        'kind = "socket"\nradius = 25.0\nn_rings = 8\nn_sectors = 24',
        'kind = "generator"\nfunction = "hip_meshes"\nparameters = {step = 10.0}',
    )
    problem = build_problem(parse(text))
    assert problem.body2.reference == pytest.approx((0.0, 0.0, -0.5))
    assert problem.layer.source_face is not None


def test_generator_errors():
    text = BASE.replace(
        'kind = "socket"\nradius = 25.0\nn_rings = 8\nn_sectors = 24', 'kind = "generator"\nfunction = "nope"'
    )
    with pytest.raises(ScenarioError, match="hip_meshes"):
        build_problem(parse(text))
    text = text.replace('"nope"', '"socket_layer"\nparameters = {radiuss = 3}')
    with pytest.raises(ScenarioError, match="do not fit socket_layer"):
        build_problem(parse(text))
