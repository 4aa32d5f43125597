"""The objects :func:`~dea_opt.opensim.read_model` returns: plain, immutable, in mm, N, MPa.

Every length is converted from the model's metres to mm as it is read (translations, path
points, slack lengths, thicknesses, proximities), every modulus from Pa to MPa; angles stay in
radians; a coordinate's values stay in OpenSim's units (rad for a rotation, m for a translation)
because they are the model's and its motion files' own. Transforms are 4x4 arrays ``T_A_B``, the
pose of frame B in frame A (``x_A = R x_B + p``), with ``p`` in mm. Frames, joints and other
components are named by their path in the model (``/bodyset/femur_r/femur_implant``), as
OpenSim names them. The conventions are written down in ``formulations/opensim.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from ..errors import OpenSimModelError

__all__ = [
    "Constant",
    "ContactMesh",
    "ContactPair",
    "Coordinate",
    "Frame",
    "Joint",
    "Ligament",
    "LinearFunction",
    "MultiplierFunction",
    "NotModelled",
    "PathPoint",
    "TransformAxis",
    "UnsupportedFunction",
    "WrapObject",
    "frozen_array",
    "frozen_mapping",
]


def frozen_array(values, shape=None) -> np.ndarray:
    """A read-only float64 copy of ``values`` (reshaped to ``shape`` when given)."""
    a = np.array(values, dtype=float)
    if shape is not None:
        a = a.reshape(shape)
    a.setflags(write=False)
    return a


def frozen_mapping(items) -> MappingProxyType:
    """A read-only view of a dict made from ``items`` (a mapping or pairs), in their order."""
    return MappingProxyType(dict(items))


# --- functions of the coordinates -----------------------------------------------------------


@dataclass(frozen=True)
class LinearFunction:
    """OpenSim's ``LinearFunction``: ``f(q) = slope q + intercept``."""

    slope: float = 1.0
    intercept: float = 0.0

    def __call__(self, values: tuple) -> float:
        return self.slope * values[0] + self.intercept


@dataclass(frozen=True)
class Constant:
    """OpenSim's ``Constant``: ``f = value`` whatever the coordinates."""

    value: float = 0.0

    def __call__(self, values: tuple) -> float:
        return self.value


@dataclass(frozen=True)
class MultiplierFunction:
    """OpenSim's ``MultiplierFunction``: ``f(q) = scale g(q)`` (what scaling a model writes)."""

    scale: float
    function: Any

    def __call__(self, values: tuple) -> float:
        return self.scale * self.function(values)


@dataclass(frozen=True)
class UnsupportedFunction:
    """A function dea-opt does not evaluate (``SimmSpline``, ``PolynomialFunction``, ...):
    ``kind`` is its OpenSim type, ``line`` where the model gives it. Calling it raises."""

    kind: str
    line: int
    where: str = ""

    def __call__(self, values: tuple) -> float:
        raise OpenSimModelError(
            f"{self.where} (line {self.line}) is a {self.kind}, which dea-opt does not evaluate (it evaluates "
            f"LinearFunction, Constant and MultiplierFunction of those): the bodies it moves have no pose here"
        )


# --- frames, joints, coordinates --------------------------------------------------------------


@dataclass(frozen=True)
class Frame:
    """A physical frame: ``kind`` "ground", "body" or "offset" (a ``PhysicalOffsetFrame``).

    ``parent`` is the path of the frame an offset frame is fixed to, ``transform`` its pose
    there (4x4, mm: ``translation`` then the body-fixed x-y-z ``orientation``, as OpenSim
    composes them); identity and None for a body or ground. ``body`` names the body (or
    "ground") the frame is fixed to, through its chain of parents.
    """

    path: str
    name: str
    kind: str
    body: str
    parent: str | None = None
    transform: np.ndarray = field(default_factory=lambda: frozen_array(np.eye(4)))
    line: int = 0


@dataclass(frozen=True)
class TransformAxis:
    """One of a ``CustomJoint``'s six axes: ``rotation1..3`` then ``translation1..3``.

    ``axis`` is the unit axis (the model's, normalised as Simbody does), ``coordinates`` the
    names the function takes, ``function`` the amount of rotation (rad) or translation (m) as a
    function of them; ``given`` is False for OpenSim's default function (the model gave none).
    """

    name: str
    axis: np.ndarray
    coordinates: tuple
    function: Any
    given: bool = True


@dataclass(frozen=True)
class Coordinate:
    """A generalised coordinate: its joint, default value, range and OpenSim's motion type.

    Values are in OpenSim's units: rad for ``motion == "rotational"``, m for
    ``"translational"``; a ``"coupled"`` coordinate (its function scales it or is not linear)
    has the units its functions give it.
    """

    name: str
    joint: str
    default_value: float
    range: tuple
    clamped: bool
    locked: bool
    motion: str
    line: int


@dataclass(frozen=True)
class Joint:
    """A joint between two frames: ``kind`` is its OpenSim type.

    ``parent_frame`` and ``child_frame`` are frame paths, ``parent_body``/``child_body`` the
    bodies they are fixed to. A ``CustomJoint`` has its six :class:`TransformAxis` in ``axes``; a
    ``WeldJoint`` none (the two frames coincide). Other kinds are read with their coordinates
    but not evaluated (``supported`` is False).
    """

    name: str
    kind: str
    parent_frame: str
    child_frame: str
    parent_body: str
    child_body: str
    coordinates: tuple
    axes: tuple
    line: int

    @property
    def supported(self) -> bool:
        return self.kind in ("CustomJoint", "WeldJoint")


# --- contact ------------------------------------------------------------------------------


@dataclass(frozen=True)
class ContactMesh:
    """A ``Smith2018ContactMesh``: its surface, the frame it is fixed to and its layer.

    ``file`` is the mesh file as the model names it, ``resolved`` where it was found (next to
    the model, then in its ``Geometry/`` folder, as OpenSim looks) or None, ``searched`` the
    places looked at. ``elastic_modulus`` (MPa), ``poissons_ratio`` and ``thickness`` (mm) are
    the layer's; ``scale`` is the factor from the file's coordinates to mm (1000 times the
    model's ``scale_factors``).
    """

    name: str
    path: str
    frame: str
    body: str
    file: str
    resolved: Path | None
    searched: tuple
    elastic_modulus: float
    poissons_ratio: float
    thickness: float
    scale: np.ndarray
    line: int

    def load(self):
        """The surface in mm, in its own frame (``frame``), checked and repaired by
        :func:`dea_opt.mesh.load_mesh`; raises :class:`~dea_opt.errors.OpenSimModelError` when the
        file was not found."""
        if self.resolved is None:
            raise OpenSimModelError(
                f"contact mesh {self.name} (line {self.line}): its file {self.file!r} is in none of "
                f"{', '.join(str(p) for p in self.searched)}"
            )
        from ..mesh import load_mesh

        if np.ptp(self.scale) == 0.0:
            return load_mesh(self.resolved, scale=float(self.scale[0]))
        mesh = load_mesh(self.resolved)
        mesh.apply_scale(self.scale)  # per-axis scale factors of a scaled model
        return mesh


@dataclass(frozen=True)
class ContactPair:
    """A ``Smith2018ArticularContactForce``: springs on the ``casting`` mesh (dea-opt's mesh 1)
    cast onto the ``target`` (mesh 2).

    ``min_proximity``/``max_proximity`` (mm) bound the depth (overlap) of a contacting
    triangle, ``formulation`` is "linear" or "nonlinear", ``lumped`` JAM's
    ``use_lumped_contact_model``. :meth:`law` gives the matching dea-opt law.
    """

    name: str
    casting: ContactMesh
    target: ContactMesh
    min_proximity: float
    max_proximity: float
    formulation: str
    lumped: bool
    line: int

    @property
    def thickness(self) -> float:
        """The spring's unloaded length ``h = h_casting + h_target`` (mm)."""
        return self.casting.thickness + self.target.thickness

    @property
    def modulus(self) -> float:
        """``H`` (MPa) of dea-opt's law for this pair (``formulations/opensim.md``, "Contact").

        Lumped: ``H = (1 - nu) E / ((1 + nu)(1 - 2 nu))`` with E and nu the two meshes' means;
        not lumped, linear: the two layers in series over ``h``,
        ``H = h k_c k_t / (k_c + k_t)`` with ``k = (1 - nu) E / ((1 + nu)(1 - 2 nu) h_mesh)``.
        """
        c, t = self.casting, self.target
        if self.lumped:
            E = 0.5 * (c.elastic_modulus + t.elastic_modulus)
            nu = 0.5 * (c.poissons_ratio + t.poissons_ratio)
            return _aggregate(E, nu)
        if self.formulation != "linear":
            raise OpenSimModelError(
                f"contact {self.name} (line {self.line}): the nonlinear formulation without the lumped model "
                f"(two logarithmic layers in series, solved per triangle) has no dea-opt law"
            )
        kc = _aggregate(c.elastic_modulus, c.poissons_ratio) / c.thickness
        kt = _aggregate(t.elastic_modulus, t.poissons_ratio) / t.thickness
        return self.thickness * kc * kt / (kc + kt)

    def law(self):
        """dea-opt's law: :class:`~dea_opt.laws.LinearLaw` (linear) or
        :class:`~dea_opt.laws.BlankevoortLaw` (nonlinear: ``p = -H ln(1 - d/h)``), of :attr:`modulus`,
        for springs of thickness :attr:`thickness`."""
        from ..laws import BlankevoortLaw, LinearLaw

        H = self.modulus
        return LinearLaw(H) if self.formulation == "linear" else BlankevoortLaw(H)

    @property
    def window(self) -> tuple:
        """dea-opt's proximity window ``(max_gap, max_overlap)`` (mm): JAM's depth window
        ``[min_proximity, max_proximity]`` as gaps (a gap is minus the depth)."""
        return (-self.min_proximity, self.max_proximity)


def _aggregate(E: float, nu: float) -> float:
    """The aggregate (confined compression) modulus ``(1 - nu) E / ((1 + nu)(1 - 2 nu))`` (MPa)."""
    return (1.0 - nu) * E / ((1.0 + nu) * (1.0 - 2.0 * nu))


# --- ligaments and what is not modelled ----------------------------------------------------------


@dataclass(frozen=True)
class PathPoint:
    """A point of a ligament's path: ``location`` (mm) in ``frame``, fixed to ``body``.

    ``kind`` is its OpenSim type: "PathPoint" (fixed), "ConditionalPathPoint" or
    "MovingPathPoint" (not modelled, see :class:`NotModelled`).
    """

    name: str
    frame: str
    body: str
    location: np.ndarray
    kind: str
    line: int


@dataclass(frozen=True)
class Ligament:
    """A ``Blankevoort1991Ligament`` bundle.

    ``points`` are its fixed path points in order (the first and last are the insertions);
    ``stiffness`` is in N per unit strain, ``slack_length`` in mm (given, or from
    ``reference_strain`` at the default pose, ``slack_from`` says which), ``transition_strain``
    and ``damping`` (N per unit strain rate) as OpenSim reads them, with its defaults (0.06,
    0.003) when the model leaves them out. ``wraps`` names its wrap objects (not modelled).
    """

    name: str
    points: tuple
    stiffness: float
    slack_length: float
    slack_from: str
    reference_strain: float | None
    transition_strain: float
    damping: float
    wraps: tuple
    applies_force: bool
    line: int

    @property
    def body1(self) -> str:
        return self.points[0].body

    @property
    def body2(self) -> str:
        return self.points[-1].body


@dataclass(frozen=True)
class WrapObject:
    """A wrap object (``WrapEllipsoid``, ``WrapCylinder``, ...): ``kind``, the ``body`` it is
    fixed to, its pose there (4x4, mm) and its dimensions (mm: ``radii`` of an ellipsoid,
    ``radius`` and ``length`` of a cylinder, ``radius`` of a sphere; empty when unknown)."""

    name: str
    kind: str
    body: str
    transform: np.ndarray
    dimensions: MappingProxyType
    line: int


@dataclass(frozen=True)
class NotModelled:
    """One thing of the model dea-opt does not model, by name, with what happens instead.

    ``kind``: "wrap", "via_points", "conditional_path_point", "moving_path_point", "muscle",
    "force", "constraint", "joint", "joint_function", "contact", "ligament", "property",
    "component". ``detail`` holds numbers where they are known (lengths in mm, at the
    model's default pose).
    """

    kind: str
    name: str
    what: str
    line: int = 0
    detail: MappingProxyType = field(default_factory=lambda: MappingProxyType({}))

    def describe(self) -> str:
        """One line: kind, name, what and the details."""
        extra = "; ".join(f"{k} = {_short(v)}" for k, v in self.detail.items())
        return f"{self.kind} {self.name} (line {self.line}): {self.what}" + (f" [{extra}]" if extra else "")


def _short(value) -> str:
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, (tuple, list)):
        return "[" + ", ".join(_short(v) for v in value) + "]"
    return str(value)
