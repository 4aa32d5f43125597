"""``dea-opt init``: a commented scenario from meshes that ``dea-opt run`` solves as it stands.

On a small knee of one's own (``first_hour.py``) in millimetres and in metres, with a force, a
CSV path whose sign is flipped and an OpenSim file whose moments are in N mm; the choices it
makes (units, free dofs, the modulus and its source) against closed forms; and on the real knee
(``../shared/data/knee``, skipped without it): init then run, no hand edits, exit 0.
"""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest
from conftest import KNEE, KNEE_FILES
from first_hour import STO_PREFIX, write_csv, write_meshes, write_sto
from typer.testing import CliRunner

from dea_opt.cli import app
from dea_opt.errors import InputError
from dea_opt.laws.moduli import MODULI, confined_modulus
from dea_opt.run.init import choose_free, parse_part, sniff_scale

runner = CliRunner()


def invoke(*args):
    result = runner.invoke(app, [str(a) for a in args])
    assert "Traceback" not in result.output and "internal error" not in result.output, result.output
    return result


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    return write_meshes(tmp_path_factory.mktemp("knee") / "mm")


def init(meshes, out: Path, *extra, load="1000"):
    return invoke(
        "init",
        "--body1",
        f"medial={meshes['medial']}",
        "--body1",
        f"lateral={meshes['lateral']}",
        "--body2",
        meshes["femur"],
        "--load",
        load,
        "-o",
        out,
        *extra,
    )


def comments(text: str) -> str:
    """The file's comments as one line of words."""
    return " ".join(word for line in text.splitlines() if line.startswith("#") for word in line[1:].split())


def run(path: Path, *extra):
    return invoke("run", path, "-o", path.parent / "out", *extra)


# --- the pieces, against what they must give -----------------------------------------------------


def test_parse_part_reads_one_file_or_labelled_files():
    assert parse_part(["femur.stl"], "--body2") == "femur.stl"
    assert parse_part(["medial=a.stl", "lateral=b.stl"], "--body1") == {"medial": "a.stl", "lateral": "b.stl"}
    for bad in ([], ["a.stl", "b.stl"], ["medial=a.stl", "medial=b.stl"], ["=a.stl"]):
        with pytest.raises(InputError, match="--body1"):
            parse_part(bad, "--body1")


@pytest.mark.parametrize(
    "sizes, scale",
    [({"a": 60.0, "b": 120.0}, 1.0), ({"a": 0.06, "b": 0.12}, 1000.0), ({"a": 60000.0}, 0.001)],
)
def test_sniff_scale_from_the_meshes_size(sizes, scale):
    found, why = sniff_scale(sizes)
    assert found == scale and "a joint's cartilage spans 10-200 mm" in why


@pytest.mark.parametrize("sizes", [{"a": 2.0}, {"a": 60.0, "b": 0.12}, {"a": 1e9}])
def test_sniff_scale_stops_when_the_size_does_not_say(sizes):
    with pytest.raises(InputError, match="give --scale"):
        sniff_scale(sizes)


@pytest.mark.parametrize("length, width", [(40.0, 10.0), (20.0, 20.0)])
def test_choose_free_on_a_plate_against_its_closed_form(length, width):
    """A plate of uniform springs with normals along z: about its centre the stiffness is ``sum k``
    along uz, none along ux, uy, rz, and ``sum k y^2 / L^2``, ``sum k x^2 / L^2`` about x and y
    with ``L^2`` the mean of ``x^2 + y^2``: ``b^2 / (a^2 + b^2)`` and ``a^2 / (a^2 + b^2)`` of it."""
    from dea_opt.geometry import plate_layer

    layer = plate_layer(length, width, 200, 50, 2.0)
    free, stiffness = choose_free(layer, layer.points.mean(axis=0))
    # the midpoint grid's second moments: a^2 / 12 (1 - 1 / n^2)
    x2 = length**2 / 12.0 * (1.0 - 1.0 / 200**2)
    y2 = width**2 / 12.0 * (1.0 - 1.0 / 50**2)
    assert stiffness["uz"] == pytest.approx(1.0)
    assert stiffness["ry"] == pytest.approx(x2 / (x2 + y2), rel=1e-9)
    assert stiffness["rx"] == pytest.approx(y2 / (x2 + y2), rel=1e-9)
    assert stiffness["ux"] == stiffness["uy"] == stiffness["rz"] == pytest.approx(0.0, abs=1e-12)
    expected = ["uz", *(d for d, s in (("rx", y2 / (x2 + y2)), ("ry", x2 / (x2 + y2))) if s >= 0.2)]
    assert free == sorted(expected, key=["ux", "uy", "uz", "rx", "ry", "rz"].index)


def test_choose_free_leaves_a_ball_free_to_slide_not_to_turn():
    """A ball in its socket: every translation is resisted, a rotation about the springs'
    centroid is (half) a rotation about the ball's centre, which no spring resists."""
    from dea_opt.geometry import socket_layer

    layer = socket_layer(radius=25.0, thickness=3.0, coverage=80.0, n_rings=12, n_sectors=36)
    centre = layer.areas @ layer.points / layer.areas.sum()
    free, _ = choose_free(layer, centre)
    assert free == ["ux", "uy", "uz"]


def test_the_table_of_moduli_confines_as_the_sources_say():
    # (1 - nu) E / ((1 + nu)(1 - 2 nu)), by hand for the four rows that convert
    assert confined_modulus(10.0, 0.45) == pytest.approx(0.55 * 10.0 / (1.45 * 0.1))
    rows = {row.key: row for row in MODULI}
    assert rows["uhmwpe-cams"].H == round(0.55 * 463.0 / (1.45 * 0.1))
    assert rows["uhmwpe-dm"].H == round(0.54 * 46.3 / (1.46 * 0.08))
    assert rows["uhmwpe-ankle"].H == round(0.62 * 475.0 / (1.38 * 0.24))
    assert rows["knee-cartilage"].H == 10.0 and "Lenhart" in rows["knee-cartilage"].source


# --- init, then run ------------------------------------------------------------------------------


def test_init_then_run_solves_the_knee_as_written(tmp_path, meshes):
    out = tmp_path / "knee.toml"
    result = init(meshes, out)
    assert result.exit_code == 0, result.output
    text = out.read_text()
    data = tomllib.loads(text)
    assert data["geometry"]["scale"] == 1.0 and set(data["geometry"]["mesh1"]) == {"medial", "lateral"}
    assert data["body2"]["reference"] == "contact" and data["body2"]["free"] == ["uz", "ry"]
    assert data["load"]["force"] == [0.0, 0.0, -1000.0] and data["law"]["H"] == 10.0
    knee = next(row for row in MODULI if row.key == "knee-cartilage")
    assert "Lenhart" in text and knee.advice in comments(text) and knee.source in comments(text)
    assert "millimetres" in result.output and "run it: dea-opt run" in result.output
    ran = run(out)
    assert ran.exit_code == 0, ran.output
    summary = json.loads((tmp_path / "out" / "contact.json").read_text())
    assert summary["validity"]["valid"] and set(summary["regions"]) == {"medial", "lateral"}
    assert np.linalg.norm(summary["contact_force_N"]) == pytest.approx(1000.0, rel=1e-6)


def test_init_writes_the_scale_of_meshes_in_metres(tmp_path):
    files = write_meshes(tmp_path / "m", scale=1e-3)
    out = tmp_path / "knee.toml"
    result = init(files, out)
    assert result.exit_code == 0, result.output
    assert tomllib.loads(out.read_text())["geometry"]["scale"] == 1000.0 and "metres" in result.output
    assert run(out).exit_code == 0


def test_init_stops_saying_why_when_the_size_does_not_say_the_units(tmp_path):
    files = write_meshes(tmp_path / "small", scale=0.03)  # about 2 mm across: a rat's knee, or cm?
    result = init(files, tmp_path / "knee.toml")
    assert result.exit_code == 2 and "give --scale" in result.output and "does not say their units" in result.output
    assert not (tmp_path / "knee.toml").exists()
    assert init(files, tmp_path / "knee.toml", "--scale", "30").exit_code == 0


def test_init_negates_a_load_path_that_pulls_apart(tmp_path, meshes):
    from first_hour import stance

    _, forces, moments = stance()
    loads = write_csv(tmp_path / "walk.csv", forces=-forces, moments=-moments)
    out = tmp_path / "walk.toml"
    result = init(meshes, out, load=loads)
    assert result.exit_code == 0, result.output
    data = tomllib.loads(out.read_text())
    assert data["load_path"]["scale"] == -1.0 and data["load_path"]["file"] == "walk.csv"
    assert "pull the bodies apart in 11 of 11" in result.output
    ran = run(out)
    assert ran.exit_code == 0, ran.output


@pytest.mark.slow
def test_init_reads_an_opensim_file_its_columns_sign_and_units(tmp_path, meshes):
    write_sto(tmp_path / "walk.sto", moment_factor=1.0)  # the tibia's reaction, moments in N mm
    out = tmp_path / "walk.toml"
    result = init(meshes, out, load=tmp_path / "walk.sto")
    assert result.exit_code == 0, result.output
    section = tomllib.loads(out.read_text())["load_path"]
    assert section["units"] == "mm"
    assert section["columns"] == {q: f"-{STO_PREFIX}_{q.lower()}" for q in ("Fx", "Fy", "Fz", "Mx", "My", "Mz")}
    ran = run(out)
    assert ran.exit_code == 0, ran.output
    # and in N m, as OpenSim writes it: units = "SI"
    write_sto(tmp_path / "si.sto")
    assert init(meshes, tmp_path / "si.toml", load=tmp_path / "si.sto").exit_code == 0
    assert tomllib.loads((tmp_path / "si.toml").read_text())["load_path"]["units"] == "SI"


def test_init_refuses_to_replace_a_file_without_force(tmp_path, meshes):
    out = tmp_path / "knee.toml"
    out.write_text("mine")
    result = init(meshes, out)
    assert result.exit_code == 2 and "exists" in result.output and "--force" in result.output
    assert out.read_text() == "mine"
    assert init(meshes, out, "--force").exit_code == 0 and out.read_text() != "mine"


@pytest.mark.parametrize(
    "extra, message",
    [
        (["--load", "-5"], "a number > 0"),
        (["--load", "nowhere.csv"], "--load must be a force in N or a load file"),
        (["--material", "steel"], "--material must be one of"),
        (["--landmark", "medial=1,2"], "--landmark must look like NAME=X,Y,Z"),
    ],
)
def test_init_bad_options_are_one_paragraph(tmp_path, meshes, extra, message):
    out = tmp_path / "knee.toml"
    args = ["--body1", meshes["medial"], "--body2", meshes["femur"], "-o", out, *extra]
    if "--load" not in extra:
        args += ["--load", "1000"]
    result = invoke("init", *args)
    assert result.exit_code == 2 and result.output.startswith("dea-opt: error: ") and message in result.output


def test_init_writes_the_anatomical_frame_and_the_chosen_modulus(tmp_path, meshes):
    out = tmp_path / "knee.toml"
    # the plateaus' centres as landmarks (medial at larger x, as the files lie) and a point above
    extra = ["--landmark", "medial=-50,-6,-19", "--landmark", "lateral=-90,-6,-19", "--landmark", "proximal=-70,-6,20"]
    result = init(meshes, out, *extra, "--side", "right", "--material", "uhmwpe-cams")
    assert result.exit_code == 0, result.output
    data = tomllib.loads(out.read_text())
    assert data["output"]["anatomy"]["landmarks"]["medial"] == [-50.0, -6.0, -19.0]
    assert data["law"]["H"] == next(row.H for row in MODULI if row.key == "uhmwpe-cams")
    assert "cams_Mplus_right_contact.osim" in out.read_text()
    assert init(meshes, out, "--modulus", "7.5", "--force").exit_code == 0
    assert tomllib.loads(out.read_text())["law"]["H"] == 7.5 and "--modulus" in out.read_text()


# --- the real knee -------------------------------------------------------------------------------

needs_knee = pytest.mark.skipif(not all((KNEE / f).is_file() for f in KNEE_FILES), reason="no knee meshes")


@pytest.mark.slow
@needs_knee
def test_the_real_knee_init_then_run_is_valid_with_no_hand_edit(tmp_path):
    out = tmp_path / "knee.toml"
    result = invoke(
        "init",
        "--body1",
        f"medial={KNEE / 'medial_tibial_cartilage.stl'}",
        "--body1",
        f"lateral={KNEE / 'lateral_tibial_cartilage.stl'}",
        "--body2",
        KNEE / "femoral_cartilage.stl",
        "--load",
        "1000",
        "-o",
        out,
    )
    assert result.exit_code == 0, result.output
    ran = run(out)
    assert ran.exit_code == 0, ran.output
    summary = json.loads((tmp_path / "out" / "contact.json").read_text())
    assert summary["validity"]["valid"] and set(summary["regions"]) == {"medial", "lateral"}
    # the reference is the springs' area-weighted centroid, summed here from contact.csv
    springs = np.genfromtxt(tmp_path / "out" / "contact.csv", delimiter=",", names=True)
    centre = np.array([springs["area_mm2"] @ springs[f"{c}_mm"] for c in "xyz"]) / springs["area_mm2"].sum()
    reference = re_reference(out.read_text())
    np.testing.assert_allclose(reference, centre, atol=0.01)


def re_reference(text: str) -> np.ndarray:
    """The centre the file's comment states for ``reference = "contact"`` (mm, 4 digits)."""
    import re

    match = re.search(r"springs as cast, here \(([-\d.e+]+), ([-\d.e+]+), ([-\d.e+]+)\) mm", comments(text))
    assert match, text
    return np.array([float(v) for v in match.groups()])
