"""Triangle meshes in, springs out: reading surfaces, ray casting gaps and cartilage thickness.

A researcher's data are cartilage surfaces segmented from MRI or CT. This package reads them
(:func:`load_mesh`), checks and repairs them, and turns two of them into a
:class:`~dea_opt.layer.SpringLayer` (:func:`springs_from_meshes`): one spring per articular
face of mesh 1, at its centroid, along its normal, with the gap to mesh 2 and the cartilage
thickness measured by ray casting. Lengths are in mm throughout.

Ray casting uses trimesh with Intel Embree (the ``embreex`` package, the optional ``fast``
extra) when it is installed and a numpy uniform-grid caster with exact float64 ray/triangle tests otherwise (trimesh's own
``ray_triangle`` fallback queries its r-tree once per ray and takes minutes on a knee); both
give the same springs. Every step is vectorized over faces.

Two faults of OpenSim-JAM's elastic foundation are avoided on purpose:

* a ray never takes a hit on the far (back) side of a curved mesh 2: only faces of mesh 2 that
  face the ray count, and of those the one nearest the spring;
* results need not depend on which mesh casts: :func:`springs_both_ways` casts both ways and
  measures the difference.

The proximity window is a property of a pose: a ray that reaches mesh 2 only behind mesh 1's
own far side went back through the spring layer and is rejected, overlaps deeper than the
window are counted as dropped (:class:`SpringCast` ``.dropped``), and :func:`recast` re-casts at
another pose with the window following mesh 2 (:func:`recast_at_solution`: at a solved pose,
with the force the springs carry there). Each spring keeps its target on mesh 2 (point, normal,
face) for :func:`tangent_plane_gap`.

The modules: :mod:`~dea_opt.mesh.readers` (file formats; the legacy-VTK parser in
:mod:`~dea_opt.mesh.legacy_vtk`; :mod:`~dea_opt.mesh.sniff`, what a file holds),
:mod:`~dea_opt.mesh.repair`, :mod:`~dea_opt.mesh.budget` (memory guards),
:mod:`~dea_opt.mesh.raycast` (grid and Embree), :mod:`~dea_opt.mesh.springs` (springs from two
meshes, poses, the window's drops), :mod:`~dea_opt.mesh.recast`, :mod:`~dea_opt.mesh.facecast` (casting chosen faces at a
pose, and whether hits left their faces: what keeps the springs of a finite-kinematics solve up
to date) and :mod:`~dea_opt.mesh.both_ways`.
"""

from .both_ways import TwoWaySprings, springs_both_ways
from .facecast import FaceCast, Mesh1, Mesh2, cast_faces, follow_faces, measure, off_face
from .raycast import ENGINES, surface_thickness
from .readers import LOADERS, as_mesh, concatenate_meshes, load_mesh
from .recast import (
    Recast,
    body_pose,
    recast,
    recast_at_solution,
    relative_pose,
    tangent_plane_gap,
)
from .springs import (
    DROP_REASONS,
    LOST_REASONS,
    MAX_ANGLE,
    MAX_GAP,
    MAX_OVERLAP,
    Dropped,
    SpringCast,
    cast_springs,
    check_pose,
    springs_from_meshes,
)

__all__ = [
    "DROP_REASONS",
    "ENGINES",
    "LOADERS",
    "LOST_REASONS",
    "MAX_ANGLE",
    "MAX_GAP",
    "MAX_OVERLAP",
    "Dropped",
    "FaceCast",
    "Mesh1",
    "Mesh2",
    "Recast",
    "SpringCast",
    "TwoWaySprings",
    "as_mesh",
    "body_pose",
    "cast_faces",
    "follow_faces",
    "measure",
    "cast_springs",
    "check_pose",
    "concatenate_meshes",
    "load_mesh",
    "off_face",
    "recast",
    "recast_at_solution",
    "relative_pose",
    "springs_both_ways",
    "springs_from_meshes",
    "surface_thickness",
    "tangent_plane_gap",
]
