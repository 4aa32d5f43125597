"""Building what a scenario describes: the law, the springs (from generators, tables or meshes), the bodies and the problem.

Optional parts (geometry generators, meshes, the problem classes) are imported where they
are used, so that reading and validating a scenario stays light.
"""

from __future__ import annotations

import numpy as np

from ..errors import ScenarioError
from ..io.tables import read_springs
from ..kinematics import DOFS
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

__all__ = ["build_geometry", "build_layer", "build_law", "build_problem", "load_meshes", "pose_builder",
           "springs_from_mesh_section"]


def build_law(section: LawSection):
    """The :class:`~dea_opt.laws.Law` of ``[law]``."""
    from .. import laws

    if section.kind == "linear":
        return laws.LinearLaw(section.H)
    if section.kind == "ateshian":
        return laws.AteshianLaw(section.H, section.beta)
    if section.kind == "cubic":
        return laws.CubicLaw(section.H, section.beta)
    if section.kind == "polynomial":
        return laws.PolynomialLaw(section.H, section.beta, section.order)
    return laws.BlankevoortLaw(section.H)


def build_layer(section, pose=None):
    """The :class:`~dea_opt.layer.SpringLayer` of ``[geometry]`` (mesh 2 moved by ``pose``)."""
    from .. import geometry

    if isinstance(section, PlateGeometry):
        return geometry.plate_layer(section.length, section.width, section.nx, section.ny, section.thickness)
    if isinstance(section, SphereOnBedGeometry):
        return geometry.sphere_on_bed_layer(section.radius, section.thickness, section.extent,
                                            section.n_rings, section.n_sectors)
    if isinstance(section, SocketGeometry):
        return geometry.socket_layer(section.radius, section.thickness, section.coverage,
                                     section.n_rings, section.n_sectors, section.gap)
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
        public = sorted(n for n in dir(geometry) if not n.startswith("_") and callable(getattr(geometry, n))
                        and getattr(getattr(geometry, n), "__module__", "") == geometry.__name__
                        and not isinstance(getattr(geometry, n), type))
        raise ScenarioError(f"geometry.function must name a builder in dea_opt.geometry ({', '.join(public)}), "
                            f"got {section.function!r}")
    try:
        return function(**section.parameters)
    except TypeError as exc:
        raise ScenarioError(f"geometry.parameters do not fit {section.function}: {exc}") from None


def _layer_of(built, name: str, pose=None):
    from ..layer import SpringLayer

    if isinstance(built, SpringLayer):
        if pose is not None:
            raise ScenarioError(f"geometry.function {name} returns springs, not meshes, so poses cannot move it")
        return built
    if hasattr(built, "mesh1") and hasattr(built, "mesh2"):
        options = dict(getattr(built, "options", {}) or {})
        if pose is not None:
            options["pose"] = pose
        from ..mesh import springs_from_meshes

        return springs_from_meshes(built.mesh1, built.mesh2, **options)
    raise ScenarioError(f"geometry.function {name} returned {type(built).__name__}, not a SpringLayer or a "
                        f"pair of meshes")


def build_geometry(section) -> tuple:
    """``(layer, (reference1, reference2))``: a generated mesh pair brings its bodies' reference
    points; other geometries give ``(None, None)``."""
    if isinstance(section, GeneratorGeometry):
        built = _from_generator(section)
        return _layer_of(built, section.function), (getattr(built, "reference1", None),
                                                    getattr(built, "reference2", None))
    return build_layer(section), (None, None)


def pose_builder(section):
    """``pose -> SpringLayer`` for geometries made of meshes (None for spring geometries).

    The meshes are read (or made) once; each call casts the springs again with mesh 2
    moved by the 4x4 ``pose``.
    """
    if isinstance(section, MeshGeometry):
        meshes = load_meshes(section)
        return lambda pose: springs_from_mesh_section(section, meshes, pose)
    if isinstance(section, GeneratorGeometry):
        built = _from_generator(section)
        if hasattr(built, "mesh1"):
            return lambda pose: _layer_of(built, section.function, pose)
    return None


def load_meshes(section: MeshGeometry) -> dict:
    """Read the meshes of a ``kind = "meshes"`` geometry (mesh1, mesh2 and any bone meshes)."""
    from ..mesh import load_mesh

    meshes = {"mesh1": load_mesh(section.mesh1, scale=section.scale),
              "mesh2": load_mesh(section.mesh2, scale=section.scale)}
    for k in (1, 2):
        bone = getattr(section, f"bone{k}")
        meshes[f"bone{k}"] = None if bone is None else load_mesh(bone, scale=section.scale)
    return meshes


def springs_from_mesh_section(section: MeshGeometry, meshes: dict, pose=None):
    """Springs from the loaded ``meshes`` with the section's options; ``pose`` overrides its pose."""
    from ..mesh import springs_from_meshes

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
    return springs_from_meshes(meshes["mesh1"], meshes["mesh2"], **options)


def _body(section: BodySection, default_free, default_reference):
    from ..problem import Body

    free = default_free if section.free is None else tuple(section.free)
    reference = section.reference if section.reference is not None else (default_reference or (0.0, 0.0, 0.0))
    return Body(reference=tuple(reference), free=free, prescribed=dict(section.prescribed))


def build_problem(scenario: Scenario, layer=None):
    """The :class:`~dea_opt.problem.ContactProblem` of a scenario.

    With ``[load]`` the problem carries that load; with ``[load_path]`` it carries no
    load yet (:func:`read_load_path` gives the frames). ``layer`` replaces the geometry's.
    """
    from ..problem import ContactProblem, Load

    if layer is None:
        layer, (reference1, reference2) = build_geometry(scenario.geometry)
    else:
        reference1 = reference2 = None
    problem = ContactProblem(
        layer, build_law(scenario.law),
        body1=_body(scenario.body1, (), reference1),
        body2=_body(scenario.body2, DOFS, reference2),
    )
    if scenario.load is not None:
        load = scenario.load
        scaled = Load(force=np.multiply(load.force, load.scale), moment=np.multiply(load.moment, load.scale),
                      point=None if load.point is None else tuple(load.point))
        problem = problem.with_load(scaled, body=load.body)
    return problem
