"""The results of a sweep: an append-only journal under a file lock, claims, and sweep.csv.

Files in a sweep's folder::

    sweep.jsonl              the journal: one JSON record per computed case, appended, never rewritten
    sweep.csv                the table a user opens: the journal's last record of each case, one row
                             per case, rewritten atomically from the journal
    .sweep/lock              the journal's lock (``flock``): exclusive to append or rewrite sweep.csv
    .sweep/claims/<id>       a case's claim (``flock``), held by the process computing it
    .sweep/records/<id>.json the case's last record, how many times it was computed, and where its
                             line sits in the journal

Why a journal and not sweep.csv appended under a lock: a retry must *replace* a case's row,
and two sweeps of one folder may set different keys (different columns), neither of which
an appended CSV can do. Appending one line is O(1) whatever the number of rows; sweep.csv
is rewritten from the journal at the end of a sweep and at intervals (its cost is bounded
as a share of the wall time, see ``TablePublisher``), and a later record of a case replaces
the earlier one there.

The locks are dea-opt's one file lock (:mod:`dea_opt.files.locks`): a claim is released by the
kernel when its process dies (``kill -9`` included). Lock files are never deleted: deleting a
lock file while another process waits on it would let a third process lock a new file of the
same name.

Why an append-only file and not SQLite (WAL): the journal is also the record a user reads
(one JSON line per computed case), and a sweep's folder usually lies on a cluster's network
file system, where SQLite's WAL mode does not work (it needs memory shared between the
processes of one machine) and its other modes rely on POSIX locks that such file systems often
get wrong; ``flock`` on NFSv4 holds. A line is written with one ``write`` under the lock, and a
torn last line (a process killed mid-write) is cut before the next one is appended.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import time
from pathlib import Path

from ..errors import InputError
from ..files.atomic import naming
from ..files.locks import hold, mark_holder

__all__ = [
    "JOURNAL_NAME",
    "LOG_NAME",
    "RESULTS_NAME",
    "TablePublisher",
    "append",
    "check_results_csv",
    "claim",
    "holds",
    "line_of",
    "publish_table",
    "read_case_record",
    "read_records",
    "read_results",
    "results_table",
    "seed_from_csv",
    "write_case_record",
]

RESULTS_NAME = "sweep.csv"
JOURNAL_NAME = "sweep.jsonl"
LOG_NAME = "sweep.log"
_STATE = ".sweep"
_JOURNAL_ONLY = ("inputs",)  # nested fields the journal keeps and sweep.csv leaves out
_MOVE_AWAY = "move it away to start the sweep afresh"


def _journal_lock(out: Path, shared: bool = False):
    return hold(Path(out) / _STATE / "lock", shared=shared)


@contextlib.contextmanager
def claim(out, case_id: str, *, wait: bool = False):
    """Claim a case for this process: yields True while held, False if another live process holds it.

    The claim is a lock on ``.sweep/claims/<case id>``; it ends when the block ends or the
    process dies, so a killed sweep never leaves a case claimed.
    """
    with hold(Path(out) / _STATE / "claims" / case_id, wait=wait) as fd:
        if fd is None:
            yield False
            return
        mark_holder(fd)  # for a curious user; the lock is what counts
        yield True


# --- the journal ------------------------------------------------------------------------


def _plain(value):
    """JSON for numpy scalars and paths (the rows come from pandas and numpy)."""
    if hasattr(value, "item"):
        return value.item()
    return str(value)


def line_of(record: dict) -> bytes:
    """The journal line of ``record`` (the same bytes for the same record)."""
    return (json.dumps(record, separators=(",", ":"), default=_plain) + "\n").encode("utf-8")


def _drop_torn_tail(fd: int) -> None:
    """Cut a last line without its newline (a write cut short by kill -9 or a crash)."""
    size = os.fstat(fd).st_size
    if size == 0 or os.pread(fd, 1, size - 1) == b"\n":
        return
    end = size
    while end > 0:
        start = max(0, end - 65536)
        i = os.pread(fd, end - start, start).rfind(b"\n")
        if i >= 0:
            os.ftruncate(fd, start + i + 1)
            return
        end = start
    os.ftruncate(fd, 0)


def append(out, record: dict) -> list:
    """Append ``record`` to the journal under its lock; return ``[offset, length]`` of its line.

    One ``write`` of one line, then ``fsync``: the cost does not grow with the journal.
    """
    line = line_of(record)
    path = Path(out) / JOURNAL_NAME
    with _journal_lock(out), naming(path):
        fd = os.open(path, os.O_RDWR | os.O_APPEND | os.O_CREAT, 0o644)
        try:
            _drop_torn_tail(fd)
            offset = os.fstat(fd).st_size
            view = memoryview(line)
            while view:
                view = view[os.write(fd, view) :]
            os.fsync(fd)
        finally:
            os.close(fd)
    return [offset, len(line)]


def holds(out, pointer, record: dict) -> bool:
    """Whether the journal still holds ``record`` at ``pointer`` (``[offset, length]``)."""
    if not (isinstance(pointer, list) and len(pointer) == 2 and all(isinstance(p, int) for p in pointer)):
        return False
    try:
        with open(Path(out) / JOURNAL_NAME, "rb") as handle:
            handle.seek(pointer[0])
            return handle.read(pointer[1]) == line_of(record)
    except OSError:
        return False


def _parse(data: bytes, path: Path) -> dict:
    """``{case id: last record}`` in order of each case's first record."""
    records: dict = {}
    lines = data.split(b"\n")
    # The last piece has no newline: empty, or a line cut short (kill -9); the next append cuts it.
    for number, raw in enumerate(lines[:-1], start=1):
        if not raw.strip():
            continue
        try:
            record = json.loads(raw.decode("utf-8"))
        except (UnicodeDecodeError, ValueError) as exc:
            raise InputError(
                f"the sweep journal {path} cannot be read: line {number} is not a JSON record "
                f"({exc}); {_MOVE_AWAY} (or delete that line)"
            ) from None
        if not isinstance(record, dict) or not isinstance(record.get("case_id"), str):
            raise InputError(
                f"the sweep journal {path} cannot be read: line {number} is not a case record "
                f"(expected a JSON object with a string case_id); {_MOVE_AWAY}"
            )
        records[record["case_id"]] = record
    return records


def read_records(out) -> dict:
    """Every case's last record in the journal (empty when there is no journal)."""
    path = Path(out) / JOURNAL_NAME
    if not path.is_file():
        return {}
    with _journal_lock(out, shared=True):
        data = path.read_bytes()
    return _parse(data, path)


# --- the table --------------------------------------------------------------------------


def results_table(records: dict):
    """A DataFrame with one row per case (nested fields such as ``inputs`` stay in the journal)."""
    import pandas as pd

    rows = [{k: v for k, v in r.items() if k not in _JOURNAL_ONLY} for r in records.values()]
    table = pd.DataFrame(rows)
    if len(table):
        table["case_id"] = table["case_id"].astype(str)
    return table


def publish_table(out):
    """Rewrite sweep.csv atomically from the journal (under its lock, so writers never interleave)."""
    from ..files import write_data

    out = Path(out)
    path = out / JOURNAL_NAME
    with _journal_lock(out):
        records = _parse(path.read_bytes(), path) if path.is_file() else {}
        table = results_table(records)
        if records:  # no journal yet: no table either (an empty CSV would not even have a header)
            write_data(out / RESULTS_NAME, table.to_csv(index=False, lineterminator="\n"))
    return table


class TablePublisher:
    """Rewrites sweep.csv at most every ``interval`` seconds and 20 times as long as the last
    rewrite took, so rewriting costs at most about 5 % of a sweep's time however many rows."""

    def __init__(self, out, interval: float = 2.0):
        self.out = Path(out)
        self.interval = interval
        self.last = time.monotonic()
        self.cost = 0.0

    def maybe(self) -> None:
        if time.monotonic() - self.last >= max(self.interval, 20 * self.cost):
            self.now()

    def now(self):
        start = time.monotonic()
        table = publish_table(self.out)
        self.last = time.monotonic()
        self.cost = self.last - start
        return table


def check_results_csv(path):
    """Read sweep.csv as a check: a named InputError if it is not a results table.

    Returns the table (a DataFrame; empty when the file is missing or empty).
    """
    import pandas as pd

    path = Path(path)
    if not path.is_file() or not path.read_bytes().strip():
        return pd.DataFrame()
    journal = path.with_name(JOURNAL_NAME)
    hint = f"move it away (dea-opt rewrites it from the journal {journal.name})" if journal.is_file() else _MOVE_AWAY
    try:
        table = pd.read_csv(path, dtype={"case_id": str})
    except (UnicodeDecodeError, pd.errors.ParserError, pd.errors.EmptyDataError, ValueError) as exc:
        reason = "it is not UTF-8 text" if isinstance(exc, UnicodeDecodeError) else str(exc).strip()
        raise InputError(f"the results table {path} cannot be read ({reason}); {hint}") from None
    if "case_id" not in table.columns:
        raise InputError(
            f"the results table {path} has no case_id column (columns: "
            f"{', '.join(map(str, table.columns[:8]))}); it is not a dea-opt sweep table; {hint}"
        )
    if table["case_id"].isna().any():
        row = int(table["case_id"].isna().to_numpy().argmax()) + 2
        raise InputError(f"the results table {path} has a row without case_id (line {row}); {hint}")
    return table


def seed_from_csv(out, table) -> None:
    """Start the journal from a sweep.csv written before journals existed (keeps its rows)."""
    out = Path(out)
    path = out / JOURNAL_NAME
    with _journal_lock(out):
        if path.is_file() and path.stat().st_size:
            return  # another sweep started the journal meanwhile
        lines = []
        for row in table.to_dict("records"):
            lines.append(line_of({k: (None if isinstance(v, float) and math.isnan(v) else v) for k, v in row.items()}))
        from ..files import write_data

        write_data(path, b"".join(lines))


def read_results(path):
    """The results table of a sweep: one row per case (a DataFrame; empty when there is none yet).

    Parameters
    ----------
    path : str or Path
        The sweep's folder, or its ``sweep.csv`` or ``sweep.jsonl``. The journal is read
        when there is one (it is never behind sweep.csv), else sweep.csv.

    Raises
    ------
    InputError
        The journal or sweep.csv is not a dea-opt results table.
    """
    path = Path(path)
    folder = path if path.is_dir() else path.parent
    if (folder / JOURNAL_NAME).is_file():
        return results_table(read_records(folder))
    return check_results_csv(folder / RESULTS_NAME)


# --- one record per case ----------------------------------------------------------------


def _case_record_path(out, case_id: str) -> Path:
    return Path(out) / _STATE / "records" / f"{case_id}.json"


def read_case_record(out, case_id: str) -> dict:
    """``{"record", "runs", "journal"}`` of a case (empty when missing or unreadable)."""
    try:
        data = json.loads(_case_record_path(out, case_id).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return data if isinstance(data, dict) and isinstance(data.get("record"), dict) else {}


def write_case_record(out, case_id: str, record: dict, runs: int, pointer) -> None:
    """Replace ``.sweep/records/<id>.json`` atomically; call it only while holding the case's claim.

    Unlike :func:`dea_opt.files.write_data` the temporary file has a fixed name: the claim makes
    this process its only writer, and a kill -9 leaves at most one temporary file per case,
    overwritten by the next computation, instead of one more random name each time.
    """
    path = _case_record_path(out, case_id)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    data = json.dumps({"record": record, "runs": runs, "journal": pointer}, indent=1, default=_plain) + "\n"
    with naming(path, tmp), open(tmp, "w", encoding="utf-8") as handle:
        handle.write(data)
        handle.flush()
        os.fsync(handle.fileno())
    os.replace(tmp, path)
