"""Memory checked before a large allocation: an estimate against what the machine has free.

A request that cannot fit (a load path resampled to 1e9 frames, a table of every spring at
every frame of a long path) raises :class:`~dea_opt.errors.SizeLimitError` with the estimate
before anything is allocated, instead of being killed by the operating system without a word.
The free memory is read by :mod:`dea_opt.mesh.budget` (the guards of generated meshes, casts
and mesh files). Sizes in bytes.
"""

from __future__ import annotations

from .errors import SizeLimitError

__all__ = ["available_memory", "check_memory", "format_bytes"]

#: Share of the free memory one request may take: the rest is the interpreter, the libraries
#: and the temporaries of whatever computes the result.
USABLE_SHARE = 0.8


def available_memory() -> float:
    """Memory the system can give this process now (bytes): ``MemAvailable`` of
    ``/proc/meminfo`` on Linux, else the physical memory (:func:`dea_opt.mesh.budget.available_memory`,
    the one reader of it)."""
    from .mesh.budget import available_memory as available

    return float(available())


def format_bytes(n: float) -> str:
    """``n`` bytes as ``12.3 GB`` (powers of 1000; :func:`dea_opt.mesh.budget.format_bytes`)."""
    from .mesh.budget import format_bytes as formatted

    return formatted(n)


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
    if needed <= USABLE_SHARE * available:
        return
    message = (f"{what} would need about {format_bytes(needed)} of memory, and this machine has "
               f"{format_bytes(available)} free")
    raise SizeLimitError(f"{message}: {advice}" if advice else message, needed=float(needed),
                         available=float(available), what=what)
