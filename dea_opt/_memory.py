"""Memory checked before a large allocation: an estimate against what the machine has free.

A request that cannot fit (a load path resampled to 1e9 frames, a table of every spring at
every frame of a long path) raises :class:`~dea_opt.errors.SizeLimitError` with the estimate
before anything is allocated, instead of being killed by the operating system without a word.
Sizes in bytes.
"""

from __future__ import annotations

import os

from .errors import SizeLimitError

__all__ = ["available_memory", "check_memory", "format_bytes"]

#: Share of the free memory one request may take: the rest is the interpreter, the libraries
#: and the temporaries of whatever computes the result.
USABLE_SHARE = 0.8


def available_memory() -> float | None:
    """Memory the system can give this process now (bytes), or None when it cannot tell.

    ``MemAvailable`` of ``/proc/meminfo`` on Linux (free plus reclaimable cache); elsewhere
    the physical memory, an upper bound.
    """
    try:
        with open("/proc/meminfo", encoding="ascii") as handle:
            for line in handle:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024.0
    except (OSError, ValueError, IndexError):
        pass
    try:
        return float(os.sysconf("SC_PHYS_PAGES")) * float(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):
        return None


def format_bytes(n: float) -> str:
    """``n`` bytes as ``12.3 GB`` (powers of 1000, as a reader compares with a machine's RAM)."""
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:.0f} B"


def check_memory(needed: float, what: str, advice: str = "") -> None:
    """Raise :class:`SizeLimitError` when ``needed`` bytes exceed the usable free memory.

    Parameters
    ----------
    needed : float
        Estimated bytes of the allocation (and what it keeps alive).
    what : str
        What asked for it, as the user wrote it, e.g. ``"load_path.frames = 1000000000"``.
    advice : str
        What to do instead, one sentence.
    """
    available = available_memory()
    if available is None or needed <= USABLE_SHARE * available:
        return
    message = (f"{what} would need about {format_bytes(needed)} of memory, and this machine has "
               f"{format_bytes(available)} free")
    raise SizeLimitError(f"{message}: {advice}" if advice else message, needed=float(needed),
                         available=float(available), what=what)
