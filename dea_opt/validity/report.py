"""The validity report's types: the limits of the checks, one check, and a report of them all.

:mod:`dea_opt.validity` (``formulations/validity.md``) makes them; the checks are in
:mod:`dea_opt.validity.checks`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .._checks.inputs import number_in_range
from ..errors import InputError

__all__ = ["CHECK_UNITS", "DEFAULT_LIMITS", "Check", "Validity", "ValidityLimits", "check_column"]


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
    lost_through_layer : int, default 0
        Springs of a finite-kinematics solve that carried load and were lost through the layer
        (at the solved pose their rays meet mesh 2 behind mesh 1's far side) that are allowed.
    stability : float, default 1e-9
        Largest negative stiffness of a finite-kinematics equilibrium along any free direction,
        as a fraction of the stiffest direction's (round-off: any clearly negative stiffness
        makes the equilibrium unstable).
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
    lost_through_layer: int = 0
    stability: float = 1e-9

    def __post_init__(self):
        set_ = object.__setattr__
        if self.compression is not None:
            set_(self, "compression", _limit("ValidityLimits.compression", self.compression, 1.0))
        set_(self, "crushing", _limit("ValidityLimits.crushing", self.crushing, 1.0))
        set_(self, "rotation", _limit("ValidityLimits.rotation", self.rotation, 180.0))
        set_(self, "gap_error", _limit("ValidityLimits.gap_error", self.gap_error))
        set_(self, "peak_pressure", _limit("ValidityLimits.peak_pressure", self.peak_pressure))
        set_(self, "stability", _limit("ValidityLimits.stability", self.stability, 1.0))
        for name in ("extent", "layer_area", "thickness"):
            set_(self, name, _range(f"ValidityLimits.{name}", getattr(self, name)))
        for name in ("dropped_springs", "lost_through_layer"):
            count = getattr(self, name)
            if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
                raise InputError(f"ValidityLimits.{name} must be an integer >= 0, got {count!r}")
            set_(self, name, int(count))


DEFAULT_LIMITS = ValidityLimits()


@dataclass(frozen=True)
class Check:
    """One validity check of one result.

    Attributes
    ----------
    name : str
        ``strain``, ``rotation``, ``gap_error``, ``extent``, ``layer_area``, ``thickness``,
        ``peak_pressure``, ``dropped_springs``, ``lost_through_layer`` or ``stability``.
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
            **{_detail_key(None, key): _json_number(v) for key, v in self.details},
        }

    @property
    def column(self) -> str:
        """The check's column in a table: ``validity_<name>``, ending with its unit when it has one
        (``validity_rotation_deg``, ``validity_peak_pressure_MPa``; :mod:`dea_opt.units`)."""
        return check_column(self.name)


#: The unit of each check whose value has one (:data:`dea_opt.units.SUFFIXES`); the others are a
#: strain, a fraction of the thickness, a count of springs or a relative stiffness.
CHECK_UNITS = {
    "rotation": "deg",
    "body_rotation": "deg",
    "extent": "mm",
    "layer_area": "mm^2",
    "thickness": "mm",
    "peak_pressure": "MPa",
}


def check_column(name: str) -> str:
    """A check's column in a table: ``validity_<name>`` with the suffix of its unit
    (:data:`CHECK_UNITS`): ``validity_rotation_deg``, ``validity_strain``."""
    from ..units import with_unit

    return with_unit(f"validity_{name}", CHECK_UNITS.get(name, ""))


def _detail_key(head: str | None, key: str) -> str:
    """A detail's name: one named by its unit (``mm``) is ``<head>_mm`` (``value_mm`` in JSON,
    ``validity_gap_error_mm`` in a table); another (``bundle``) keeps its name after ``head``."""
    from ..units import SUFFIXES

    if key in SUFFIXES:
        return f"{head or 'value'}_{SUFFIXES[key]}"
    return key if head is None else f"{head}_{key}"


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
        """``{valid, validity_failed, <check column>[_<detail>]: value}`` for one table row (each
        check's column :attr:`Check.column`, ending with its unit: ``validity_rotation_deg``);
        ``validity_failed`` joins the failed checks' names with ``;``."""
        row = {"valid": self.valid, "validity_failed": ";".join(c.name for c in self.failed)}
        for c in self.checks:
            row[c.column] = float(c.value)
            for key, value in c.details:
                row[_detail_key(f"validity_{c.name}", key)] = float(value)
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
