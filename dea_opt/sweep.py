"""Sweeps: the Cartesian product of ``--set`` values, each case a task on a Dask cluster.

``dea-opt sweep hip.toml --set law.H=0.3,0.45,0.6 --set load_path.scale=1,2`` makes six
cases. Each case gets a stable id (a hash of its overrides), its own output folder
``<out>/cases/<case id>/`` and, when it finishes, one row in ``<out>/sweep.csv``, written
by the client as results arrive (``as_completed``) and replaced atomically each time. A
rerun reads ``sweep.csv`` and skips every case already there, so an interrupted sweep
resumes where it stopped and nothing finished is computed again.

Dask is an extra (``pip install dea-opt[distributed]``). By default a LocalCluster of
``workers`` processes with one thread each is started; ``scheduler`` connects to a
running cluster instead (its workers must see the same file system), and
``scheduler="synchronous"`` runs the cases one after another in this process.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import os
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path

from .errors import DeaError, InputError, MissingDependencyError
from .scenario import load_scenario, parse_set

__all__ = ["Case", "SweepResult", "make_cases", "case_id", "run_case", "run_sweep", "RESULTS_NAME"]

RESULTS_NAME = "sweep.csv"
_DASK_HINT = "sweeps run on Dask: pip install dea-opt[distributed] (or: pip install 'dask[distributed]')"


def case_id(overrides: dict) -> str:
    """A stable 12-character id of a case: the hash of its overrides (key order does not matter)."""
    text = json.dumps(overrides, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:12]


@dataclass(frozen=True)
class Case:
    """One combination of overrides."""

    overrides: dict

    @property
    def id(self) -> str:
        return case_id(self.overrides)


def make_cases(sets) -> list[Case]:
    """The Cartesian product of ``["law.H=0.3,0.45", "load.scale=1,2"]`` as cases (in order)."""
    parsed = [parse_set(text) for text in sets]
    keys = [key for key, _ in parsed]
    duplicated = {k for k in keys if keys.count(k) > 1}
    if duplicated:
        raise InputError(f"--set names {', '.join(sorted(duplicated))} more than once; give all its values in one "
                         f"--set, separated by commas")
    return [Case(dict(zip(keys, values))) for values in itertools.product(*(v for _, v in parsed))]


# --- one case (runs on a worker) --------------------------------------------------------

def run_case(scenario_path: str, overrides: dict, case_dir: str, method: str | None = None) -> dict:
    """Run one case and write its outputs into ``case_dir``; never raises.

    Returns the case's row: ``case_id``, the overrides, ``status`` (``ok``; ``failed``
    when an answer failed its certificate; ``error`` with ``message`` otherwise), headline
    numbers (for a load path: the largest over the frames), times and ``output_dir``. The
    row is also written to ``case_dir/case.json`` with a count of the case's runs.
    """
    from .run import run_scenario

    start = time.perf_counter()
    row = {"case_id": case_id(overrides), **overrides}
    try:
        scenario = load_scenario(scenario_path, overrides)
        outcome = run_scenario(scenario, output_dir=case_dir, method=method, progress=False)
        row |= {"status": "ok" if outcome.success else "failed", "message": outcome.message, **outcome.headline}
    except DeaError as exc:
        row |= {"status": "error", "message": " ".join(str(exc).split())}
    except Exception as exc:  # noqa: BLE001 - one broken case must not end the sweep
        last = traceback.extract_tb(exc.__traceback__)[-1]
        where = f"{Path(last.filename).name}:{last.lineno}"
        row |= {"status": "error", "message": f"{type(exc).__name__}: {exc} ({where})"}
    row |= {"wall_time": time.perf_counter() - start, "output_dir": str(case_dir),
            "finished": time.strftime("%Y-%m-%dT%H:%M:%S"), "pid": os.getpid()}
    _write_case_record(Path(case_dir), row)
    return row


def _write_case_record(case_dir: Path, row: dict) -> None:
    """``case.json``: the case's row and how many times it has been computed (``runs``).

    ``runs`` above 1 means a case was computed again (its row never reached the results
    table, e.g. the sweep was killed between the two).
    """
    from .io import write_data

    record = case_dir / "case.json"
    runs = 0
    if record.is_file():
        try:
            runs = int(json.loads(record.read_text()).get("runs", 0))
        except (ValueError, OSError):
            runs = 0
    data = {**row, "runs": runs + 1}
    write_data(record, json.dumps(data, indent=2, default=str) + "\n")


# --- the results table ------------------------------------------------------------------

def read_results(path) -> "object":
    """The results table (a DataFrame; empty when the file does not exist yet)."""
    import pandas as pd

    path = Path(path)
    if not path.is_file() or path.stat().st_size == 0:
        return pd.DataFrame()
    try:
        return pd.read_csv(path, dtype={"case_id": str})
    except (pd.errors.ParserError, pd.errors.EmptyDataError) as exc:
        raise InputError(f"the results table {path} cannot be read ({exc}); move it away to start the sweep "
                         f"afresh") from None


def append_row(path, row: dict) -> None:
    """Add ``row`` to the results table, replacing the file atomically."""
    import pandas as pd

    from .io import write_data

    table = read_results(path)
    table = pd.concat([table, pd.DataFrame([row])], ignore_index=True) if len(table) else pd.DataFrame([row])
    write_data(path, table.to_csv(index=False, lineterminator="\n"))


# --- the sweep --------------------------------------------------------------------------

@dataclass(eq=False)
class SweepResult:
    """What a sweep did: the whole results table, and which cases ran now or were skipped."""

    table: object
    results_path: Path
    ran: list = field(default_factory=list)
    skipped: list = field(default_factory=list)

    @property
    def failed(self) -> list:
        """Case ids whose status is not ``ok``."""
        if not len(self.table):
            return []
        return self.table.loc[self.table["status"] != "ok", "case_id"].tolist()


def _client(scheduler, workers):
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise MissingDependencyError(_DASK_HINT) from None
    if scheduler:
        try:
            return Client(scheduler, timeout="10s"), None
        except (OSError, TimeoutError, ValueError) as exc:
            raise InputError(f"cannot reach the Dask scheduler at {scheduler!r}: {exc}") from None
    import logging

    # dashboard_address=":0": the scheduler's HTTP server on a free port, so that two sweeps
    # (or a sweep and a notebook) never fight over port 8787.
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0",
                           silence_logs=logging.ERROR)
    return Client(cluster), cluster


def run_sweep(scenario_path, sets, output_dir=None, *, scheduler: str | None = None, workers: int = 2,
              method: str | None = None, retry_failed: bool = False, progress: bool = False,
              on_row=None) -> SweepResult:
    """Run every case of the ``--set`` product not already in the results table.

    Parameters
    ----------
    scenario_path : str or Path
        The scenario TOML.
    sets : sequence of str
        ``"key.path=v1,v2,..."`` (see :func:`dea_opt.scenario.parse_set`).
    output_dir : str or Path, optional
        Where ``sweep.csv`` and ``cases/`` go; default ``<the scenario's output>/sweep``.
    scheduler : str, optional
        A Dask scheduler address (``tcp://host:8786``), or ``"synchronous"`` to run the
        cases here one by one; default a LocalCluster.
    workers : int
        Worker processes of the LocalCluster (one thread each).
    method : str, optional
        Overrides ``[solve].method``.
    retry_failed : bool
        Run again the cases whose row says ``error`` or ``failed``.
    progress : bool
        Show a progress bar (on a terminal).
    on_row : callable, optional
        Called with each new row as it is written.

    Raises
    ------
    InputError
        Bad ``--set``, or a case whose scenario is invalid (checked before any runs).
    MissingDependencyError
        Dask is not installed.
    """
    from tqdm.auto import tqdm

    if isinstance(workers, bool) or int(workers) != workers or workers < 1:
        raise InputError(f"workers must be a positive integer, got {workers!r}")
    cases = make_cases(sets)
    if not cases:
        raise InputError("a sweep needs at least one --set KEY=VALUES")
    scenario_path = Path(scenario_path).resolve()
    base = load_scenario(scenario_path)
    for case in cases:  # every case must be a valid scenario before anything starts
        load_scenario(scenario_path, case.overrides)
    out = Path(output_dir).resolve() if output_dir is not None else base.output_dir() / "sweep"
    results = out / RESULTS_NAME
    done = _finished(read_results(results), retry_failed)
    todo = [c for c in cases if c.id not in done]
    skipped = [c.id for c in cases if c.id in done]
    bar = tqdm(total=len(cases), initial=len(skipped), desc="sweep", unit="case",
               disable=None if progress else True)
    try:
        rows = _execute(todo, scenario_path, out, method, scheduler, int(workers), results, bar, on_row)
    finally:
        bar.close()
    return SweepResult(table=read_results(results), results_path=results, ran=[r["case_id"] for r in rows],
                       skipped=skipped)


def _finished(table, retry_failed: bool) -> set:
    if not len(table) or "case_id" not in table:
        return set()
    if retry_failed and "status" in table:
        table = table[table["status"] == "ok"]
    return set(table["case_id"].astype(str))


def _execute(todo, scenario_path, out, method, scheduler, workers, results, bar, on_row) -> list:
    rows = []

    def record(row):
        append_row(results, row)
        rows.append(row)
        bar.update()
        if on_row is not None:
            on_row(row)

    if not todo:
        return rows
    args = [(str(scenario_path), case.overrides, str(out / "cases" / case.id), method) for case in todo]
    if scheduler == "synchronous":
        for a in args:
            record(run_case(*a))
        return rows
    client, cluster = _client(scheduler, workers)
    try:
        from dask.distributed import as_completed

        futures = [client.submit(run_case, *a, key=f"dea-case-{case.id}", pure=False) for case, a in zip(todo, args)]
        for future in as_completed(futures):
            record(future.result())
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return rows
