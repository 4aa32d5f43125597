"""Progress: on a terminal the stages of a run and a bar over its frames, runs, cases or solves
with the time left; nothing when piped, nothing with ``--quiet`` (or ``progress=False``).

Each case runs in a subprocess whose stderr (and, for the command line, stdout) is either a
pseudo-terminal or a pipe.
"""

from __future__ import annotations

import fcntl
import os
import pty
import re
import struct
import subprocess
import sys
import termios
import textwrap

import pytest
from conftest import invoke

PATH = """
import numpy as np, dea_opt as d
from dea_opt.geometry import socket_layer
layer = socket_layer(radius=25.0, thickness=3.0, coverage=80.0, n_rings=6, n_sectors=12, gap=0.1)
problem = d.ContactProblem(layer, d.LinearLaw(10.0), free=("ux", "uy", "uz"))
d.solve_path(problem, np.tile([0.0, 0.0, -500.0], (5, 1)), method="newton", progress={progress})
"""

STUDY = """
import dea_opt as d
from dea_opt.geometry import sphere_on_bed_layer
from dea_opt.study import run_study
layer = sphere_on_bed_layer(n_rings=8, n_sectors=12)
problem = d.ContactProblem(layer, d.LinearLaw(5.0), force=(0, 0, -20), reference=(0, 0, 25), free=("uz",))
run_study(problem, methods=("newton",), progress={progress})
"""


def run(code: str, terminal: bool) -> str:
    """The script's stderr, read from a pseudo-terminal or a pipe."""
    return run_command([sys.executable, "-c", textwrap.dedent(code)], terminal)


def run_command(command, terminal: bool, *, stdout: bool = False, cwd=None, code: int = 0) -> str:
    """The command's stderr (and its stdout with ``stdout``), read from a pseudo-terminal or a
    pipe; ``code`` its exit code."""
    env = {**os.environ, "MPLBACKEND": "Agg", "TQDM_MININTERVAL": "0"}
    if not terminal:
        done = subprocess.run(command, check=False, capture_output=True, text=True, env=env, timeout=300, cwd=cwd)
        assert done.returncode == code, done.stderr
        return done.stderr + (done.stdout if stdout else "")
    leader, follower = pty.openpty()
    # a terminal 100 columns wide (a new pseudo-terminal has none, and tqdm fits its bar to it)
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 30, 100, 0, 0))
    process = subprocess.Popen(
        command,
        stdin=subprocess.DEVNULL,
        stdout=follower if stdout else subprocess.DEVNULL,
        stderr=follower,
        env=env,
        cwd=cwd,
    )
    os.close(follower)
    chunks = []
    while True:
        try:
            data = os.read(leader, 4096)
        except OSError:  # the terminal closes when the process ends
            break
        if not data:
            break
        chunks.append(data)
    os.close(leader)
    assert process.wait(timeout=300) == code, b"".join(chunks).decode("utf-8", "replace")
    return b"".join(chunks).decode("utf-8", "replace")


@pytest.mark.parametrize("code, unit", [(PATH, "frame"), (STUDY, "run")])
@pytest.mark.slow
def test_a_bar_on_a_terminal_and_nothing_in_a_pipe(code, unit):
    shown = run(code.format(progress=True), terminal=True)
    assert f"{unit}" in shown and "|" in shown  # a tqdm bar: "frames: 100%|####| 5/5 [...frame/s]"
    assert run(code.format(progress=True), terminal=False) == ""
    assert run(code.format(progress=False), terminal=True) == ""


# --- the command line ----------------------------------------------------------------------------

#: A bar with the time left: tqdm's ``[elapsed<remaining, rate]``.
TIME_LEFT = re.compile(r"\[\d\d:\d\d<\d\d:\d\d")
#: What progress draws, and nothing else does: a stage line or a bar.
DRAWN = re.compile(r"dea-opt: (reading|casting|solving|checking|writing)|\d+%\|")


def cli(*args) -> list:
    return [sys.executable, "-m", "dea_opt.cli", *map(str, args)]


@pytest.fixture(scope="module")
def knee(tmp_path_factory):
    """The small knee of ``first_hour.py``: a static scenario and an 11-frame path."""
    from first_hour import scenario_text, write_csv, write_meshes

    folder = tmp_path_factory.mktemp("progress")
    files = write_meshes(folder / "mm")
    (folder / "static.toml").write_text(scenario_text(files))
    write_csv(folder / "walk.csv")
    (folder / "walk.toml").write_text(scenario_text(files, load='[load_path]\nfile = "walk.csv"\n'))
    return folder


@pytest.mark.parametrize("quiet", [False, True])
def test_run_shows_its_stages_and_the_frames_time_left_on_a_terminal_only(knee, tmp_path, quiet):
    flag = ["--quiet"] if quiet else []
    static = run_command(cli("run", knee / "static.toml", "-o", tmp_path / "a", *flag), True, stdout=True)
    path = run_command(cli("run", knee / "walk.toml", "-o", tmp_path / "b", *flag), True, stdout=True)
    if quiet:
        assert not DRAWN.search(static) and not DRAWN.search(path)
        return
    for stage in ("reading meshes", "casting springs", "checking the inputs", "solving (auto)", "writing outputs"):
        assert f"dea-opt: {stage}" in static, static
    assert "dea-opt: reading the load path" in path and "solving frames" in path and "/11 [" in path
    assert TIME_LEFT.search(path), path
    # the summary is printed still, after the progress is cleared
    assert "validity: valid" in static and "validity:" in path


def piped(*args) -> str:
    """``dea-opt ARGS`` run in this process, whose output streams are no terminal (as a pipe is
    not): its stderr and stdout; it must exit 0."""
    result = invoke(*args)
    assert result.exit_code == 0, result.stderr
    return result.stderr + result.stdout


def test_run_draws_nothing_into_a_pipe(knee, tmp_path):
    static = piped("run", knee / "static.toml", "-o", tmp_path / "a")
    path = piped("run", knee / "walk.toml", "-o", tmp_path / "b")
    assert not DRAWN.search(static) and not DRAWN.search(path), static + path
    assert "validity: valid" in static  # what a run prints is there, the progress is not


SPHERE = """\
[geometry]
kind = "sphere_on_bed"
extent = 7.0
n_rings = 30
n_sectors = 24
[law]
kind = "ateshian"
H = {H}
beta = 0.3
[body2]
reference = [0.0, 0.0, 25.0]
free = ["uz", "rx", "ry"]
[load]
force = [0.0, 0.0, -20.0]
point = [0.5, 0.3, 0.0]
"""


@pytest.fixture(scope="module")
def sphere(tmp_path_factory):
    """A sphere on a bed, and the film its law H = 0.6 leaves (for calibrate)."""
    import numpy as np

    import dea_opt as d
    from dea_opt.scenario import build_problem, parse_scenario

    folder = tmp_path_factory.mktemp("sphere")
    (folder / "sphere.toml").write_text(SPHERE.format(H=1.2))
    solution = d.solve(build_problem(parse_scenario(SPHERE.format(H=0.6))))
    points = solution.problem.layer.points
    rows = np.column_stack([points, solution.pressure])
    (folder / "film.csv").write_text("x,y,z,p\n" + "\n".join(",".join(f"{v:.12g}" for v in r) for r in rows))
    return folder


@pytest.mark.parametrize("terminal", [True, False])
@pytest.mark.slow
def test_compare_and_calibrate_show_progress_on_a_terminal_only(sphere, tmp_path, terminal):
    compared = run_command(
        cli("compare", sphere / "sphere.toml", "--methods", "newton,nlp", "-o", tmp_path / "c"), terminal
    )
    fitted = run_command(
        cli(
            "calibrate",
            sphere / "sphere.toml",
            "--data",
            sphere / "film.csv",
            "--parameters",
            "H",
            "-o",
            tmp_path / "f",
        ),
        terminal,
    )
    if terminal:
        assert "compare:" in compared and "run" in compared and TIME_LEFT.search(compared), compared
        assert "fitting:" in fitted and "solve" in fitted, fitted  # a count: how many solves is not known ahead
        assert "dea-opt: reading the pressure map" in fitted
    else:
        assert not DRAWN.search(compared) and "compare:" not in compared
        assert not DRAWN.search(fitted) and "fitting:" not in fitted
    quiet = run_command(
        cli("compare", sphere / "sphere.toml", "--methods", "newton", "-o", tmp_path / "q", "--quiet"), terminal
    )
    assert not DRAWN.search(quiet) and "compare:" not in quiet


@pytest.mark.parametrize("terminal", [True, False])
def test_sweep_shows_its_cases_on_a_terminal_only(sphere, tmp_path, terminal):
    args = (
        "sweep",
        sphere / "sphere.toml",
        "--set",
        "law.H=0.5,0.6",
        "--scheduler",
        "synchronous",
        "-o",
        tmp_path / "s",
    )
    swept = run_command(cli(*args), True, stdout=True) if terminal else piped(*args)
    assert "2 case(s) run" in swept
    assert bool(re.search(r"sweep: +\d+%\|", swept)) is terminal, swept
