"""A joint's springs cast from meshes, kept up to date as its bodies move (finite kinematics).

Written math: ``formulations/joint.md`` ("Finite kinematics", "The solve"). Between casts a
spring's gap is taken to the tangent plane of the face of mesh 2 its ray met, exact while the hit
stays on that face: on the way to equilibrium the springs near contact follow body 2 to the faces
under them (:func:`follow`, across mesh 2's edges, no cast), and where the forces balance the
springs are cast again (:func:`recast`): that cast alone decides the springs an answer is
certified with.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .configuration import Configuration

__all__ = ["follow", "recast"]

#: The springs whose gap at the pose is below this (mm) follow body 2 between casts (:func:`follow`):
#: those that carry load, or may, within what is left of a solve once its residual has fallen.
_NEAR = 0.5


def recast(config: Configuration) -> tuple | None:
    """The contacts' springs cast again at the pose where they came from a cast, or None where no
    contact was cast from meshes."""
    from ..formulations.finite import Targets
    from ..mesh import recast as cast_again

    states, any_cast = [], False
    for i, state in enumerate(config.states):
        if state.cast is None:
            states.append(state)
            continue
        any_cast = True
        again = cast_again(state.cast, config.relative(i))
        layer = again.cast.layer
        targets = Targets.from_layer(layer, pose=state.targets.frame)
        states.append(replace(state, layer=layer, targets=targets, dropped=again.dropped))
    return tuple(states) if any_cast else None


def follow(config: Configuration) -> tuple | None:
    """The contacts' springs near contact (gap below :data:`_NEAR`) with their targets moved to the
    faces of mesh 2 their rays cross at the pose: followed across its edges from the faces they met
    (:meth:`dea_opt.mesh.walk.Walker.follow`), or, where that walk ends, by the ray's first crossing
    facing it; None where no target moved (or no contact was cast). The springs, the other targets
    and the cast are kept: between casts the steps see the faces under the springs as body 2 moves
    (a tangent plane is exact only on its face), and the cast where the forces balance
    (:func:`recast`, which alone decides the answer's springs) then changes little or nothing."""
    from ..formulations.finite import Targets
    from ..mesh import Mesh2

    states, moved_any = [], False
    for i, (state, gaps) in enumerate(zip(config.states, config.gaps)):
        t = state.targets
        if state.cast is None or t.faces is None:
            states.append(state)
            continue
        near = np.flatnonzero(gaps.s < _NEAR)
        T = config.relative(i)  # mesh 2's own frame in body 1's: the rays in mesh 2's frame, as a cast
        R, shift = T[:3, :3], T[:3, 3]
        origins = (state.layer.points[near] - shift) @ R
        directions = state.layer.normals[near] @ R
        mesh2 = Mesh2.of(state.cast)
        walk = mesh2.walker.follow(t.faces[near], origins, directions)
        face, dist = walk.face.copy(), walk.t.copy()
        with np.errstate(invalid="ignore"):
            ok = walk.found & (walk.along < 0) & np.isfinite(dist)
        lost = np.flatnonzero(~ok)
        if len(lost):
            # the hit moved more faces than a walk takes: the ray's first crossing from behind its spring
            back = _NEAR + 1.0
            hit, ahead = mesh2.first(origins[lost] - back * directions[lost], directions[lost])
            facing = hit >= 0
            along = np.einsum("ij,ij->i", np.take(mesh2.planes.normals, hit.clip(0), axis=0), directions[lost])
            facing &= along < 0
            face[lost[facing]], dist[lost[facing]] = hit[facing], ahead[facing] - back
            ok[lost[facing]] = True
        moved = ok & (face != t.faces[near])
        if not moved.any():
            states.append(state)
            continue
        moved_any = True
        idx, face = near[moved], face[moved]
        points, normals, faces = t.points.copy(), t.normals.copy(), t.faces.copy()
        points[idx] = origins[moved] + dist[moved, None] * directions[moved]
        normals[idx] = np.take(mesh2.planes.normals, face, axis=0)
        faces[idx] = face
        states.append(replace(state, targets=Targets.cast_planes(points, normals, t.frame, faces)))
    return tuple(states) if moved_any else None
