"""Finite kinematics, the arrays of a solve: the springs' targets, the FiniteSystem, its scaling, and
the formulations a method tries.

Written math: ``formulations/finite.md``. Used by :mod:`~dea_opt.finite.driver`, which
solves what these build.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..formulations._parts.system import SpringSystem
from ..formulations.finite import SHARED, FiniteSystem, Targets, evaluate, scale, small_system
from ..kinematics import DOFS
from ..mesh import SpringCast

__all__ = ["build_system", "check_bodies", "plan", "planes_note", "remembered", "resolve_targets", "scaled_directions"]

_GAP_TOL = 1e-6  # mm per mm of the layer's size: targets must reproduce the layer's gaps


def resolve_targets(problem) -> tuple[Targets, object]:
    """``(targets, cast)``: the springs' targets at zero displacement, and the SpringCast to re-cast
    from (None without meshes). Checked to reproduce the layer's gaps."""
    layer, given = problem.layer, problem.targets
    cast = None
    if given is None:
        targets = Targets.from_layer(layer) if layer.has_targets else Targets.facing(layer)
    elif isinstance(given, SpringCast):
        cast = given
        if len(cast.layer) != len(layer) or not np.array_equal(
            np.asarray(cast.layer.source_face), np.asarray(layer.source_face)
        ):
            raise InputError(
                f"targets is a SpringCast of {len(cast.layer)} springs, but the problem's layer has "
                f"{len(layer)}: pass the cast the layer came from (ContactProblem(cast.layer, ..., "
                f"targets=cast))"
            )
        if layer is cast.layer:  # the cast's own targets give its gaps (they are where its rays met)
            own = cast.layer
            pose = np.asarray(cast.pose, dtype=float)
            return Targets.cast_planes(own.target_points, own.target_normals, pose, own.target_faces), cast
        targets = Targets.from_layer(cast.layer, pose=cast.pose)
    else:
        targets = given
        if len(targets) != len(layer):
            raise InputError(f"targets has {len(targets)} entries, the layer {len(layer)} springs: give one per spring")
    s0 = evaluate(targets, layer.points, layer.normals, targets.frame).s
    size = max(float(np.abs(layer.points).max(initial=0.0)), 1.0)
    error = np.abs(s0 - layer.gap)
    if len(error) and not (error.max() <= _GAP_TOL * size):
        i = int(np.nanargmax(np.where(np.isfinite(error), error, np.inf)))
        raise InputError(
            f"targets must reproduce the layer's gaps at zero displacement: spring {i} has gap "
            f"{layer.gap[i]:.6g} mm, its target gives {s0[i]:.6g} mm; build the targets from the same "
            f"geometry (Targets.from_layer(layer), the SpringCast, or planes/spheres through the gaps)"
        )
    return targets, cast


def check_bodies(problem) -> None:
    """Finite kinematics move body 2 against a fixed body 1 (only the relative pose matters)."""
    body1 = problem.body1
    moved = [d for d, v in body1.prescribed.items() if v != 0.0]
    if body1.free or moved:
        what = f"free dofs {body1.free}" if body1.free else f"prescribed motion {moved}"
        raise InputError(
            f"kinematics='finite' moves body 2 against a fixed body 1, but body1 has {what}: fix body 1 "
            f"and give the motion to body 2 (only the relative pose matters)"
        )


def build_system(problem, targets, tracker=None) -> FiniteSystem:
    """The :class:`FiniteSystem` of ``problem``'s springs and ``targets``, or of ``tracker``'s springs
    (a load path's previous frame's, or the cast's) with the problem's body 2 and load."""
    layer, body2 = problem.layer, problem.body2
    free = np.array([DOFS.index(d) for d in body2.free], dtype=int)
    base = np.zeros(6)
    for dof, value in body2.prescribed.items():
        base[DOFS.index(dof)] = value
    if tracker is not None:
        s = tracker.springs
        return FiniteSystem.of_rows(
            s.points,
            s.normals,
            s.areas,
            tracker.thickness,
            tracker.targets(),
            s.pT,
            s.nT,
            s.arms,
            s.mT,
            s.qm,
            np.asarray(body2.reference, dtype=float),
            free,
            base,
            np.asarray(body2.force, dtype=float),
            np.asarray(body2.moment, dtype=float),
        )
    springs = (layer.points, layer.normals, layer.areas, layer.thickness, targets)
    return FiniteSystem(
        *springs,
        np.asarray(body2.reference, dtype=float),
        free,
        base,
        np.asarray(body2.force, dtype=float),
        np.asarray(body2.moment, dtype=float),
    )


def scaled_directions(system, law) -> tuple[np.ndarray, float, SpringSystem]:
    """``(T, E0, small)``: the scaled directions of :func:`~dea_opt.formulations._parts.scaling.scaling`,
    from the resistance of the springs' small system at zero displacement (held directions left
    out; :func:`~dea_opt.formulations.finite.small_system`: the springs of this solve at body 2's
    base pose, exact gaps), sized by the larger of the load and the overlap of those gaps."""
    small = small_system(system, law)
    T, E0 = scale(small.resistance.basis(law.modulus), small.load, system, law, small.e0)
    return T, E0, small


def plan(method, law, options: dict) -> list[tuple[str, dict, object]]:
    """``[(formulation, its options, x0), ...]`` in the order ``method`` tries them, for finite kinematics.

    ``method`` is ``"auto"`` (the registered formulations that solve finite kinematics for
    ``law``, in order: ``finite``, then ``finite_nlp``), one of them, or ``"newton"``/``"nlp"``
    (which stand for them: :func:`dea_opt.formulations.resolve`). Any other is an :class:`~dea_opt.errors.InputError` from the registry
    (``qp``: a small-kinematics method). Options are checked by the registry; under ``auto``
    each goes to the first formulation that declares it, the re-casting ones to both.
    """
    from ..formulations import check_options, names, resolve, takes
    from ..formulations import options as declared

    options = dict(options)
    x0 = options.pop("x0", None)
    if method != "auto":
        name = resolve(method, law, "finite").check()
        return [(name, check_options(name, options), x0)]
    chain = [n for n in names() if takes(n, law, "finite")][:2]
    parts: dict = {n: {} for n in chain}
    known = {n: {option.name for option in declared(n)} for n in chain}
    for key, value in options.items():
        homes = [n for n in chain if key in known[n]]
        if not homes:
            accepted = sorted(set().union(*known.values()) | {"x0"})
            raise InputError(f"method 'auto' takes the options {accepted}, got unknown option {key!r}")
        for home in homes if key in SHARED else homes[:1]:
            parts[home][key] = value
    return [(n, check_options(n, parts[n]), x0 if i == 0 else None) for i, n in enumerate(chain)]


def remembered(problem):
    """``problem`` with ``targets=`` the :class:`~dea_opt.mesh.SpringCast` its layer is the layer of
    (:func:`~dea_opt.mesh.springs_from_meshes`, ``cast_springs(...).layer``: :attr:`~dea_opt.layer.SpringLayer.cast`)
    where no targets were given: finite kinematics on meshes keep the springs on mesh 2 as body 2
    moves by default, not on the tangent planes of the start's hits. Any other problem as it is."""
    from dataclasses import replace

    cast = getattr(problem.layer, "cast", None)
    if problem.targets is None and isinstance(cast, SpringCast) and cast.layer is problem.layer:
        return replace(problem, targets=cast)
    return problem


def planes_note(problem) -> str:
    """What an answer on the tangent planes of the faces a cast's rays met, not re-cast as body 2
    moved, says of its gaps: exact while each hit stays on its face, measured against mesh 2 at
    the solved pose where the meshes are known (the ``gap_error`` validity check), else not."""
    said = "its springs stayed on the tangent planes of the faces of mesh 2 their rays met at the start, not re-cast"
    if isinstance(problem.targets, SpringCast):
        return f"{said} (recast=False): gap_error measures them against mesh 2 at the solved pose"
    if isinstance(getattr(problem.layer, "cast", None), SpringCast):
        return (
            f"{said} (the layer is part of a cast's springs, not the cast's own: give the whole cast's layer, or "
            f"targets=the SpringCast, to re-cast): gap_error measures them against its meshes at the solved pose"
        )
    return (
        f"{said}: their gaps are approximate once a hit leaves its face, by an amount not measured here (the "
        f"layer knows no meshes: give targets=the SpringCast it was cast by to re-cast, and gap_error)"
    )
