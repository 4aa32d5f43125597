"""Cases of a sweep and the work of one case: claim it, check it is not done, compute, record."""

from __future__ import annotations

import hashlib
import itertools
import json
import os
import time
import traceback
from dataclasses import dataclass
from pathlib import Path

from ..errors import DeaError, InputError, ScenarioError
from ..mesh import cache as spring_cache
from ..scenario import check_kinematics_method, parse_scenario, parse_set
from ..scenario.keys import ContentKey, FileHashes, content_key
from ..status import RunStatus
from . import journal

__all__ = [
    "RETRIED",
    "STATUSES",
    "Case",
    "CaseTask",
    "case_id",
    "case_name",
    "make_cases",
    "parse_case",
    "read_text",
    "run_case",
    "swept_keys",
    "value_columns",
    "work",
    "work_claimed",
]

#: The input files' hashes, computed once per (path, size, modification time) in this process:
#: a worker hashes the meshes of its first case only.
_HASHES = FileHashes()

#: Where a sweep's workers share their spring casts (:mod:`dea_opt.mesh.cache`).
SPRING_CACHE = ".sweep/springs"

#: Every status a case's row can have: a run's (:class:`~dea_opt.status.RunStatus`: ``ok``,
#: ``outside_validity`` (exit 3 of ``dea-opt run``), ``certificate_failed``, ``load_not_supported``
#: or ``pose_error`` when an answer, or a load path's frame, has no certified answer) or ``error``
#: (the case could not run: its ``message`` says why).
STATUSES = tuple(RunStatus)
#: The statuses ``--retry-failed`` recomputes: an answer without a certificate, or an error.
RETRIED = tuple(status for status in RunStatus if status.failed)


def case_id(overrides: dict) -> str:
    """A stable 12-character id of a case: the hash of its overrides (key order does not matter).

    The id names the case's row and folder; whether its row is still valid is decided by its
    content key (:mod:`dea_opt.scenario.keys`), so an edited scenario replaces the row.
    """
    text = json.dumps(overrides, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:12]


def case_name(overrides: dict, swept=()) -> str:
    """A case named by its swept values as ``--set`` writes them: ``law.H=8, load.scale=-1`` (every
    override when none of them is swept)."""
    keys = [k for k in overrides if k in swept] or list(overrides)
    return ", ".join(f"{k}={_value_text(overrides[k])}" for k in keys)


def _value_text(value) -> str:
    if isinstance(value, (list, tuple)):
        return "[" + ",".join(_value_text(v) for v in value) + "]"
    return f"{value:g}" if isinstance(value, float) else str(value)


def value_columns(overrides: dict) -> dict:
    """A case's overrides as columns of its row, each key ending with its unit when it has one
    (``law.H`` -> ``law.H_MPa``, ``load.scale`` stays: :func:`dea_opt.scenario.docs.key_unit`)."""
    from ..scenario.docs import key_unit
    from ..units import SUFFIXES, with_unit

    out = {}
    for key, value in overrides.items():
        unit = key_unit(key)
        out[with_unit(key, unit) if unit in SUFFIXES else key] = value
    return out


@dataclass(frozen=True)
class Case:
    """One combination of overrides."""

    overrides: dict

    @property
    def id(self) -> str:
        return case_id(self.overrides)


def swept_keys(sets) -> tuple:
    """The keys of ``["law.H=0.3,0.45", "load.scale=1"]`` given several values (``("law.H",)``)."""
    return tuple(key for key, values in map(parse_set, sets) if len(values) > 1)


def make_cases(sets) -> list[Case]:
    """The Cartesian product of ``["law.H=0.3,0.45", "load.scale=1,2"]`` as cases (in order)."""
    parsed = [parse_set(text) for text in sets]
    keys = [key for key, _ in parsed]
    duplicated = {k for k in keys if keys.count(k) > 1}
    if duplicated:
        raise InputError(
            f"--set names {', '.join(sorted(duplicated))} more than once; give all its values in one "
            f"--set, separated by commas"
        )
    return [Case(dict(zip(keys, values))) for values in itertools.product(*(v for _, v in parsed))]


def read_text(path: Path) -> tuple[str, str]:
    """``(text, SHA-256 of the bytes)`` of a scenario file."""
    data = Path(path).read_bytes()
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ScenarioError(f"scenario file {path} is not UTF-8 text (byte {exc.start})") from None
    return text, hashlib.sha256(data).hexdigest()


def parse_case(scenario_path: Path, text: str, overrides: dict, swept=()):
    """The scenario of a case, parsed from ``text`` (the file's contents) as ``load_scenario`` would;
    ``swept``: the keys the sweep gives several values (:func:`swept_keys`; see
    :func:`dea_opt.scenario.parse_scenario`)."""
    return parse_scenario(
        text, name=str(scenario_path), base_dir=scenario_path.resolve().parent, overrides=overrides, swept=swept
    )


def with_outputs(scenario, outputs):
    """``scenario`` writing ``outputs`` (a list of ``[output].formats``; None: its own)."""
    if outputs is None:
        return scenario
    return scenario.model_copy(update={"output": scenario.output.model_copy(update={"formats": list(outputs)})})


def run_case(
    scenario_path,
    overrides: dict,
    case_dir,
    method: str | None = None,
    *,
    text: str | None = None,
    key: ContentKey | None = None,
    outputs=None,
    swept=(),
) -> dict:
    """Run one case and write its outputs into ``case_dir``; never raises.

    Parameters
    ----------
    scenario_path : str or Path
    overrides : dict
    case_dir : str or Path
    method : str, optional
        Overrides ``[solve].method``.
    text : str, optional
        The scenario's text (default: read from ``scenario_path``); the sweep passes the
        text it hashed, so the row is computed from exactly what its key says.
    key : ContentKey, optional
        The case's content key (default: computed here).
    outputs : sequence of str, optional
        The files the case writes (``[output].formats``: csv, json, vtk, png); default the
        scenario's own.
    swept : sequence of str
        The keys the sweep gives several values (:func:`swept_keys`).

    Returns
    -------
    dict
        The case's row: ``case`` (its swept values, :func:`case_name`), ``case_id``, the
        overrides (:func:`value_columns`: each key with its unit, ``law.H_MPa``), ``status`` (one
        of :data:`STATUSES`:
        ``ok``; ``outside_validity`` when certified but outside its model's validity;
        ``certificate_failed``, ``load_not_supported`` or ``pose_error`` when an answer, or a
        frame, has no certified answer; ``error`` with ``message`` when the case could not
        run), ``exit_code`` (that of ``dea-opt run``), headline
        numbers (for a load path: the largest over the frames), ``warnings`` (the run's
        validity warnings, joined by `` | ``), ``wall_time_s``,
        ``output_dir`` (empty when the case left no folder: refused before it wrote anything),
        ``finished``, ``pid`` and the content key's fields.
    """
    from ..run import run_scenario

    start = time.perf_counter()
    path = Path(scenario_path)
    row = {"case": case_name(overrides, swept), "case_id": case_id(overrides), **value_columns(overrides)}
    columns = {}
    try:
        if text is None:
            text, sha = read_text(path)
        else:
            sha = hashlib.sha256(text.encode("utf-8")).hexdigest()
        scenario = parse_case(path, text, overrides, swept)
        columns = (key or content_key(scenario, sha, overrides, method, _HASHES, outputs)).columns()
        check_kinematics_method(scenario, method, "--method" if method else None)
        scenario = with_outputs(scenario, outputs)
        # The case folder is the sweep's own (an older dea-opt may have left outputs there without a manifest).
        # Pictures drawn here: the sweep's workers keep every core busy with cases.
        outcome = run_scenario(
            scenario, output_dir=case_dir, method=method, progress=False, force=True, background_pictures=False
        )
        row |= {
            "status": str(outcome.status),
            "exit_code": outcome.exit_code,
            "message": outcome.message,
            **outcome.headline,
            "warnings": " | ".join(" ".join(w.split()) for w in outcome.warnings),
        }
    except DeaError as exc:
        row |= {"status": str(RunStatus.ERROR), "message": " ".join(str(exc).split())}
    except Exception as exc:  # noqa: BLE001 - one broken case must not end the sweep
        last = traceback.extract_tb(exc.__traceback__)[-1]
        where = f"{Path(last.filename).name}:{last.lineno}"
        row |= {"status": str(RunStatus.ERROR), "message": f"{type(exc).__name__}: {exc} ({where})"}
    row |= {
        "wall_time_s": time.perf_counter() - start,
        # a case refused before it wrote anything leaves no folder (dea_opt.run.folderlock): none named
        "output_dir": str(case_dir) if Path(case_dir).is_dir() else "",
        "finished": time.strftime("%Y-%m-%dT%H:%M:%S"),
        "pid": os.getpid(),
        **columns,
    }
    return row


@dataclass(frozen=True)
class CaseTask:
    """One case as a worker receives it (picklable).

    ``wait`` says whether to wait for a claim another process holds (True) or to hand
    the case back as ``busy`` (False) so the sweep does other cases first.
    """

    out: str
    scenario_path: str
    scenario_text: str
    scenario_sha256: str
    case_id: str
    overrides: dict
    method: str | None = None
    retry_failed: bool = False
    wait: bool = False
    outputs: tuple | None = None
    swept: tuple = ()


def work(task: CaseTask) -> dict:
    """Do one case of a sweep, at most once across every process working on its folder.

    Returns ``{"outcome": "busy"}`` when another live process holds the case's claim (and
    ``task.wait`` is False), else :func:`work_claimed`'s answer.
    """
    with journal.claim(task.out, task.case_id, wait=task.wait) as held:
        if not held:
            return {"outcome": "busy", "case_id": task.case_id}
        with spring_cache.active(Path(task.out) / SPRING_CACHE):
            return work_claimed(task)


def _accepted(record: dict, retry_failed: bool) -> bool:
    status = record.get("status")
    return status in STATUSES and not (retry_failed and status in RETRIED)


def work_claimed(task: CaseTask) -> dict:
    """The work of :func:`work` once the claim is held.

    If the case's last record was computed from the same content (another process finished
    it while this one waited), that record is the answer (``"adopted"``); otherwise the case
    is computed, its record appended to the journal and then written to
    ``.sweep/records/<id>.json`` with the count of its computations (``"ran"``).
    """
    out = Path(task.out)
    path = Path(task.scenario_path)
    try:
        key = content_key(
            parse_case(path, task.scenario_text, task.overrides, task.swept),
            task.scenario_sha256,
            task.overrides,
            task.method,
            _HASHES,
            task.outputs,
        )
    except DeaError:
        key = None  # run_case records the error
    previous = journal.read_case_record(out, task.case_id)
    record = previous.get("record") or {}
    if key is not None and record.get("key") == key.digest and _accepted(record, task.retry_failed):
        if not journal.holds(out, previous.get("journal"), record):  # the journal was moved away: restore it
            pointer = journal.append(out, record)
            journal.write_case_record(out, task.case_id, record, int(previous.get("runs", 1)), pointer)
        return {"outcome": "adopted", "row": record}
    row = run_case(
        path,
        task.overrides,
        out / "cases" / task.case_id,
        task.method,
        text=task.scenario_text,
        key=key,
        outputs=task.outputs,
        swept=task.swept,
    )
    pointer = journal.append(out, row)
    record = json.loads(journal.line_of(row))
    journal.write_case_record(out, task.case_id, record, int(previous.get("runs", 0)) + 1, pointer)
    return {"outcome": "ran", "row": record}
