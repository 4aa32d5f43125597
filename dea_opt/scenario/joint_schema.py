"""A whole joint in a scenario file: ``[[bodies]]``, ``[[contacts]]``, ``[[ligaments]]``.

A scenario with ``[[bodies]]`` is a :class:`JointScenario` (:func:`dea_opt.scenario.load_scenario`
tells them apart); the two-body form (``[geometry]``, ``[law]``, ``[body1]``, ``[body2]``) stays
as it is. Each contact has a ``geometry`` and a ``law`` table of the two-body kinds; a joint is
solved statically (the bodies' own loads) or along ``[load_path]``: a CSV whose columns are
``time`` and ``<body>.<quantity>``, a load (``Fx`` ... ``Mz``: N, N mm) or a prescribed dof
(``ux`` ... ``rz``: mm, rad) of that body per frame. Units: mm, N, N mm, MPa, s.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, model_validator

from .fields import DofList, File, NonNegative, Positive, Vector3, _Section
from .schema import (
    GeneratorGeometry,
    LawSection,
    MeshGeometry,
    OutputSection,
    PlateGeometry,
    RegionsSection,
    ScenarioFile,
    SocketGeometry,
    SphereOnBedGeometry,
    SpringsGeometry,
)

__all__ = [
    "JointBodySection",
    "JointBushingSection",
    "JointCoordinatesSection",
    "JointFrameSection",
    "JointLoadSection",
    "JointMeshGeometry",
    "JointSpringSection",
    "JointContactSection",
    "JointLigamentSection",
    "JointLoadPathSection",
    "JointScenario",
    "JointSolveSection",
]

JointMethod = Literal["auto", "newton", "qp", "nlp"]
Row4 = Annotated[list[float], Field(min_length=4, max_length=4)]
Matrix4 = Annotated[list[Row4], Field(min_length=4, max_length=4)]
Matrix3 = Annotated[list[Vector3], Field(min_length=3, max_length=3)]
Vector6 = Annotated[list[float], Field(min_length=6, max_length=6)]


class JointCoordinatesSection(_Section):
    """A body's six coordinates as an OpenSim CustomJoint's (finite kinematics): the body's dofs
    rx, ry, rz are the joint's three rotations (rad, body-fixed in order about rotation_axes) and
    ux, uy, uz its three translations (mm, along translation_axes of the fixed frame); each axis
    value is slope * coordinate + intercept. Written by dea-opt import-osim --fixed."""

    joint: str | None = Field(None, description="the OpenSim joint it came from (for reports)")
    frame: Matrix4 = Field(description="the joint's fixed frame in the world at the start pose (4x4, mm)")
    rotation_axes: Matrix3 = Field(description="the three rotation axes (rows, in frame)")
    translation_axes: Matrix3 = Field(description="the three translation axes (rows, in frame)")
    start: Vector6 = Field(description="the coordinates at the start pose, in dof order ux..rz (mm, rad)")
    slopes: Vector6 = Field([1.0] * 6, description="the axes' linear functions' slopes, in dof order")
    intercepts: Vector6 = Field([0.0] * 6, description="their intercepts (mm, rad), in dof order")
    inverted: bool = Field(False, description="true where the body is the joint's parent, moving on its child")
    names: Annotated[list[str], Field(min_length=6, max_length=6)] | None = Field(
        None, description="the coordinates' names in dof order (a motion file's columns)"
    )


class JointMeshGeometry(MeshGeometry):
    """Two triangle meshes, each placed in the world by its own pose (as an OpenSim model places its
    contact meshes in their bodies' frames): springs on mesh 1 by ray casting to mesh 2. [regions]
    then cut across an axis of mesh 1's own frame (the frame of its file)."""

    pose1: Matrix4 | None = Field(None, description="4x4 pose of mesh 1's file in the world at the start pose (mm)")
    pose2: Matrix4 | None = Field(None, description="4x4 pose of mesh 2's file in the world at the start pose (mm)")
    scale1: Positive | None = Field(None, description="mesh 1's factor to mm (default: scale)")
    scale2: Positive | None = Field(None, description="mesh 2's factor to mm (default: scale)")

    @model_validator(mode="after")
    def _one_placement(self):
        if self.pose is not None:
            raise ValueError("a joint's contact places each mesh by pose1 and pose2 (in the world), not by pose")
        return self


JointGeometry = Annotated[
    PlateGeometry | SphereOnBedGeometry | SocketGeometry | GeneratorGeometry | JointMeshGeometry | SpringsGeometry,
    Field(discriminator="kind"),
]


class JointBodySection(_Section):
    """One rigid body of the joint: a body with no free dof is held where it is (ground)."""

    name: str = Field(min_length=1, description="the body's name, which contacts and ligaments use")
    reference: Vector3 = Field([0.0, 0.0, 0.0], description="centre of rotation, moments about it (mm)")
    free: DofList = Field([], description='free dofs, e.g. ["ux", "uy", "uz"], or "all" / "none" (default none)')
    prescribed: dict[Literal["ux", "uy", "uz", "rx", "ry", "rz"], float] = Field(
        default_factory=dict, description="dofs held at a displacement, e.g. {uz = -0.1} (mm, rad)"
    )
    force: Vector3 = Field([0.0, 0.0, 0.0], description="force on the body (N)")
    moment: Vector3 = Field([0.0, 0.0, 0.0], description="moment about its reference (N mm)")
    point: Vector3 | None = Field(None, description="where the force acts (mm, world at the start pose); moves with it")
    load_frame: Literal["ground", "body"] = Field(
        "ground", description='"body": force and moment in the body\'s axes (its pose), turning with it'
    )
    pose: Matrix4 | None = Field(None, description="the body's own frame in the world at the start pose (4x4, mm)")
    coordinates: JointCoordinatesSection | None = None


class JointContactSection(_Section):
    """A layer of springs between two bodies: its springs on body1, their normals toward body2."""

    name: str | None = Field(None, description='a label for the outputs (default "body1-body2")')
    body1: str = Field(description="the body carrying the springs")
    body2: str = Field(description="the body the springs push")
    geometry: JointGeometry
    law: LawSection
    regions: RegionsSection | None = None


class JointLigamentSection(_Section):
    """A ligament bundle: the straight line between an insertion on each of two bodies, tension only
    (no wrapping around obstacles). Give slack_length or reference_strain."""

    name: str | None = Field(None, description="a label for the ligament table")
    body1: str = Field(description="the body of the first insertion")
    point1: Vector3 = Field(description="the first insertion, global frame at the start pose (mm)")
    body2: str = Field(description="the body of the second insertion")
    point2: Vector3 = Field(description="the second insertion (mm)")
    stiffness: Positive = Field(description="N per unit strain")
    slack_length: Positive | None = Field(None, description="L0 (mm)")
    reference_strain: float | None = Field(None, gt=-1.0, description="the strain at the start pose")
    law: Literal["blankevoort", "linear"] = Field("blankevoort", description="Blankevoort 1991 or linear")
    transition_strain: float = Field(0.06, gt=0.0, le=1.0, description="where the toe region ends")

    @model_validator(mode="after")
    def _one_length(self):
        if (self.slack_length is None) == (self.reference_strain is None):
            raise ValueError("give exactly one of slack_length and reference_strain")
        return self


class JointSpringSection(_Section):
    """A linear spring between a point on each of two bodies: it pulls and pushes, f = k (L - L_r)."""

    name: str | None = Field(None, description="a label for the tables")
    body1: str = Field(description="the body of the first end")
    point1: Vector3 = Field(description="the first end, global frame at the start pose (mm)")
    body2: str = Field(description="the body of the second end")
    point2: Vector3 = Field(description="the second end (mm)")
    stiffness: Positive = Field(description="N/mm")
    rest_length: NonNegative | None = Field(None, description="L_r (mm; default the length at the start pose)")


class JointBushingSection(_Section):
    """A linear bushing between two bodies: a frame fixed to each, coincident at the start pose."""

    name: str | None = Field(None, description="a label for the tables")
    body1: str = Field(description="the first body")
    body2: str = Field(description="the second body")
    frame: Matrix4 | None = Field(None, description="the bushing's frame in the world at the start pose (4x4, mm)")
    translational_stiffness: Vector3 = Field([0.0, 0.0, 0.0], description="N/mm along each axis")
    rotational_stiffness: Vector3 = Field([0.0, 0.0, 0.0], description="N mm/rad about each axis")


class JointLoadSection(_Section):
    """A force and a moment at a point of a body, in the ground frame or the body's own axes."""

    body: str = Field(description="the body it acts on")
    force: Vector3 = Field([0.0, 0.0, 0.0], description="N")
    moment: Vector3 = Field([0.0, 0.0, 0.0], description="N mm")
    point: Vector3 | None = Field(None, description="where (mm, world at the start pose; default the reference)")
    frame: Literal["ground", "body"] = Field("ground", description="ground (fixed in space) or body (turns with it)")


class JointFrameSection(_Section):
    """A frame fixed to a body (a load path's poses are of one frame in another)."""

    name: str = Field(min_length=1, description="the frame's name")
    body: str = Field(description="the body it is fixed to")
    pose: Matrix4 = Field(description="its pose in the world at the start pose (4x4, mm)")


class JointLoadPathSection(_Section):
    """Loads and prescribed motions per frame, from up to three files. ``file``: a CSV with
    ``time`` (s) and ``<body>.<quantity>`` columns (``femur.Fz``, ``femur.rx``; forces N, moments
    N mm about the body's reference, or in its axes where its load_frame is body; dofs mm and
    rad). ``motion``: an OpenSim .sto/.mot of coordinates named by bodies' coordinates names
    (rotations in rad or degrees as its header says, translations in m). ``poses``: a CSV of 4x4
    poses (T00..T33, mm) of frame ``moving`` in frame ``reference`` per frame (e.g. a fluoroscopic
    gait), the moving frame's body following. ``prescribe`` chooses the dofs the motion or the
    poses prescribe (``femur.rx`` or a coordinate's name; default every one they give); the
    others stay free. With ``motion`` or ``poses`` the frames are theirs, and ``file``'s columns
    are interpolated at their times. Lines of a CSV starting with # are comments."""

    file: File | None = Field(None, description="the CSV of loads and prescribed dofs (path)")
    motion: File | None = Field(None, description="an OpenSim .sto/.mot of coordinates (path)")
    poses: File | None = Field(None, description="a CSV of 4x4 poses T00..T33 per frame (path)")
    moving: str | None = Field(None, description="with poses: the frame (or body) they place")
    reference: str | None = Field(None, description="with poses: the frame (or body) they are given in")
    prescribe: list[str] | None = Field(None, description="the dofs the motion prescribes (default all it gives)")

    @model_validator(mode="after")
    def _sources(self):
        if self.file is None and self.motion is None and self.poses is None:
            raise ValueError("give a file (loads), a motion (.sto/.mot) or poses (a CSV of 4x4 poses)")
        if self.motion is not None and self.poses is not None:
            raise ValueError("give motion or poses, not both")
        if self.poses is not None and (self.moving is None or self.reference is None):
            raise ValueError("poses need the frames they relate: moving and reference")
        if self.prescribe is not None and self.motion is None and self.poses is None:
            raise ValueError("prescribe chooses dofs of a motion or poses")
        return self


class JointSolveSection(_Section):
    """How to solve a joint (``run``) and what to compare (``compare``)."""

    method: JointMethod = Field("auto", description="auto, newton, qp (linear elements only) or nlp")
    methods: list[Literal["newton", "qp", "nlp"]] | None = Field(
        None, min_length=1, description="methods for compare (default: every one that solves the joint)"
    )
    kinematics: Literal["small", "finite"] = Field("small", description="small (linearised) or finite (exact)")
    certificate_tol: Positive = Field(1e-6, description="bound on every certificate residual")
    allow_outside_validity: bool = Field(False, description="exit 0 instead of 3 for an answer outside validity")

    @model_validator(mode="after")
    def _qp_is_small(self):
        if self.kinematics == "finite" and self.method == "qp":
            raise ValueError('method "qp" is a small-kinematics method; kinematics is "finite"')
        return self


class JointScenario(ScenarioFile):
    """A whole joint: several bodies, contact layers and ligaments."""

    title: str = Field("", description="a name for reports")
    bodies: list[JointBodySection] = Field(min_length=1, description="the rigid bodies")
    contacts: list[JointContactSection] = Field(default_factory=list, description="the contact layers")
    ligaments: list[JointLigamentSection] = Field(default_factory=list, description="the ligament bundles")
    springs: list[JointSpringSection] = Field(default_factory=list, description="linear springs between points")
    bushings: list[JointBushingSection] = Field(default_factory=list, description="linear bushings between frames")
    loads: list[JointLoadSection] = Field(default_factory=list, description="forces and moments at points")
    frames: list[JointFrameSection] = Field(default_factory=list, description="frames fixed to bodies")
    load_path: JointLoadPathSection | None = None
    solve: JointSolveSection = Field(default_factory=JointSolveSection)
    output: OutputSection = Field(default_factory=OutputSection)

    @model_validator(mode="after")
    def _names(self):
        names = [b.name for b in self.bodies]
        if len(set(names)) != len(names):
            raise ValueError(f"bodies must have different names, got {names}")
        for kind in ("contacts", "ligaments", "springs", "bushings", "loads", "frames"):
            for i, item in enumerate(getattr(self, kind)):
                for end in ("body1", "body2") if kind not in ("loads", "frames") else ("body",):
                    if getattr(item, end) not in names:
                        raise ValueError(f"{kind}[{i}].{end} is {getattr(item, end)!r}, not a body (bodies: {names})")
        return self
