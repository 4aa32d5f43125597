"""The lock that keeps two runs out of one output folder (``.dea-opt.lock``), and what a run that
published nothing takes away again.

A run holds the lock (:mod:`dea_opt.files.locks`, the one lock of dea-opt: the kernel releases
it when the process ends, even after ``kill -9``) while it writes into its folder (:func:`dea_opt.run.publish.output_run`). A run
that leaves without publishing (bad input refused, exit 2) removes what it made for itself: the
lock file, if it made it, and the folders it made, if nothing else is in them. So a refused run
leaves no trace, and a folder that was there before, or holds anything else, stays.

It removes them while it still holds the lock. Another run may have opened the lock file before
it was removed and lock it once it is released: that run then holds a file no longer at the path,
which keeps no one out, so it looks again (:func:`dea_opt.files.locks.held_at`) and makes the folder and lock anew.
"""

from __future__ import annotations

import contextlib
import os
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import OutputFolderError
from ..files.locks import held_at, holder, mark_holder, try_lock

__all__ = ["LOCK_NAME", "Made", "folder_lock", "remove_made"]

LOCK_NAME = ".dea-opt.lock"
_TRIES = 100  # turns of looking again, each after a run removed the folder or lock it had made


@dataclass
class Made:
    """What a run made to hold its folder's lock: ``folders`` (outermost first), ``lock`` (the file)."""

    folders: list[Path] = field(default_factory=list)
    lock: bool = False


def _make_folder(folder: Path, made: Made) -> None:
    """Make ``folder`` and its missing parents, noting those made here in ``made``."""
    for path in [*reversed(folder.parents), folder]:
        if path.is_dir():
            continue
        try:
            os.mkdir(path)
            made.folders.append(path)
        except FileExistsError:  # made meanwhile by another run (a file there: opening the lock says so)
            pass
        except FileNotFoundError:  # a parent removed meanwhile by the run that made it: look again
            return
        except OSError as exc:
            raise OutputFolderError(f"cannot create the output folder {path} ({exc.strerror or exc})") from None


def _open_lock(path: Path) -> tuple[int | None, bool]:
    """``(fd, made)`` of the lock file at ``path``, made here or not; ``(None, False)`` when its
    folder was removed meanwhile."""
    for flags, made in ((os.O_CREAT | os.O_EXCL, True), (0, False)):
        try:
            return os.open(path, os.O_RDWR | flags, 0o644), made
        except FileExistsError:
            continue
        except FileNotFoundError:
            return None, False
        except OSError as exc:
            raise OutputFolderError(f"cannot lock the output folder {path.parent} ({exc.strerror or exc})") from None
    return None, False  # made by another run, then removed by it: look again


@contextlib.contextmanager
def folder_lock(folder: Path):
    """Make ``folder`` if needed and hold its lock for the block; yields what was made (:class:`Made`).

    Raises
    ------
    OutputFolderError
        Another run holds the lock (naming its pid), or the folder cannot be made or locked.
    """
    made = Made()
    for _ in range(_TRIES):
        _make_folder(folder, made)
        fd, made.lock = _open_lock(folder / LOCK_NAME)
        if fd is None:
            continue
        if not try_lock(fd, wait=False):
            pid = holder(fd)
            os.close(fd)
            raise OutputFolderError(
                f"another dea-opt run (pid {pid or 'unknown'}) is writing into the output "
                f"folder {folder}: wait for it, or choose another folder (-o)"
            )
        if held_at(fd, folder / LOCK_NAME):
            break
        os.close(fd)
    else:  # pragma: no cover - a hundred runs, one after the other, made and removed the folder meanwhile
        raise OutputFolderError(f"the output folder {folder} keeps being removed by other runs: try again")
    try:
        mark_holder(fd)
        yield made
    finally:
        os.close(fd)  # releases the lock, as the end of the process does


def remove_made(folder: Path, made: Made) -> None:
    """Remove what a run that published nothing made (:class:`Made`), with the lock held: its lock
    file, then its folders, innermost first, each only if empty (``os.rmdir``)."""
    with contextlib.suppress(OSError):
        if made.lock:
            os.unlink(folder / LOCK_NAME)
        for path in reversed(made.folders):
            os.rmdir(path)  # the first that is not empty ends the removal
