"""Memory guards: the size of a mesh to build, read or cast is checked before allocating.

An oversized request (``hip_meshes(step=0.01)``, a cast between two meshes of tens of
millions of faces, a multi-gigabyte mesh file) is a :class:`~dea_opt.errors.SizeLimitError`
(an :class:`~dea_opt.errors.InputError`)
that names the parameter and gives an estimate of the memory it would need, rather than a
process killed by the operating system. The estimates are peak bytes per face, measured on
this code (``tests/mesh/test_mesh_errors.py`` checks one is an upper bound on a measured peak), compared
with all the memory the machine has available (:func:`dea_opt._checks.memory.check_memory` with
``share=PEAK_SHARE``).
"""

from __future__ import annotations

import os

from .._checks.memory import available_memory, check_memory, format_bytes, format_count

__all__ = [
    "BYTES_PER_CAST_FACE",
    "BYTES_PER_FILE_BYTE",
    "BYTES_PER_GENERATED_FACE",
    "BYTES_PER_LAYER_SPRING",
    "PEAK_SHARE",
    "available_memory",
    "check_cast_size",
    "check_file_size",
    "check_memory",
    "format_bytes",
    "format_count",
]

#: Share of the free memory a mesh's estimate may take: the estimates below are measured peaks,
#: temporaries included.
PEAK_SHARE = 1.0
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


def check_cast_size(n_faces1: int, n_faces2: int, engine: str = "grid") -> None:
    """Check that casting springs between meshes of these face counts fits in memory
    (``engine`` is ``"embree"`` or ``"grid"``, the one that will run)."""
    estimate = BYTES_PER_CAST_FACE[engine] * (n_faces1 + n_faces2)
    check_memory(
        estimate,
        f"casting springs from mesh1 ({n_faces1} faces) onto mesh2 ({n_faces2} faces)",
        "decimate the meshes (a knee's cartilage needs 10^4-10^5 faces)",
        share=PEAK_SHARE,
    )


def check_file_size(path) -> None:
    """Check that reading and repairing the mesh file ``path`` fits in memory."""
    size = os.stat(path).st_size
    check_memory(
        BYTES_PER_FILE_BYTE * size,
        f"reading mesh file {path} ({format_bytes(size)})",
        "decimate the mesh before reading it (a knee's cartilage needs 10^4-10^5 faces)",
        share=PEAK_SHARE,
    )
