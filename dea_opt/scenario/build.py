"""Building what a scenario describes: the law, the springs (from generators, tables or meshes), the bodies and the problem.

Optional parts (geometry generators, meshes, the problem classes) are imported where they
are used, so that reading and validating a scenario stays light.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from ..errors import DeaError, ScenarioError
from ..io.tables import read_springs
from .schema import (
    BodySection,
    GeneratorGeometry,
    LawSection,
    MeshGeometry,
    PlateGeometry,
    Scenario,
    SocketGeometry,
    SphereOnBedGeometry,
    SpringsGeometry,
)

__all__ = [
    "apply_regions",
    "build_geometry",
    "build_geometry_cast",
    "build_law",
    "build_layer",
    "build_problem",
    "build_problem_cast",
    "cast_from_mesh_section",
    "check_kinematics_method",
    "contact_centre",
    "key_origin",
    "load_meshes",
    "pose_builder",
    "pose_caster",
    "springs_from_mesh_section",
]


def build_law(section: LawSection):
    """The :class:`~dea_opt.laws.Law` of ``[law]``, made by the registry :data:`~dea_opt.laws.LAWS`."""
    from ..errors import InputError
    from ..laws import LAWS

    try:
        return LAWS.build(section.kind, section.parameters, prefix="law.")
    except InputError as exc:
        raise ScenarioError(f"[law]: {exc}") from None


def build_layer(section, pose=None):
    """The :class:`~dea_opt.layer.SpringLayer` of ``[geometry]`` (mesh 2 moved by ``pose``)."""
    from .. import geometry

    if isinstance(section, PlateGeometry):
        return geometry.plate_layer(section.length, section.width, section.nx, section.ny, section.thickness)
    if isinstance(section, SphereOnBedGeometry):
        return geometry.sphere_on_bed_layer(
            section.radius, section.thickness, section.extent, section.n_rings, section.n_sectors
        )
    if isinstance(section, SocketGeometry):
        return geometry.socket_layer(
            section.radius, section.thickness, section.coverage, section.n_rings, section.n_sectors, section.gap
        )
    if isinstance(section, SpringsGeometry):
        return read_springs(section.file)
    if isinstance(section, GeneratorGeometry):
        return _layer_of(_from_generator(section), section.function, pose)
    meshes = load_meshes(section)
    return springs_from_mesh_section(section, meshes, pose)


def _from_generator(section: GeneratorGeometry):
    """Call the builder; a :class:`~dea_opt.geometry.MeshPair` is returned as is."""
    from .. import geometry

    function = getattr(geometry, section.function, None)
    if section.function.startswith("_") or not callable(function):
        # the mesh builders (dea_opt.geometry.meshes), not the exact layers nor MeshPair itself
        public = sorted(n for n in geometry.meshes.__all__ if not isinstance(getattr(geometry, n), type))
        raise ScenarioError(
            f"geometry.function must name a builder in dea_opt.geometry ({', '.join(public)}), got {section.function!r}"
        )
    parameters = _checked_parameters(function, section)
    try:
        return function(**parameters)
    except DeaError:
        raise
    except MemoryError as exc:
        raise ScenarioError(
            f"geometry.parameters of {section.function} ask for more memory than there is ({exc}): "
            f"use a coarser step or fewer elements"
        ) from None
    except (TypeError, ValueError, ArithmeticError, IndexError) as exc:
        raise ScenarioError(f"geometry.parameters do not fit {section.function}: {type(exc).__name__}: {exc}") from None


def _checked_parameters(function, section: GeneratorGeometry) -> dict:
    """The generator's keyword arguments, each checked against its signature and annotation."""
    import inspect
    import typing

    from pydantic import TypeAdapter, ValidationError

    signature = inspect.signature(function)
    try:
        hints = typing.get_type_hints(function)
    except Exception:  # noqa: BLE001 - an annotation that does not resolve is not checked
        hints = {}
    accepted = [n for n, q in signature.parameters.items() if q.kind in (q.POSITIONAL_OR_KEYWORD, q.KEYWORD_ONLY)]
    checked = {}
    for name, value in section.parameters.items():
        if name not in accepted:
            raise ScenarioError(
                f"geometry.parameters do not fit {section.function}: it takes no parameter "
                f"{name!r} (geometry.parameters.{name}); it takes {', '.join(accepted)}"
            )
        hint = hints.get(name)
        if hint is None or hint is typing.Any:
            checked[name] = value
            continue
        try:
            checked[name] = TypeAdapter(hint).validate_python(value, strict=True)
        except ValidationError as exc:
            expected = {float: "a number", int: "an integer", bool: "true or false", str: "a string"}.get(
                hint, getattr(hint, "__name__", str(hint))
            )
            detail = exc.errors()[0]["msg"] if exc.errors() else str(exc)
            raise ScenarioError(
                f"geometry.parameters.{name} of {section.function} must be {expected} ({detail.lower()}), got {value!r}"
            ) from None
    return checked


def _layer_of(built, name: str, pose=None):
    from ..layer import SpringLayer

    if isinstance(built, SpringLayer):
        if pose is not None:
            raise ScenarioError(f"geometry.function {name} returns springs, not meshes, so poses cannot move it")
        return built
    return _cast_of(built, name, pose).layer


def _cast_of(built, name: str, pose=None):
    """The :class:`~dea_opt.mesh.SpringCast` of a generated pair of meshes (mesh 2 at ``pose``)."""
    if not (hasattr(built, "mesh1") and hasattr(built, "mesh2")):
        raise ScenarioError(
            f"geometry.function {name} returned {type(built).__name__}, not a SpringLayer or a pair of meshes"
        )
    options = {} if pose is None else {"pose": pose}
    if callable(getattr(built, "cast", None)):
        return built.cast(**options)
    from ..mesh import cast_springs

    return cast_springs(built.mesh1, built.mesh2, **{**dict(getattr(built, "options", {}) or {}), **options})


def build_geometry(section) -> tuple:
    """``(layer, (reference1, reference2))``: a generated mesh pair brings its bodies' reference
    points; other geometries give ``(None, None)``."""
    layer, references, _ = build_geometry_cast(section)
    return layer, references


def build_geometry_cast(section, meshes: dict | None = None) -> tuple:
    """``(layer, (reference1, reference2), cast)``: as :func:`build_geometry`, with the
    :class:`~dea_opt.mesh.SpringCast` the springs came from when they were cast from meshes
    (files or a generated pair), else None; :func:`dea_opt.mesh.recast_at_solution` takes it.
    ``meshes``: what :func:`load_meshes` read of a ``kind = "meshes"`` section already (not
    read again)."""
    if isinstance(section, GeneratorGeometry):
        built = _from_generator(section)
        references = (getattr(built, "reference1", None), getattr(built, "reference2", None))
        from ..layer import SpringLayer

        if isinstance(built, SpringLayer):
            return built, references, None
        cast = _cast_of(built, section.function)
        return cast.layer, references, cast
    if isinstance(section, MeshGeometry):
        from ..progress import stage

        meshes = load_meshes(section) if meshes is None else meshes
        stage("casting springs")
        cast = cast_from_mesh_section(section, meshes)
        return cast.layer, (None, None), cast
    return build_layer(section), (None, None), None


def pose_builder(scenario):
    """``pose -> SpringLayer`` for geometries made of meshes (None for spring geometries).

    ``scenario`` is a :class:`Scenario` (its ``[regions]`` label every layer alike) or just its
    ``[geometry]``. The meshes are read (or made) once; each call casts the springs again with
    mesh 2 moved by the 4x4 ``pose``.
    """
    caster = pose_caster(scenario)
    return None if caster is None else (lambda pose: caster(pose).layer)


def pose_caster(scenario):
    """``pose -> SpringCast`` for geometries made of meshes (None for spring geometries): as
    :func:`pose_builder`, keeping what each ray met (for :func:`dea_opt.mesh.recast_at_solution`);
    the cast's layer carries the labels of ``[regions]``."""
    import dataclasses

    section = getattr(scenario, "geometry", scenario)
    regions = getattr(scenario, "regions", None)
    if isinstance(section, MeshGeometry):
        meshes = load_meshes(section)

        def cast(pose):
            return cast_from_mesh_section(section, meshes, pose)
    elif isinstance(section, GeneratorGeometry) and hasattr(built := _from_generator(section), "mesh1"):

        def cast(pose):
            return _cast_of(built, section.function, pose)
    else:
        return None
    if regions is None:
        return cast
    # One cut for every frame: the springs of the start pose decide where it lies.
    cut = _cut(cast(None).layer, regions)

    def labelled(pose):
        springs = cast(pose)
        return dataclasses.replace(springs, layer=apply_regions(springs.layer, regions, cut))

    return labelled


def _load_part(files, scale: float):
    """``(mesh, labels)``: one mesh (labels None), or a table of labelled meshes joined into one;
    read once per process inside a sweep's cache (:mod:`dea_opt.mesh.cache`)."""
    from ..mesh import cache as spring_cache

    return spring_cache.mesh_part(files, scale, _read_part)


def _read_part(files, scale: float):
    from ..mesh import concatenate_meshes, load_mesh

    if isinstance(files, dict):
        return concatenate_meshes({label: load_mesh(path, scale=scale) for label, path in files.items()})
    return load_mesh(files, scale=scale), None


def load_meshes(section: MeshGeometry) -> dict:
    """Read the meshes of a ``kind = "meshes"`` geometry: ``mesh1``, ``mesh2`` (a table of labelled
    meshes joined into one), their face labels ``labels1``, ``labels2`` (None for one mesh) and any
    bone meshes ``bone1``, ``bone2``."""
    from ..progress import stage

    stage("reading meshes")
    meshes = {}
    for k in (1, 2):
        meshes[f"mesh{k}"], meshes[f"labels{k}"] = _load_part(getattr(section, f"mesh{k}"), section.scale)
        bone = getattr(section, f"bone{k}")
        meshes[f"bone{k}"] = None if bone is None else _load_part(bone, section.scale)[0]
    return meshes


def springs_from_mesh_section(section: MeshGeometry, meshes: dict, pose=None, *, as_cast: bool = False):
    """Springs from the loaded ``meshes`` with the section's options; ``pose`` overrides its pose.

    Each spring is labelled with its face's part of mesh 1 and, when mesh 2 is a table too,
    with the part of mesh 2 its ray meets (``"medial/femur"``). ``as_cast`` returns the
    :class:`~dea_opt.mesh.SpringCast` (its layer so labelled), which finite kinematics re-cast from.
    """
    cast = cast_from_mesh_section(section, meshes, pose)
    return cast if as_cast else cast.layer


def cast_from_mesh_section(section: MeshGeometry, meshes: dict, pose=None):
    """The :class:`~dea_opt.mesh.SpringCast` of :func:`springs_from_mesh_section` (its layer labelled)."""
    import dataclasses

    from ..mesh import cache as spring_cache

    options = {}
    for k in (1, 2):
        bone = meshes.get(f"bone{k}")
        thickness = getattr(section, f"thickness{k}")
        options[f"thickness{k}"] = bone if bone is not None else thickness
    for name in ("max_gap", "max_overlap", "max_angle"):
        if getattr(section, name) is not None:
            options[name] = getattr(section, name)
    if pose is None and section.pose is not None:
        pose = np.array(section.pose, dtype=float)
    if pose is not None:
        options["pose"] = np.asarray(pose, dtype=float)
    # Through a sweep's cache when one is active: each distinct geometry and pose cast once.
    cast = spring_cache.cast(meshes["mesh1"], meshes["mesh2"], labels=meshes.get("labels1"), **options)
    labels2 = meshes.get("labels2")
    if labels2 is None:
        return cast
    met = _labels_met(meshes["mesh2"], labels2, cast)
    labels = met if cast.layer.labels is None else np.char.add(np.char.add(cast.layer.labels.astype(str), "/"), met)
    return dataclasses.replace(cast, layer=dataclasses.replace(cast.layer, labels=labels))


def _labels_met(mesh2, labels2, cast) -> np.ndarray:
    """The label of the face of mesh 2 each spring's ray met.

    The caster may have cleaned mesh 2 (dropped degenerate faces), so its face numbers are
    matched to the labelled mesh by face centroid, not by index.
    """
    from scipy.spatial import cKDTree

    _, index = cKDTree(mesh2.triangles_center).query(cast.mesh2.triangles_center[cast.hit_face])
    return np.asarray(labels2)[index].astype(str)


def axis_vector(axis: str) -> np.ndarray:
    """The unit vector of ``"x"``, ``"-y"``, ... (the axes ``[regions] split`` accepts)."""
    vector = np.zeros(3)
    vector["xyz".index(axis[-1])] = -1.0 if axis.startswith("-") else 1.0
    return vector


def _cut(layer, regions) -> float:
    """Where ``[regions]`` cuts ``layer`` along its axis (mm)."""
    if regions.at != "centroid":
        return float(regions.at)
    coordinate = layer.points @ axis_vector(regions.split)
    return float(layer.areas @ coordinate / layer.areas.sum())


def apply_regions(layer, regions, cut: float | None = None):
    """``layer`` with labels from ``[regions]``: ``names[0]`` below the cut along the axis, ``names[1]``
    above (at ``cut`` when given: a load path's frames share the cut of its first layer)."""
    import dataclasses

    if layer.labels is not None:
        raise ScenarioError(
            "[regions] splits springs that have no labels, but these springs have labels already "
            "(a table of meshes, or a label column): remove [regions] or the labels"
        )
    cut = _cut(layer, regions) if cut is None else cut
    below = layer.points @ axis_vector(regions.split) < cut
    return dataclasses.replace(layer, labels=np.where(below, regions.names[0], regions.names[1]))


def contact_centre(layer) -> tuple:
    """The centre of the contact, what ``reference = "contact"`` names (mm): the area-weighted
    centroid of the springs' points as cast, ``sum(area_i p_i) / sum(area_i)`` over every spring
    of the layer (points on body 1's surface; springs not yet in contact count too)."""
    points = np.asarray(layer.points, dtype=float)
    areas = np.asarray(layer.areas, dtype=float)
    if not len(points) or not areas.sum() > 0:
        raise ScenarioError('reference = "contact" needs springs to take the centre of, and the layer has none')
    return tuple(float(v) for v in areas @ points / areas.sum())


def _body(section: BodySection, default_free, default_reference, layer=None):
    from ..problem import Body

    free = default_free if section.free is None else tuple(section.free)
    reference: tuple
    if section.reference == "contact":
        reference = contact_centre(layer)
    else:
        given = section.reference if section.reference is not None else default_reference
        reference = tuple(given) if given is not None else (0.0, 0.0, 0.0)
    prescribed = dict(section.prescribed)
    if free is None:  # Body's default: every dof the body does not prescribe
        return Body(reference=tuple(reference), prescribed=prescribed)
    return Body(reference=tuple(reference), free=free, prescribed=prescribed)


def build_problem(scenario: Scenario, layer=None):
    """The :class:`~dea_opt.problem.ContactProblem` of a scenario.

    With ``[load]`` the problem carries that load; with ``[load_path]`` it carries no
    load yet (:func:`read_load_path` gives the frames). ``layer`` replaces the geometry's.
    """
    if layer is None:
        return build_problem_cast(scenario)[0]
    return _problem_cast(scenario, layer, (None, None), None)[0]


def build_problem_cast(scenario: Scenario, meshes: dict | None = None) -> tuple:
    """``(problem, cast)``: :func:`build_problem` and the :class:`~dea_opt.mesh.SpringCast` its
    springs were cast by (None unless they came from meshes), to re-cast them at the solved
    pose (:func:`dea_opt.mesh.recast_at_solution`); finite kinematics re-casts from it as body 2
    moves. ``meshes``: the section's meshes read already (:func:`load_meshes`)."""
    layer, references, cast = build_geometry_cast(scenario.geometry, meshes)
    return _problem_cast(scenario, layer, references, cast)


def _problem_cast(scenario: Scenario, layer, references, cast) -> tuple:
    """``(problem, cast)``: the cast carries the labels of ``[regions]`` too (the layer it holds is
    the problem's: finite kinematics re-cast from it, and its answers are checked against it)."""
    from ..problem import ContactProblem, Load

    reference1, reference2 = references
    if scenario.regions is not None:
        layer = apply_regions(layer, scenario.regions)
        cast = None if cast is None else dataclasses.replace(cast, layer=layer)
    problem = ContactProblem(
        layer,
        build_law(scenario.law),
        body1=_body(scenario.body1, (), reference1, layer),
        body2=_body(scenario.body2, None, reference2, layer),
        kinematics=scenario.solve.kinematics,
        targets=cast if scenario.solve.kinematics == "finite" else None,
    )
    if scenario.load is not None:
        load = scenario.load
        scaled = Load(
            force=tuple(np.multiply(load.force, load.scale)),
            moment=tuple(np.multiply(load.moment, load.scale)),
            point=None if load.point is None else tuple(load.point),
        )
        problem = problem.with_load(scaled, body=load.body)
    return problem, cast


def check_kinematics_method(scenario: Scenario, method: str | None = None, what: str | None = None) -> None:
    """A :class:`ScenarioError` when ``method`` (default ``solve.method``; ``what`` names where it
    came from, e.g. ``--method``) does not solve ``solve.kinematics``: it names both keys, where
    each came from (the file's line or ``--set``) and the methods that do. For finite kinematics
    ``newton`` and ``nlp`` stand for ``finite`` and ``finite_nlp``, and pass."""
    from .. import formulations
    from .joint_schema import JointScenario

    if isinstance(scenario, JointScenario):
        return  # a joint's methods are checked by its run (dea_opt/run/runner.py)
    method = scenario.solve.method if method is None else method
    kinematics = scenario.solve.kinematics
    if not isinstance(method, str) or method == "auto" or method not in formulations.names():
        return  # auto solves both; an unknown name is check_method_name's to refuse
    solved = formulations.capabilities(formulations.resolve(method, None, kinematics).name).kinematics
    if kinematics in solved:
        return

    def origin(key: str) -> str:
        said = key_origin(scenario, f"solve.{key}")
        return f" ({said})" if said else ""

    given = f"{what} {method!r}" if what else f"solve.method = {method!r}{origin('method')}"
    other = next(k for k in ("small", "finite") if k != kinematics)
    able = formulations.resolve(method, build_law(scenario.law), kinematics).use(prefix="")
    raise ScenarioError(
        f"{scenario.source or scenario.title or 'the scenario'}: {given} is a {' and '.join(solved)}-kinematics "
        f'method and solve.kinematics = "{kinematics}"{origin("kinematics")}: use '
        f'{f"{what} " if what else "solve.method = "}{able}; or set solve.kinematics = "{other}"'
    )


def key_origin(scenario: Scenario, key: str) -> str:
    """Where the value of ``key`` (``"solve.kinematics"``) in ``scenario`` came from, for messages:
    ``"from --set"``, ``"line N"`` of its file, or ``""`` (a default, or a file no longer readable)."""
    from pathlib import Path

    from .parse import _origin

    try:
        text = Path(scenario.source).read_text(encoding="utf-8") if scenario.source else ""
    except (OSError, UnicodeDecodeError):
        text = ""
    return _origin(key, tuple(key.split(".")), text, scenario.overrides)
