"""Memory checked before a large allocation: an estimate against what the machine has free.

A request that cannot fit (a load path resampled to 1e9 frames, a table of every spring at
every frame of a long path, ``hip_meshes(step=0.01)``, a cast between meshes of tens of
millions of faces) raises :class:`~dea_opt.errors.SizeLimitError` with the estimate before
anything is allocated, instead of being killed by the operating system without a word. This
module is the one reader of the free memory; :mod:`dea_opt.mesh.budget` holds the estimates of
meshes and casts. Sizes in bytes.
"""

from __future__ import annotations

import os

from ..errors import SizeLimitError

__all__ = ["USABLE_SHARE", "available_memory", "check_memory", "format_bytes", "format_count"]

#: Share of the free memory a request may take when its estimate counts only what it keeps:
#: the rest is the interpreter, the libraries and the temporaries of whatever computes it. An
#: estimate of the measured peak (temporaries included) passes ``share=1.0``.
USABLE_SHARE = 0.8


def available_memory() -> int:
    """Bytes of memory available to a new allocation: ``MemAvailable`` of ``/proc/meminfo``
    on Linux, else the physical memory, else 8 GiB when neither is known."""
    try:
        with open("/proc/meminfo", encoding="ascii") as lines:
            for line in lines:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, OSError, ValueError):
        return 8 * 1024**3


def format_count(n: int) -> str:
    """An integer as is below 10^15, else as ``"3.6e+20"`` (``">1e+300"`` beyond floats)."""
    if n < 10**15:
        return str(n)
    return f"{float(n):.3g}" if n < 10**300 else ">1e+300"


def format_bytes(n: float) -> str:
    """``n`` bytes as e.g. ``"62 GB"`` (powers of 1000)."""
    n = float(min(n, 10**300))
    for unit in ("bytes", "kB", "MB", "GB", "TB"):
        if abs(n) < 1000:
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.3g} {unit}"
        n /= 1000.0
    return f"{n:.3g} PB"


def check_memory(needed: float, what: str, advice: str = "", *, share: float = USABLE_SHARE) -> None:
    """Raise :class:`SizeLimitError` when ``needed`` bytes exceed ``share`` of the free memory.

    Parameters
    ----------
    needed : float
        Estimated bytes of the allocation (and what it keeps alive).
    what : str
        What asked for it, as the user wrote it, e.g. ``"load_path.frames = 1000000000"``.
    advice : str
        What to do instead, one sentence.
    share : float
        Share of the free memory the request may take (:data:`USABLE_SHARE`; 1 for an
        estimate of the measured peak).
    """
    available = available_memory()
    needed = float(min(needed, 10**300))  # counts from tiny steps may exceed any float
    if needed <= share * available:
        return
    message = (
        f"{what} would need about {format_bytes(needed)} of memory, and this machine has {format_bytes(available)} free"
    )
    raise SizeLimitError(
        f"{message}: {advice}" if advice else message, needed=needed, available=float(available), what=what
    )
