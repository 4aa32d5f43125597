"""Scale-out shown, not assumed: a Dask scheduler and two workers started as separate
processes on the loopback interface, and ``dea-opt sweep --scheduler tcp://127.0.0.1:PORT``
running its cases on them, as it would on a cluster's nodes sharing a file system."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import pytest
from conftest import scenario_text

from dea_opt.sweep import RESULTS_NAME, read_results

pytest.importorskip("distributed")

PLATE = scenario_text(
    title="plate for a distributed sweep",
    nx=100,
    ny=10,
    force=-100.0,
    point=(5.0, 0.0, 0.0),
    formats=("csv", "json", "vtk", "png"),
)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _dask(*args) -> list[str]:
    script = Path(sys.executable).with_name("dask")
    return [str(script), *args] if script.exists() else [sys.executable, "-m", "distributed.cli.dask_spec", *args]


def _wait_for_workers(address: str, count: int, timeout: float = 90.0) -> list[int]:
    """The pids of the workers once ``count`` have joined the scheduler at ``address``."""
    from dask.distributed import Client

    with Client(address, timeout="30s") as client:
        client.wait_for_workers(count, timeout=timeout)
        return sorted(client.run(os.getpid).values())


def _command() -> list[str]:
    script = Path(sys.executable).with_name("dea-opt")
    entry = "import sys; from dea_opt.cli import main; sys.exit(main())"
    return [str(script)] if script.exists() else [sys.executable, "-c", entry]


@pytest.mark.slow
def test_a_sweep_runs_on_a_scheduler_and_two_workers_started_apart(tmp_path):
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    logs = tmp_path / "logs"
    logs.mkdir()
    started = []

    def start(name, *args):
        with open(logs / f"{name}.log", "w") as log:
            process = subprocess.Popen(
                _dask(*args), stdout=log, stderr=subprocess.STDOUT, cwd=tmp_path, start_new_session=True
            )
        started.append(process)
        return process

    try:
        start("scheduler", "scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard")
        for k in range(2):
            start(
                f"worker{k}",
                "worker",
                address,
                "--nthreads",
                "1",
                "--nworkers",
                "1",
                "--host",
                "127.0.0.1",
                "--no-dashboard",
                "--name",
                f"w{k}",
            )
        worker_pids = _wait_for_workers(address, 2)
        scenario = tmp_path / "plate.toml"
        scenario.write_text(PLATE)
        out = tmp_path / "sweep"
        command = _command() + [
            "sweep",
            str(scenario),
            "--set",
            "law.H=6,8,10,12,14,16",
            "--set",
            "load.scale=1,2",
            "--scheduler",
            address,
            "--outputs",
            "csv,json",
            "-o",
            str(out),
        ]
        done = subprocess.run(command, capture_output=True, text=True, timeout=600, check=False)
        assert done.returncode == 0, done.stderr + (logs / "worker0.log").read_text()[-2000:]
        assert done.stdout.startswith("12 case(s) run, 0 already finished")
        table = pd.read_csv(out / RESULTS_NAME)
        assert len(table) == 12 and (table["status"] == "ok").all()
        # The cases ran in the two workers started here, both of them, not in the sweep's process.
        assert set(table["pid"]) == set(worker_pids)
        # Each case's numbers: the plate's uniform pressure F / A under its own load scale.
        pressure = 100.0 * table["load.scale"] / (40.0 * 10.0)
        assert ((table["mean_pressure_MPa"] - pressure).abs() <= 1e-9 * pressure).all()
        assert sorted(
            p.name for p in (out / "cases" / table["case_id"].iloc[0]).iterdir() if not p.name.startswith(".")
        ) == ["contact.csv", "contact.json", "manifest.json"]
        # A rerun through the same cluster finds every case finished.
        again = subprocess.run(command, capture_output=True, text=True, timeout=300, check=False)
        assert again.returncode == 0 and again.stdout.startswith("0 case(s) run, 12 already finished")
        assert len(read_results(out)) == 12
    finally:
        for process in reversed(started):
            if process.poll() is None:
                os.killpg(process.pid, signal.SIGTERM)
        deadline = time.monotonic() + 30
        for process in started:
            try:
                process.wait(timeout=max(deadline - time.monotonic(), 0.1))
            except subprocess.TimeoutExpired:
                os.killpg(process.pid, signal.SIGKILL)
                process.wait(timeout=10)


@pytest.mark.slow
def test_the_local_cluster_runs_cases_on_one_thread_without_the_profiler():
    """What a sweep's LocalCluster gives each case: one thread, OpenBLAS on one thread, glibc's
    own malloc thresholds, no statistical profiler sampling the case's stack, and Dask's periodic
    checks once a second."""
    from dea_opt.sweep import _client

    client, cluster = _client(None, 2)
    try:

        def probe(dask_worker):
            import os

            import dask

            return (
                dask_worker.state.nthreads,
                os.environ.get("OPENBLAS_NUM_THREADS"),
                os.environ.get("MALLOC_TRIM_THRESHOLD_"),
                dask.config.get("distributed.worker.profile.enabled"),
                dask.config.get("distributed.admin.tick.interval"),
                dask.config.get("distributed.worker.memory.monitor-interval"),
            )

        seen = client.run(probe)
    finally:
        client.close()
        cluster.close()
    assert len(seen) == 2
    assert set(seen.values()) == {(1, "1", None, False, "1s", "1s")}
