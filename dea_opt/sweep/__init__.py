"""Sweeps: the Cartesian product of ``--set`` values, each case a task on a Dask cluster.

``dea-opt sweep hip.toml --set law.H=0.3,0.45,0.6 --set load_path.scale=1,2`` makes six
cases. Each case has a stable id (a hash of its overrides) and its own output folder
``<out>/cases/<case id>/``. When a case finishes, the worker that computed it appends its
record to the journal ``<out>/sweep.jsonl`` under a file lock; ``<out>/sweep.csv``, one row
per case, is rewritten atomically from the journal at intervals and at the end (see
:mod:`dea_opt.sweep.journal`).

A row counts as finished only while it was computed from the same content: the same
scenario text, the same bytes of every input file the case reads, the same overrides and
``--method``, the same dea-opt version (its ``key`` column, :mod:`dea_opt.scenario.keys`).
A rerun skips the finished cases and recomputes the others, saying why; the new row
replaces the old one. ``retry_failed`` recomputes the rows of a case without a certified answer
or with an error (:data:`~dea_opt.sweep.cases.RETRIED`). A row's ``status`` is a
:class:`~dea_opt.status.RunStatus`: ``ok``, ``outside_validity``, ``certificate_failed``,
``load_not_supported``, ``pose_error`` or ``error`` (:data:`~dea_opt.sweep.cases.STATUSES`).

Several sweeps may work on one folder at once (the same sweep twice, or sweeps with other
cases): a process claims a case before computing it (a lock that dies with the process),
so no case is computed twice at once and no row is lost or doubled; a case another live
process is computing is done last, after waiting for it, and taken from its record.

Dask is an extra (``pip install dea-opt[distributed]``). By default a LocalCluster of
``workers`` processes with one thread each is started; ``scheduler`` connects to a
running cluster instead (its workers must see the same file system), and
``scheduler="synchronous"`` runs the cases one after another in this process.
"""

from __future__ import annotations

import contextlib
import math
import secrets
import sys
from collections import deque
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from ..errors import InputError, MissingDependencyError
from ..run.publish import RunInterrupted
from ..scenario import check_method_name, load_scenario
from ..scenario.keys import FileHashes, content_key, stale_reason
from ..status import RunStatus
from . import journal
from .cases import (
    RETRIED,
    Case,
    CaseTask,
    case_id,
    make_cases,
    parse_case,
    read_text,
    run_case,
    swept_keys,
    work,
)
from .journal import JOURNAL_NAME, LOG_NAME, RESULTS_NAME, read_results
from .logs import routed_to_log

__all__ = [
    "JOURNAL_NAME",
    "LOG_NAME",
    "RESULTS_NAME",
    "Case",
    "SweepResult",
    "case_id",
    "format_row",
    "make_cases",
    "read_results",
    "run_case",
    "run_sweep",
]

_DASK_HINT = "sweeps run on Dask: pip install dea-opt[distributed] (or: pip install 'dask[distributed]')"


@dataclass(eq=False)
class SweepResult:
    """What a sweep did.

    Attributes
    ----------
    table : DataFrame
        The whole results table (every case of the folder, one row each).
    results_path : Path
        ``sweep.csv``.
    cases : list of str
        This sweep's case ids, in order.
    ran : list of str
        Cases computed by this call.
    skipped : list of str
        Cases already finished (same content) when the sweep started.
    adopted : list of str
        Cases another process finished while this sweep ran (not computed here).
    recomputed : dict {case id: reason}
        Cases whose row was stale (or failed, with ``retry_failed``), and why.
    report_path : Path or None
        The sweep's ``report.html`` (:mod:`dea_opt.report.sweep`), once written.
    """

    table: Any
    results_path: Path
    cases: list = field(default_factory=list)
    ran: list = field(default_factory=list)
    skipped: list = field(default_factory=list)
    adopted: list = field(default_factory=list)
    recomputed: dict = field(default_factory=dict)
    report_path: Path | None = None

    def _with_status(self, statuses) -> list:
        if self.table is None or not len(self.table) or "status" not in self.table:
            return []
        status = dict(zip(self.table["case_id"], self.table["status"]))
        return [c for c in self.cases if status.get(c, "ok") in statuses]

    @property
    def failed(self) -> list:
        """This sweep's case ids without a certified answer or with an error (:data:`RETRIED`)."""
        return self._with_status(RETRIED)

    @property
    def outside_validity(self) -> list:
        """This sweep's case ids whose status is ``outside_validity``."""
        return self._with_status((RunStatus.OUTSIDE_VALIDITY,))

    @property
    def exit_code(self) -> int:
        """1 when a case has no certified answer or an error; else 3 when a case is ``outside_validity``
        and its scenario does not allow it (``[solve] allow_outside_validity``); else 0."""
        if self.failed:
            return 1
        table = self.table
        codes = dict(zip(table["case_id"], table["exit_code"])) if "exit_code" in table else {}
        # A row without an exit code (an older dea-opt's) counts as not allowed.
        return 3 if any(codes.get(c) != 0 for c in self.outside_validity) else 0


def format_row(row: dict, overrides: dict, note: str = "") -> str:
    """One line for a finished case: id, overrides, status, peak pressure, wall time."""
    values = " ".join(f"{k}={v}" for k, v in overrides.items())
    line = f"case {row.get('case_id')}  {values}  {row.get('status')}"
    peak = row.get("peak_pressure_MPa")
    if isinstance(peak, (int, float)) and not math.isnan(peak):
        line += f"  peak {peak:.4g} MPa"
    wall = row.get("wall_time_s")
    if isinstance(wall, (int, float)):
        line += f"  {wall:.1f} s"
    if row.get("status") == RunStatus.ERROR:
        message = " ".join(str(row.get("message", "")).split())
        line += f"  ({message[:100]}{'...' if len(message) > 100 else ''})"
    return line + (f"  {note}" if note else "")


def _require_dask() -> None:
    try:
        import dask.distributed  # noqa: F401
    except ImportError:
        raise MissingDependencyError(_DASK_HINT) from None


def _client(scheduler, workers):
    _require_dask()
    from dask.distributed import Client, LocalCluster

    if scheduler:
        try:
            return Client(scheduler, timeout="10s"), None
        except (OSError, TimeoutError, ValueError) as exc:
            raise InputError(f"cannot reach the Dask scheduler at {scheduler!r}: {exc}") from None
    import logging

    import dask

    # dashboard_address=":0": the scheduler's HTTP server on a free port, so that two sweeps
    # (or a sweep and a notebook) never fight over port 8787. MALLOC_TRIM_THRESHOLD_ unset:
    # Dask's default (64 kB) fixes glibc's thresholds, so that every array of a few hundred
    # kB is mapped and unmapped afresh; a case of the knee took 1.6 times as long. The workers'
    # statistical profiler off, and the periodic checks of every Dask process (the event loop's
    # tick, the memory and system monitors) ten to fifty times less often: with every core
    # running a case each wake-up takes a core from one, and on two workers of a 2-core
    # machine the knee's cases took 5 to 10 % longer with the profiler on and 4 to 5 % longer
    # with Dask's intervals (no one reads a sweep's profile or its dashboard).
    with dask.config.set(
        {
            "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_": None,
            "distributed.worker.profile.enabled": False,
            "distributed.admin.tick.interval": "1s",
            "distributed.admin.system-monitor.interval": "5s",
            "distributed.worker.memory.monitor-interval": "1s",
        }
    ):
        cluster = LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0", silence_logs=logging.ERROR
        )
    return Client(cluster), cluster


def _check(workers, method) -> str | None:
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise InputError(f"workers must be a positive integer, got {workers!r}")
    if method is None:
        return None
    return check_method_name(method.strip().lower() if isinstance(method, str) else method, "method (--method)")


def check_outputs(outputs) -> tuple | None:
    """``--outputs`` as a tuple of ``[output].formats`` names (None: the scenario's own)."""
    from ..scenario import FORMATS

    if outputs is None:
        return None
    if isinstance(outputs, str):
        outputs = [] if outputs.strip().lower() == "none" else [p.strip().lower() for p in outputs.split(",")]
    if not isinstance(outputs, (list, tuple)) or not all(isinstance(p, str) for p in outputs):
        raise InputError(f"outputs must be a list of {', '.join(FORMATS)} (or 'none'), got {outputs!r}")
    unknown = [p for p in outputs if p not in FORMATS]
    if unknown:
        raise InputError(
            f"outputs (--outputs) must be among {', '.join(FORMATS)} (or 'none'), got {', '.join(map(repr, unknown))}"
        )
    return tuple(dict.fromkeys(outputs))


def run_sweep(
    scenario_path,
    sets,
    output_dir=None,
    *,
    scheduler: str | None = None,
    workers: int = 2,
    method: str | None = None,
    retry_failed: bool = False,
    progress: bool = False,
    on_row=None,
    on_report=None,
    log: bool = True,
    outputs=None,
    report: bool = True,
) -> SweepResult:
    """Run every case of the ``--set`` product whose row is missing or stale.

    Parameters
    ----------
    scenario_path : str or Path
        The scenario TOML.
    sets : sequence of str
        ``"key.path=v1,v2,..."`` (see :func:`dea_opt.scenario.parse_set`).
    output_dir : str or Path, optional
        Where ``sweep.csv``, ``sweep.jsonl``, ``sweep.log`` and ``cases/`` go; default
        ``<the scenario's output>/sweep``.
    scheduler : str, optional
        A Dask scheduler address (``tcp://host:8786``), or ``"synchronous"`` to run the
        cases here one by one; default a LocalCluster.
    workers : int
        Worker processes of the LocalCluster (one thread each).
    method : str, optional
        Overrides ``[solve].method`` (part of each case's content key).
    outputs : sequence of str or str, optional
        The files each case writes into its folder, any of csv, json, vtk, png (a list, or
        ``"csv,json"``; ``"none"`` or an empty list: only the row and the case's manifest);
        default the scenario's ``[output].formats``. Part of each case's content key.
    retry_failed : bool
        Recompute the cases whose row says ``error`` or ``failed``; the new row replaces it.
    progress : bool
        A progress bar on stdout (on a terminal).
    on_row : callable, optional
        Called with each finished case's row (this sweep's or another process's) as it arrives.
    on_report : callable, optional
        Called with one line of text per event: why a case is recomputed (before the cases
        start) and each finished case (:func:`format_row`).
    log : bool
        Route Dask's logs, worker tracebacks and Python warnings to ``<output>/sweep.log``
        while the sweep runs (see :func:`dea_opt.sweep.logs.routed_to_log`).
    report : bool
        Write ``report.html`` into the sweep's folder at the end: every case of the folder, a
        sortable table and a plot of any output against any swept value (:mod:`dea_opt.report.sweep`).

    Raises
    ------
    InputError
        Bad ``--set``, a case whose scenario is invalid, or a ``sweep.csv`` / ``sweep.jsonl``
        that is not a dea-opt results table (all checked before any case runs).
    MissingDependencyError
        Dask is not installed.
    """
    from ..progress import bar as progress_bar

    method = _check(workers, method)
    outputs = check_outputs(outputs)
    cases = make_cases(sets)
    swept = swept_keys(sets)
    if not cases:
        raise InputError("a sweep needs at least one --set KEY=VALUES")
    scenario_path = Path(scenario_path).expanduser().resolve()
    base = load_scenario(scenario_path)
    text, sha = read_text(scenario_path)  # from here on every case is parsed from these very bytes
    hashes = FileHashes()
    keys = {}
    for case in cases:  # every case must be a valid scenario before anything starts
        keys[case.id] = content_key(
            parse_case(scenario_path, text, case.overrides, swept), sha, case.overrides, method, hashes, outputs
        )
    out = Path(output_dir).expanduser().resolve() if output_dir is not None else base.output_dir() / "sweep"
    if out.exists() and not out.is_dir():
        raise InputError(f"the sweep's output folder {out} is a file")
    legacy = journal.check_results_csv(out / RESULTS_NAME)
    records = journal.read_records(out)
    if not records and len(legacy):
        journal.seed_from_csv(out, legacy)
        records = journal.read_records(out)

    skipped, recomputed, todo = [], {}, []
    for case in cases:
        record = records.get(case.id)
        reason = None if record is None else stale_reason(record, keys[case.id])
        if record is not None and reason is None and retry_failed and record.get("status") in RETRIED:
            reason = f"its row says {record.get('status')}; retrying"
        if record is not None and reason is None:
            skipped.append(case.id)
            continue
        todo.append(case)
        if reason is not None:
            recomputed[case.id] = reason
    result = SweepResult(
        table=None, results_path=out / RESULTS_NAME, cases=[c.id for c in cases], skipped=skipped, recomputed=recomputed
    )
    if todo and scheduler != "synchronous":
        _require_dask()
    tasks = [
        CaseTask(
            str(out),
            str(scenario_path),
            text,
            sha,
            case.id,
            case.overrides,
            method,
            retry_failed,
            outputs=outputs,
            swept=swept,
        )
        for case in todo
    ]
    with routed_to_log(out / LOG_NAME) if log else contextlib.nullcontext() as logfile:
        for case_key, reason in recomputed.items():
            line = f"case {case_key}: {reason}; recomputing"
            if logfile is not None:
                logfile.write(line + "\n")
            if on_report is not None:
                on_report(line)
        bar = progress_bar(len(cases), "sweep", "case", progress, file=sys.stdout, initial=len(skipped))
        publisher = journal.TablePublisher(out)
        overrides = {c.id: c.overrides for c in cases}

        def arrived(outcome: dict) -> None:
            row = outcome["row"]
            (result.ran if outcome["outcome"] == "ran" else result.adopted).append(row["case_id"])
            bar.update()
            if on_row is not None:
                on_row(row)
            if on_report is not None:
                note = "(finished by another sweep)" if outcome["outcome"] == "adopted" else ""
                on_report(format_row(row, overrides[row["case_id"]], note))
            publisher.maybe()

        try:
            _execute(tasks, scheduler, workers, arrived)
        except KeyboardInterrupt:
            stopped = True
        else:
            stopped = False
        finally:
            bar.close()
            result.table = publisher.now()
    if stopped:
        raise RunInterrupted(_interrupted_report(out, cases)) from None
    if report and result.table is not None and len(result.table):
        from ..report import write_sweep_report

        result.report_path = write_sweep_report(out, result.table, swept, scenario_path, sets)
    return result


def _interrupted_report(out: Path, cases) -> str:
    """What a sweep stopped by Ctrl-C leaves: the cases recorded, and how to compute the others."""
    recorded = journal.read_records(out)
    finished = sum(case.id in recorded for case in cases)
    rest = len(cases) - finished
    then = f"; rerun the same command to compute the other {rest} (the finished ones are skipped)" if rest else ""
    return (
        f"{finished} of the sweep's {len(cases)} cases are finished, their rows in {out / JOURNAL_NAME} and "
        f"{out / RESULTS_NAME}{then}"
    )


def _execute(tasks: list, scheduler, workers: int, arrived) -> None:
    """Run the tasks; a case another process holds is handed back and done last, waiting for it."""
    if not tasks:
        return
    if scheduler == "synchronous":
        queue = deque(tasks)
        while queue:
            task = queue.popleft()
            outcome = work(task)
            if outcome["outcome"] == "busy":
                queue.append(replace(task, wait=True))
            else:
                arrived(outcome)
        return
    client, cluster = _client(scheduler, workers)
    try:
        from dask.distributed import as_completed

        def submit(task):
            # A fresh key per submission: a resubmitted case must not be taken for the finished one.
            return client.submit(work, task, key=f"dea-case-{task.case_id}-{secrets.token_hex(4)}", pure=False)

        futures = [submit(task) for task in tasks]
        pending = {future.key: task for future, task in zip(futures, tasks)}
        running = as_completed(futures)
        for future in running:
            task = pending.pop(future.key)
            outcome = future.result()
            if outcome["outcome"] == "busy":
                task = replace(task, wait=True)
                again = submit(task)
                pending[again.key] = task
                running.add(again)
            else:
                arrived(outcome)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
