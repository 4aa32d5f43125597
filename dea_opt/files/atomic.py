"""Files written atomically: a temporary file beside the target, ``fsync``, then a rename.

An interrupted run leaves either the old file or the new one, never half of one. The
temporary file is hidden (``.name.<random>.tmp.ext``: the target's extension is kept, so
writers that pick the format from it still work), takes the target's permissions (or the
umask's for a new file) and is removed when writing fails. :func:`atomic_path` is the one
implementation; :func:`write_atomic`, :func:`write_data` and :func:`atomic_open` are fronts
to it for a writer function, for ``str``/``bytes`` and for an open file.

Inside :func:`staged` (a run's output folder, :mod:`dea_opt.run.publish`), a finished file is
not renamed into place: its temporary file waits, complete and fsynced, until the run
publishes every output at once, so a reader never sees files of two runs as one. A target
that is itself a temporary file (one :func:`atomic_path` yielded, handed to a writer in another
process or drawn later: :class:`dea_opt.run.pictures.PictureFiles`) is filled in place, never
staged: the one who holds it stages it when its :func:`atomic_path` block ends.

A write that fails (a full disk, a file-size limit, an I/O error) raises an :class:`OSError`
naming the file it was writing (:func:`naming`): the operating system names none when a
``write`` or ``fsync`` fails, and "No space left on device" alone does not say where.
"""

from __future__ import annotations

import contextlib
import os
import re
import secrets
import stat
import threading
from pathlib import Path

from ..errors import InputError

__all__ = [
    "TEMPORARY_NAME",
    "Staging",
    "atomic_open",
    "atomic_path",
    "file_path",
    "naming",
    "staged",
    "staged_file",
    "write_atomic",
    "write_data",
]

#: The name of a temporary file: ``.<target name>.<8 hex>.tmp<target suffix>``.
TEMPORARY_NAME = re.compile(r"^\..+\.[0-9a-f]{8}\.tmp(\.[^.]*)?$")


def file_path(path, argument: str = "path") -> Path:
    """``path`` as a :class:`Path` naming a file (not a directory), or a named InputError."""
    if isinstance(path, bytes):
        path = os.fsdecode(path)
    if not isinstance(path, (str, os.PathLike)):
        raise InputError(f"{argument} must be a file path (str or os.PathLike), got {type(path).__name__}")
    target = Path(path)
    if not target.name or target.name in (".", ".."):
        raise InputError(f"{argument} must name a file, got {str(path)!r}")
    if target.is_dir():
        raise InputError(f"{argument} must be a file path, got the directory {str(target)!r}")
    return target


def _fsync(path: Path, directory: bool = False) -> None:
    # Some platforms cannot open or fsync a directory; the rename has happened regardless.
    try:
        fd = os.open(path, os.O_RDONLY if (directory or os.name != "nt") else os.O_RDWR)
    except OSError:
        if directory:
            return
        raise
    try:
        os.fsync(fd)
    except OSError:
        if not directory:
            raise
    finally:
        os.close(fd)


@contextlib.contextmanager
def naming(path, *temporaries):
    """An :class:`OSError` raised in the block names ``path`` when it names no file or one of
    ``temporaries`` (the hidden file written in its place): ``[Errno 28] No space left on
    device: '/runs/knee/frames.csv'``. The error keeps its number (and so its subclass)."""
    try:
        yield
    except OSError as exc:
        if exc.filename is not None and str(exc.filename) not in {str(t) for t in temporaries}:
            raise
        raise OSError(exc.errno, exc.strerror or str(exc), str(path)) from exc


@contextlib.contextmanager
def atomic_path(path, *, argument: str = "path"):
    """Context manager yielding a temporary path that replaces ``path`` on success.

    The temporary file lies in the directory of ``path`` (created with its parents when
    missing) and already exists, empty; write it by name (any writer that opens a file by
    name works). On a clean exit it is fsynced and renamed over ``path`` with
    :func:`os.replace`; on an exception (``KeyboardInterrupt`` included) it is removed and
    ``path`` is left as it was. Writers that insist on adding their own extension
    (``numpy.save``) must be told not to.

    Parameters
    ----------
    path : str or os.PathLike
        The file to (re)write.
    argument : str
        The argument name used in error messages.

    Yields
    ------
    pathlib.Path
        The temporary file to write.

    Raises
    ------
    InputError
        ``path`` is not a path, is a directory, or its directory cannot be created or
        written.
    """
    target = file_path(path, argument)
    parent = target.parent
    # the folders this write makes (usually none: one stat)
    missing = [] if parent.is_dir() else [p for p in (parent, *parent.parents) if not p.is_dir()]
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputError(f"{argument}: cannot create the directory {str(parent)!r} ({exc.strerror or exc})") from None
    while True:  # O_EXCL: a name another writer holds is never reused
        tmp = parent / f".{target.name}.{secrets.token_hex(4)}.tmp{target.suffix}"
        try:
            os.close(os.open(tmp, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o666))  # 0o666 minus the umask
            break
        except FileExistsError:
            continue
        except OSError as exc:
            raise InputError(
                f"{argument}: cannot write in the directory {str(parent)!r} ({exc.strerror or exc})"
            ) from None
    # A temporary file as the target is a reserved one being filled: its holder stages it.
    staging = None if TEMPORARY_NAME.match(target.name) else _staging_of(target)
    if staging is not None and missing:
        staging.made(missing)
    try:
        with naming(target, tmp):
            with contextlib.suppress(OSError):  # a new file keeps the umask's mode
                os.chmod(tmp, stat.S_IMODE(target.stat().st_mode))
            yield tmp
            _fsync(tmp)
            if staging is not None:
                staging.defer(tmp, target)
                return
            os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise
    _fsync(parent, directory=True)


def write_atomic(path, writer, *, argument: str = "path") -> Path:
    """Write ``path`` atomically with ``writer(temporary_path)``; return ``path``.

    Parameters
    ----------
    path : str or os.PathLike
        The file to (re)write; missing parent directories are created.
    writer : callable
        Called once with the temporary :class:`pathlib.Path` (same directory and extension
        as ``path``) and must write the whole file there. If it raises, the temporary file
        is removed, ``path`` keeps its old contents and the exception propagates.
    argument : str
        The argument name used in error messages.

    Examples
    --------
    >>> write_atomic("out/table.txt", lambda tmp: tmp.write_text("hello"))  # doctest: +SKIP
    """
    if not callable(writer):
        raise InputError(f"writer must be callable, got {type(writer).__name__}")
    with atomic_path(path, argument=argument) as tmp:
        writer(tmp)
    return Path(path)


def write_data(path, data, *, argument: str = "path") -> Path:
    """Write ``data`` (``str`` as UTF-8 with its line ends as given, or ``bytes``) atomically."""
    binary = isinstance(data, (bytes, bytearray))
    with atomic_open(path, "wb" if binary else "w", newline="", argument=argument) as handle:
        handle.write(data)
    return Path(path)


@contextlib.contextmanager
def atomic_open(
    path, mode: str = "w", *, encoding: str | None = None, newline: str | None = None, argument: str = "path"
):
    """``open`` for writing, atomically: the file appears complete or not at all.

    Parameters
    ----------
    path : str or os.PathLike
    mode : {"w", "wb"}
        Text or binary.
    encoding : str, optional
        Text encoding; default UTF-8 in text mode.
    newline : str, optional
        As for :func:`open` (use ``""`` for :mod:`csv`).
    argument : str
        The argument name used in error messages.

    Yields
    ------
    file object
    """
    if mode not in ("w", "wb"):
        raise InputError(f"mode must be 'w' or 'wb', got {mode!r}")
    with atomic_path(path, argument=argument) as tmp:
        handle = open(tmp, "wb") if mode == "wb" else open(tmp, "w", encoding=encoding or "utf-8", newline=newline)
        with handle:
            yield handle


# --- staging: a run's files wait until they are published together ----------------------


class Staging:
    """The finished but unpublished files of one output folder: ``{target: temporary file}``.

    Made by :func:`staged`; :mod:`dea_opt.run.publish` renames them into place together.
    """

    def __init__(self, root: Path):
        self.root = root
        self.pending: dict[Path, Path] = {}
        self._made: set[Path] = set()  # folders under the root its writes made (series_frames/)
        self._lock = threading.Lock()

    def made(self, folders) -> None:
        """Note ``folders`` that a staged write made (removed by :meth:`discard` when left empty)."""
        with self._lock:
            self._made.update(Path(f).resolve() for f in folders if Path(f).resolve().is_relative_to(self.root))

    def defer(self, tmp: Path, target: Path) -> None:
        """Keep ``tmp`` as the next content of ``target`` (a file written twice keeps the last)."""
        key = target.parent.resolve() / target.name
        with self._lock:
            old = self.pending.pop(key, None)
            self.pending[key] = tmp
        if old is not None and old != tmp:
            with contextlib.suppress(OSError):
                old.unlink()

    def close(self) -> None:
        """Stop deferring: files written under the root from now on are renamed into place at once."""
        with _STAGINGS_LOCK:
            if _STAGINGS.get(self.root) is self:
                del _STAGINGS[self.root]

    def take(self) -> dict:
        """The pending files ``{target: temporary file}``; the staging forgets them."""
        with self._lock:
            pending, self.pending = self.pending, {}
        return pending

    def discard(self) -> None:
        """Remove every pending temporary file (the run ends without publishing), then the folders
        the staged writes made that this leaves empty, innermost first (a load path's
        ``series_frames/`` of a run stopped at a failed frame: nothing of it was published)."""
        with self._lock:
            pending, self.pending = self.pending, {}
            made, self._made = self._made, set()
        for tmp in pending.values():
            with contextlib.suppress(OSError):
                tmp.unlink()
        for folder in sorted(made, key=lambda f: len(f.parts), reverse=True):
            with contextlib.suppress(OSError):  # not empty (a file of someone else's): kept
                folder.rmdir()


_STAGINGS: dict[Path, Staging] = {}
_STAGINGS_LOCK = threading.Lock()


def _staging_of(target: Path) -> Staging | None:
    if not _STAGINGS:
        return None
    where = target.parent.resolve() / target.name
    with _STAGINGS_LOCK:
        for root, staging in _STAGINGS.items():
            if where.is_relative_to(root):
                return staging
    return None


def staged_file(path) -> Path:
    """The file that holds ``path``'s content now: its staged temporary file while a run's outputs
    wait to be published (:func:`staged`), else ``path`` itself (a report embeds the pictures the
    run drew before they are published)."""
    target = Path(path)
    staging = _staging_of(target)
    if staging is not None:
        with staging._lock:
            tmp = staging.pending.get(target.parent.resolve() / target.name)
        if tmp is not None:
            return tmp
    return target


@contextlib.contextmanager
def staged(root):
    """While the block runs, files written atomically under ``root`` wait in a :class:`Staging`.

    Every thread's writes count (a registry by folder, not a context variable). The files
    are not renamed into place here: the caller closes the staging and publishes what it
    :meth:`~Staging.take` s. On leaving the block, what is still pending is removed.
    """
    root = Path(root).resolve()
    staging = Staging(root)
    with _STAGINGS_LOCK:
        if root in _STAGINGS:
            raise InputError(f"the folder {str(root)!r} is already being written by this process")
        _STAGINGS[root] = staging
    try:
        yield staging
    finally:
        staging.close()
        staging.discard()
