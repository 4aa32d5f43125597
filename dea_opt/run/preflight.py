"""The implausibility check a run makes before it solves: units, the reference point, the load.

A wrong unit or sign still solves, or fails frame after frame, and the validity report then
names the consequences (seven failed checks for meshes in metres); this check names the cause
first, with the scenario key to change, before any time is spent solving. It stops (a
:class:`~dea_opt.errors.DeaError`, exit 2 at the command line) what cannot be meant:

- meshes (or a springs table) whose size says metres or micrometres:
  ``[geometry] scale = 1000``;
- a body free to turn about a reference point left at the origin, farther from the contact's
  centre than the layer's radius: ``[body2] reference = "contact"``;
- a load (every loaded frame of a path) that pulls the bodies apart
  (:class:`~dea_opt.errors.LoadNotSupportedError` when no spring could carry it, proven by
  :func:`~dea_opt.run.contact_shape.pulls_apart_proven`), that lies along the contact's
  surface (a force in the wrong column), or whose moments need a lever arm of a hundred layer
  radii (moments in N mm read as N m: ``[load_path] units = "mm"``).

What is plausible but suspicious is solved, and said first (``dea-opt: warning: suspicious
input: ...``, the first line of the verdict, ``suspicious_input`` in the JSON summary): a
modulus outside every material's (``H`` in kPa), a load that is a thousandth of what a contact
of this size carries (kN), a path without moments while a rotation is free. These values are
right for some studies (a polyethylene insert, a rat's knee), so they do not stop a run.
``[solve] check_inputs = false`` turns the whole check off. The guide's
:doc:`/guide/errors` page lists every message.
"""

from __future__ import annotations

import numpy as np

from ..errors import ImplausibleInputError, LoadNotSupportedError
from ..laws.moduli import MODULI
from .contact_shape import MOMENT_ARMS, ContactShape, frame_causes, moment_arms, vector_text
from .diagnose import LoadSource, cause_text, who_text

__all__ = ["MODULUS_RANGE", "check_inputs", "check_meshes", "loaded_frames"]

#: Sizes (mm) of a joint's cartilage mesh that are taken as millimetres: below, metres; above,
#: micrometres (the validity's ``extent`` limits).
MESH_SIZE = (1.0, 1000.0)
#: Moduli (MPa) taken as plausible: from a tenth of the smallest of dea-opt's table of moduli
#: (:data:`dea_opt.laws.moduli.MODULI`) to twice its largest; outside, a unit slip.
MODULUS_RANGE = (min(row.H for row in MODULI) / 10.0, max(row.H for row in MODULI) * 2.0)
#: A load's largest force over the springs' area (MPa) below which it looks like kN.
LEAST_MEAN_PRESSURE = 0.01


def check_meshes(scenario, meshes: dict) -> None:
    """Stop meshes whose size says they are not in millimetres (before any spring is cast)."""
    if not scenario.solve.check_inputs:
        return
    section = scenario.geometry
    sizes = {}
    for k in (1, 2):
        mesh = meshes.get(f"mesh{k}")
        if mesh is not None and len(mesh.vertices):
            sizes[f"mesh{k}"] = float(np.linalg.norm(mesh.extents))
    if not sizes:
        return
    largest = max(sizes.values())
    factor = _thousands(largest)
    if factor == 1.0:
        return
    spans = " and ".join(f"{size:.3g} mm ({name})" for name, size in sizes.items())
    given = f"with [geometry] scale = {section.scale:g} " if section.scale != 1.0 else ""
    units = "metres" if factor > 1 else "micrometres"
    raise ImplausibleInputError(
        f"the meshes look like {units}, not millimetres: {given}they span {spans}, where a joint's cartilage "
        f"spans 10-200 mm; set [geometry] scale = {section.scale * factor:g} (dea-opt works in mm; "
        f"[solve] check_inputs = false solves them as they are)",
        key="geometry.scale",
    )


def _thousands(size: float) -> float:
    """The power of 1000 that brings ``size`` (mm) inside :data:`MESH_SIZE` (1 when inside)."""
    low, high = MESH_SIZE
    factor = 1.0
    while size * factor < low and factor < 1e9:
        factor *= 1000.0
    while size * factor > high and factor > 1e-9:
        factor /= 1000.0
    return factor


def check_inputs(scenario, problem, data=None) -> list[str]:
    """Stop what cannot be meant, and return the suspicions (one line each, cause and fix).

    Parameters
    ----------
    scenario : Scenario
    problem : ContactProblem
        As built from ``scenario`` (its springs, bodies and, for ``[load]``, its load).
    data : LoadPathData, optional
        The frames of ``[load_path]``.

    Raises
    ------
    ImplausibleInputError
        Springs in metres, a reference left at a far origin, every loaded frame along the
        surface or pulling apart, moments a thousand times too large.
    LoadNotSupportedError
        Every loaded frame pulls the bodies apart where no spring could carry it.
    """
    if not scenario.solve.check_inputs or not len(problem.layer):
        return []
    shape = ContactShape.of(problem.layer)
    _check_springs_size(scenario, shape)
    _check_references(scenario, problem, shape)
    source = LoadSource.of(scenario)
    loads = _frames(scenario, problem, data)
    suspicions = []
    if loads is not None:
        _check_loads(problem, shape, source, *loads)
        suspicions += _load_size(shape, source, loads[0])
        suspicions += _missing_moments(scenario, problem, source, data)
    suspicions += _modulus(scenario)
    suspicions += _far_references(scenario, problem, shape)
    return suspicions


def _check_springs_size(scenario, shape: ContactShape) -> None:
    if scenario.geometry.kind != "springs":
        return
    factor = _thousands(2.0 * shape.radius)
    if factor != 1.0:
        units = "metres" if factor > 1 else "micrometres"
        raise ImplausibleInputError(
            f"the springs of {scenario.geometry.file} look like {units}, not millimetres: they span "
            f"{2 * shape.radius:.3g} mm where a joint's layer spans 10-200 mm; write the table in mm (x, y, z, "
            f"thickness, gap times {factor:g}, area times {factor**2:g})",
            key="geometry.file",
        )


def _rotating(body) -> list[str]:
    return [dof for dof in ("rx", "ry", "rz") if dof in set(body.free)]


def _check_references(scenario, problem, shape: ContactShape) -> None:
    """A body free to turn whose reference was left at the origin, far from the contact."""
    if scenario.geometry.kind not in ("meshes", "springs"):
        return  # a generator brings its bodies' reference points (a sphere's centre, a ball's)
    for k in (1, 2):
        section, body = getattr(scenario, f"body{k}"), getattr(problem, f"body{k}")
        turns = _rotating(body)
        if section.reference is not None or not turns or not shape.far(body.reference):
            continue
        raise ImplausibleInputError(
            f"[body{k}] reference is not set, so body {k} turns (free {', '.join(turns)}) about the origin "
            f"(0, 0, 0) mm, {shape.distance(body.reference):.3g} mm from the contact's centre "
            f"{vector_text(shape.centre)} mm, beyond the layer's radius ({shape.radius:.3g} mm), and a force "
            f'without a point acts there; set [body{k}] reference = "contact" (the contact\'s centre) or the point '
            f"your load acts at (mm)",
            key=f"body{k}.reference",
        )


def _far_references(scenario, problem, shape: ContactShape) -> list[str]:
    if scenario.geometry.kind not in ("meshes", "springs"):
        return []
    lines = []
    for k in (1, 2):
        section, body = getattr(scenario, f"body{k}"), getattr(problem, f"body{k}")
        if section.reference is None or section.reference == "contact" or not _rotating(body):
            continue
        if shape.far(body.reference):
            lines.append(
                f"[body{k}] reference {vector_text(body.reference)} mm is {shape.distance(body.reference):.3g} mm "
                f"from the contact's centre {vector_text(shape.centre)} mm, beyond the layer's radius "
                f"({shape.radius:.3g} mm): body {k} turns about it and a force without a point acts there; "
                f'is it the point you meant? (reference = "contact" takes the contact\'s centre)'
            )
    return lines


def _frames(scenario, problem, data):
    """``(forces (T, 3), moments (T, 3), point, body)`` of the load or the path, or None."""
    if data is not None:
        loads = np.asarray(data.loads, dtype=float)
        return loads[:, :3], loads[:, 3:], data.point, data.body
    section = scenario.load
    if section is None:
        return None
    force = np.multiply(section.force, section.scale)[None, :]
    moment = np.multiply(section.moment, section.scale)[None, :]
    return force, moment, section.point, section.body


def loaded_frames(forces) -> np.ndarray:
    """The frames whose force is at least 5 % of the largest (a swing phase's near-zero forces
    say nothing about the load's direction or units)."""
    sizes = np.linalg.norm(forces, axis=1)
    top = float(sizes.max(initial=0.0))
    return np.flatnonzero((sizes > 0.0) & (sizes >= 0.05 * top))


def _check_loads(problem, shape, source, forces, moments, point, body) -> None:
    """Stop a load (every loaded frame of a path) that pulls apart or lies along the surface,
    or whose moments need a hundred layer radii of lever arm on the typical loaded frame."""
    frames = loaded_frames(forces)
    if not len(frames):
        return
    arms = moment_arms(shape, problem, forces[frames], moments[frames], point, body)
    arm = float(np.median(arms))
    who = who_text(source, len(frames), len(forces))
    if arm > MOMENT_ARMS * shape.radius:
        text = cause_text("moment_units", source, shape, forces[frames], who, body, arm)
        raise ImplausibleInputError(
            text + "; [solve] check_inputs = false solves it as it is", key=source.key("moment_units")
        )
    causes = set(frame_causes(shape, problem, forces[frames], moments[frames], point, body))
    if causes <= {"pulls_apart", "pulls_apart_proven"}:
        first = "pulls_apart_proven" if causes == {"pulls_apart_proven"} else "pulls_apart"
    elif causes == {"along_surface"}:
        first = "along_surface"
    else:
        return
    text = cause_text(first, source, shape, forces[frames], who, body, arm)
    if first == "pulls_apart_proven" and getattr(problem, "kinematics", "small") != "finite":
        raise LoadNotSupportedError(
            text + "; compression-only springs cannot carry it (proven before solving: no spring's normal points "
            "against it)"
        )
    raise ImplausibleInputError(text + "; [solve] check_inputs = false solves it as it is", key=source.key(first))


def _load_size(shape, source, forces) -> list[str]:
    top = float(np.linalg.norm(forces, axis=1).max(initial=0.0))
    if top == 0.0 or top / shape.area >= LEAST_MEAN_PRESSURE:
        return []
    return [
        f"the load looks a thousand times too small: its largest force, {top:.3g} N, spread over the "
        f"{shape.area:.4g} mm^2 of springs is {top / shape.area:.2g} MPa, where a joint's contact carries 0.1-10 "
        f"MPa on average; if it is in kN, set {source.table} scale = 1000 (forces are in N)"
    ]


def _missing_moments(scenario, problem, source, data) -> list[str]:
    """A path without moments while the loaded body may turn (or a .sto whose moment columns are
    left unread)."""
    if data is None:
        return []
    body = problem.body1 if data.body == 1 else problem.body2
    turns = _rotating(body)
    if not turns or np.asarray(data.loads, dtype=float)[:, 3:].any():
        return []
    unread = source.unread_moments()
    if unread:
        return [
            f"{source.name} has moment columns ({', '.join(unread)}) that [load_path] columns does not name, "
            f'so every moment is 0 while {", ".join(turns)} is free; name them: columns = {{Mx = "...", '
            f'My = "...", Mz = "..."}}'
        ]
    return [
        f"{source.name} gives no moments (no Mx, My, Mz), so every frame's force acts at body {data.body}'s "
        f"reference point {vector_text(body.reference)} mm with no moment about it while {', '.join(turns)} is "
        f"free; if your loads have moments, add them ({source.moment_fix()})"
    ]


def _modulus(scenario) -> list[str]:
    modulus = scenario.law.parameters.get("H")
    if not isinstance(modulus, (int, float)):
        return []
    low, high = MODULUS_RANGE
    if low <= modulus <= high:
        return []
    guess = "kPa" if modulus > high else "GPa"
    meant = modulus / 1000.0 if modulus > high else modulus * 1000.0
    least, most = min(MODULI, key=lambda row: row.H), max(MODULI, key=lambda row: row.H)
    return [
        f"[law] H = {modulus:g} MPa is far outside dea-opt's table of moduli ({least.H:g} MPa for {least.material} "
        f"to {most.H:g} MPa for {most.material}; the tutorial's 'Which modulus'): if you gave {guess}, write "
        f"H = {meant:g} (moduli are in MPa)"
    ]
