"""The tutorial "Your own joint" (``docs/_tutorials/your_own_joint.py``) runs as it stands and
reaches what its page says: the error without a reference point, a crushed layer at the
equilibrium modulus, a valid answer whose springs carry the load, the pose trap, and the same
answer from its scenario file."""

from __future__ import annotations

import runpy
import warnings
from pathlib import Path

import numpy as np
import pytest

import dea_opt as d

TUTORIAL = Path(__file__).resolve().parents[2] / "docs" / "_tutorials" / "your_own_joint.py"


@pytest.mark.slow
def test_the_tutorial_runs_and_says_what_it_shows(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    with warnings.catch_warnings():
        warnings.simplefilter("error", d.ValidityWarning)  # only the crushed case may warn, and it silences it
        namespace = runpy.run_path(str(TUTORIAL), run_name="__main__")
    out = capsys.readouterr().out
    assert "LoadNotSupportedError:" in out and "(0, 0, 0) mm" in out
    assert not namespace["soft"].validity.valid and "strain" in namespace["soft"].validity.failed[0].name
    solution, layer = namespace["solution"], namespace["layer"]
    assert solution.success and solution.validity.valid
    # the springs carry the 1000 N (their own sum, not the certificate) and balance its moment
    forces = solution.pressure * layer.areas  # N, pushing the femur along +z
    assert float(forces.sum()) == pytest.approx(1000.0, rel=1e-9)
    arm = layer.points - namespace["centre"]
    moment_y = float(np.sum(arm[:, 2] * 0.0 - arm[:, 0] * forces))
    assert abs(moment_y) < 1e-6 * 1000.0 * np.abs(arm[:, 0]).max()
    assert "springs cast there: none" in out and "springs cast there: none" not in out.split("about the joint")[1]
    assert namespace["from_file"].peak_pressure == pytest.approx(solution.peak_pressure, rel=1e-9)
    assert namespace["outcome"].exit_code == 0
    plt = namespace["plt"]
    plt.close("all")
