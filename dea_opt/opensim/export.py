"""An OpenSim model as a dea-opt scenario: the ``[[bodies]]``, ``[[frames]]``, ``[[contacts]]`` and
``[[ligaments]]`` of the multi-body joint, and what is not modelled as comments (``dea-opt
import-osim``). ``dea-opt run`` takes it as written.

Everything is written in OpenSim's ground frame at the model's default coordinates (the start
pose), in mm, N, MPa, as the joint takes it (its ligament points are global points at the start
pose). The keys, one table per element:

``[[bodies]]``
    ``name``; ``reference`` (mm): the body's origin at the start pose; ``free``: the free dofs
    (written ``[]``: held; choose them); ``pose`` (4x4, mm): the body's frame in ground at the
    start pose (the axes of a load in its frame); for a body jointed to a body held in place
    (``--fixed``), ``[bodies.coordinates]``: that joint's coordinates as the body's dofs
    (:func:`~dea_opt.opensim.joints.joint_coordinates`).
``[[frames]]``
    ``name``, ``body`` and ``pose`` (4x4 in ground at the start pose) of each offset frame of the
    bodies written: the frames a load path's poses relate.
``[[contacts]]``
    ``name``; ``body1``/``body2``: the casting mesh's body (mesh 1 carries the springs) and the
    target's; ``[contacts.geometry]``: ``kind = "meshes"``, ``mesh1``/``mesh2`` (the files,
    relative to the scenario), ``scale1``/``scale2`` (their factors to mm), ``pose1``/``pose2``
    (4x4: each mesh's frame in ground at the start pose), ``thickness1``/``thickness2`` (mm),
    ``max_gap``/``max_overlap`` (mm: JAM's proximity window as gaps); ``[contacts.law]``: ``kind``
    and ``H`` (MPa) for springs of thickness ``thickness1 + thickness2``.
``[[ligaments]]``
    ``name``; ``body1``/``point1``, ``body2``/``point2`` (mm, global at the start pose): the first
    and last path points; ``stiffness`` (N per unit strain); ``slack_length`` (mm); ``law``
    ("blankevoort"); ``transition_strain``.
``[solve]``
    ``kinematics = "finite"``: the model's motions are finite, its contacts cast from meshes.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from .._version import __version__
from ..errors import OpenSimModelError
from ..files.atomic import write_atomic

__all__ = ["scenario_text", "write_scenario"]


def _num(x: float) -> str:
    value = float(x)
    if not np.isfinite(value):
        raise OpenSimModelError(f"a value to write is not finite: {value}")
    return repr(0.0 if value == 0.0 else value)


def _vec(values) -> str:
    return "[" + ", ".join(_num(v) for v in values) + "]"


def _matrix(T, indent: str) -> str:
    rows = [_vec(row) for row in np.asarray(T)]
    return "[\n" + "".join(f"{indent}  {r},\n" for r in rows) + f"{indent}]"


def _str(text: str) -> str:
    return json.dumps(str(text), ensure_ascii=False)  # a JSON string is a TOML basic string


def _comment(text: str) -> str:
    return "# " + " ".join(str(text).split())


def _mesh_file(mesh, override, folder: Path) -> tuple:
    """``(path text, scale, note)`` of a contact mesh for the scenario in ``folder``."""
    if override is not None:
        target, scale, note = Path(override).resolve(), 1.0, "given on the command line, taken in mm"
    elif mesh.resolved is not None:
        target, scale, note = Path(mesh.resolved).resolve(), None, ""
    else:
        searched = ", ".join(str(p) for p in mesh.searched) or "nowhere (the name leaves the model's folders)"
        return mesh.file, None, f"NOT FOUND: {mesh.file!r} was looked for in {searched}"
    try:
        text = os.path.relpath(target, folder.resolve())
    except ValueError:  # another drive
        text = str(target)
    return text.replace(os.sep, "/"), scale, note


def scenario_text(
    model, output: Path | None = None, meshes: dict | None = None, fixed=(), leave_out=(), free=None, regions=None
) -> str:
    """The scenario file of ``model`` (TOML text), its paths relative to ``output``'s folder.

    ``meshes`` maps a contact mesh's name to a file to use in its place (in mm), for models
    whose mesh files were renamed or converted. ``fixed`` names bodies held in place: each body
    on the other side of a CustomJoint from one of them gets that joint's coordinates as its dofs.
    ``leave_out`` names bodies left out with every contact pair and bundle that touches them
    (listed in the scenario's comments). ``free`` (``{body: dofs}``, a list or ``"all"``) writes
    those bodies' free dofs (default: none, every body held); ``regions`` (``{pair: {split, at,
    names}}``) a contact pair's ``[contacts.regions]``, cut in its casting mesh's own frame.
    """
    free, regions = dict(free or {}), dict(regions or {})
    from .joints import joint_coordinates, movable_joints

    folder = (output.parent if output is not None else Path.cwd()).resolve()
    meshes = dict(meshes or {})
    unknown = sorted(set(meshes) - set(model.contact_meshes))
    if unknown:
        raise OpenSimModelError(
            f"{model.path}: has no contact mesh {', '.join(unknown)} (its meshes: "
            f"{', '.join(model.contact_meshes) or 'none'})"
        )
    missing = sorted((set(fixed) | set(leave_out)) - set(model.bodies))
    if missing:
        raise OpenSimModelError(
            f"{model.path}: has no body {', '.join(missing)} (--fixed and --leave-out name bodies of the model)"
        )
    both = sorted(set(fixed) & set(leave_out))
    if both:
        raise OpenSimModelError(f"{', '.join(both)}: a body cannot be both fixed and left out")
    out_set = set(leave_out)
    pairs = [p for p in model.contact_pairs.values() if not {p.casting.body, p.target.body} & out_set]
    ligaments = [lig for lig in model.ligaments.values() if not {p.body for p in lig.points} & out_set]
    dropped = [p.name for p in model.contact_pairs.values() if p not in pairs]
    dropped += [lig.name for lig in model.ligaments.values() if lig not in ligaments]
    used = {p.body for lig in ligaments for p in lig.points}
    used |= {m.body for pair in pairs for m in (pair.casting, pair.target)}
    used.discard("ground")
    values = model.default_coordinates()
    poses = {"ground": np.eye(4), **model.poses(bodies=sorted(used | set(fixed)))}
    moving = {b: j for b, j in movable_joints(model, fixed).items() if b in used}
    out = [
        f"# dea-opt scenario written by `dea-opt import-osim` (dea-opt {__version__}) from {model.path.name}",
        f"# (OpenSim model {model.name!r}). Frame: OpenSim's ground at the model's default coordinates (the",
        "# start pose); mm, N, MPa. [[bodies]], [[frames]], [[contacts]] and [[ligaments]] are the multi-body",
        "# joint's tables; choose each body's free dofs and add the loads or the motion ([load_path]).",
        "# Default coordinates (rad, m): "
        + ", ".join(
            f"{n} = {_num(values[n])}" for n, c in model.coordinates.items() if c.joint in _joints(model, used)
        ),
        "",
        f"title = {_str(f'{model.name}: imported from {model.path.name}')}",
        "",
    ]
    if leave_out:
        out += [
            _comment(
                f"Left out (--leave-out {' '.join(leave_out)}): those bodies, the contact pairs and the "
                f"{len(dropped) - (len(model.contact_pairs) - len(pairs))} bundles that touch them: "
                + ", ".join(dropped)
            ),
            "",
        ]
    out += [
        "[solve]",
        'kinematics = "finite"',
        "",
    ]
    for body in model.bodies:
        if body not in used:
            continue
        T = poses[body]
        out += [
            "[[bodies]]",
            f"name = {_str(body)}",
            f"reference = {_vec(T[:3, 3])}",
            f"free = {_free(free.get(body, []))}" + ("  # held in place (--fixed)" if body in fixed else ""),
            f"pose = {_matrix(T, '')}",
            "",
        ]
        if body in moving:
            out += _coordinates(joint_coordinates(model, moving[body], body), moving[body])
    offsets = {path: f for path, f in model.frames.items() if f.kind == "offset" and f.body in used}
    count: dict = {}
    for frame in offsets.values():
        count[frame.name] = count.get(frame.name, 0) + 1
    for path, frame in offsets.items():
        if True:
            out += [
                "[[frames]]",
                f"name = {_str(frame.name if count[frame.name] == 1 else path)}",
                f"body = {_str(frame.body)}",
                f"pose = {_matrix(poses[frame.body] @ model.frame_in_body(path), '')}",
                "",
            ]
    for pair in pairs:
        out += _contact(model, pair, poses, meshes, folder)
        if pair.name in regions:
            r = regions[pair.name]
            out += ["[contacts.regions]", _comment(f"cut across {pair.casting.name}'s own axis {r['split']}")]
            out += [f"split = {_str(r['split'])}", f"at = {_num(r.get('at', 0.0))}"]
            out += [f"names = [{', '.join(_str(n) for n in r.get('names', ('medial', 'lateral')))}]", ""]
    for lig in ligaments:
        out += _ligament(model, lig, poses)
    out.append(f"# ---- not modelled ({len(model.not_modelled)}): dea-opt does not model these parts of the model ----")
    out += [_comment(item.describe()) for item in model.not_modelled]
    return "\n".join(out) + "\n"


def _free(dofs) -> str:
    if isinstance(dofs, str):
        return _str(dofs)
    return "[" + ", ".join(_str(d) for d in dofs) + "]"


def _coordinates(c, joint: str) -> list:
    """A body's ``[bodies.coordinates]`` table."""
    side = "the joint's parent, moving on its child" if c.inverted else "the joint's child"
    return [
        "[bodies.coordinates]",
        _comment(
            f"{joint}'s coordinates as this body's dofs ({side}): ux, uy, uz its translations (mm), rx, ry, rz "
            f"its rotations (rad), in this order:"
        ),
        f"names = [{', '.join(_str(n) for n in c.names)}]",
        f"joint = {_str(joint)}",
        f"frame = {_matrix(c.frame, '')}",
        f"rotation_axes = {_matrix(c.rotation_axes, '')}",
        f"translation_axes = {_matrix(c.translation_axes, '')}",
        f"start = {_vec(c.start)}",
        f"slopes = {_vec(c.slopes)}",
        f"intercepts = {_vec(c.intercepts)}",
        f"inverted = {'true' if c.inverted else 'false'}",
        "",
    ]


def _joints(model, bodies: set) -> set:
    """The joints on the way from ground to ``bodies``."""
    by_child = {j.child_body: j for j in model.joints.values()}
    found: set = set()
    for body in bodies:
        seen = set()
        while body in by_child and body not in seen:
            seen.add(body)
            found.add(by_child[body].name)
            body = by_child[body].parent_body
    return found


def _contact(model, pair, poses: dict, meshes: dict, folder: Path) -> list:
    lines = []
    try:
        law = pair.law()
    except OpenSimModelError as exc:
        return [_comment(f"contact {pair.name} is left out: {exc}"), ""]
    lines.append("[[contacts]]")
    lines.append(f"name = {_str(pair.name)}")
    lines.append(f"body1 = {_str(pair.casting.body)}")
    lines.append(f"body2 = {_str(pair.target.body)}")
    lines.append("")
    lines.append("[contacts.geometry]")
    lines.append('kind = "meshes"')
    for k, mesh in ((1, pair.casting), (2, pair.target)):
        text, scale, note = _mesh_file(mesh, meshes.get(mesh.name), folder)
        if note:
            lines.append(_comment(f"mesh{k} ({mesh.name}): {note}"))
        if scale is None:
            if np.ptp(mesh.scale) != 0.0:
                raise OpenSimModelError(
                    f"contact mesh {mesh.name} (line {mesh.line}) has unequal scale factors {mesh.scale / 1000.0}: "
                    f"dea-opt scales a mesh file by one factor"
                )
            scale = float(mesh.scale[0])
        lines.append(f"mesh{k} = {_str(text)}")
        lines.append(f"scale{k} = {_num(scale)}")
        lines.append(f"pose{k} = {_matrix(poses[mesh.body] @ model.frame_in_body(mesh.frame), '')}")
        lines.append(f"thickness{k} = {_num(mesh.thickness)}")
    max_gap, max_overlap = pair.window
    lines.append(_comment(f"JAM's depth window [{pair.min_proximity}, {pair.max_proximity}] mm as gaps"))
    lines.append(f"max_gap = {_num(max(max_gap, 0.0))}")
    lines.append(f"max_overlap = {_num(max_overlap)}")
    lines.append("")
    kind = "linear" if pair.formulation == "linear" else "blankevoort"
    lumped = "lumped (E, nu averaged, h added)" if pair.lumped else "two layers in series"
    lines.append("[contacts.law]")
    lines.append(
        _comment(
            f"{pair.formulation} elastic foundation, {lumped}: H = {pair.modulus:.6g} MPa over h = "
            f"{pair.thickness:.6g} mm"
        )
    )
    lines.append(f"kind = {_str(kind)}")
    lines.append(f"H = {_num(law.H)}")
    lines.append("")
    return lines


def _ligament(model, lig, poses: dict) -> list:
    first, last = lig.points[0], lig.points[-1]
    ends = []
    for point in (first, last):
        T = poses[point.body] @ model.frame_in_body(point.frame)
        ends.append(T[:3, :3] @ point.location + T[:3, 3])
    lines = ["[[ligaments]]", f"name = {_str(lig.name)}"]
    for k, (point, x) in enumerate(zip((first, last), ends), start=1):
        lines.append(_comment(f"{point.name}: {_vec(point.location)} mm in {point.frame}"))
        lines.append(f"body{k} = {_str(point.body)}")
        lines.append(f"point{k} = {_vec(x)}")
    if lig.wraps or len(lig.points) > 2:
        lines.append(_comment("straight line from the first to the last path point: see 'not modelled' below"))
    lines += [
        f"stiffness = {_num(lig.stiffness)}",
        f"slack_length = {_num(lig.slack_length)}",
        'law = "blankevoort"',
        f"transition_strain = {_num(lig.transition_strain)}",
        "",
    ]
    return lines


def write_scenario(model, output, meshes: dict | None = None, fixed=(), leave_out=(), free=None, regions=None) -> Path:
    """Write :func:`scenario_text` to ``output`` atomically; return its path."""
    output = Path(output)
    text = scenario_text(model, output, meshes, fixed, leave_out, free, regions)
    return write_atomic(output, lambda tmp: Path(tmp).write_text(text, encoding="utf-8"), argument="output")
