"""A whole joint in a scenario file: ``[[bodies]]``, ``[[contacts]]``, ``[[ligaments]]``.

A scenario with ``[[bodies]]`` is a :class:`JointScenario` (:func:`dea_opt.scenario.load_scenario`
tells them apart); the two-body form (``[geometry]``, ``[law]``, ``[body1]``, ``[body2]``) stays
as it is. Each contact has a ``geometry`` and a ``law`` table of the two-body kinds; a joint is
solved statically (the bodies' own loads) or along ``[load_path]``: a CSV whose columns are
``time`` and ``<body>.<quantity>``, a load (``Fx`` ... ``Mz``: N, N mm) or a prescribed dof
(``ux`` ... ``rz``: mm, rad) of that body per frame. Units: mm, N, N mm, MPa, s.
"""

from __future__ import annotations

from pathlib import Path
from typing import Literal

from pydantic import Field, PrivateAttr, model_validator

from .fields import DofList, File, Positive, Vector3, _Section
from .schema import Geometry, LawSection, OutputSection, RegionsSection

__all__ = [
    "JointBodySection",
    "JointContactSection",
    "JointLigamentSection",
    "JointLoadPathSection",
    "JointScenario",
    "JointSolveSection",
]

JointMethod = Literal["auto", "newton", "qp", "nlp"]


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
    point: Vector3 | None = Field(None, description="where the force acts (mm); adds its moment")


class JointContactSection(_Section):
    """A layer of springs between two bodies: its springs on body1, their normals toward body2."""

    name: str | None = Field(None, description='a label for the outputs (default "body1-body2")')
    body1: str = Field(description="the body carrying the springs")
    body2: str = Field(description="the body the springs push")
    geometry: Geometry
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


class JointLoadPathSection(_Section):
    """Loads and prescribed motions per frame: a CSV with ``time`` (s) and ``<body>.<quantity>``
    columns (``femur.Fz``, ``femur.rx``; forces N, moments N mm about the body's reference, dofs mm
    and rad). A dof column prescribes that dof at every frame; a load column replaces the body's
    load there; lines starting with # are comments."""

    file: File = Field(description="the CSV (path)")


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


class JointScenario(_Section):
    """A whole joint: several bodies, contact layers and ligaments."""

    title: str = Field("", description="a name for reports")
    bodies: list[JointBodySection] = Field(min_length=1, description="the rigid bodies")
    contacts: list[JointContactSection] = Field(default_factory=list, description="the contact layers")
    ligaments: list[JointLigamentSection] = Field(default_factory=list, description="the ligament bundles")
    load_path: JointLoadPathSection | None = None
    solve: JointSolveSection = Field(default_factory=JointSolveSection)
    output: OutputSection = Field(default_factory=OutputSection)
    _source: str | None = PrivateAttr(None)
    _text_sha256: str | None = PrivateAttr(None)
    _overrides: dict = PrivateAttr(default_factory=dict)
    _notes: list = PrivateAttr(default_factory=list)

    @model_validator(mode="after")
    def _names(self):
        names = [b.name for b in self.bodies]
        if len(set(names)) != len(names):
            raise ValueError(f"bodies must have different names, got {names}")
        for kind in ("contacts", "ligaments"):
            for i, item in enumerate(getattr(self, kind)):
                for end in ("body1", "body2"):
                    if getattr(item, end) not in names:
                        raise ValueError(f"{kind}[{i}].{end} is {getattr(item, end)!r}, not a body (bodies: {names})")
        return self

    @property
    def source(self) -> str | None:
        return self._source

    @property
    def text_sha256(self) -> str | None:
        return self._text_sha256

    @property
    def overrides(self) -> dict:
        return dict(self._overrides)

    @property
    def notes(self) -> list:
        return list(self._notes)

    @property
    def base_dir(self) -> Path:
        return Path(self._source).parent if self._source else Path.cwd()

    def output_dir(self, override=None) -> Path:
        """The output folder: ``override`` (relative to the working directory) or ``[output].directory``."""
        if override is not None:
            return Path(override).expanduser().resolve()
        path = Path(self.output.directory).expanduser()
        return path if path.is_absolute() else (self.base_dir / path).resolve()
