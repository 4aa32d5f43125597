"""Scenario files: one TOML file describes one analysis (geometry, law, bodies, load, solve, output).

A scenario is read with :func:`load_scenario`, validated by pydantic models (unknown keys,
wrong types and missing files are errors that name the key path, and for TOML syntax
errors the line), and turned into a :class:`~dea_opt.problem.ContactProblem` by
:func:`build_problem` and, for a load path, a table of frames by :func:`read_load_path`.
Relative paths resolve against the scenario file's folder. ``dea-opt schema`` prints
:func:`schema_text`, which is generated from the models below, so it cannot drift.

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

from __future__ import annotations

import copy
import re
import textwrap
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any, Literal, Union

import numpy as np
from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationError,
    ValidationInfo,
    model_validator,
)

from .errors import InputError, ScenarioError
from .kinematics import DOFS
from .tables import read_numeric_csv, read_springs, write_springs

__all__ = [
    "Scenario", "ScenarioError", "LoadPathData", "load_scenario", "parse_scenario",
    "build_problem", "build_layer", "build_geometry", "build_law", "pose_builder", "read_load_path",
    "read_springs", "write_springs",
    "parse_set", "apply_overrides", "schema_text", "METHOD_NAMES", "FORMATS",
]

METHOD_NAMES = ("auto", "newton", "qp", "nlp")
FORMATS = ("csv", "json", "vtk", "png")
_FORCE_COLUMNS = ("Fx", "Fy", "Fz")
_MOMENT_COLUMNS = ("Mx", "My", "Mz")
_POSE_COLUMNS = ("pose_tx", "pose_ty", "pose_tz", "pose_rx", "pose_ry", "pose_rz")


# --- field types ------------------------------------------------------------------------

def _existing_file(value: str, info: ValidationInfo) -> str:
    """Resolve ``value`` against the scenario's folder and insist that the file exists."""
    base = (info.context or {}).get("base_dir")
    path = Path(value).expanduser()
    if not path.is_absolute() and base is not None:
        path = Path(base) / path
    if not path.is_file():
        raise ValueError(f"file not found: {path}")
    return str(path.resolve())


def _dof_list(value):
    # "all" / "none" are accepted as shorthands for the list of every dof / no dof.
    if value == "all":
        return list(DOFS)
    if value == "none":
        return []
    return value


File = Annotated[str, AfterValidator(_existing_file)]
Vector3 = Annotated[list[float], Field(min_length=3, max_length=3)]
Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]
Count = Annotated[int, Field(ge=1)]
Dof = Literal["ux", "uy", "uz", "rx", "ry", "rz"]
DofList = Annotated[list[Dof], BeforeValidator(_dof_list)]


class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", strict=True)


# --- [geometry] -------------------------------------------------------------------------

class PlateGeometry(_Section):
    """A rigid plate on a flat bonded layer (``dea_opt.geometry.plate_layer``): the core's plate case."""

    kind: Literal["plate"]
    length: Positive = Field(40.0, description="plate length along x (mm)")
    width: Positive = Field(10.0, description="plate width along y (mm)")
    nx: Count = Field(400, description="springs along x")
    ny: Count = Field(10, description="springs along y")
    thickness: Positive = Field(2.0, description="layer thickness (mm)")


class SphereOnBedGeometry(_Section):
    """A rigid sphere touching a flat bed (``dea_opt.geometry.sphere_on_bed_layer``)."""

    kind: Literal["sphere_on_bed"]
    radius: Positive = Field(25.0, description="sphere radius (mm)")
    thickness: Positive = Field(2.0, description="layer thickness (mm)")
    extent: Positive = Field(8.0, description="radius of the bed patch carrying springs (mm)")
    n_rings: Count = Field(200, description="rings of springs")
    n_sectors: Count = Field(128, description="sectors of springs")


class SocketGeometry(_Section):
    """A ball in a spherical socket (``dea_opt.geometry.socket_layer``): a simple hip.

    The socket opens toward +z around the ball's centre at the origin; give body 2 free
    translations only (rotations about the centre meet no spring).
    """

    kind: Literal["socket"]
    radius: Positive = Field(25.0, description="head radius (mm)")
    thickness: Positive = Field(3.0, description="total cartilage thickness, both layers (mm)")
    coverage: Annotated[float, Field(gt=0, le=180)] = Field(
        80.0, description="half-angle of the socket cap (degrees)")
    n_rings: Count = Field(45, description="rings of springs")
    n_sectors: Count = Field(120, description="sectors of springs")
    gap: float = Field(0.0, description="radial clearance between head and socket (mm)")


class GeneratorGeometry(_Section):
    """Any builder in ``dea_opt.geometry``, called with ``parameters``, e.g. ``function =
    "hip_meshes"``. A builder of springs is used as is; a mesh pair (``MeshPair``) is cast
    into springs with its own options and supplies the bodies' reference points.
    """

    kind: Literal["generator"]
    function: str = Field(description="name of a function in dea_opt.geometry")
    parameters: dict[str, Any] = Field(default_factory=dict, description="its keyword arguments")


class MeshGeometry(_Section):
    """Two triangle meshes (STL, OBJ, PLY, VTK), springs on mesh 1 by ray casting to mesh 2."""

    kind: Literal["meshes"]
    mesh1: File = Field(description="articular surface of body 1 (path)")
    mesh2: File = Field(description="articular surface of body 2 (path)")
    scale: Positive = Field(1.0, description="factor to millimetres (1000 for files in metres)")
    thickness1: Positive | None = Field(
        None, description="cartilage thickness on body 1 (mm); omit for a closed cartilage surface")
    thickness2: Positive | None = Field(None, description="cartilage thickness on body 2 (mm)")
    bone1: File | None = Field(None, description="bone mesh of body 1 to measure thickness to (path)")
    bone2: File | None = Field(None, description="bone mesh of body 2 to measure thickness to (path)")
    max_gap: NonNegative | None = Field(None, description="largest gap that makes a spring (mm)")
    max_overlap: NonNegative | None = Field(None, description="largest initial overlap (mm)")
    max_angle: Annotated[float, Field(gt=0, le=180)] | None = Field(
        None, description="largest angle between facing normals (degrees)")
    pose: list[Annotated[list[float], Field(min_length=4, max_length=4)]] | None = Field(
        None, min_length=4, max_length=4, description="4x4 rigid transform applied to mesh 2")

    @model_validator(mode="after")
    def _one_thickness(self):
        for k in (1, 2):
            if getattr(self, f"thickness{k}") is not None and getattr(self, f"bone{k}") is not None:
                raise ValueError(f"give thickness{k} or bone{k}, not both")
        return self


class SpringsGeometry(_Section):
    """A springs table: CSV with columns x,y,z,nx,ny,nz,area,thickness[,gap][,label] or NPZ."""

    kind: Literal["springs"]
    file: File = Field(description="CSV or NPZ file of springs (path)")


Geometry = Annotated[
    Union[PlateGeometry, SphereOnBedGeometry, SocketGeometry, GeneratorGeometry, MeshGeometry, SpringsGeometry],
    Field(discriminator="kind"),
]
GEOMETRY_KINDS = ("plate", "sphere_on_bed", "socket", "generator", "meshes", "springs")


# --- [law], [body1], [body2] ------------------------------------------------------------

_NEEDS_BETA = ("ateshian", "cubic", "polynomial")


class LawSection(_Section):
    """The spring law (stress positive in tension, H in MPa)."""

    kind: Literal["linear", "ateshian", "cubic", "polynomial", "blankevoort"] = Field(
        "linear", description="linear | ateshian | cubic | polynomial | blankevoort")
    H: Positive = Field(description="small-strain modulus (MPa)")
    beta: NonNegative | None = Field(None, description="Ateshian's beta (ateshian, cubic, polynomial)")
    order: Count | None = Field(None, description="Taylor order (polynomial only)")

    @model_validator(mode="after")
    def _parameters_fit_kind(self):
        if self.kind in _NEEDS_BETA and self.beta is None:
            raise ValueError(f"law kind {self.kind!r} needs beta")
        if self.kind not in _NEEDS_BETA and self.beta is not None:
            raise ValueError(f"law kind {self.kind!r} takes no beta")
        if (self.kind == "polynomial") != (self.order is not None):
            raise ValueError("order is required for kind 'polynomial' and only there")
        return self


class BodySection(_Section):
    """One rigid body. Default: body 1 fixed, body 2 free in all six dofs."""

    reference: Vector3 | None = Field(
        None, description="centre of rotation, moments about it (mm); default the generator's, else the origin")
    free: DofList | None = Field(None, description='free dofs, e.g. ["ux", "uy", "uz"], or "all" / "none"')
    prescribed: dict[Dof, float] = Field(
        default_factory=dict, description="dofs held at a displacement, e.g. {uz = -0.1} (mm, rad)")


# --- [load], [load_path] ----------------------------------------------------------------

class LoadSection(_Section):
    """One static load."""

    force: Vector3 = Field([0.0, 0.0, 0.0], description="force (N)")
    moment: Vector3 = Field([0.0, 0.0, 0.0], description="moment about the body's reference (N mm)")
    point: Vector3 | None = Field(None, description="where the force acts (mm); adds its moment")
    body: Literal[1, 2] = Field(2, description="the body carrying the load")
    scale: float = Field(1.0, description="factor on force and moment (for sweeps)")


class LoadPathSection(_Section):
    """A sequence of quasi-static loads: a CSV with columns time,Fx,Fy,Fz[,Mx,My,Mz] and
    optional pose columns pose_tx,pose_ty,pose_tz (mm), pose_rx,pose_ry,pose_rz (degrees,
    about the fixed x, y, z axes in that order) that move mesh 2 per frame. Lines starting
    with # are comments."""

    file: File | None = Field(None, description="load CSV (path)")
    builtin: Literal["hip_gait"] | None = Field(
        None, description='a shipped load path instead of a file: "hip_gait" (synthetic, 101 frames)')
    body: Literal[1, 2] = Field(2, description="the body carrying the loads")
    point: Vector3 | None = Field(None, description="where the forces act (mm)")
    scale: float = Field(1.0, description="factor on every force and moment (for sweeps)")
    frames: Count | None = Field(None, description="resample to this many evenly spaced frames")

    @model_validator(mode="after")
    def _one_source(self):
        if (self.file is None) == (self.builtin is None):
            raise ValueError("give exactly one of file or builtin")
        return self


# --- [solve], [output] ------------------------------------------------------------------

class SolveSection(_Section):
    """How to solve (``run``) and what to compare (``compare``)."""

    method: Literal["auto", "newton", "qp", "nlp"] = Field("auto", description="auto | newton | qp | nlp")
    solver: str = Field("CLARABEL", description="QP solver for method qp (any cvxpy QP solver)")
    tol: Positive | None = Field(None, description="solver tolerance (default: the formulation's)")
    certificate_tol: Positive = Field(1e-6, description="bound on every certificate residual")
    form: Literal["constrained", "reduced"] = Field("constrained", description="NLP form")
    methods: list[Literal["newton", "qp", "nlp"]] = Field(
        ["newton", "qp", "nlp"], min_length=1, description="methods for compare")
    solvers: list[str] = Field(
        ["CLARABEL", "OSQP", "SCS", "PIQP"], min_length=1, description="QP solvers for compare")
    accuracy: list[Literal["low", "default", "high"]] = Field(
        ["default"], min_length=1, description="accuracy settings for compare")
    repeat: Count = Field(1, description="repeats per compare case")


class OutputSection(_Section):
    """Where results go and in which formats."""

    directory: str = Field("results", description="output folder (relative to the scenario file)")
    formats: list[Literal["csv", "json", "vtk", "png"]] = Field(
        list(FORMATS), description="any of csv, json, vtk, png")
    exposure_threshold: NonNegative = Field(
        1.0, description="pressure threshold of the exposure measures (MPa)")


class Scenario(_Section):
    """A whole analysis. Exactly one of [load] and [load_path]."""

    title: str = Field("", description="a name for reports")
    geometry: Geometry
    law: LawSection
    body1: BodySection = Field(default_factory=BodySection)
    body2: BodySection = Field(default_factory=BodySection)
    load: LoadSection | None = None
    load_path: LoadPathSection | None = None
    solve: SolveSection = Field(default_factory=SolveSection)
    output: OutputSection = Field(default_factory=OutputSection)
    # Not a TOML key: the file the scenario came from (relative paths resolve against it).
    _source: str | None = PrivateAttr(None)

    @model_validator(mode="after")
    def _one_load(self):
        if (self.load is None) == (self.load_path is None):
            raise ValueError("give exactly one of the tables [load] and [load_path]")
        return self

    @property
    def source(self) -> str | None:
        """The scenario file (None for a scenario made from text)."""
        return self._source

    @property
    def base_dir(self) -> Path:
        return Path(self._source).parent if self._source else Path.cwd()

    def output_dir(self, override=None) -> Path:
        """The output folder: ``override`` (relative to the working directory) or ``[output].directory``."""
        if override is not None:
            return Path(override).expanduser().resolve()
        path = Path(self.output.directory).expanduser()
        return path if path.is_absolute() else (self.base_dir / path).resolve()


# --- reading ----------------------------------------------------------------------------

def load_scenario(path, overrides: dict | None = None) -> Scenario:
    """Read and validate a scenario file.

    Parameters
    ----------
    path : str or Path
        The TOML file.
    overrides : dict, optional
        ``{"law.H": 0.45, ...}`` applied to the file's values before validation
        (see :func:`parse_set`).

    Raises
    ------
    ScenarioError
        Naming the file, the key path and (when known) the line.
    """
    path = Path(path).expanduser()
    if not path.is_file():
        raise ScenarioError(f"scenario file not found: {path}")
    text = path.read_text(encoding="utf-8")
    return parse_scenario(text, name=str(path), base_dir=path.resolve().parent, overrides=overrides)


def parse_scenario(text: str, *, name: str = "<scenario>", base_dir=None, overrides: dict | None = None) -> Scenario:
    """Validate scenario TOML ``text``; relative paths resolve against ``base_dir``."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ScenarioError(f"{name} is not valid TOML: {exc}") from None
    if overrides:
        data = apply_overrides(data, overrides)
    base_dir = Path.cwd() if base_dir is None else Path(base_dir)
    try:
        scenario = Scenario.model_validate(data, context={"base_dir": base_dir})
    except ValidationError as exc:
        raise ScenarioError(_describe_errors(exc, name, text, data, overrides or {})) from None
    if name != "<scenario>":
        scenario._source = str(Path(base_dir) / Path(name).name)
    return scenario


def _describe_errors(exc: ValidationError, name: str, text: str, data: dict, overrides: dict) -> str:
    parts = []
    for error in exc.errors():
        loc = _clean_loc(error["loc"])
        if error["type"] in ("union_tag_invalid", "union_tag_not_found"):
            loc = (*loc, "kind")
        key = _key_path(loc)
        line = None if error["type"] == "missing" else _find_line(text, loc)
        if any(key == k or key.startswith(k + ".") or key.startswith(k + "[") for k in overrides):
            where = f"{key} (from --set)"
        else:
            where = f"{key} (line {line})" if line else (key or "top level")
        parts.append(f"{where}: {_message(error, loc, data)}")
    plural = "s" if len(parts) > 1 else ""
    return f"{name} has {len(parts)} error{plural}: " + "; ".join(parts)


def _clean_loc(loc: tuple) -> tuple:
    # pydantic puts the union tag (e.g. "socket") into the location of [geometry] errors.
    if len(loc) >= 2 and loc[0] == "geometry" and loc[1] in GEOMETRY_KINDS:
        loc = loc[:1] + loc[2:]
    return tuple(p for p in loc if not (isinstance(p, str) and p.startswith(("function-", "literal["))))


def _key_path(loc: tuple) -> str:
    text = ""
    for part in loc:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text


def _message(error: dict, loc: tuple, data: dict) -> str:
    kind = error["type"]
    given = error.get("input")
    if kind == "extra_forbidden":
        allowed = _allowed_keys(loc[:-1], data)
        hint = f"; allowed here: {', '.join(allowed)}" if allowed else ""
        return f"unknown key {loc[-1]!r}{hint}"
    if kind == "missing":
        return "required table is missing" if len(loc) == 1 and loc[0] in Scenario.model_fields else \
            "required key is missing"
    if kind == "union_tag_invalid":
        return f"unknown kind {error['ctx']['tag']!r}; expected one of {error['ctx']['expected_tags']}"
    if kind == "union_tag_not_found":
        return f"required key is missing; expected one of {', '.join(repr(k) for k in GEOMETRY_KINDS)}"
    message = error["msg"]
    if message.startswith("Value error, "):
        message = message[len("Value error, "):]
    if kind in ("float_type", "int_type", "string_type", "bool_type", "list_type", "dict_type",
                "literal_error", "int_from_float", "float_parsing"):
        message += f", got {_short(given)}" + (" (a string)" if isinstance(given, str) else "")
    return message


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 50 else text[:47] + "..."


def _allowed_keys(loc: tuple, data: dict) -> list[str]:
    """The keys the table at ``loc`` accepts (for 'unknown key' messages)."""
    model = Scenario
    node = data
    for part in loc:
        if not isinstance(part, str) or model is None:
            return []
        node = node.get(part, {}) if isinstance(node, dict) else {}
        field = model.model_fields.get(part)
        if field is None:
            return []
        model = _section_model(field.annotation, node)
    if model is None:
        return []
    return list(model.model_fields)


def _section_model(annotation, node):
    """The model class behind a field annotation (picking the geometry variant by ``kind``)."""
    from typing import get_args

    candidates = [a for a in _flatten(annotation) if isinstance(a, type) and issubclass(a, BaseModel)]
    if len(candidates) > 1 and isinstance(node, dict):
        for model in candidates:
            kind = model.model_fields.get("kind")
            if kind is not None and node.get("kind") in get_args(kind.annotation):
                return model
        return None
    return candidates[0] if candidates else None


def _flatten(annotation):
    from typing import get_args

    args = get_args(annotation)
    if not args:
        return [annotation]
    return [x for a in args for x in _flatten(a)]


def _find_line(text: str, loc: tuple) -> int | None:
    """The 1-based line of the key ``loc`` in the TOML ``text`` (best effort, else None).

    Falls back to the enclosing key's line (an inline table or a list element).
    """
    keys = [p for p in loc if isinstance(p, str)]
    while keys:
        line = _find_key_line(text, keys)
        if line is not None:
            return line
        keys = keys[:-1]
    return None


def _find_key_line(text: str, keys: list) -> int | None:
    table, key = keys[:-1], keys[-1]
    header = re.compile(r"^\s*\[\s*([A-Za-z0-9_.\s]+?)\s*\]\s*(#.*)?$")
    assignment = re.compile(rf"^\s*{re.escape(key)}\s*=")
    current: list[str] = []
    table_line = None
    for number, line in enumerate(text.splitlines(), start=1):
        match = header.match(line)
        if match:
            current = [p.strip() for p in match.group(1).split(".")]
            if current == keys and table_line is None:
                table_line = number
            continue
        if current == table and assignment.match(line):
            return number
    return table_line


# --- --set overrides --------------------------------------------------------------------

def parse_set(text: str) -> tuple[str, list]:
    """Split ``"law.H=0.3,0.45,0.6"`` into ``("law.H", [0.3, 0.45, 0.6])``.

    Values are read as TOML values (numbers, booleans, ``[1, 2, 3]``, quoted strings);
    anything else is kept as a string. Commas inside brackets or quotes do not split.
    """
    key, sep, values = text.partition("=")
    key = key.strip()
    if not sep or not key or not re.fullmatch(r"[A-Za-z0-9_]+(\.[A-Za-z0-9_]+)*", key):
        raise ScenarioError(f"--set must look like KEY.PATH=VALUE[,VALUE...], e.g. law.H=0.3,0.45, got {text!r}")
    items = _split_values(values)
    if not items or any(item == "" for item in items):
        raise ScenarioError(f"--set {key} has an empty value in {text!r}")
    return key, [_parse_value(item) for item in items]


def _split_values(text: str) -> list[str]:
    items, depth, quote, current = [], 0, None, ""
    for char in text:
        if quote:
            quote = None if char == quote else quote
        elif char in "\"'":
            quote = char
        elif char in "[{":
            depth += 1
        elif char in "]}":
            depth -= 1
        elif char == "," and depth == 0:
            items.append(current.strip())
            current = ""
            continue
        current += char
    items.append(current.strip())
    return items


def _parse_value(text: str):
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def apply_overrides(data: dict, overrides: dict) -> dict:
    """A deep copy of the TOML ``data`` with ``{"table.key": value}`` set (tables created)."""
    data = copy.deepcopy(data)
    for key, value in overrides.items():
        node = data
        parts = key.split(".")
        for depth, part in enumerate(parts[:-1]):
            node = node.setdefault(part, {})
            if not isinstance(node, dict):
                raise ScenarioError(f"--set {key}: {'.'.join(parts[:depth + 1])} is a value, not a table")
        node[parts[-1]] = value
    return data


# --- building the problem ---------------------------------------------------------------

def build_law(section: LawSection):
    """The :class:`~dea_opt.laws.Law` of ``[law]``."""
    from . import laws

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
    from . import geometry

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
    from . import geometry

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
    from .layer import SpringLayer

    if isinstance(built, SpringLayer):
        if pose is not None:
            raise ScenarioError(f"geometry.function {name} returns springs, not meshes, so poses cannot move it")
        return built
    if hasattr(built, "mesh1") and hasattr(built, "mesh2"):
        options = dict(getattr(built, "options", {}) or {})
        if pose is not None:
            options["pose"] = pose
        from .mesh import springs_from_meshes

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
    from .mesh import load_mesh

    meshes = {"mesh1": load_mesh(section.mesh1, scale=section.scale),
              "mesh2": load_mesh(section.mesh2, scale=section.scale)}
    for k in (1, 2):
        bone = getattr(section, f"bone{k}")
        meshes[f"bone{k}"] = None if bone is None else load_mesh(bone, scale=section.scale)
    return meshes


def springs_from_mesh_section(section: MeshGeometry, meshes: dict, pose=None):
    """Springs from the loaded ``meshes`` with the section's options; ``pose`` overrides its pose."""
    from .mesh import springs_from_meshes

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
    from .problem import Body

    free = default_free if section.free is None else tuple(section.free)
    reference = section.reference if section.reference is not None else (default_reference or (0.0, 0.0, 0.0))
    return Body(reference=tuple(reference), free=free, prescribed=dict(section.prescribed))


def build_problem(scenario: Scenario, layer=None):
    """The :class:`~dea_opt.problem.ContactProblem` of a scenario.

    With ``[load]`` the problem carries that load; with ``[load_path]`` it carries no
    load yet (:func:`read_load_path` gives the frames). ``layer`` replaces the geometry's.
    """
    from .problem import ContactProblem, Load

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


# --- tables: load paths and springs -----------------------------------------------------

@dataclass(frozen=True, eq=False)
class LoadPathData:
    """The frames of a load path.

    Attributes
    ----------
    times : ndarray (T,)
        s.
    loads : ndarray (T, 6)
        ``Fx, Fy, Fz`` (N), ``Mx, My, Mz`` (N mm), already scaled.
    poses : ndarray (T, 4, 4) or None
        Rigid transforms of body 2's mesh.
    body : int
        The body the loads act on.
    point : tuple or None
        Where the forces act (mm).
    """

    times: np.ndarray
    loads: np.ndarray
    poses: np.ndarray | None = None
    body: int = 2
    point: tuple | None = None

    def __len__(self) -> int:
        return len(self.times)

    def load_objects(self) -> list:
        """One :class:`~dea_opt.problem.Load` per frame."""
        from .problem import Load

        return [Load(force=row[:3], moment=row[3:], point=self.point) for row in self.loads]


def read_load_path(section: LoadPathSection) -> LoadPathData:
    """Read (or make) the frames of ``[load_path]``, scaled and resampled as asked."""
    if section.builtin == "hip_gait":
        from .gait import HIP_GAIT_CSV

        source = HIP_GAIT_CSV
    else:
        source = section.file
    table = read_numeric_csv(source, ("time", *_FORCE_COLUMNS), _MOMENT_COLUMNS + _POSE_COLUMNS, "load path")
    name = section.file or "the hip_gait load path"
    times = table["time"].to_numpy(dtype=float)
    if len(times) > 1 and not (np.diff(times) > 0).all():
        i = int(np.argmax(np.diff(times) <= 0)) + 1
        raise ScenarioError(f"{name}: column time must increase, but row {i + 1} has time {times[i]:g} after "
                            f"{times[i - 1]:g}")
    loads = np.column_stack([table.get(c, 0.0 * times) for c in _FORCE_COLUMNS + _MOMENT_COLUMNS]) * section.scale
    present = [c for c in _POSE_COLUMNS if c in table]
    if present and len(present) != len(_POSE_COLUMNS):
        missing = [c for c in _POSE_COLUMNS if c not in table]
        raise ScenarioError(f"{name}: pose columns must come all six together; missing {', '.join(missing)}")
    poses = pose_matrices(table[list(_POSE_COLUMNS)].to_numpy(dtype=float)) if present else None
    if section.frames is not None and section.frames != len(times):
        times, loads, poses = _resample(times, loads, poses, section.frames)
    point = None if section.point is None else tuple(section.point)
    return LoadPathData(times=times, loads=loads, poses=poses, body=section.body, point=point)


def pose_matrices(columns: np.ndarray) -> np.ndarray:
    """4x4 transforms from rows ``tx, ty, tz`` (mm), ``rx, ry, rz`` (degrees, fixed axes x, y, z)."""
    from scipy.spatial.transform import Rotation

    columns = np.atleast_2d(columns)
    poses = np.tile(np.eye(4), (len(columns), 1, 1))
    poses[:, :3, :3] = Rotation.from_euler("xyz", columns[:, 3:6], degrees=True).as_matrix()
    poses[:, :3, 3] = columns[:, :3]
    return poses


def _resample(times, loads, poses, n):
    new = np.linspace(times[0], times[-1], n)
    loads = np.column_stack([np.interp(new, times, col) for col in loads.T])
    if poses is not None:
        # Nearest frame: interpolating rotation matrices entry by entry would not stay rigid.
        nearest = np.abs(new[:, None] - times[None, :]).argmin(axis=1)
        poses = poses[nearest]
    return new, loads, poses


# --- the documented schema --------------------------------------------------------------

_SECTIONS = (
    ("geometry", (PlateGeometry, SphereOnBedGeometry, SocketGeometry, MeshGeometry, SpringsGeometry,
                  GeneratorGeometry)),
    ("law", (LawSection,)),
    ("body1", (BodySection,)),
    ("body2", (BodySection,)),
    ("load", (LoadSection,)),
    ("load_path", (LoadPathSection,)),
    ("solve", (SolveSection,)),
    ("output", (OutputSection,)),
)


def schema_text() -> str:
    """The scenario schema as commented TOML: every table, key, type, default and meaning."""
    lines = [
        "# dea-opt scenario file (TOML). Units: mm, N, N mm, MPa, s.",
        "# Relative paths resolve against the scenario file's folder. Unknown keys are errors.",
        "# Give exactly one of [load] and [load_path].",
        "",
        'title = ""  # string, optional: a name for reports',
    ]
    for table, models in _SECTIONS:
        lines.append("")
        lines.append(f"[{table}]")
        if len(models) > 1:
            kinds = " | ".join(m.model_fields["kind"].annotation.__args__[0] for m in models)
            lines.append(f"# Choose one kind ({kinds}); each kind takes the keys listed under it.")
        for model in models:
            doc = " ".join((model.__doc__ or "").replace("``", "").split())
            if len(models) > 1:
                kind = model.model_fields["kind"].annotation.__args__[0]
                lines.append("")
                lines.extend(textwrap.wrap(f"--- {doc}", 96, initial_indent="# ", subsequent_indent="#     "))
                lines.append(f'kind = "{kind}"')
            else:
                lines.extend(textwrap.wrap(doc, 96, initial_indent="# ", subsequent_indent="# "))
            for name, field in model.model_fields.items():
                if name == "kind" and len(models) > 1:
                    continue
                lines.append(_field_line(name, field))
    return "\n".join(lines) + "\n"


def _field_line(name: str, field) -> str:
    from pydantic_core import PydanticUndefined

    description = field.description or ""
    if field.default is PydanticUndefined and field.default_factory is None:
        return f"{name} = ...  # required; {description}"
    default = field.default_factory() if field.default_factory is not None else field.default
    if default is None:
        return f"# {name} = ...  # optional; {description}"
    return f"{name} = {_toml_value(default)}  # {description}"


def _toml_value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, str):
        return f'"{value}"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {_toml_value(v)}" for k, v in value.items()) + "}"
    return repr(value)
