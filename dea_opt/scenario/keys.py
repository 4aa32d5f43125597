"""Content keys: what a sweep case's row was computed from.

A row is reused only while everything that shaped its numbers is unchanged: the bytes of the
scenario file, the bytes of every input file the case's scenario reads (meshes, bone meshes,
springs tables, load-path CSVs, files named by generator parameters), the case's overrides,
the ``--method`` given to the sweep and the dea-opt version. The input files are found in the
*loaded* scenario, after the overrides are applied (an override may name another file), and
are keyed by where the scenario names them (``geometry.mesh1``), not by their path, so a
project folder moved elsewhere keeps its results.

It lives with the scenarios (not the sweeps) because a run's report lists the same input files
with their SHA-256 (:mod:`dea_opt.report.sections`), and reports stand below the sweeps.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass
from pathlib import Path

from .._version import __version__

__all__ = ["ContentKey", "FileHashes", "content_key", "input_files", "sha256_file", "stale_reason"]

_CHUNK = 1 << 20


def sha256_file(path) -> str:
    """The SHA-256 of a file's bytes (hex)."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        while block := handle.read(_CHUNK):
            digest.update(block)
    return digest.hexdigest()


class FileHashes:
    """SHA-256 of files, computed once per (path, size, modification time) within one sweep."""

    def __init__(self):
        self._known: dict = {}

    def __call__(self, path: Path) -> str:
        status = os.stat(path)
        stamp = (str(path), status.st_size, status.st_mtime_ns)
        if stamp not in self._known:
            self._known[stamp] = sha256_file(path)
        return self._known[stamp]


def _as_file(text: str, base: Path) -> Path | None:
    if not text or len(text) > 4096 or "\0" in text or "\n" in text:
        return None
    try:
        path = Path(text).expanduser()
        path = path if path.is_absolute() else base / path
        return path.resolve() if path.is_file() else None
    except (OSError, ValueError, RuntimeError):
        return None


def input_files(scenario) -> dict:
    """``{key path: file}`` for every string of the loaded scenario that names an existing file.

    Walking every value, rather than a list of known keys, keeps this right when the
    scenario grows new file keys (a table of labelled meshes, a new load-path format);
    relative strings are tried against the scenario's folder. The output folder is a
    folder, not a file, so it never counts.
    """
    found: dict = {}
    base = scenario.base_dir

    def walk(node, where: str) -> None:
        if isinstance(node, dict):
            for name, value in node.items():
                walk(value, f"{where}.{name}" if where else str(name))
        elif isinstance(node, (list, tuple)):
            for i, value in enumerate(node):
                walk(value, f"{where}[{i}]")
        elif isinstance(node, str):
            path = _as_file(node, base)
            if path is not None:
                found[where] = path

    walk(scenario.model_dump(), "")
    return found


@dataclass(frozen=True)
class ContentKey:
    """Everything a case's row depends on, and its digest (the ``key`` column).

    Attributes
    ----------
    scenario : str
        SHA-256 of the scenario file's bytes.
    inputs : tuple of (str, str, str)
        ``(key path, file name, SHA-256)`` of every input file, sorted by key path.
    overrides : str
        The case's overrides as canonical JSON.
    method : str or None
        The sweep's ``--method`` (None: the scenario's ``[solve].method``).
    version : str
        The dea-opt version.
    outputs : str or None
        The sweep's ``--outputs`` as ``"csv,json"`` (None: the scenario's ``[output].formats``).
    """

    scenario: str
    inputs: tuple
    overrides: str
    method: str | None
    version: str
    outputs: str | None = None

    @property
    def digest(self) -> str:
        """16 hex characters of the SHA-256 of all the fields (``outputs`` only when given, so
        that rows computed before the option existed keep their key)."""
        fields = [self.scenario, [[k, h] for k, _, h in self.inputs], self.overrides, self.method, self.version]
        if self.outputs is not None:
            fields.append(self.outputs)
        return hashlib.sha256(json.dumps(fields, separators=(",", ":")).encode()).hexdigest()[:16]

    def columns(self) -> dict:
        """The fields a row keeps: ``key``, ``scenario_sha256``, ``dea_opt_version``, ``method_option``,
        ``outputs_option`` and ``inputs`` (``{key path: [file name, SHA-256]}``; the journal keeps
        it, sweep.csv does not)."""
        return {
            "key": self.digest,
            "scenario_sha256": self.scenario,
            "dea_opt_version": self.version,
            "method_option": self.method,
            "outputs_option": self.outputs,
            "inputs": {k: [name, h] for k, name, h in self.inputs},
        }


def content_key(
    scenario,
    scenario_sha256: str,
    overrides: dict,
    method: str | None = None,
    hashes: FileHashes | None = None,
    outputs=None,
) -> ContentKey:
    """The :class:`ContentKey` of a loaded ``scenario`` (overrides already applied).

    Parameters
    ----------
    scenario : Scenario
        As returned by ``load_scenario(path, overrides)``.
    scenario_sha256 : str
        SHA-256 of the scenario file's bytes (the text it was parsed from).
    overrides : dict
        The case's ``--set`` values.
    method : str, optional
        The sweep's ``--method``.
    hashes : FileHashes, optional
        A cache shared by the cases of one sweep.
    outputs : sequence of str, optional
        The sweep's ``--outputs``.
    """
    hashes = hashes or FileHashes()
    inputs = tuple(sorted((where, path.name, hashes(path)) for where, path in input_files(scenario).items()))
    return ContentKey(
        scenario=scenario_sha256,
        inputs=inputs,
        overrides=json.dumps(overrides, sort_keys=True, separators=(",", ":")),
        method=method,
        version=__version__,
        outputs=None if outputs is None else ",".join(outputs),
    )


def stale_reason(record: dict, key: ContentKey) -> str | None:
    """Why ``record`` (a row of the journal) was not computed from ``key``; None when it was."""
    old = record.get("key")
    if not isinstance(old, str) or not old:
        return "its row has no content key (it was computed by an older dea-opt)"
    if old == key.digest:
        return None
    reasons = []
    if record.get("dea_opt_version") != key.version:
        reasons.append(f"it was computed by dea-opt {record.get('dea_opt_version')}, this is {key.version}")
    if record.get("scenario_sha256") != key.scenario:
        reasons.append("the scenario changed since its row was computed")
    before = record["inputs"] if isinstance(record.get("inputs"), dict) else {}
    now = {where: (name, h) for where, name, h in key.inputs}
    for where in sorted(set(before) | set(now)):
        then = before.get(where)
        then_hash = then[1] if isinstance(then, (list, tuple)) and len(then) == 2 else None
        if where not in now:
            reasons.append(f"it no longer reads {where}")
        elif then_hash is None:
            reasons.append(f"it now reads {where} ({now[where][0]})")
        elif then_hash != now[where][1]:
            reasons.append(f"the input file {where} ({now[where][0]}) changed since its row was computed")
    if record.get("outputs_option") != key.outputs:
        was, now_outputs = record.get("outputs_option"), key.outputs
        reasons.append(
            f"it wrote the outputs {was or '(the scenario default)'}, now {now_outputs or '(the scenario default)'}"
        )
    if record.get("method_option") != key.method:
        was, now_method = record.get("method_option"), key.method
        reasons.append(
            f"it was solved with --method {was or '(the scenario default)'}, now "
            f"{now_method or '(the scenario default)'}"
        )
    return "; ".join(reasons) or "its content key differs"
