"""Where a run's files go: one output folder, one consistent set of files, a manifest written last.

A run (``dea-opt run``, ``demo``, ``compare`` and each case of a sweep) writes into one output
folder through :func:`output_run`:

1. The folder must be new, empty, or hold an earlier dea-opt run (its ``manifest.json``, or
   the ``INCOMPLETE.json`` of an interrupted one); any other folder is an
   :class:`~dea_opt.errors.OutputFolderError` naming it, unless ``force`` (so no file of the
   user's is ever overwritten by surprise).
2. A lock (``.dea-opt.lock``, :mod:`dea_opt.run.folderlock`) keeps two runs out of one folder;
   temporary files left by a process killed earlier (``.name.<hex>.tmp.*``) are removed. A run
   that publishes nothing removes the lock file and the folders it made, if nothing else is in them.
3. Every output is written atomically but *staged* (:func:`dea_opt.files.atomic.staged`): complete
   temporary files wait beside their targets, and the folder still holds the previous run.
4. :meth:`OutputRun.publish` hashes the staged files, writes ``INCOMPLETE.json``, removes the
   old ``manifest.json`` and the old run's files, renames the new files into place, writes the
   new ``manifest.json`` (run id, dea-opt version, scenario hash, every file with its size and
   SHA-256) **last**, and removes ``INCOMPLETE.json``. Ctrl-C waits for the end of this step.

So whatever stops a run (Ctrl-C, kill -9, a full disk), the folder holds either a manifest
whose files all exist and agree with it, or no manifest (and ``INCOMPLETE.json`` saying why).
:func:`check_outputs` verifies a folder against its manifest.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import secrets
import signal
import threading
import time
from pathlib import Path

from .._version import __version__
from ..errors import InputError, OutputFolderError
from ..files.atomic import TEMPORARY_NAME, staged, write_data
from .folderlock import LOCK_NAME, folder_lock, remove_made

__all__ = [
    "INCOMPLETE_NAME",
    "LOCK_NAME",
    "MANIFEST_NAME",
    "OutputRun",
    "RunInterrupted",
    "check_output_folder",
    "check_outputs",
    "forget_published",
    "interrupted_report",
    "output_folder_path",
    "output_run",
    "published_report",
    "read_manifest",
]

MANIFEST_NAME = "manifest.json"
INCOMPLETE_NAME = "INCOMPLETE.json"
_MANIFEST_FORMAT = "dea-opt run manifest"
_INCOMPLETE_FORMAT = "dea-opt incomplete run"
#: Sub-folders another dea-opt command made (a sweep's or a comparison's), recognised by these names.
_OWN_SUBFOLDER_MARKS = (MANIFEST_NAME, INCOMPLETE_NAME, LOCK_NAME, "sweep.jsonl", ".sweep")


class RunInterrupted(KeyboardInterrupt):
    """Ctrl-C during a run; ``report`` says truthfully what the output folder holds."""

    def __init__(self, report: str):
        super().__init__(report)
        self.report = report


def output_folder_path(folder, argument: str = "output folder") -> Path:
    """``folder`` as an absolute :class:`Path`, or a named InputError (NUL bytes, not a path)."""
    if isinstance(folder, bytes):
        folder = os.fsdecode(folder)
    if not isinstance(folder, (str, os.PathLike)):
        raise InputError(f"{argument} must be a path (str or os.PathLike), got {type(folder).__name__}")
    text = os.fspath(folder)
    if "\0" in text:
        raise InputError(f"{argument} contains a NUL byte, which no file system allows: {text!r}")
    if not text.strip():
        raise InputError(f"{argument} must name a folder, got {text!r}")
    return Path(text).expanduser().absolute()


def _read_json(path: Path) -> dict | None:
    try:
        with open(path, encoding="utf-8") as handle:
            data = json.load(handle)
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def read_manifest(folder) -> dict | None:
    """The ``manifest.json`` of a dea-opt run in ``folder``, or None (absent, unreadable or not dea-opt's)."""
    data = _read_json(Path(folder) / MANIFEST_NAME)
    if data is None or data.get("format") != _MANIFEST_FORMAT or not isinstance(data.get("files"), dict):
        return None
    return data


def _marker(folder: Path) -> dict | None:
    data = _read_json(folder / INCOMPLETE_NAME)
    return data if data is not None and data.get("format") == _INCOMPLETE_FORMAT else None


def _sha256(path: Path) -> str:
    with open(path, "rb") as handle:
        return hashlib.file_digest(handle, "sha256").hexdigest()


def check_outputs(folder) -> list[str]:
    """What is wrong with ``folder`` against its manifest: ``[]`` when every listed file exists
    with the listed size and SHA-256; ``["no manifest..."]`` when there is none."""
    folder = Path(folder)
    manifest = read_manifest(folder)
    if manifest is None:
        return [f"{folder} has no dea-opt {MANIFEST_NAME}"]
    problems = []
    for name, entry in manifest["files"].items():
        path = folder / name
        if not path.is_file():
            problems.append(f"{name} is missing")
        elif path.stat().st_size != entry.get("size_bytes"):
            problems.append(f"{name} has {path.stat().st_size} bytes, the manifest says {entry.get('size_bytes')}")
        elif _sha256(path) != entry.get("sha256"):
            problems.append(f"{name} differs from the manifest's SHA-256")
    return problems


# --- which folders a run may write into ---------------------------------------------------


def _other_run(entry: os.DirEntry) -> bool:
    """A sub-folder another dea-opt command made (a sweep's or a comparison's)."""
    return entry.is_dir(follow_symlinks=False) and any(
        (Path(entry.path) / mark).exists() for mark in _OWN_SUBFOLDER_MARKS
    )


def _internal(entry: os.DirEntry, depth: int = 0) -> bool:
    """dea-opt's own bookkeeping: the lock, temporary files, a sweep's or comparison's folder,
    and a sub-folder holding nothing else (``series_frames/`` of a run killed before it
    published: only its staged frames, or nothing)."""
    if entry.name == LOCK_NAME or (TEMPORARY_NAME.match(entry.name) and entry.is_file(follow_symlinks=False)):
        return True
    if _other_run(entry):
        return True
    if entry.is_dir(follow_symlinks=False) and depth < 2:
        try:
            with os.scandir(entry.path) as inner:
                return all(_internal(e, depth + 1) for e in inner)
        except OSError:
            return False
    return False


def check_output_folder(folder, force: bool = False) -> Path:
    """The absolute output folder, if a run may write into it; else :class:`OutputFolderError`.

    A run may write into a folder that does not exist yet, is empty (but for dea-opt's own
    lock and temporary files), or holds an earlier dea-opt run (``manifest.json``, or
    ``INCOMPLETE.json`` of an interrupted one). ``force`` allows any folder: files with the
    names of the outputs are then replaced, other files are left alone.
    """
    path = output_folder_path(folder)
    if path.exists() and not path.is_dir():
        raise OutputFolderError(f"the output folder {path} is a file, not a folder: choose another folder (-o)")
    if force or not path.exists() or read_manifest(path) is not None or _marker(path) is not None:
        return path
    try:
        with os.scandir(path) as entries:
            foreign = sorted(e.name for e in entries if not _internal(e))
    except OSError as exc:
        raise OutputFolderError(f"the output folder {path} cannot be read ({exc.strerror or exc})") from None
    if foreign:
        shown = ", ".join(foreign[:5]) + (f" and {len(foreign) - 5} more" if len(foreign) > 5 else "")
        raise OutputFolderError(
            f"the output folder {path} holds files dea-opt did not write ({shown}) and no dea-opt {MANIFEST_NAME}: "
            f"dea-opt writes only into a new or empty folder, or one holding an earlier dea-opt run, so that "
            f"no file of yours is overwritten; choose another folder (-o), or pass --force to write into it "
            f"anyway (files named like the outputs are then replaced)"
        )
    return path


def _remove_stale(folder: Path) -> list[Path]:
    """Remove the temporary files a killed run left in ``folder`` and its sub-folders (one level).

    A sub-folder that is another run's (a comparison's, a sweep's) is left alone: that run may
    be writing there now, and cleans it itself.
    """
    removed = []
    folders = [folder]
    with contextlib.suppress(OSError), os.scandir(folder) as entries:
        folders += [Path(e.path) for e in entries if e.is_dir(follow_symlinks=False) and not _other_run(e)]
    for where in folders:
        with contextlib.suppress(OSError), os.scandir(where) as entries:
            for entry in entries:
                if TEMPORARY_NAME.match(entry.name) and entry.is_file(follow_symlinks=False):
                    with contextlib.suppress(OSError):
                        os.unlink(entry.path)
                        removed.append(Path(entry.path))
    return removed


def _fsync_dir(path: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(path, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


@contextlib.contextmanager
def _sigint_deferred():
    """Hold Ctrl-C until the block ends (main thread only); yields a list that is non-empty if one came."""
    came: list = []
    if threading.current_thread() is not threading.main_thread():
        yield came
        return
    previous = signal.getsignal(signal.SIGINT)
    signal.signal(signal.SIGINT, lambda *_: came.append(True))
    try:
        yield came
    finally:
        signal.signal(signal.SIGINT, previous)


class OutputRun:
    """One run's output folder while the run writes into it (made by :func:`output_run`).

    Attributes
    ----------
    folder : Path
    run_id : str
        16 hex characters, also in the manifest.
    previous : dict or None
        The manifest of the run the folder held when this one started.
    manifest : dict or None
        This run's manifest, once published.
    """

    def __init__(self, folder: Path, staging, previous: dict | None, info: dict):
        self.folder = folder
        self.staging = staging
        self.previous = previous
        self.info = dict(info)
        self.run_id = secrets.token_hex(8)
        self.started = time.strftime("%Y-%m-%dT%H:%M:%S%z")
        self.manifest: dict | None = None

    def state(self) -> str:
        """What the folder holds now, in one sentence (for an interrupted run)."""
        return _holds(self.folder, self.previous, self.manifest)

    def publish(self, **summary) -> dict:
        """Rename every staged file into place and write the manifest last; returns the manifest.

        ``summary`` (status, exit code, ...) goes into the manifest beside the run's ``info``.
        """
        self.staging.close()
        pending = self.staging.take()
        try:
            files = {}
            for target, tmp in sorted(pending.items()):
                files[target.relative_to(self.folder).as_posix()] = {
                    "size_bytes": tmp.stat().st_size,
                    "sha256": _sha256(tmp),
                }
        except BaseException:
            _unlink_all(pending.values())
            raise
        with _sigint_deferred() as interrupted:
            try:
                self._swap(pending, files, summary)
            except BaseException:
                _unlink_all(pending.values())
                raise
        _published.pop(self.folder, None)
        _published[self.folder] = self
        while len(_published) > _PUBLISHED_KEPT:  # a worker process publishes case after case
            _published.pop(next(iter(_published)))
        if interrupted:
            raise RunInterrupted(self.state())
        return self.manifest or {}

    def _swap(self, pending: dict, files: dict, summary: dict) -> None:
        folder = self.folder
        _write_json(
            folder / INCOMPLETE_NAME,
            {
                "format": _INCOMPLETE_FORMAT,
                "run_id": self.run_id,
                "started": self.started,
                "message": (
                    f"dea-opt run {self.run_id} was replacing the outputs in this folder and did not finish: "
                    f"the files here may come from two runs; rerun to complete them"
                ),
            },
        )
        with contextlib.suppress(FileNotFoundError):
            os.unlink(folder / MANIFEST_NAME)
        _fsync_dir(folder)
        if self.previous is not None:
            _remove_old(folder, set(self.previous["files"]) - set(files))
        for target, tmp in pending.items():
            os.replace(tmp, target)
        for parent in {target.parent for target in pending} | {folder}:
            _fsync_dir(parent)
        manifest = {
            "format": _MANIFEST_FORMAT,
            "run_id": self.run_id,
            "dea_opt_version": __version__,
            "created": self.started,
            "published": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            **self.info,
            **summary,
            "files": files,
        }
        _write_json(folder / MANIFEST_NAME, manifest)
        os.unlink(folder / INCOMPLETE_NAME)
        _fsync_dir(folder)
        self.manifest = manifest


def _holds(folder: Path, previous: dict | None, published: dict | None) -> str:
    """What ``folder`` holds, in one sentence: ``published`` is the manifest this run wrote there
    (None: it published nothing), ``previous`` the one the folder held before."""
    if published is not None:
        return (
            f"the outputs of this run were published before the interrupt: {folder} holds them, "
            f"complete, listed in {MANIFEST_NAME}"
        )
    if previous is not None:
        return (
            f"no output of this run was published; {folder} still holds the complete outputs of the "
            f"previous run {previous.get('run_id')} ({previous.get('created')}), listed in {MANIFEST_NAME}"
        )
    if (folder / INCOMPLETE_NAME).exists():
        return (
            f"no output of this run was published; {folder} holds an incomplete earlier run "
            f"({INCOMPLETE_NAME}, no {MANIFEST_NAME}): rerun to complete it"
        )
    return (
        f"no output of this run was published; {folder} holds no complete outputs (removed when this "
        f"run made it and nothing else is in it)"
    )


#: The runs this process published, by folder: a Ctrl-C that comes after a run published (while
#: it closes its pictures, prints its summary) must say so, not "nothing was published".
_published: dict[Path, OutputRun] = {}
_PUBLISHED_KEPT = 16  # the last ones: a command publishes one run, or a few


def forget_published() -> None:
    """Start a new command: no run of it has published yet."""
    _published.clear()


def published_report() -> str | None:
    """What the runs this process published since :func:`forget_published` left, or None."""
    return "; ".join(run.state() for run in _published.values()) or None


def interrupted_report(folder) -> str:
    """What ``folder`` holds, for a Ctrl-C that came outside a run's publication (before it began,
    or after it ended)."""
    path = output_folder_path(folder)
    run = _published.get(path)
    if run is not None:
        return run.state()
    return _holds(path, read_manifest(path), None)


def _write_json(path: Path, data: dict) -> None:
    from ..io.summary import jsonable

    write_data(path, json.dumps(jsonable(data), indent=2, allow_nan=False) + "\n")


def _unlink_all(paths) -> None:
    for path in paths:
        with contextlib.suppress(OSError):
            os.unlink(path)


def _remove_old(folder: Path, names) -> None:
    """Remove the files of the previous run that this one does not write (and folders left empty)."""
    emptied = set()
    for name in names:
        path = folder / name
        # A manifest is data: never follow it outside the folder.
        if ".." in Path(name).parts or Path(name).is_absolute() or not path.is_file() or path.is_symlink():
            continue
        with contextlib.suppress(OSError):
            path.unlink()
            emptied.add(path.parent)
    for parent in sorted(emptied, key=lambda p: len(p.parts), reverse=True):
        if parent != folder:
            with contextlib.suppress(OSError):
                parent.rmdir()  # only if empty


@contextlib.contextmanager
def output_run(folder, *, force: bool = False, info: dict | None = None):
    """The output folder of one run: checked, locked, cleaned of stale temporary files, staged.

    Parameters
    ----------
    folder : str or os.PathLike
    force : bool
        Write into a folder that holds other files (see :func:`check_output_folder`).
    info : dict, optional
        What the manifest records about the run (scenario, its SHA-256, overrides, ...).

    Yields
    ------
    OutputRun
        Write the outputs into ``run.folder`` (they are staged), then call
        :meth:`OutputRun.publish`. Leaving the block without publishing removes the staged
        files and leaves the folder as it was: the lock file and the folders this run made are
        removed too, those that hold nothing else (:mod:`dea_opt.run.folderlock`); Ctrl-C becomes
        :class:`RunInterrupted`, whose ``report`` says what the folder holds.

    Raises
    ------
    OutputFolderError
        The folder holds files of someone else's, or another run is writing into it.
    """
    path = check_output_folder(folder, force)
    with folder_lock(path) as made:
        run = None
        try:
            _remove_stale(path)
            with staged(path) as staging:
                run = OutputRun(staging.root, staging, read_manifest(path), info or {})
                try:
                    yield run
                except RunInterrupted:
                    raise
                except KeyboardInterrupt:
                    raise RunInterrupted(run.state()) from None
        finally:
            if run is None or run.manifest is None:  # nothing published: take away what this run made
                remove_made(path, made)
