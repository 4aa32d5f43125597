"""The new user's ten mistakes, one by one at the command line: each gets a first line that names
the cause and the fix (the scenario key to change), and the exit code the house gives it: 2 for
input that cannot be meant (one paragraph, no traceback), the run's own code for input that is
plausible but suspicious (solved, the suspicion said first).

Every case runs ``dea-opt run`` on a small knee of one's own (``first_hour.py``): three
cartilage files 70 mm from the origin, the reference point at the contact's centre
(``reference = "contact"``), the femur free to sink and tilt.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from first_hour import scenario_text, sto_columns, write_csv, write_meshes, write_sto
from typer.testing import CliRunner

from dea_opt.cli import app

runner = CliRunner()


def run(tmp_path, text: str, *args, name: str = "case.toml"):
    """``dea-opt run`` of the scenario ``text``: (exit code, first line of what the terminal shows,
    the whole output in one line)."""
    path = tmp_path / name
    path.write_text(text)
    result = runner.invoke(app, ["run", str(path), *map(str, args)])
    assert "Traceback" not in result.output and "internal error" not in result.output, result.output
    lines = result.output.splitlines()
    return result.exit_code, lines[0] if lines else "", " ".join(result.output.split())


@pytest.fixture(scope="module")
def meshes(tmp_path_factory):
    return write_meshes(tmp_path_factory.mktemp("knee") / "mm")


def error_line(code, first, *words):
    """An error paragraph of exit code 2 whose first line names every one of ``words``."""
    assert code == 2, first
    assert first.startswith("dea-opt: error: "), first
    for word in words:
        assert word in first, first


# --- 1-2: the file itself -------------------------------------------------------------------------


def test_a_typed_key_is_named_first_with_the_key_it_meant(tmp_path, meshes):
    text = scenario_text(meshes).replace("H = 10.0", "HH = 10.0")
    code, first, _ = run(tmp_path, text)
    error_line(code, first, "law.HH", "unknown key 'HH': did you mean 'H'?")
    # the consequence (H missing) comes after its cause
    assert first.index("law.HH") < first.index("needs H")


def test_a_typed_key_elsewhere_suggests_the_allowed_key(tmp_path, meshes):
    code, first, _ = run(tmp_path, scenario_text(meshes).replace("free =", "fre ="))
    error_line(code, first, "body2.fre", "did you mean 'free'?")


def test_a_wrong_path_names_the_key_the_file_and_the_file_it_meant(tmp_path, meshes):
    wrong = str(meshes["femur"]).replace("femur.stl", "femoral.stl")
    code, first, _ = run(tmp_path, scenario_text({**meshes, "femur": wrong}))
    error_line(code, first, "geometry.mesh2", "file not found", "femoral.stl", "did you mean femur.stl?")


def test_a_wrong_folder_says_which_part_of_the_path_exists(tmp_path, meshes):
    wrong = str(meshes["femur"]).replace("/mm/", "/nm/")
    code, first, _ = run(tmp_path, scenario_text({**meshes, "femur": wrong}))
    error_line(code, first, "geometry.mesh2", "does not exist")


# --- 3: meshes in metres --------------------------------------------------------------------------


def test_meshes_in_metres_are_stopped_before_casting_naming_the_scale_key(tmp_path):
    files = write_meshes(tmp_path / "m", scale=1e-3)
    code, first, _ = run(tmp_path, scenario_text(files))
    error_line(code, first, "look like metres", "[geometry] scale = 1000")
    # the fix it names runs: with scale = 1000 the same files solve inside validity
    code, first, _ = run(tmp_path, scenario_text(files, scale=1000.0), "-o", tmp_path / "out")
    assert code == 0, first


def test_a_scale_applied_twice_is_named_too(tmp_path, meshes):
    code, first, _ = run(tmp_path, scenario_text(meshes, scale=1000.0))
    error_line(code, first, "look like micrometres", "with [geometry] scale = 1000", "scale = 1")


# --- 4-7: the load --------------------------------------------------------------------------------


def test_a_load_in_the_wrong_column_is_named(tmp_path, meshes):
    from first_hour import stance

    _, forces, moments = stance()
    moved = forces[:, [2, 1, 0]]  # the compressive force written into Fx
    loads = write_csv(tmp_path / "walk.csv", forces=moved, moments=moments)
    code, first, _ = run(tmp_path, scenario_text(meshes, load=f'[load_path]\nfile = "{loads}"\n'))
    error_line(code, first, "every frame of walk.csv lies along the contact's surface", "belongs in Fz (now in Fx)")


def test_a_static_force_in_the_wrong_component_gets_the_corrected_force(tmp_path, meshes):
    text = scenario_text(meshes).replace("[0.0, 0.0, -1000.0]", "[-1000.0, 0.0, 0.0]")
    code, first, _ = run(tmp_path, text)
    error_line(code, first, "lies along the contact's surface", "[load] force = [0.0, 0.0, -1000.0]")


def test_a_forgotten_sign_is_named_once_for_every_frame_with_the_key(tmp_path, meshes):
    _, forces, moments = __import__("first_hour").stance()
    loads = write_csv(tmp_path / "walk.csv", forces=-forces, moments=-moments)
    code, first, everything = run(tmp_path, scenario_text(meshes, load=f'[load_path]\nfile = "{loads}"\n'))
    error_line(code, first, "every frame of walk.csv pulls the bodies apart", "[load_path] scale = -1")
    assert "cannot carry" in first and everything.count("pulls") == 1


def test_a_forgotten_sign_in_an_opensim_file(tmp_path, meshes):
    write_sto(tmp_path / "walk.sto")
    section = f'[load_path]\nfile = "{tmp_path / "walk.sto"}"\ncolumns = {sto_columns(sign="")}\n'
    code, first, _ = run(tmp_path, scenario_text(meshes, load=section))
    error_line(code, first, "pulls the bodies apart", "scale = -1", 'leading "-"')


def test_a_static_load_pulling_apart_gets_the_negated_force(tmp_path, meshes):
    code, first, _ = run(tmp_path, scenario_text(meshes).replace("-1000.0]", "1000.0]"))
    error_line(code, first, "the load pulls the bodies apart", "[load] force = [0.0, 0.0, -1000.0]", "cannot carry")


def test_moments_in_n_mm_read_as_si_get_units_mm(tmp_path, meshes):
    write_sto(tmp_path / "walk.sto", moment_factor=1.0)  # N mm in a file read as N m
    section = f'[load_path]\nfile = "{tmp_path / "walk.sto"}"\ncolumns = {sto_columns()}\n'
    code, first, _ = run(tmp_path, scenario_text(meshes, load=section))
    error_line(code, first, "look 1000x too large", '[load_path] units = "mm"')
    # the fix it names runs
    code, first, _ = run(tmp_path, scenario_text(meshes, load=section + 'units = "mm"\n'), "-o", tmp_path / "out")
    assert code == 0, first


def test_missing_moment_columns_are_said_first_and_the_path_solves(tmp_path, meshes):
    write_sto(tmp_path / "walk.sto")
    section = f'[load_path]\nfile = "{tmp_path / "walk.sto"}"\ncolumns = {sto_columns(moments=False)}\n'
    code, first, everything = run(tmp_path, scenario_text(meshes, load=section), "-o", tmp_path / "out")
    assert first.startswith("dea-opt: warning: suspicious input: walk.sto has moment columns"), first
    assert f"{__import__('first_hour').STO_PREFIX}_my" in first and "Mx =" in first
    assert code == 0, everything
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert summary["suspicious_input"] and "moment columns" in summary["suspicious_input"][0]


def test_a_csv_without_moments_while_a_rotation_is_free_is_said(tmp_path, meshes):
    _, forces, _ = __import__("first_hour").stance()
    loads = write_csv(tmp_path / "walk.csv", forces=forces, columns=("Fx", "Fy", "Fz"))
    code, first, _ = run(tmp_path, scenario_text(meshes, load=f'[load_path]\nfile = "{loads}"\n'), "-o", tmp_path / "o")
    assert first.startswith("dea-opt: warning: suspicious input: walk.csv gives no moments"), first
    assert "while ry is free" in first and code == 0


# --- 8: an existing output folder -----------------------------------------------------------------


def test_an_existing_folder_of_ones_own_is_named_with_the_fix(tmp_path, meshes):
    folder = tmp_path / "results"
    folder.mkdir()
    (folder / "notes.txt").write_text("mine")
    code, first, _ = run(tmp_path, scenario_text(meshes), "-o", folder)
    error_line(code, first, str(folder), "notes.txt", "-o", "--force")
    assert (folder / "notes.txt").read_text() == "mine"


# --- 9-10: plausible but suspicious: solved, and said first ---------------------------------------


def test_h_in_kpa_is_solved_and_said_first(tmp_path, meshes):
    text = scenario_text(meshes).replace("H = 10.0", "H = 10000.0")
    code, first, everything = run(tmp_path, text, "-o", tmp_path / "out")
    assert first.startswith("dea-opt: warning: suspicious input: [law] H = 10000 MPa"), first
    assert "if you gave kPa, write H = 10" in first
    summary = json.loads((tmp_path / "out" / "contact.json").read_text())
    # the verdict's first line is the suspicion; the exit code is the validity's own
    assert everything.index("input: suspicious: [law] H = 10000") < everything.index("validity:")
    assert code == (0 if summary["validity"]["valid"] else 3)
    assert not summary["validity"]["valid"] and "peak_pressure" in summary["validity"]["failed"]
    assert summary["suspicious_input"][0].startswith("[law] H = 10000 MPa")


def test_a_load_in_kn_is_solved_and_said_first(tmp_path, meshes):
    text = scenario_text(meshes).replace("-1000.0]", "-1.0]")
    code, first, _ = run(tmp_path, text, "-o", tmp_path / "out")
    assert first.startswith("dea-opt: warning: suspicious input: the load looks a thousand times too small"), first
    assert "if it is in kN, set [load] scale = 1000" in first
    summary = json.loads((tmp_path / "out" / "contact.json").read_text())
    assert code == 0 and summary["validity"]["valid"]
    # solved as given (1 N, not scaled): the springs' resultant carries 1 N
    assert np.linalg.norm(summary["contact_force_N"]) == pytest.approx(1.0, rel=1e-6)


def test_modulus_in_gpa_is_said(tmp_path, meshes):
    text = scenario_text(meshes).replace("H = 10.0", "H = 0.01")
    code, first, _ = run(tmp_path, text, "-o", tmp_path / "out")
    assert first.startswith("dea-opt: warning: suspicious input: [law] H = 0.01 MPa"), first
    assert "if you gave GPa, write H = 10" in first


# --- the reference point --------------------------------------------------------------------------


def test_a_reference_left_at_the_origin_is_stopped_naming_contact(tmp_path, meshes):
    text = scenario_text(meshes).replace('reference = "contact"\n', "")
    code, first, _ = run(tmp_path, text)
    error_line(code, first, "[body2] reference is not set", "from the contact's centre", 'reference = "contact"')


def test_an_explicit_far_reference_is_named_in_the_unsupported_load(tmp_path, meshes):
    text = scenario_text(meshes).replace('reference = "contact"', "reference = [0.0, 0.0, 0.0]")
    code, first, _ = run(tmp_path, text)
    error_line(code, first, "cannot carry", "likely because body 2's reference point (0, 0, 0) mm is")
    assert 'reference = "contact"' in first


def test_the_check_can_be_turned_off_and_the_frames_then_fail_grouped(tmp_path, meshes):
    """With ``check_inputs = false`` the forgotten sign solves frame by frame: every frame fails,
    and the run says so in one complete line with the fix, not once per frame."""
    _, forces, moments = __import__("first_hour").stance()
    loads = write_csv(tmp_path / "walk.csv", forces=-forces, moments=-moments)
    text = scenario_text(meshes, load=f'[load_path]\nfile = "{loads}"\n', extra="[solve]\ncheck_inputs = false\n")
    code, _, everything = run(tmp_path, text, "-o", tmp_path / "out")
    assert code == 1
    assert "11 of 11 frames without a certified answer: every frame (11 of 11) load_not_supported: each frame " in (
        everything
    )
    assert "pulls the bodies apart" in everything and "[load_path] scale = -1" in everything
    # once per time the run's message is printed (the summary, then the reason on stderr), uncut
    assert everything.count("pulls the bodies apart") == everything.count("frames without a certified answer")
    assert "..." not in everything
