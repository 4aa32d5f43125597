"""The scenario schema: pydantic models of every table and key, and :func:`schema_text` made from them.

Unknown keys and wrong types are errors (``extra="forbid"``, strict types); files are
resolved against the scenario's folder (``base_dir`` in the validation context) and must
exist. ``dea-opt schema`` prints :func:`dea_opt.scenario.docs.schema_text`, which is
generated from the models below, so it cannot drift. Units: mm, N, N mm, MPa, s.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal, get_args

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    PrivateAttr,
    ValidationInfo,
    field_validator,
    model_validator,
)
from pydantic_core import PydanticCustomError

from ..laws import LAWS
from .fields import (
    ComparedMethod,
    Count,
    Dof,
    DofList,
    File,
    MeshFiles,
    Method,
    NonNegative,
    Positive,
    Vector3,
    _anatomy,
    _no_nul,
    _Section,
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
    "LoadPathSection",
    "LoadSection",
    "MeshGeometry",
    "OutputSection",
    "PlateGeometry",
    "RegionsSection",
    "Scenario",
    "ScenarioFile",
    "SocketGeometry",
    "SolveSection",
    "SphereOnBedGeometry",
    "SpringsGeometry",
    "check_method_name",
    "law_model",
    "method_names",
]

Format = Literal["csv", "json", "vtk", "png", "html"]
FORMATS: tuple[Format, ...] = get_args(Format)
#: The quantities of a load path a column can be: time, force, moment and the pose of mesh 2.
LoadPathColumn = Literal[
    "time", "Fx", "Fy", "Fz", "Mx", "My", "Mz", "pose_tx", "pose_ty", "pose_tz", "pose_rx", "pose_ry", "pose_rz"
]
LOAD_PATH_COLUMNS: tuple[LoadPathColumn, ...] = get_args(LoadPathColumn)


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
    coverage: Annotated[float, Field(gt=0, le=180)] = Field(80.0, description="half-angle of the socket cap (degrees)")
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
    """Two triangle meshes (STL, OBJ, PLY, VTK), springs on mesh 1 by ray casting to mesh 2. Either
    may be a table of labelled meshes, e.g. mesh1 = {medial = "medial.stl", lateral = "lateral.stl"}:
    the parts are joined and each spring carries the label of its part (of mesh 1, or of the face
    of mesh 2 its ray meets; "medial/femur" when both are tables), so every output reports the
    compartments."""

    kind: Literal["meshes"]
    mesh1: MeshFiles = Field(description="articular surface of body 1 (path), or a table {label = path}")
    mesh2: MeshFiles = Field(description="articular surface of body 2 (path), or a table {label = path}")
    scale: Positive = Field(1.0, description="factor to millimetres (1000 for files in metres)")
    thickness1: Positive | None = Field(
        None, description="cartilage thickness on body 1 (mm); omit for a closed cartilage surface"
    )
    thickness2: Positive | None = Field(None, description="cartilage thickness on body 2 (mm)")
    bone1: File | None = Field(None, description="bone mesh of body 1 to measure thickness to (path)")
    bone2: File | None = Field(None, description="bone mesh of body 2 to measure thickness to (path)")
    max_gap: NonNegative | None = Field(None, description="largest gap that makes a spring (mm)")
    max_overlap: NonNegative | None = Field(None, description="largest initial overlap (mm)")
    max_angle: Annotated[float, Field(gt=0, le=180)] | None = Field(
        None, description="largest angle between facing normals (degrees)"
    )
    pose: list[Annotated[list[float], Field(min_length=4, max_length=4)]] | None = Field(
        None, min_length=4, max_length=4, description="4x4 rigid transform applied to mesh 2"
    )

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
    PlateGeometry | SphereOnBedGeometry | SocketGeometry | GeneratorGeometry | MeshGeometry | SpringsGeometry,
    Field(discriminator="kind"),
]
GEOMETRY_KINDS = ("plate", "sphere_on_bed", "socket", "generator", "meshes", "springs")


# --- [law], [body1], [body2] ------------------------------------------------------------


def _law_json_schema(schema: dict) -> None:
    # The JSON Schema of [law]: one alternative per registered kind, made when asked.
    schema["oneOf"] = [law_model(kind).model_json_schema() for kind in LAWS]


class LawSection(_Section):
    """The spring law (stress positive in tension, moduli in MPa): a kind registered in
    dea_opt.laws.LAWS and that kind's parameters, listed below for each kind."""

    model_config = ConfigDict(extra="allow", strict=True, json_schema_extra=_law_json_schema)

    kind: str = Field("linear", description=" | ".join(LAWS))

    @model_validator(mode="before")
    @classmethod
    def _parameters_of_kind(cls, data):
        if not isinstance(data, dict):
            return data
        return law_model(data.get("kind", "linear")).model_validate(data).model_dump()

    @property
    def parameters(self) -> dict:
        """The law's parameters (everything but ``kind``)."""
        return dict(self.model_extra or {})


_LAW_MODELS: dict = {}


def law_model(kind) -> type[BaseModel]:
    """The pydantic model of ``[law]`` for ``kind``, made from the registry (:data:`~dea_opt.laws.LAWS`)."""
    from pydantic import create_model

    key = (kind if isinstance(kind, str) else None, LAWS.version)
    if key in _LAW_MODELS:
        return _LAW_MODELS[key]
    config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False)
    # The kinds are the registry's, known when the model is made: a Literal built at run time.
    fields: dict[str, Any]
    if not isinstance(kind, str) or kind not in LAWS:
        fields = {"kind": (Literal.__getitem__(tuple(LAWS)), "linear")}
        name, doc = "UnknownLaw", None
    else:
        fields = {"kind": (Literal.__getitem__(kind), kind)}
        for p in LAWS[kind].parameters:
            bounds = {}
            if p.range is not None and p.range.low is not None:
                bounds["gt" if p.range.low_open else "ge"] = p.range.low
            if p.range is not None and p.range.high is not None:
                bounds["le"] = p.range.high
            default = ... if p.required else p.default
            fields[p.name] = (p.type, Field(default, description=p.describe(), **bounds))
        name, doc = f"{kind}Law", f"{kind}: {LAWS[kind].doc}"
    _LAW_MODELS[key] = create_model(name, __config__=config, __doc__=doc, **fields)
    return _LAW_MODELS[key]


class BodySection(_Section):
    """One rigid body. Default: body 1 fixed, body 2 free in all six dofs."""

    reference: Vector3 | Literal["contact"] | None = Field(
        None,
        description='centre of rotation, moments about it (mm); or "contact": the centre of the contact, the '
        "area-weighted centroid of the springs as cast (their points on body 1's surface); default the "
        "generator's, else the origin",
    )
    free: DofList | None = Field(None, description='free dofs, e.g. ["ux", "uy", "uz"], or "all" / "none"')
    prescribed: dict[Dof, float] = Field(
        default_factory=dict, description="dofs held at a displacement, e.g. {uz = -0.1} (mm, rad)"
    )

    @model_validator(mode="after")
    def _free_or_prescribed(self):
        both = [dof for dof in self.free or () if dof in self.prescribed]
        if both:
            raise ValueError(
                f"a dof cannot be both free and prescribed: {', '.join(both)} is in free = {self.free} "
                f"and in prescribed; remove it from one of them"
            )
        return self


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
    about the fixed x, y, z axes in that order) that move mesh 2 per frame; lines starting
    with # are comments. Or an OpenSim Storage file (.sto, .mot: what JointReaction and
    Inverse Kinematics write) whose columns are named in `columns`; its rotations are read
    in degrees or radians as its header's inDegrees says."""

    file: File | None = Field(None, description="load CSV, or OpenSim .sto/.mot (path)")
    builtin: Literal["hip_gait"] | None = Field(
        None, description='a shipped load path instead of a file: "hip_gait" (synthetic, 101 frames)'
    )
    columns: dict[LoadPathColumn, str] | None = Field(
        None,
        description="for .sto/.mot: the file's column of each quantity, e.g. {Fx = \"knee_r_on_femur_r_in_"
        'femur_r_fx", ...} (Fx, Fy, Fz required; a leading "-" negates a column; time defaults '
        'to "time"; quantities not named are 0)',
    )
    units: Literal["SI", "mm"] | None = Field(
        None,
        description='units of a .sto/.mot file: "SI" (OpenSim\'s N, N m, m: moments and pose '
        'translations are converted to N mm and mm; the default) or "mm" (N, N mm, mm)',
    )
    body: Literal[1, 2] = Field(2, description="the body carrying the loads")
    point: Vector3 | None = Field(None, description="where the forces act (mm)")
    scale: float = Field(1.0, description="factor on every force and moment (for sweeps)")
    frames: Count | None = Field(None, description="resample to this many evenly spaced frames")

    @model_validator(mode="after")
    def _one_source(self):
        if (self.file is None) == (self.builtin is None):
            raise ValueError("give exactly one of file or builtin")
        opensim = self.file is not None and Path(self.file).suffix.lower() in (".sto", ".mot")
        if opensim and self.columns is None:
            raise ValueError(
                'an OpenSim .sto/.mot load path needs columns = {Fx = "...", Fy = "...", '
                'Fz = "...", ...}: which column of the file is which'
            )
        if not opensim and (self.columns is not None or self.units is not None):
            raise ValueError("columns and units apply to OpenSim .sto/.mot load paths only")
        if opensim and not {"Fx", "Fy", "Fz"} <= set(self.columns):
            missing = sorted({"Fx", "Fy", "Fz"} - set(self.columns))
            raise ValueError(f"columns must name the force columns Fx, Fy and Fz; missing {', '.join(missing)}")
        return self


class RegionsSection(_Section):
    """Labels for springs that have none (a single mesh, a generator, a springs table without a
    label column): split them in two by a plane across an axis, e.g. the knee's medial and
    lateral compartments. Which side is medial depends on the frame and the body's side: check it."""

    split: Literal["x", "y", "z", "-x", "-y", "-z"] = Field(description="the axis to split across")
    at: float | Literal["centroid"] = Field(
        "centroid", description='where to cut along the axis (mm), or "centroid": the springs\' area centroid'
    )
    names: Annotated[list[str], Field(min_length=2, max_length=2)] = Field(
        ["medial", "lateral"], description="the labels below and above the cut"
    )

    @model_validator(mode="after")
    def _two_names(self):
        if self.names[0] == self.names[1] or not all(n.strip() for n in self.names):
            raise ValueError(f"names must be two different, non-empty labels, got {self.names}")
        return self


# --- [solve], [output] ------------------------------------------------------------------


class SolveSection(_Section):
    """How to solve (``run``) and what to compare (``compare``)."""

    method: Method = Field("auto", description="auto, or a registered formulation")
    solver: str = Field("CLARABEL", description="QP solver for method qp (any cvxpy QP solver)")
    tol: Positive | None = Field(None, description="solver tolerance (default: the formulation's)")
    certificate_tol: Positive = Field(1e-6, description="bound on every certificate residual")
    form: Literal["constrained", "reduced"] = Field("constrained", description="NLP form")
    methods: list[ComparedMethod] | None = Field(
        None,
        min_length=1,
        description="methods for compare (default: every registered formulation that solves the problem)",
    )
    solvers: list[str] = Field(["CLARABEL", "OSQP", "SCS", "PIQP"], min_length=1, description="QP solvers for compare")
    accuracy: list[Literal["low", "default", "high"]] = Field(
        ["default"], min_length=1, description="accuracy settings for compare"
    )
    repeat: Count = Field(1, description="repeats per compare case")
    kinematics: Literal["small", "finite"] = Field(
        "small",
        description="small: the paper's linearised rigid motion (Eq. 9-11), gaps cast once; finite: exact "
        "rotations and gaps at the current pose, springs cast from meshes re-cast as body 2 "
        "moves (method newton and nlp stand for the finite formulations; qp is small only)",
    )
    max_recasts: Annotated[int, Field(ge=0)] | None = Field(
        None,
        description="finite kinematics: updates of the springs after converged solves, at most (default 10); an "
        "answer whose springs still change at the last one fails as max_iterations",
    )
    check_inputs: bool = Field(
        True,
        description="run the implausibility checks before solving (units of meshes, loads and moduli, a reference "
        "point far from the contact, a load that pulls the bodies apart or lies along the surface); false solves "
        "what they would stop (the validity checks still judge the answer)",
    )
    allow_outside_validity: bool = Field(
        False,
        description="exit 0 instead of 3 when an answer is certified but outside its model's validity (for "
        "exploring on purpose; the outputs still say so)",
    )

    @field_validator("max_recasts")
    @classmethod
    def _recasts_need_finite(cls, value, info: ValidationInfo):
        # A field's error (solve.max_recasts), which names where solve.kinematics came from ("related").
        kinematics = info.data.get("kinematics")
        if value is not None and kinematics is not None and kinematics != "finite":
            raise PydanticCustomError(
                "needs_finite",
                "max_recasts = {value} counts the updates of springs that follow body 2, which only "
                'kinematics = "finite" has; solve.kinematics is "{kinematics}"',
                {"value": value, "kinematics": kinematics, "related": "kinematics"},
            )
        return value


class OutputSection(_Section):
    """Where results go and in which formats."""

    directory: Annotated[str, AfterValidator(_no_nul)] = Field(
        "results",
        description="output folder (relative to the scenario file): new, empty, or holding an earlier dea-opt run",
    )
    formats: list[Format] = Field(
        list(FORMATS), description="any of csv, json, vtk, png, html (report.html: the run on one page)"
    )
    maps: list[Annotated[int, Field(ge=0)]] = Field(
        [],
        description="frames of a load path (indices, as frames.csv counts them) whose pressure map is drawn "
        "(map_frame_NNNN.png), besides the peak frame's (peak.png); e.g. [0, 50]",
    )
    exposure_threshold: NonNegative = Field(1.0, description="pressure threshold of the exposure measures (MPa)")
    anatomy: Annotated[dict[str, Any] | None, AfterValidator(_anatomy)] = Field(
        None,
        description="the anatomical frame of the maps and centres of pressure: two or three of medial, "
        'anterior, proximal (directions, mesh coordinates) and side = "right" | "left", e.g. '
        '{medial = [1, 0, 0], proximal = [0, 0, 1], side = "right"}; or landmarks = {medial = '
        '[...], lateral = [...], proximal = [...]} with side (and origin = "midpoint", a '
        "landmark or a point, mm); see dea_opt.anatomy.AnatomicalFrame.from_dict",
    )


class ScenarioFile(_Section):
    """What a scenario read from a file knows besides its tables: the file, the SHA-256 of its text,
    the ``--set`` overrides applied to it, notes for the user, and where its outputs go.

    :class:`Scenario` (two bodies) and :class:`~dea_opt.scenario.joint_schema.JointScenario` (a
    whole joint) are both; :func:`~dea_opt.scenario.parse.parse_scenario` fills these in after
    validating the tables.
    """

    # Not TOML keys: the file the scenario came from (relative paths resolve against it), the
    # SHA-256 of its text, the --set overrides applied to it and notes for the user.
    _source: str | None = PrivateAttr(None)
    _text_sha256: str | None = PrivateAttr(None)
    _overrides: dict = PrivateAttr(default_factory=dict)
    _notes: list = PrivateAttr(default_factory=list)
    if TYPE_CHECKING:  # each scenario declares [output] among its own tables, in its own order
        output: OutputSection

    @property
    def source(self) -> str | None:
        """The scenario file (None for a scenario made from text)."""
        return self._source

    @property
    def text_sha256(self) -> str | None:
        """SHA-256 of the scenario's TOML text (before overrides)."""
        return self._text_sha256

    @property
    def overrides(self) -> dict:
        """The ``--set`` overrides applied to it."""
        return dict(self._overrides)

    @property
    def notes(self) -> list:
        """What reading it changed on purpose, e.g. a law parameter dropped for a kind that takes none."""
        return list(self._notes)

    @property
    def base_dir(self) -> Path:
        """The folder relative paths resolve against: the scenario file's, else the working directory."""
        return Path(self._source).parent if self._source else Path.cwd()

    def output_dir(self, override=None) -> Path:
        """The output folder: ``override`` (relative to the working directory) or ``[output].directory``."""
        if override is not None:
            return Path(override).expanduser().resolve()
        path = Path(self.output.directory).expanduser()
        return path if path.is_absolute() else (self.base_dir / path).resolve()


class Scenario(ScenarioFile):
    """A whole analysis. Exactly one of [load] and [load_path]."""

    title: str = Field("", description="a name for reports")
    geometry: Geometry
    law: LawSection
    body1: BodySection = Field(default_factory=BodySection)
    body2: BodySection = Field(default_factory=BodySection)
    load: LoadSection | None = None
    load_path: LoadPathSection | None = None
    regions: RegionsSection | None = None
    solve: SolveSection = Field(default_factory=SolveSection)
    output: OutputSection = Field(default_factory=OutputSection)

    @model_validator(mode="after")
    def _one_load(self):
        if (self.load is None) == (self.load_path is None):
            raise ValueError("give exactly one of the tables [load] and [load_path]")
        return self
