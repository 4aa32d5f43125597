"""A load path too large for the machine is refused before any work per frame, at every entry point:
the Python API (an array, a DataFrame, a sequence of Load), a scenario's load path and the CLI.

Nothing here times anything: the guard must come before any O(frames) work, which the tests
see by construction. An array of 1e9 frames is a broadcast view (48 bytes of data); a sequence
counts the frames it is asked for; a child process runs under an address-space limit of about
2 GB beyond what it has, so a single array of 1e9 numbers (8 GB) fails there at once instead of
filling the machine's memory.
"""

from __future__ import annotations

import subprocess
import sys
import textwrap
from collections.abc import Sequence

import pandas as pd
import pytest
from conftest import COARSE_SOCKET
from typer.testing import CliRunner

import dea_opt as d
from dea_opt._checks import memory
from dea_opt.cli import app
from dea_opt.errors import SizeLimitError
from dea_opt.geometry import plate_layer
from dea_opt.loadpath import path_memory, solve_path
from dea_opt.problem import Load
from dea_opt.scenario import load_scenario
from dea_opt.scenario.load_path import read_load_path

BILLION = 10**9


def plate_problem():
    layer = plate_layer(10.0, 10.0, 4, 4, thickness=2.0)
    return d.ContactProblem(layer, d.LinearLaw(1.0), reference=(0, 0, 0), free=("uz",))


class CountingFrames(Sequence):
    """``n`` frames of one load that record which frames were read (and refuse to be read more
    than a few times: a walk over 1e9 frames would otherwise run for minutes)."""

    def __init__(self, n: int):
        self.n, self.read = n, []

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, k):
        if isinstance(k, slice):
            raise AssertionError("the frames were sliced before the size check")
        self.read.append(k)
        if len(self.read) > 3:
            raise AssertionError(f"frame {k} was read before the size check")
        return Load(force=(0.0, 0.0, -10.0))


def test_a_sequence_of_a_billion_loads_is_refused_before_a_frame_is_read():
    frames = CountingFrames(BILLION)
    with pytest.raises(SizeLimitError, match="1000000000 frames") as caught:
        solve_path(plate_problem(), frames, outputs=d.PathOutputs(keep_solutions=False, keep_pressures=False))
    assert caught.value.needed > caught.value.available
    assert frames.read == []


def test_a_dataframe_is_counted_by_its_length(monkeypatch):
    problem = plate_problem()
    table = pd.DataFrame({"Fx": [0.0] * 4, "Fy": 0.0, "Fz": -10.0})
    monkeypatch.setattr(memory, "available_memory", lambda: 1.0)
    columns_read = []
    monkeypatch.setattr(pd.DataFrame, "__getitem__", lambda self, key: columns_read.append(key))
    with pytest.raises(SizeLimitError, match="a load path of 4 frames"):
        solve_path(problem, table)
    assert columns_read == []  # no column was read, let alone converted


BROADCAST = textwrap.dedent("""
    import resource, sys
    import numpy as np
    import dea_opt as d
    from dea_opt.errors import SizeLimitError
    from dea_opt.geometry import plate_layer

    layer = plate_layer(10.0, 10.0, 4, 4, thickness=2.0)
    problem = d.ContactProblem(layer, d.LinearLaw(1.0), reference=(0, 0, 0), free=("uz",))
    problem.system()
    with open("/proc/self/statm") as f:
        used = int(f.read().split()[0]) * resource.getpagesize()
    limit = used + 2 * 1024**3  # one array of 1e9 numbers (8 GB) cannot be made below this
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))
    row = np.array([0, 0, -10, 0, 0, 0], dtype=sys.argv[1])  # integers: a conversion would copy
    loads = np.broadcast_to(row, (10**9, 6))
    try:
        d.solve_path(problem, loads, outputs=d.PathOutputs(keep_solutions=False, keep_pressures=False))
    except SizeLimitError as exc:
        print("refused:", exc)
    """)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the address-space limit is read from /proc")
@pytest.mark.parametrize("dtype", ["float64", "int64"])
def test_a_broadcast_billion_frame_array_is_refused_before_any_array_of_its_length(dtype):
    done = subprocess.run(
        [sys.executable, "-c", BROADCAST, dtype], capture_output=True, text=True, timeout=300, check=False
    )
    assert done.returncode == 0, done.stderr[-2000:]
    assert "refused: a load path of 1000000000 frames" in done.stdout
    assert "would need about" in done.stdout and "TB of memory" in done.stdout


PATH_CSV = "time,Fx,Fy,Fz\n0,0,0,-500\n1,0,0,-900\n"
SCENARIO = COARSE_SOCKET + '[regions]\nsplit = "x"\n[load_path]\nfile = "path.csv"\nframes = 100000\n'


@pytest.fixture
def big_path(tmp_path, monkeypatch):
    """A socket scenario resampled to 1e5 frames, on a machine whose free memory lets the frames
    be read (the estimate without the springs' regions) but not solved (the regions' columns
    too); and a count of the Load objects made."""
    (tmp_path / "path.csv").write_text(PATH_CSV)
    (tmp_path / "path.toml").write_text(SCENARIO)
    read = path_memory(100_000, 0)
    solved = path_memory(100_000, 0, keep_solutions=False, keep_pressures=False, n_regions=2)
    assert solved > 1.1 * read
    monkeypatch.setattr(memory, "available_memory", lambda: (read + solved) / 2 / memory.USABLE_SHARE)
    made = []
    original = Load.__post_init__

    def counted(self):
        made.append(1)
        original(self)

    monkeypatch.setattr(Load, "__post_init__", counted)
    return tmp_path / "path.toml", made


def test_a_scenario_path_is_refused_before_a_load_is_made(big_path):
    from dea_opt.run import run_scenario

    scenario, made = big_path
    loaded = load_scenario(scenario)
    assert len(read_load_path(loaded.load_path)) == 100_000  # the frames fit; solving them does not
    with pytest.raises(SizeLimitError, match="100000 frames"):
        run_scenario(loaded, scenario.parent / "out")
    assert made == []


def test_the_cli_refuses_it_before_a_load_is_made(big_path):
    scenario, made = big_path
    result = CliRunner().invoke(app, ["run", str(scenario), "-o", str(scenario.parent / "out")])
    assert result.exit_code == 2, result.output
    assert "100000 frames" in result.stderr and "would need about" in result.stderr
    assert "Traceback" not in result.stderr
    assert made == []
    assert not (scenario.parent / "out").exists()
