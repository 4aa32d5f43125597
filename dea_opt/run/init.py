"""``dea-opt init``: a commented scenario, written from cartilage meshes, that runs as it stands.

From one or several labelled mesh files per body and a load (a number of newtons, or a load
file for a path), :func:`init_scenario` reads the meshes, sniffs their units, casts the springs
once and decides, saying why in the file's comments:

- the units (``[geometry] scale``), from the meshes' size (a joint's cartilage spans 10-200
  mm), or stops when the size does not say (``--scale``);
- the reference point: ``reference = "contact"``, the contact's centre;
- the free dofs: those the springs resist (:func:`choose_free`);
- the load's direction: pressing body 2 onto body 1 along the contact's mean normal; for a file,
  its sign (negated when it pulls the bodies apart) and, for an OpenSim ``.sto``, which columns
  and which units (:mod:`dea_opt.run.init_load`);
- ``H`` with its source, from :data:`dea_opt.laws.moduli.MODULI`;
- the compartments (the files' labels), the anatomical frame (landmarks or axes given) and the
  outputs.

The file is then read back, its problem built from the springs cast, and the check every run
makes before solving (:func:`dea_opt.run.preflight.check_inputs`) run on it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from .init_load import relative_path as _relative
from .init_load import wrapped as _wrapped

__all__ = ["InitResult", "choose_free", "init_scenario", "parse_part", "sniff_scale"]

#: Sizes (bounding-box diagonals) of a joint's cartilage mesh, in mm, that decide its units.
JOINT_SIZE = (5.0, 500.0)
#: Least stiffness of a free dof's direction, over the stiffest's (:func:`choose_free`).
LEAST_STIFFNESS = 0.2
_DOFS = ("ux", "uy", "uz", "rx", "ry", "rz")


@dataclass
class InitResult:
    """What :func:`init_scenario` wrote: ``path``, its ``text``, the springs cast and the
    ``notes`` (one line per decision) and ``suspicions`` (the check before solving's)."""

    path: Path
    text: str
    springs: int
    notes: list = field(default_factory=list)
    suspicions: list = field(default_factory=list)


def parse_part(values, option: str):
    """``["femur.stl"]`` -> ``"femur.stl"``; ``["medial=med.stl", "lateral=lat.stl"]`` ->
    ``{"medial": "med.stl", "lateral": "lat.stl"}`` (one option given once per labelled file)."""
    values = list(values or [])
    if not values:
        raise InputError(f"{option} needs a mesh file (or LABEL=FILE, once per labelled file)")
    labelled = [v.partition("=") for v in values]
    if len(values) == 1 and not labelled[0][1]:
        return values[0]
    parts = {}
    for text, (label, sep, path) in zip(values, labelled):
        label, path = label.strip(), path.strip()
        if not sep or not label or not path:
            raise InputError(f"{option} {text!r}: give LABEL=FILE for each of several files (e.g. medial=medial.stl)")
        if label in parts:
            raise InputError(f"{option}: the label {label!r} is given twice")
        parts[label] = path
    return parts


def _files(part) -> dict:
    return part if isinstance(part, dict) else {"": part}


def sniff_scale(sizes: dict) -> tuple[float, str]:
    """``(scale, why)``: the factor to millimetres that the meshes' sizes (``{name: diagonal}``,
    file units) say, or an :class:`InputError` saying why they do not."""
    low, high = JOINT_SIZE
    verdicts = {}
    for name, size in sizes.items():
        for factor, units in ((1.0, "millimetres"), (1000.0, "metres"), (0.001, "micrometres")):
            if low <= size * factor <= high:
                verdicts[name] = (factor, units)
    spans = ", ".join(f"{size:.3g} ({name})" for name, size in sizes.items())
    found = set(verdicts.values())
    if len(verdicts) == len(sizes) and len(found) == 1:
        factor, units = found.pop()
        return factor, f"the meshes span {spans} units: {units} (a joint's cartilage spans 10-200 mm)"
    raise InputError(
        f"the meshes' size does not say their units: they span {spans} units, where a joint's cartilage spans "
        f"{low:g}-{high:g} mm (millimetres of a small animal's joint, centimetres, or files in different "
        f"units?); give --scale, the factor to millimetres (1 for mm, 10 for cm, 1000 for m)"
    )


def choose_free(layer, centre) -> tuple[list[str], dict]:
    """The dofs of body 2 the springs resist, and each dof's relative stiffness.

    The layer's stiffness about ``centre`` with every spring in contact, ``K = sum k_i a_i
    a_i^T``, ``a_i = (n_i, (p_i - c) x n_i / L)``, ``k_i = area_i / thickness_i`` (``H``
    cancels), ``L`` the springs' RMS distance from ``c`` (so that a rotation counts as the arc
    length it moves the springs). The translation along the contact's mean normal is free; each
    other dof, stiffest first, joins the free ones when the smallest eigenvalue of ``K`` over
    them stays at least :data:`LEAST_STIFFNESS` of ``K``'s largest diagonal entry: a direction
    the springs hardly resist (sliding along the surface, a ball turning in its socket) stays
    held, and the fixture carries that part of the load.
    """
    points = np.asarray(layer.points, dtype=float) - np.asarray(centre, dtype=float)
    normals = np.asarray(layer.normals, dtype=float)
    k = np.asarray(layer.areas, dtype=float) / np.asarray(layer.thickness, dtype=float)
    arm = float(np.sqrt(k @ np.einsum("ij,ij->i", points, points) / k.sum())) or 1.0
    rows = np.hstack([normals, np.cross(points, normals) / arm])
    K = (rows * k[:, None]).T @ rows
    top = float(K.diagonal().max())
    mean = k @ normals
    first = int(np.argmax(np.abs(mean)))
    rest = sorted((j for j in range(6) if j != first), key=lambda j: (j >= 3, -K[j, j]))
    chosen = [first]
    for j in rest:
        trial = [*chosen, j]
        if np.linalg.eigvalsh(K[np.ix_(trial, trial)]).min() >= LEAST_STIFFNESS * top:
            chosen.append(j)
    stiffness = {_DOFS[j]: float(K[j, j] / top) for j in range(6)}
    return [_DOFS[j] for j in sorted(chosen)], stiffness


def _toml_value(value) -> str:
    if isinstance(value, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_toml_value(v)}" for k, v in value.items()) + " }"
    if isinstance(value, (list, tuple, np.ndarray)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, bool):
        return "true" if value else "false"
    return repr(round(float(value), 6) + 0.0)


def _key(name: str) -> str:
    import re

    return name if re.fullmatch(r"[A-Za-z0-9_-]+", name) else _toml_value(name)


def _vector(vector, digits: int = 4) -> str:
    return "(" + ", ".join(f"{float(v):.{digits}g}" for v in vector) + ")"


def init_scenario(
    body1,
    body2,
    load,
    output,
    *,
    scale: float | None = None,
    material: str | None = None,
    modulus: float | None = None,
    landmarks: dict | None = None,
    axes: dict | None = None,
    side: str | None = None,
    max_gap: float | None = None,
    title: str | None = None,
    sto_prefix: str | None = None,
    force: bool = False,
) -> InitResult:
    """Write a commented scenario for the meshes ``body1`` and ``body2`` under ``load``.

    Parameters
    ----------
    body1, body2 : str or dict {label: str}
        Mesh files of body 1 (held fixed; it carries the springs) and body 2 (loaded), one path
        or a table of labelled paths (the labels become compartments).
    load : float or str
        A force in N pressing body 2 onto body 1 (along the contact's mean normal), or a load
        file: a CSV with ``time, Fx, Fy, Fz[, Mx, My, Mz]`` or an OpenSim ``.sto``/``.mot``.
    output : str or Path
        The scenario file to write (``.toml``).
    scale : float, optional
        The meshes' factor to mm; default: sniffed from their size (:func:`sniff_scale`).
    material : str, optional
        A row of :data:`dea_opt.laws.moduli.MODULI` (default ``knee-cartilage``).
    modulus : float, optional
        ``H`` in MPa, instead of the table's.
    landmarks, axes : dict {direction: (3,)}, optional
        The anatomical frame: three landmarks (points, in the mesh files' units), or two or
        three directions, with ``side``.
    max_gap : float, optional
        The proximity window's largest gap (mm; default :data:`dea_opt.mesh.springs.MAX_GAP`).
    title : str, optional
    sto_prefix : str, optional
        For a ``.sto`` with several joints' columns: the prefix of the one to read.
    force : bool
        Overwrite ``output``.

    Raises
    ------
    InputError
        A missing file, units the meshes' size does not say, no springs between the meshes, a
        load file whose columns do not say which is the force, an existing ``output``.
    """
    from ..laws.moduli import DEFAULT_MATERIAL
    from ..laws.moduli import modulus as table_row
    from ..mesh import load_mesh
    from ..mesh.springs import MAX_GAP
    from .init_load import describe_load

    output = Path(output).expanduser().resolve()
    if output.exists() and not force:
        raise InputError(f"{output} exists: choose another file (-o) or pass --force to replace it")
    if output.suffix.lower() != ".toml":
        raise InputError(f"-o must name a .toml file, got {output.name}")
    folder = output.parent
    if not folder.is_dir():
        raise InputError(f"-o: the folder {folder} does not exist")
    from ..progress import stage

    parts = {"body1": body1, "body2": body2}
    stage("reading meshes")
    sizes = {}
    for option, part in parts.items():
        for label, path in _files(part).items():
            name = f"--{option} {label + '=' if label else ''}{path}"
            if not Path(path).expanduser().is_file():
                raise InputError(f"{name}: file not found: {Path(path).expanduser().resolve()}")
            sizes[Path(path).name] = float(np.linalg.norm(load_mesh(Path(path).expanduser()).extents))
    notes = []
    if scale is None:
        scale, why = sniff_scale(sizes)
    else:
        why = f"given (--scale): the meshes span {', '.join(f'{s * scale:.3g} mm' for s in sizes.values())}"
    notes.append(f"units: {why}; scale = {scale:g}")
    row = table_row(material or DEFAULT_MATERIAL)
    H = float(modulus) if modulus is not None else float(row.H)
    max_gap = MAX_GAP if max_gap is None else float(max_gap)
    files = {option: _written(part, folder) for option, part in parts.items()}
    anatomy = _anatomy(landmarks, axes, side, scale)
    probe = _text(files, scale, max_gap, H, row, modulus, ["uz"], None, anatomy, output, title, None)
    scenario, layer, problem = _cast(probe, output)
    from .contact_shape import ContactShape

    shape = ContactShape.of(layer)
    free, stiffness = choose_free(layer, shape.centre)
    loaded = describe_load(load, shape, folder, sto_prefix)
    notes += loaded.notes
    text = _text(
        files, scale, max_gap, H, row, modulus, free, (shape, stiffness, len(layer)), anatomy, output, title, loaded
    )
    suspicions = _check(text, output, layer)
    from ..files.atomic import write_data

    write_data(output, text)
    notes.append(
        f"{len(layer)} springs cast; reference: the contact's centre {_vector(shape.centre)} mm; free: {', '.join(free)}"
    )
    notes.append(f"H = {H:g} MPa ({'given (--modulus)' if modulus is not None else row.material + ', ' + row.key})")
    return InitResult(output, text, len(layer), notes, suspicions)


def _written(part, folder: Path):
    if isinstance(part, dict):
        return {label: _relative(path, folder) for label, path in part.items()}
    return _relative(part, folder)


def _anatomy(landmarks, axes, side, scale: float):
    if not landmarks and not axes:
        return None
    from ..anatomy import AnatomicalFrame

    if landmarks and axes:
        raise InputError("give --landmark or --axis, not both")
    spec: dict = {"side": side} if side else {}
    if landmarks:
        spec["landmarks"] = {name: [float(c) * scale for c in point] for name, point in landmarks.items()}
    else:
        spec.update({name: [float(c) for c in vector] for name, vector in axes.items()})
    try:
        AnatomicalFrame.from_dict(spec)
    except InputError as exc:
        raise InputError(f"--landmark/--axis/--side: {exc}") from None
    return spec


def _cast(text: str, output: Path):
    """The scenario of ``text`` read, its springs cast and its problem built."""
    from ..progress import stage
    from ..scenario.build import build_problem_cast
    from ..scenario.parse import parse_scenario

    scenario = parse_scenario(text, name=output.name, base_dir=output.parent)
    stage("casting springs")
    problem, cast = build_problem_cast(scenario)
    if not len(problem.layer):
        raise InputError("no springs between the meshes: no face of body 1 faces body 2 within the window")
    return scenario, problem.layer, problem


def _check(text: str, output: Path, layer) -> list:
    """Read ``text`` back, build its problem on the springs cast and make the check every run
    makes before solving; its suspicions."""
    from ..scenario.build import build_problem
    from ..scenario.load_path import read_load_path
    from ..scenario.parse import parse_scenario
    from .preflight import check_inputs

    scenario = parse_scenario(text, name=output.name, base_dir=output.parent)
    problem = build_problem(scenario, layer=layer)
    data = None if scenario.load_path is None else read_load_path(scenario.load_path)
    return check_inputs(scenario, problem, data)


def _text(files, scale, max_gap, H, row, modulus, free, found, anatomy, output, title, loaded) -> str:
    """The scenario's TOML with its comments (``found``: ``(shape, stiffness, springs)`` once
    the springs are cast; ``loaded``: the load's section, None for the first, uncommented cast)."""
    from .._version import __version__

    labels = [label for part in files.values() if isinstance(part, dict) for label in part]
    name = title or f"{output.stem}: " + (", ".join(labels) if labels else "two bodies")
    if loaded is not None:
        name = title or f"{name}, {loaded.title}"
    lines = [
        f"# {output.name}: written by `dea-opt init` (dea-opt {__version__}); it runs as it stands:",
        f"#   dea-opt run {output.name}",
        "# Each choice below says why, and what to change (`dea-opt schema` lists every key).",
        "# Units: mm, N, N mm, MPa, s; paths are relative to this file.",
        f"title = {_toml_value(name)}",
        "",
        "[geometry]",
        'kind = "meshes"',
        "# Body 1 (held fixed) carries the springs, one per face of its cartilage facing body 2;",
        "# body 2 is the one the load moves. Labelled files become the compartments every output",
        "# reports.",
        f"mesh1 = {_toml_value(files['body1'])}",
        f"mesh2 = {_toml_value(files['body2'])}",
        "# The factor from the files' units to millimetres.",
        f"scale = {_toml_value(scale)}",
        "# The proximity window: a spring stands where body 2's surface lies at most max_gap (mm)",
        "# ahead of body 1's" + (f"; {found[2]} springs with this window." if found else "."),
        f"max_gap = {_toml_value(max_gap)}",
        "",
        "[law]",
        "# A linear spring, stress = H x strain, valid up to 30 % strain (the validity report checks;",
        '# kind = "ateshian" with beta = 0.3 holds further). H (MPa) and where it comes from:',
    ]
    if modulus is not None:
        lines.append("#   given on the command line (--modulus).")
    else:
        lines += [
            *_wrapped(f"{row.material} (dea-opt init --material {row.key}): {row.advice}.", "#   "),
            *_wrapped(f"Source: {row.source}; it gives {row.gives}.", "#   "),
            "#   Other rows: dea-opt init --help, or the tutorial 'Your own joint', 'Which modulus'.",
        ]
    lines += ['kind = "linear"', f"H = {_toml_value(H)}", "", "[body2]"]
    if found:
        shape, stiffness, _ = found
        held = [d for d in _DOFS if d not in free]
        lines += [
            "# Rotations and moments are about the contact's centre: the area-weighted centroid of the",
            f"# springs as cast, here {_vector(shape.centre)} mm.",
            'reference = "contact"',
            *_wrapped(
                f"Free: the dofs the springs resist, each at least {LEAST_STIFFNESS:.0%} as stiffly as the "
                "stiffest (relative stiffness about the contact's centre, rotations over the springs' RMS "
                "distance from it: " + ", ".join(f"{d} {stiffness[d]:.2f}" for d in _DOFS) + "). Held: "
                f"{', '.join(held) or 'none'} (the fixture carries the load along them).",
                "# ",
            ),
        ]
    else:
        lines.append('reference = "contact"')
    lines.append(f"free = {_toml_value(free)}")
    lines.append("")
    lines += loaded.lines if loaded is not None else ["[load]", "force = [0.0, 0.0, -1.0]"]
    lines += ["", "[output]", f"directory = {_toml_value(output.stem + '-results')}"]
    if loaded is not None:
        lines += _wrapped(f"Writes {loaded.outputs}, then manifest.json.", "# ")
    if anatomy is not None:
        lines.append("# The anatomical frame of the maps and centres of pressure (given to dea-opt init):")
        lines.append(f"anatomy = {_toml_value(anatomy)}")
    else:
        lines += [
            "# The maps in the joint's anatomical frame: give it from three landmarks (mm) or two",
            "# directions, with the side, e.g.",
            '# anatomy = { landmarks = { medial = [...], lateral = [...], proximal = [...] }, side = "right" }',
            '# anatomy = { medial = [1.0, 0.0, 0.0], proximal = [0.0, 0.0, 1.0], side = "right" }',
        ]
    return "\n".join(lines) + "\n"
