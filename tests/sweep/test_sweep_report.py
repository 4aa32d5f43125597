"""What a sweep shows: each finished case and a progress bar on a terminal, only the summary when
piped or --quiet, and no library noise (Dask logs, tracebacks, raw warnings) on the terminal."""

from __future__ import annotations

import os
import re
import subprocess
import sys

import pytest
from conftest import scenario_text

from dea_opt.sweep import RESULTS_NAME, format_row, make_cases

PLATE = scenario_text(point=(5.0, 0.0, 0.0), formats=("json",))
# A negative scale pulls the plate off: two error rows. H >= 8 keeps the others inside validity
# (peak 2.19 MPa: strain 0.27 at H = 8, under the linear law's 30 %).
SETS = ["law.H=8,10", "load.scale=1,-1"]


@pytest.fixture()
def plate(tmp_path):
    path = tmp_path / "plate.toml"
    path.write_text(PLATE)
    return path


def _command(plate, out, *extra) -> list[str]:
    return [
        sys.executable,
        "-m",
        "dea_opt.cli",
        "sweep",
        str(plate),
        *[a for s in SETS for a in ("--set", s)],
        "--scheduler",
        "synchronous",
        "-o",
        str(out),
        *extra,
    ]


def in_terminal(command) -> tuple[str, str, int]:
    """Run ``command`` with stdout on a pseudo-terminal; return (terminal text, stderr, exit code)."""
    import fcntl
    import pty
    import struct
    import termios

    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))  # 24 x 100, as a terminal has
    process = subprocess.Popen(command, stdin=slave, stdout=slave, stderr=subprocess.PIPE)
    os.close(slave)
    chunks = []
    while True:
        try:
            data = os.read(master, 65536)
        except OSError:  # EIO: the child closed the terminal
            break
        if not data:
            break
        chunks.append(data)
    stderr = process.stderr.read().decode()
    process.wait(timeout=120)
    os.close(master)
    return b"".join(chunks).decode(errors="replace"), stderr, process.returncode


def test_on_a_terminal_each_case_is_reported_with_a_progress_bar(plate, tmp_path):
    out = tmp_path / "sweep"
    text, stderr, code = in_terminal(_command(plate, out))
    assert code == 1  # two cases could not carry their load
    lines = [line.strip() for line in re.split(r"[\r\n]+", text) if line.strip()]
    for case in make_cases(SETS):
        overrides = " ".join(f"{k}={v}" for k, v in case.overrides.items())
        status = "ok" if case.overrides["load.scale"] > 0 else "error"
        matching = [line for line in lines if line.startswith(f"case {case.id}  {overrides}  {status}")]
        assert len(matching) == 1, lines
        if status == "ok":
            assert re.search(r"peak [0-9.]+ MPa  [0-9.]+ s$", matching[0])
    assert any(re.search(r"sweep: .*\d+/4", line) for line in lines)  # tqdm's bar
    assert "2 case(s) did not finish cleanly" in stderr and "Traceback" not in stderr


def test_quiet_on_a_terminal_prints_only_the_summary(plate, tmp_path):
    out = tmp_path / "sweep"
    text, stderr, code = in_terminal(_command(plate, out, "--quiet"))
    lines = [line for line in re.split(r"[\r\n]+", text) if line.strip()]
    assert lines == [f"4 case(s) run, 0 already finished; results: {out / RESULTS_NAME}, report: {out / 'report.html'}"]
    assert code == 1 and stderr.startswith("dea-opt: 2 case(s) did not finish cleanly")


def test_piped_prints_only_the_summary(plate, tmp_path):
    out = tmp_path / "sweep"
    done = subprocess.run(_command(plate, out), capture_output=True, text=True, timeout=120, check=False)
    assert done.stdout.splitlines() == [
        f"4 case(s) run, 0 already finished; results: {out / RESULTS_NAME}, report: {out / 'report.html'}"
    ]
    assert done.returncode == 1 and len(done.stderr.splitlines()) == 1


def test_format_row():
    row = {"case_id": "abc", "law.H_MPa": 5, "status": "ok", "peak_pressure_MPa": 2.1875, "wall_time_s": 0.42}
    assert format_row(row, {"law.H": 5}) == "case abc  law.H=5  ok  peak 2.188 MPa  0.4 s"
    failed = {"case_id": "def", "law.H_MPa": 5, "status": "error", "message": "x " * 80, "wall_time_s": 1.0}
    line = format_row(failed, {"law.H": 5}, "(finished by another sweep)")
    assert line.startswith("case def  law.H=5  error  1.0 s  (x x") and "...)" in line
    assert line.endswith("(finished by another sweep)") and "\n" not in line


ROUTED = """\
import logging, os, subprocess, sys, warnings
from dea_opt.sweep.logs import routed_to_log
with routed_to_log(sys.argv[1]):
    warnings.warn("a raw warning")
    logging.getLogger("distributed.comm").error("CommClosedError: in <TCP (closed)>")
    os.write(2, b"written to fd 2\\n")
    print("to sys.stderr", file=sys.stderr, flush=True)
    subprocess.run([sys.executable, "-c", "import sys; sys.stderr.write('from a child process')"])
print("after", file=sys.stderr, flush=True)
warnings.warn("a warning after")
"""


def test_noise_goes_to_the_log_and_the_terminal_comes_back(tmp_path):
    log = tmp_path / "sweep.log"
    done = subprocess.run(
        [sys.executable, "-c", ROUTED, str(log)], capture_output=True, text=True, timeout=60, check=False
    )
    assert done.returncode == 0
    text = log.read_text()
    for noise in ("a raw warning", "CommClosedError", "written to fd 2", "to sys.stderr", "from a child process"):
        assert noise in text
        assert noise not in done.stderr
    assert "after" in done.stderr and "a warning after" in done.stderr
    assert "after" not in text.replace("a raw warning", "")


def test_dask_noise_stays_off_the_terminal(plate, tmp_path):
    """A LocalCluster sweep, piped: the summary on stdout and nothing at all on stderr."""
    pytest.importorskip("dask.distributed")
    out = tmp_path / "sweep"
    command = [
        sys.executable,
        "-m",
        "dea_opt.cli",
        "sweep",
        str(plate),
        "--set",
        "law.H=8,10",
        "--workers",
        "1",
        "-o",
        str(out),
    ]
    done = subprocess.run(command, capture_output=True, text=True, timeout=300, check=False)
    assert done.returncode == 0, done.stderr
    assert done.stderr == ""
    assert (
        done.stdout
        == f"2 case(s) run, 0 already finished; results: {out / RESULTS_NAME}, report: {out / 'report.html'}\n"
    )
    assert (out / "sweep.log").is_file()
