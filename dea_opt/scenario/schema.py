"""The scenario schema: pydantic models of every table and key, and :func:`schema_text` made from them.

Unknown keys and wrong types are errors (``extra="forbid"``, strict types); files are
resolved against the scenario's folder (``base_dir`` in the validation context) and must
exist. ``dea-opt schema`` prints :func:`schema_text`, which is generated from the models
below, so it cannot drift. Units: mm, N, N mm, MPa, s.
"""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Annotated, Any, Literal, Union

from pydantic import (
    AfterValidator,
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationInfo,
    model_validator,
)

from ..kinematics import DOFS

__all__ = [
    "FORMATS", "GEOMETRY_KINDS", "METHOD_NAMES", "BodySection", "GeneratorGeometry", "LawSection",
    "LoadPathSection", "LoadSection", "MeshGeometry", "OutputSection", "PlateGeometry", "Scenario",
    "SocketGeometry", "SolveSection", "SphereOnBedGeometry", "SpringsGeometry", "schema_text",
]

METHOD_NAMES = ("auto", "newton", "qp", "nlp")
FORMATS = ("csv", "json", "vtk", "png")


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
