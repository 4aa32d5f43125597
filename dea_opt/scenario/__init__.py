"""Scenario files: one TOML file describes one analysis (geometry, law, bodies, load, solve, output).

A scenario is read with :func:`load_scenario`, validated by pydantic models (unknown keys,
wrong types and missing files are errors that name the key path, and for TOML syntax
errors the line), and turned into a :class:`~dea_opt.problem.ContactProblem` by
:func:`build_problem` and, for a load path, a table of frames by :func:`read_load_path`.
Relative paths resolve against the scenario file's folder. ``dea-opt schema`` prints
:func:`schema_text`, which is generated from the models, so it cannot drift.

The modules: :mod:`~dea_opt.scenario.schema` (the models), :mod:`~dea_opt.scenario.docs`
(the documented schema),
:mod:`~dea_opt.scenario.parse` (reading, errors with key paths and TOML lines, ``--set``),
:mod:`~dea_opt.scenario.build` (law, springs, bodies, problem),
:mod:`~dea_opt.scenario.load_path` (the frames of a load path, with OpenSim ``.sto``/``.mot``
files read by :mod:`dea_opt.opensim.storage`).

Units everywhere: mm, N, N mm, MPa, s.

Example::

    title = "plate, eccentric load"
    [geometry]
    kind = "springs"
    file = "plate_springs.csv"
    [law]
    kind = "linear"
    H = 10.0
    [body2]
    free = ["uz", "rx", "ry"]
    [load]
    force = [0.0, 0.0, -500.0]
    point = [5.0, 0.0, 0.0]
"""

from ..errors import ScenarioError
from ..io.tables import read_springs, write_springs
from .build import (
    apply_regions,
    build_geometry,
    build_law,
    build_layer,
    build_problem,
    build_problem_cast,
    cast_from_mesh_section,
    check_kinematics_method,
    key_origin,
    load_meshes,
    pose_builder,
    pose_caster,
    springs_from_mesh_section,
)
from .docs import schema_text
from .load_path import LoadPathData, pose_matrices, read_load_path
from .parse import apply_overrides, load_scenario, parse_scenario, parse_set
from .schema import (
    FORMATS,
    GEOMETRY_KINDS,
    LOAD_PATH_COLUMNS,
    BodySection,
    GeneratorGeometry,
    LawSection,
    LoadPathSection,
    LoadSection,
    MeshGeometry,
    OutputSection,
    PlateGeometry,
    RegionsSection,
    Scenario,
    SocketGeometry,
    SolveSection,
    SphereOnBedGeometry,
    SpringsGeometry,
    check_method_name,
    method_names,
)

__all__ = [
    "FORMATS",
    "GEOMETRY_KINDS",
    "LOAD_PATH_COLUMNS",
    "BodySection",
    "GeneratorGeometry",
    "LawSection",
    "LoadPathData",
    "LoadPathSection",
    "LoadSection",
    "MeshGeometry",
    "OutputSection",
    "PlateGeometry",
    "RegionsSection",
    "Scenario",
    "ScenarioError",
    "SocketGeometry",
    "SolveSection",
    "SphereOnBedGeometry",
    "SpringsGeometry",
    "apply_overrides",
    "apply_regions",
    "build_geometry",
    "build_law",
    "build_layer",
    "build_problem",
    "build_problem_cast",
    "cast_from_mesh_section",
    "check_kinematics_method",
    "check_method_name",
    "key_origin",
    "load_meshes",
    "load_scenario",
    "method_names",
    "parse_scenario",
    "parse_set",
    "pose_builder",
    "pose_caster",
    "pose_matrices",
    "read_load_path",
    "read_springs",
    "schema_text",
    "springs_from_mesh_section",
    "write_springs",
]
