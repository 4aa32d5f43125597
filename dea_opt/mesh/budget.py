"""Memory guards: the size of a mesh to build, read or cast is checked before allocating.

An oversized request (``hip_meshes(step=0.01)``, a cast between two meshes of tens of
millions of faces, a multi-gigabyte mesh file) is a :class:`~dea_opt.errors.SizeLimitError`
(an :class:`~dea_opt.errors.InputError`)
that names the parameter and gives an estimate of the memory it would need, rather than a
process killed by the operating system. The estimates are peak bytes per face, measured on
this code (``tests/test_mesh_errors.py`` checks one is an upper bound on a measured peak), compared
with the memory the machine has available.
"""

from __future__ import annotations

import os

from ..errors import SizeLimitError

__all__ = [
    "BYTES_PER_CAST_FACE",
    "BYTES_PER_FILE_BYTE",
    "BYTES_PER_GENERATED_FACE",
    "BYTES_PER_LAYER_SPRING",
    "available_memory",
    "check_cast_size",
    "check_file_size",
    "check_memory",
    "format_bytes",
    "format_count",
]

#: Peak bytes per face while a closed layer is generated (grids, faces, orientation,
#: trimesh's vertex merge; about 480 measured) (geometry).
BYTES_PER_GENERATED_FACE = 600
#: Peak bytes per spring while a closed-form layer is generated (about 150-190 measured)
#: (geometry).
BYTES_PER_LAYER_SPRING = 250
#: Peak bytes per face of mesh 1 and of mesh 2 while springs are cast (rays, hits, the
#: ray-casting structures), by engine: Embree (about 190 measured) and the numpy grid
#: (about 2500) (mesh.springs).
BYTES_PER_CAST_FACE = {"embree": 300, "grid": 3000}
#: Peak bytes per byte of a mesh file while it is read and repaired (3-9 measured for STL,
#: OBJ, PLY and OFF files) (mesh.readers).
BYTES_PER_FILE_BYTE = 12


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
    for unit in ("bytes", "kB", "MB", "GB", "TB", "PB"):
        if abs(n) < 1000 or unit == "PB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.3g} {unit}"
        n /= 1000.0
    raise AssertionError("unreachable")


def check_memory(what: str, estimate: float, advice: str) -> None:
    """Raise :class:`~dea_opt.errors.SizeLimitError` (an InputError) when ``estimate`` bytes
    exceed the memory available.

    Parameters
    ----------
    what : str
        The request, naming its parameters (e.g. ``"hip_meshes(step=0.01)"``).
    estimate : float
        Estimated peak bytes.
    advice : str
        What to change.
    """
    available = available_memory()
    estimate = float(min(estimate, 10**300))  # counts from tiny steps may exceed any float
    if estimate > available:
        raise SizeLimitError(f"{what} would need about {format_bytes(estimate)} of memory, more than the "
                             f"{format_bytes(available)} available: {advice}", needed=estimate,
                             available=float(available), what=what)


def check_cast_size(n_faces1: int, n_faces2: int, engine: str = "grid") -> None:
    """Check that casting springs between meshes of these face counts fits in memory
    (``engine`` is ``"embree"`` or ``"grid"``, the one that will run)."""
    estimate = BYTES_PER_CAST_FACE[engine] * (n_faces1 + n_faces2)
    check_memory(f"casting springs from mesh1 ({n_faces1} faces) onto mesh2 ({n_faces2} faces)", estimate,
                 "decimate the meshes (a knee's cartilage needs 10^4-10^5 faces)")


def check_file_size(path) -> None:
    """Check that reading and repairing the mesh file ``path`` fits in memory."""
    size = os.stat(path).st_size
    check_memory(f"reading mesh file {path} ({format_bytes(size)})", BYTES_PER_FILE_BYTE * size,
                 "decimate the mesh before reading it (a knee's cartilage needs 10^4-10^5 faces)")
