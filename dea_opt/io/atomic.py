"""Files written atomically: a temporary file beside the target, ``fsync``, then a rename.

An interrupted run leaves either the old file or the new one, never half of one. The
temporary file is hidden (``.name.<random>.tmp.ext``: the target's extension is kept, so
writers that pick the format from it still work), takes the target's permissions (or the
umask's for a new file) and is removed when writing fails. :func:`atomic_path` is the one
implementation; :func:`write_atomic`, :func:`write_data` and :func:`atomic_open` are fronts
to it for a writer function, for ``str``/``bytes`` and for an open file.
"""

from __future__ import annotations

import contextlib
import os
import secrets
import stat
from pathlib import Path

from ..errors import InputError

__all__ = ["atomic_open", "atomic_path", "file_path", "write_atomic", "write_data"]


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
            raise InputError(f"{argument}: cannot write in the directory {str(parent)!r} "
                             f"({exc.strerror or exc})") from None
    try:
        with contextlib.suppress(OSError):  # a new file keeps the umask's mode
            os.chmod(tmp, stat.S_IMODE(target.stat().st_mode))
        yield tmp
        _fsync(tmp)
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
def atomic_open(path, mode: str = "w", *, encoding: str | None = None, newline: str | None = None,
                argument: str = "path"):
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
    text = {} if mode == "wb" else {"encoding": encoding or "utf-8", "newline": newline}
    with atomic_path(path, argument=argument) as tmp, open(tmp, mode, **text) as handle:
        yield handle
