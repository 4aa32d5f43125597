"""The one file lock of dea-opt: ``flock`` on a file, released by the kernel when its process dies.

Three things hold it: an output folder's ``.dea-opt.lock`` (:mod:`dea_opt.run.folderlock`: one
run per folder), a sweep's journal lock and each case's claim (:mod:`dea_opt.sweep.journal`), and
each entry of the spring cache (:mod:`dea_opt.mesh.cache`). A lock held on an open
file ends with the process, ``kill -9`` included, so no crash leaves a folder, a case or a cast
locked; no lease, timestamp or polling is involved. POSIX only (Linux, macOS); on a network file
system the locks are as good as its ``flock`` (NFSv4: yes).

Lock files are never deleted while others may wait on them: removing one would let a third
process lock a new file of the same name while the second holds the old one. The one exception is
the output folder's lock file, which a refused run removes while it still holds it (it leaves no
trace); :func:`held_at` lets the next run see that the file it locked is no longer the one at the
path, and look again.

Written here rather than taken from ``filelock`` (the kept library for locks): its native lock
gives no way to tell a second run *who* holds a folder (the holder's pid, written into the lock
file and read back by :func:`holder`), nor to remove a lock file safely, which a refused run
needs; what remains is one ``fcntl.flock`` call, and every dea-opt lock goes through this module.
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path

from ..errors import InputError

__all__ = ["held_at", "hold", "holder", "mark_holder", "try_lock"]


def _fcntl():
    try:
        import fcntl
    except ImportError:  # pragma: no cover - Windows
        raise InputError("dea-opt's file locks need POSIX (fcntl.flock): run it on Linux or macOS") from None
    return fcntl


def try_lock(fd: int, *, shared: bool = False, wait: bool = True) -> bool:
    """Lock the open file ``fd``: True once held, False when ``wait`` is False and another holds it."""
    fcntl = _fcntl()
    mode = fcntl.LOCK_SH if shared else fcntl.LOCK_EX
    try:
        fcntl.flock(fd, mode if wait else mode | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    return True


@contextlib.contextmanager
def hold(path: Path, *, shared: bool = False, wait: bool = True):
    """Hold the lock on ``path`` (created, with its folders, when missing) for the block.

    Yields the lock file's descriptor, or None when ``wait`` is False and another process holds
    it. Closing the file at the end releases the lock, as the end of the process does.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        yield fd if try_lock(fd, shared=shared, wait=wait) else None
    finally:
        os.close(fd)


def mark_holder(fd: int) -> None:
    """Write this process's pid into the held lock file ``fd`` (for :func:`holder`; the lock is
    what counts)."""
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)


def holder(fd: int) -> str:
    """The pid the holder of the lock file ``fd`` wrote into it (:func:`mark_holder`), or ``""``."""
    return os.pread(fd, 32, 0).decode(errors="replace").strip()


def held_at(fd: int, path: Path) -> bool:
    """Whether the locked file ``fd`` is still the file at ``path`` (not one removed since)."""
    with contextlib.suppress(OSError):
        return os.path.samestat(os.fstat(fd), os.stat(path))
    return False
