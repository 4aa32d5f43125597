"""Is a solved answer inside the model it solved? The validity report of every result.

The certificate (:mod:`dea_opt.solution`) says the answer solves the equations; this module
says whether those equations still describe cartilage at that answer: the strain within the
law's range and short of crushing, rotations small enough for the linearised kinematics of
Eq. (9)-(11) (with the gap error they imply at the springs, computed exactly), sizes and
pressures that a human joint has (so meshes in metres or loads in the wrong unit are caught),
and the springs the proximity window dropped at the solved pose. The formulas, the limits and
their sources are in ``formulations/validity.md``.

Every check is one :class:`Check` (name, value, limit, unit, passed, advice); a
:class:`Validity` holds them all and is valid only if every evaluated check passed. Limits are
the documented defaults of :class:`ValidityLimits`; pass your own to :func:`assess`.
Everything is O(N) NumPy: no solve, no mesh query.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ._checks.inputs import number_in_range
from .errors import InputError
from .problem import ContactProblem

__all__ = ["DEFAULT_LIMITS", "Check", "Validity", "ValidityLimits", "assess", "rotation_gap_error"]


def _limit(name, value, high=None) -> float:
    """A limit in ``(0, high]``, or an InputError naming it."""
    return number_in_range(name, value, 0.0, high, low_open=True)


def _range(name, value) -> tuple[float, float]:
    """A pair ``(low, high)`` with ``0 <= low < high``, or an InputError naming it."""
    try:
        low, high = value
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a pair (low, high) of numbers, got {value!r}") from None
    low = number_in_range(f"{name}[0]", low, 0.0)
    return low, number_in_range(f"{name}[1]", high, low, low_open=True)


@dataclass(frozen=True)
class ValidityLimits:
    """The limits of every validity check, with documented defaults (``formulations/validity.md``).

    Parameters
    ----------
    compression : float or None, default None
        Largest compressive strain the law is trusted to; ``None`` takes the law's own
        ``valid_compression`` (0.30 for :class:`~dea_opt.laws.LinearLaw`, the paper's limit;
        none for the other laws, which then meet only ``crushing``).
    crushing : float, default 0.8
        Compressive strain no law may reach: cartilage is 68-85 % water, so at 80 %
        compression only its solid matrix (about a fifth of its volume) would be left, and a
        layer squeezed further compresses the solid itself. Strain 1 is crushed to nothing.
    rotation : float, default 3
        Largest rotation of either body (degrees) for the small-rotation kinematics.
    gap_error : float, default 0.01
        Largest error of the linearised rigid motion along a spring's normal, as a fraction
        of its thickness (an error in strain): 0.01 against working strains of 0.05-0.3.
    extent : (float, float), default (1, 1000)
        Size of the spring layer (mm): human cartilage layers span 10-100 mm.
    layer_area : (float, float), default (1, 1e5)
        Total area of the springs (mm^2): human layers carry 100-10 000 mm^2.
    thickness : (float, float), default (0.1, 20)
        Area-weighted mean spring thickness (mm): human cartilage is 0.5-6 mm thick.
    peak_pressure : float, default 35
        Largest pressure (MPa): joints see 1-20 MPa; cartilage fails at about 25-35 MPa.
    dropped_springs : int, default 0
        Springs the proximity window dropped at the solved pose that are allowed.
    """

    compression: float | None = None
    crushing: float = 0.8
    rotation: float = 3.0
    gap_error: float = 0.01
    extent: tuple = (1.0, 1000.0)
    layer_area: tuple = (1.0, 1e5)
    thickness: tuple = (0.1, 20.0)
    peak_pressure: float = 35.0
    dropped_springs: int = 0

    def __post_init__(self):
        set_ = object.__setattr__
        if self.compression is not None:
            set_(self, "compression", _limit("ValidityLimits.compression", self.compression, 1.0))
        set_(self, "crushing", _limit("ValidityLimits.crushing", self.crushing, 1.0))
        set_(self, "rotation", _limit("ValidityLimits.rotation", self.rotation, 180.0))
        set_(self, "gap_error", _limit("ValidityLimits.gap_error", self.gap_error))
        set_(self, "peak_pressure", _limit("ValidityLimits.peak_pressure", self.peak_pressure))
        for name in ("extent", "layer_area", "thickness"):
            set_(self, name, _range(f"ValidityLimits.{name}", getattr(self, name)))
        dropped = self.dropped_springs
        if isinstance(dropped, bool) or not isinstance(dropped, (int, np.integer)) or dropped < 0:
            raise InputError(f"ValidityLimits.dropped_springs must be an integer >= 0, got {dropped!r}")
        set_(self, "dropped_springs", int(dropped))


DEFAULT_LIMITS = ValidityLimits()


@dataclass(frozen=True)
class Check:
    """One validity check of one result.

    Attributes
    ----------
    name : str
        ``strain``, ``rotation``, ``gap_error``, ``extent``, ``layer_area``, ``thickness``,
        ``peak_pressure`` or ``dropped_springs``.
    value : float
        What was measured, in ``unit``; NaN when not evaluated.
    limit : float or (float, float)
        The upper bound, or the ``(low, high)`` range, the value must stay within.
    unit : str
    passed : bool or None
        ``None`` when the check was not evaluated (``advice`` says why). A value that is not
        finite fails.
    advice : str
        One line: what the failure means and what to do (empty when passed).
    details : tuple of (str, float)
        Further numbers, e.g. ``(("mm", 0.12),)`` for the gap error in mm.
    """

    name: str
    value: float
    limit: float | tuple
    unit: str
    passed: bool | None
    advice: str = ""
    details: tuple = ()

    @property
    def status(self) -> str:
        """``"passed"``, ``"failed"`` or ``"not evaluated"``."""
        return {True: "passed", False: "failed", None: "not evaluated"}[self.passed]

    def describe(self) -> str:
        """``name value > limit unit: advice`` on one line."""
        if self.passed is None:
            return f"{self.name} not evaluated: {self.advice}"
        unit = f" {self.unit}" if self.unit else ""
        if isinstance(self.limit, tuple):
            where = "within" if self.passed else "outside"
            text = f"{self.name} {self.value:.4g} {where} [{self.limit[0]:g}, {self.limit[1]:g}]{unit}"
        else:
            text = f"{self.name} {self.value:.4g} {'<=' if self.passed else '>'} {self.limit:g}{unit}"
        return f"{text}: {self.advice}" if self.advice else text

    def as_dict(self) -> dict:
        """JSON-ready: NaN becomes ``None``, a range a list."""
        return {
            "value": _json_number(self.value),
            "limit": list(self.limit) if isinstance(self.limit, tuple) else self.limit,
            "unit": self.unit,
            "status": self.status,
            "passed": self.passed,
            "advice": self.advice,
            **{key: _json_number(v) for key, v in self.details},
        }


def _json_number(value):
    return float(value) if math.isfinite(value) else None


@dataclass(frozen=True)
class Validity:
    """Whether a result lies inside the model it solved: a tuple of :class:`Check`.

    ``valid`` is True only if every evaluated check passed. ``as_dict()`` is JSON-ready,
    ``columns()`` one flat table row, ``summary()`` one line for a terminal.
    """

    checks: tuple
    limits: ValidityLimits = field(default=DEFAULT_LIMITS)

    @property
    def valid(self) -> bool:
        return all(c.passed is not False for c in self.checks)

    @property
    def failed(self) -> tuple:
        """The checks that failed, in order."""
        return tuple(c for c in self.checks if c.passed is False)

    @property
    def names(self) -> tuple:
        return tuple(c.name for c in self.checks)

    def __getitem__(self, name: str) -> Check:
        for check in self.checks:
            if check.name == name:
                return check
        raise KeyError(f"no validity check named {name!r}; the checks are {self.names}")

    def as_dict(self) -> dict:
        return {
            "valid": self.valid,
            "failed": [c.name for c in self.failed],
            "checks": {c.name: c.as_dict() for c in self.checks},
        }

    def columns(self) -> dict:
        """``{valid, validity_failed, validity_<check>[_<detail>]: value}`` for one table row;
        ``validity_failed`` joins the failed checks' names with ``;``."""
        row = {"valid": self.valid, "validity_failed": ";".join(c.name for c in self.failed)}
        for c in self.checks:
            row[f"validity_{c.name}"] = float(c.value)
            for key, value in c.details:
                row[f"validity_{c.name}_{key}"] = float(value)
        return row

    def summary(self) -> str:
        """One line: ``valid (...)`` or ``NOT VALID: <each failed check>``."""
        skipped = [c.name for c in self.checks if c.passed is None]
        note = f", {', '.join(skipped)} not evaluated" if skipped else ""
        if self.valid:
            passed = sum(c.passed is True for c in self.checks)
            return f"valid ({passed} checks passed{note})"
        failed = "; ".join(_short(c) for c in self.failed)
        return f"NOT VALID ({len(self.failed)} of {len(self.checks)} checks failed{note}): {failed}"

    def message(self) -> str:
        """Every failed check with its value, limit and advice (the ValidityWarning's text)."""
        if self.valid:
            return "the result is inside the model's validity"
        return "solved outside validity: " + "; ".join(c.describe() for c in self.failed)

    def __repr__(self) -> str:
        return f"Validity({self.summary()})"


def _short(check: Check) -> str:
    text = check.describe()
    return text.split(": ", 1)[0]


# --- the checks -------------------------------------------------------------------------------

_NOT_FINITE = "the value is not finite: the solution failed (see its certificate)"


def _strain_check(law, strain, limits: ValidityLimits) -> Check:
    own = limits.compression if limits.compression is not None else getattr(law, "valid_compression", None)
    if own is not None:
        own = _limit(f"{type(law).__name__}.valid_compression", own, 1.0)
    limit = limits.crushing if own is None else min(own, limits.crushing)
    value = float(max(-np.min(strain), 0.0)) if len(strain) else 0.0
    if np.isnan(strain).any():
        value = math.nan
    if value <= limit:
        return Check("strain", value, limit, "", True)
    return Check("strain", value, limit, "", False, _strain_advice(law, value, limit, limits))


def _strain_advice(law, value, limit, limits) -> str:
    if not math.isfinite(value):
        return _NOT_FINITE
    if value >= 1.0:
        return (
            "a spring is crushed through its whole thickness (strain <= -1), which is not physical: "
            "use a bounded law such as AteshianLaw or a smaller load, and check H and the thickness"
        )
    if value > limits.crushing:
        return (
            f"the cartilage is nearly crushed: past {limits.crushing:.0%} compression only its solid "
            f"matrix would be left, which no law of a porous layer describes; check the load, H and the "
            f"thickness"
        )
    if getattr(law, "is_linear", False) and limits.compression is None:
        return (
            f"beyond the range of the linear law ({limit:.0%} compressive strain, where Volokh, Chao & "
            f"Armand find it valid): use AteshianLaw, or check the load and H"
        )
    return f"beyond the range of {law.describe()} ({limit:.0%} compressive strain): use a law valid there"


def _rotation_error_factors(angle: float) -> tuple[float, float]:
    """``(a, b)`` with ``R - I - W = a W + b W^2`` for the rotation by ``angle`` (rad).

    ``a = sin(t)/t - 1`` (its series below 1e-4, where the difference cancels), ``b =
    (1 - cos t)/t^2 = 2 sin(t/2)^2 / t^2`` (formulations/validity.md).
    """
    if angle == 0.0:
        return 0.0, 0.5
    a = -(angle**2) / 6.0 + angle**4 / 120.0 if angle < 1e-4 else math.sin(angle) / angle - 1.0
    b = 2.0 * (math.sin(0.5 * angle) / angle) ** 2
    return a, b


def rotation_gap_error(problem, u) -> np.ndarray:
    """Exact minus linearised motion along each spring's normal (mm), shape (N,).

    For body ``k`` rotated by the vector ``theta_k = u[3:6]`` (or ``u[9:12]``) about its
    reference ``c_k``, the exact motion of a point ``x`` is ``t_k + (R_k - I)(x - c_k)`` and
    the linearised one of Eq. (9) is ``t_k + theta_k x (x - c_k)``; the result is
    ``n_i . (e_2(x_i) - e_1(x_i))`` with ``e_k = (R_k - I - [theta_k]x)(x - c_k)``, the error
    in the spring's gap (formulations/validity.md).
    """
    layer = problem.layer
    u = np.asarray(u, dtype=float)
    error = np.zeros(len(layer))
    # The rows of Eq. (11) hold r_k x n already: n . (theta x r) = theta . (r x n) is
    # -GT[3:6] . theta_1 for body 1 and GT[9:12] . theta_2 for body 2.
    GT = problem.normal_operator.T
    n_dot_x = None
    for sign, body, k in ((-1.0, problem.body1, 3), (1.0, problem.body2, 9)):
        theta = u[k : k + 3]
        angle = float(np.linalg.norm(theta))
        if not math.isfinite(angle):
            return np.full(len(layer), np.nan)
        if angle == 0.0:
            continue
        a, b = _rotation_error_factors(angle)
        c = np.asarray(body.reference)
        if n_dot_x is None:
            n_dot_x = np.einsum("ij,ij->i", layer.normals, layer.points)
        n_theta_r = sign * (theta @ GT[k : k + 3])
        # n . (theta x (theta x r)) = (n . theta)(r . theta) - |theta|^2 (n . r)
        n_twice = (layer.normals @ theta) * (layer.points @ theta - c @ theta) - angle**2 * (
            n_dot_x - layer.normals @ c
        )
        error += sign * (a * n_theta_r + b * n_twice)
    return error


_KINEMATICS_ADVICE = (
    "outside the small-rotation kinematics of Eq. (9)-(11): use finite kinematics, "
    "ContactProblem(..., kinematics='finite') (exact rotations, gaps at the current pose; "
    "formulations/finite.md), fix the dofs the joint does not move, or reduce the load"
)
_FINITE = "finite kinematics take rotations exactly: the small kinematics' error does not apply"


def _rotation_checks(problem, u, limits: ValidityLimits) -> tuple[Check, Check]:
    u = np.asarray(u, dtype=float)
    degrees = math.degrees(max(float(np.linalg.norm(u[3:6])), float(np.linalg.norm(u[9:12]))))
    if getattr(problem, "kinematics", "small") == "finite":
        return (
            Check("rotation", degrees, limits.rotation, "deg", None, _FINITE),
            Check("gap_error", math.nan, limits.gap_error, "of thickness", None, _FINITE, (("mm", math.nan),)),
        )
    if not np.isfinite(u).all():
        degrees = math.nan
    passed = degrees <= limits.rotation
    advice = "" if passed else _NOT_FINITE if math.isnan(degrees) else (f"the rotation is {_KINEMATICS_ADVICE}")
    rotation = Check("rotation", degrees, limits.rotation, "deg", passed, advice)
    layer = problem.layer
    if not len(layer):
        return rotation, Check(
            "gap_error",
            math.nan,
            limits.gap_error,
            "of thickness",
            None,
            "the layer has no springs",
            (("mm", math.nan),),
        )
    error = np.abs(rotation_gap_error(problem, u))
    mm = float(np.max(error))
    relative = float(np.max(error / layer.thickness))
    passed = relative <= limits.gap_error
    advice = (
        ""
        if passed
        else _NOT_FINITE
        if math.isnan(relative)
        else (f"the linearised rotation misplaces a spring by {mm:.3g} mm along its normal, {_KINEMATICS_ADVICE}")
    )
    return rotation, Check("gap_error", relative, limits.gap_error, "of thickness", passed, advice, (("mm", mm),))


def _range_check(name, value, limit, unit, small, large) -> Check:
    low, high = limit
    if low <= value <= high:
        return Check(name, value, limit, unit, True)
    return Check(name, value, limit, unit, False, small if value < low else large)


def _size_checks(layer, limits: ValidityLimits) -> tuple[Check, ...]:
    names = (
        ("extent", limits.extent, "mm"),
        ("layer_area", limits.layer_area, "mm^2"),
        ("thickness", limits.thickness, "mm"),
    )
    if not len(layer):
        return tuple(Check(n, math.nan, lim, unit, None, "the layer has no springs") for n, lim, unit in names)
    area = float(layer.areas.sum())
    # A layer is at least as large as its area says: springs at one point stand for a patch.
    # One strided pass per coordinate is 10x faster than np.ptp(axis=0) over (N, 3).
    span = [float(column.max() - column.min()) for column in layer.points.T]
    extent = max(math.hypot(*span), math.sqrt(area))
    thickness = float(layer.areas @ layer.thickness / area)
    metres = "the geometry looks like metres: load meshes with load_mesh(path, scale=1000)"
    microns = "the geometry looks like micrometres: load meshes with load_mesh(path, scale=0.001)"
    return (
        _range_check(
            "extent",
            extent,
            limits.extent,
            "mm",
            f"the springs span {extent:.3g} mm where a joint's layer spans 10-100 mm; {metres}",
            f"the springs span {extent:.3g} mm where a joint's layer spans 10-100 mm; {microns}",
        ),
        _range_check(
            "layer_area",
            area,
            limits.layer_area,
            "mm^2",
            f"the springs cover {area:.3g} mm^2 where a joint's layer covers 100-10000 mm^2; {metres}",
            f"the springs cover {area:.3g} mm^2 where a joint's layer covers 100-10000 mm^2; {microns}",
        ),
        _range_check(
            "thickness",
            thickness,
            limits.thickness,
            "mm",
            f"mean thickness {thickness:.3g} mm where cartilage is 0.5-6 mm thick: give it in mm",
            f"mean thickness {thickness:.3g} mm where cartilage is 0.5-6 mm thick: give it in mm",
        ),
    )


def _pressure_check(pressure, limits: ValidityLimits) -> Check:
    peak = float(np.max(pressure, initial=0.0))
    passed = peak <= limits.peak_pressure
    advice = (
        ""
        if passed
        else _NOT_FINITE
        if math.isnan(peak)
        else (
            f"a peak of {peak:.4g} MPa is above what cartilage survives (it fails at about 25-35 MPa; joints see "
            f"1-20 MPa): check the load's units (N, not body weights), H's (MPa, not kPa or Pa) and the mesh's (mm)"
        )
    )
    return Check("peak_pressure", peak, limits.peak_pressure, "MPa", passed, advice)


def _dropped_check(dropped, limits: ValidityLimits) -> Check:
    if dropped is None:
        return Check(
            "dropped_springs",
            math.nan,
            limits.dropped_springs,
            "springs",
            None,
            "no count of the springs the proximity window drops at the solved pose was given",
        )
    if isinstance(dropped, bool) or not isinstance(dropped, (int, np.integer)) or dropped < 0:
        raise InputError(f"dropped must be a count of springs (an integer >= 0) or None, got {dropped!r}")
    passed = bool(dropped <= limits.dropped_springs)
    advice = (
        ""
        if passed
        else (
            f"{dropped} spring(s) that carry load at the solved pose lie outside the proximity window: "
            f"cast the springs with a larger max_gap or max_overlap"
        )
    )
    return Check("dropped_springs", float(dropped), limits.dropped_springs, "springs", passed, advice)


def assess(
    problem, u, strain=None, pressure=None, *, limits: ValidityLimits = DEFAULT_LIMITS, dropped: int | None = None
) -> Validity:
    """The validity report of ``u`` as an answer to ``problem``.

    Parameters
    ----------
    problem : ContactProblem
    u : array_like, shape (12,)
        The displacement (mm, rad), body 1 then body 2.
    strain, pressure : array_like, shape (N,), optional
        The springs' strain and pressure (MPa) at ``u``; computed from ``problem`` if omitted.
    limits : ValidityLimits
        The limits of the checks (documented defaults).
    dropped : int, optional
        Springs that carry load at the solved pose but lie outside the proximity window
        (counted by re-casting at that pose); the check is not evaluated without it.

    Returns
    -------
    Validity
        The checks ``strain``, ``rotation``, ``gap_error``, ``extent``, ``layer_area``,
        ``thickness``, ``peak_pressure`` and ``dropped_springs``, in that order.
    """
    if not isinstance(problem, ContactProblem):
        raise InputError(f"problem must be a ContactProblem, got {type(problem).__name__}")
    if not isinstance(limits, ValidityLimits):
        raise InputError(f"limits must be a dea_opt.validity.ValidityLimits, got {type(limits).__name__}")
    u = np.asarray(u, dtype=float)
    if u.shape != (12,):
        raise InputError(f"u must have shape (12,), got shape {u.shape}")
    n = len(problem.layer)
    finite = bool(np.isfinite(u).all())
    if strain is None:
        strain = problem.strain(u) if finite else np.full(n, np.nan)
    strain = np.asarray(strain, dtype=float)
    if pressure is None:
        with np.errstate(invalid="ignore", over="ignore"):
            pressure = -problem.law.stress(np.minimum(strain, 0.0))
    pressure = np.asarray(pressure, dtype=float)
    for name, arr in (("strain", strain), ("pressure", pressure)):
        if arr.shape != (n,):
            raise InputError(f"{name} must have shape ({n},), one value per spring, got shape {arr.shape}")
    checks = (
        _strain_check(problem.law, strain, limits),
        *_rotation_checks(problem, u, limits),
        *_size_checks(problem.layer, limits),
        _pressure_check(pressure, limits),
        _dropped_check(dropped, limits),
    )
    return Validity(checks, limits)
