"""Progress bars: on a terminal for load paths and comparison studies, nothing when piped or quiet.

Each case runs in a subprocess whose stderr is either a pseudo-terminal or a pipe.
"""

from __future__ import annotations

import fcntl
import os
import pty
import struct
import subprocess
import sys
import termios
import textwrap

import pytest

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
    env = {**os.environ, "MPLBACKEND": "Agg", "TQDM_MININTERVAL": "0"}
    command = [sys.executable, "-c", textwrap.dedent(code)]
    if not terminal:
        done = subprocess.run(command, check=False, capture_output=True, text=True, env=env, timeout=300)
        assert done.returncode == 0, done.stderr
        return done.stderr
    leader, follower = pty.openpty()
    # a terminal 100 columns wide (a new pseudo-terminal has none, and tqdm fits its bar to it)
    fcntl.ioctl(follower, termios.TIOCSWINSZ, struct.pack("HHHH", 30, 100, 0, 0))
    process = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=follower, env=env)
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
    assert process.wait(timeout=300) == 0
    return b"".join(chunks).decode("utf-8", "replace")


@pytest.mark.parametrize("code, unit", [(PATH, "frame"), (STUDY, "run")])
def test_a_bar_on_a_terminal_and_nothing_in_a_pipe(code, unit):
    shown = run(code.format(progress=True), terminal=True)
    assert f"{unit}" in shown and "|" in shown  # a tqdm bar: "frames: 100%|####| 5/5 [...frame/s]"
    assert run(code.format(progress=True), terminal=False) == ""
    assert run(code.format(progress=False), terminal=True) == ""
