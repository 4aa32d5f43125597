"""The benchmarks still run: ``benchmarks/run.py --quick`` on the sections that call the public API
most (a load path, finite kinematics, the solvers' core), every case without an error.

Speed is never asserted here (``benchmarks/`` reports it); what is asserted is that the scripts
speak the package's current API: a benchmark still passing a keyword that moved elsewhere
(``solve_path``'s outputs) records each of its cases as an error, and its row goes unmeasured.
And the knee cases of the finite section (with ``../shared`` beside the project) are answers
inside the model: a speed measured on a crushed answer says nothing of what users wait for."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.slow
def test_the_quick_benchmark_runs_every_case_of_its_sections_without_an_error(tmp_path):
    run = subprocess.run(
        [sys.executable, str(ROOT / "benchmarks" / "run.py"), "--quick", "--only", "gait", "finite", "core"]
        + ["--out", str(tmp_path)],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=ROOT,
    )
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    report = (tmp_path / "run.txt").read_text()
    assert "## gait" in report and "## core" in report
    errors = [line for line in report.splitlines() if "error:" in line]
    assert not errors, "\n".join(errors)
    assert " met," in report  # the TARGETS table was printed
    # the finite section's knee cases are answers inside the model: a flexed knee turned the wrong
    # way (hyperextension, the trochlea driven into the tibia) timed a crushed answer
    if "## finite" in report and "skipped" not in report.split("## finite", 1)[1].split("##", 1)[0]:
        flexed = next(line for line in report.splitlines() if "knee flexed 15 deg about its condyles' axis" in line)
        assert "valid: finite True" in flexed, flexed
        gait = next(line for line in report.splitlines() if "frames inside the model" in line)
        frames = gait.split("frames inside the model ", 1)[1].split()[0]
        inside, total = map(int, frames.split("/"))
        assert inside == total, gait
