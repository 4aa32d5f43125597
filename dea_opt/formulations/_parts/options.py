"""What a formulation declares about itself: its options and its capabilities.

Every formulation module exposes ``OPTIONS`` (a tuple of :class:`Option`) and
``CAPABILITIES`` (a :class:`Capabilities`); :func:`validate` is the one place where options
are checked, for ``dea_opt.solve``, load paths, studies and the models built directly.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from numbers import Integral, Real
from typing import Any

from ...errors import InputError

__all__ = ["Capabilities", "Option", "Variant", "newton_tolerances", "validate"]


@dataclass(frozen=True)
class Option:
    """One option of a formulation.

    Attributes
    ----------
    name : str
    type : {float, int, bool, str, dict}
        ``float``: a real number in the open interval ``range``; ``int``: an integer
        ``>= range[0]``; ``str``: one of ``choices`` (after ``normalize``); ``dict``: a dict
        with string keys; ``bool``: True or False.
    default : object
    doc : str
        One line for the documentation's options table and the error messages.
    range : tuple, optional
        ``(low, high)`` (``high`` may be None).
    choices : tuple of str or callable, optional
        The accepted values, or a function returning them (asked only when checking).
    normalize : callable, optional
        Applied to a ``str`` value before it is checked (e.g. ``str.upper``).
    tolerance : bool
        One accuracy setting (``[solve].tol``, a study's accuracy) sets this option.
    build : bool
        Used when the model is built (True) or at each solve (False); both are given to
        the model's constructor.
    """

    name: str
    type: type
    default: object
    doc: str
    range: tuple | None = None
    choices: tuple | Callable | None = None
    normalize: Callable | None = None
    tolerance: bool = False
    build: bool = True

    def accepted(self) -> tuple:
        """The accepted values of a ``str`` option with choices."""
        return tuple(self.choices() if callable(self.choices) else self.choices or ())

    def check(self, value):
        """``value`` checked (and normalised), or an :class:`InputError` naming the option."""
        name = self.name
        if self.type is float:
            low, high = self.range or (-math.inf, math.inf)
            number = isinstance(value, Real) and not isinstance(value, bool)
            if not (number and math.isfinite(value) and low < value < high):
                raise InputError(f"{name} must be a number in ({low:g}, {high:g}), got {value!r}")
            return float(value)
        if self.type is int:
            low = (self.range or (1, None))[0]
            if isinstance(value, bool) or not isinstance(value, Integral) or value < low:
                raise InputError(f"{name} must be an integer >= {low}, got {value!r}")
            return int(value)
        if self.type is bool:
            if not isinstance(value, bool):
                raise InputError(f"{name} must be True or False, got {value!r}")
            return value
        if self.type is dict:
            if value is None:
                return {}
            if not (isinstance(value, dict) and all(isinstance(key, str) for key in value)):
                raise InputError(f"{name} must be a dict of {self.doc}, got {value!r}")
            return dict(value)
        text = self.normalize(value) if self.normalize is not None and isinstance(value, str) else value
        if isinstance(text, str) and text == self.default:
            return text  # the default needs no asking (qp's choices import cvxpy, ~1 s)
        accepted = self.accepted()
        if not isinstance(text, str) or (accepted and text not in accepted):
            raise InputError(f"{name} must be one of {list(accepted)} ({self.doc}), got {value!r}")
        return text

    def kind(self) -> str:
        """What the option takes, in words: ``number in (0, 1)``, ``integer >= 1``, ..."""
        if self.type is float:
            low, high = self.range or (-math.inf, math.inf)
            return f"number in ({low:g}, {high:g})"
        if self.type is int:
            return f"integer >= {(self.range or (1, None))[0]}"
        if self.type is str and not callable(self.choices):
            return " or ".join(map(repr, self.accepted()))
        return {str: "name", dict: "dict", bool: "True or False"}.get(self.type, self.type.__name__)

    def describe(self) -> str:
        """``name`` (kind; default): doc. For messages and listings."""
        return f"{self.name} ({self.kind()}; default {self.default!r}): {self.doc}"


@dataclass(frozen=True)
class Variant:
    """The option a comparison study varies (one row per value), and each value's label."""

    option: str
    labels: dict | None = None

    def label(self, value) -> str:
        return str((self.labels or {}).get(value, value))


@dataclass(frozen=True)
class Capabilities:
    """What a formulation can do, for the registry's queries.

    Attributes
    ----------
    laws : {"linear", "any"}
        The laws it takes: a :class:`~dea_opt.laws.LinearLaw` only (``law.is_linear``), or any.
    warm_start : bool
        A re-solve starts from the previous answer (``Model.solve(load, x0=...)``, or the
        model's own last answer).
    kinematics : tuple of str
        The kinematics it solves: ``"small"`` (the linearised small rotations of Eq. 9-11).
    duals : bool
        Its spring forces are multipliers of contact constraints (independent of the law's
        stress at ``u``, which the certificate compares them with).
    checks_load_first : bool
        Its problem is infeasible or unbounded when the springs cannot carry the load, so
        the cone test (:func:`dea_opt.check_load_supported`) runs before it, not after a
        failure.
    """

    laws: str = "any"
    warm_start: bool = False
    kinematics: tuple = ("small",)
    duals: bool = False
    checks_load_first: bool = True

    def __post_init__(self):
        if self.laws not in ("linear", "any"):
            raise InputError(f"Capabilities.laws must be 'linear' or 'any', got {self.laws!r}")

    def takes(self, law) -> bool:
        """Whether it solves problems with ``law``."""
        return self.laws == "any" or bool(law.is_linear)


def newton_tolerances(settled: str) -> tuple[Option, Option]:
    """``(xtol, gtol)`` of a Newton that re-solves at a pose (the joint's, the finite formulation's):
    the relative step that counts as converged once ``settled`` (``"the contact set is"``) is
    unchanged, and the equilibrium residual in the scaled variables; both 1e-12."""
    return (
        Option(
            "xtol",
            float,
            1e-12,
            f"relative step that counts as converged once {settled} unchanged",
            range=(0, 1),
            tolerance=True,
        ),
        Option(
            "gtol",
            float,
            1e-12,
            "equilibrium residual in the scaled variables that counts as converged",
            range=(0, 1),
            tolerance=True,
        ),
    )


def validate(method: str, options: tuple, given: dict, extra: str | None = None) -> dict[str, Any]:
    """Every option of ``options`` (``given`` or its default), checked; unknown names are an
    :class:`InputError` naming the accepted ones, unless ``extra`` says where they go (they
    are then returned unchecked, for that solver to judge).

    Parameters
    ----------
    method : str
        The formulation's name, for the messages.
    options : tuple of Option
    given : dict
    extra : str, optional
        Where options the formulation does not declare go (e.g. "passed to the QP solver").
    """
    known = {option.name: option for option in options}
    out: dict[str, Any] = {}
    for key, value in given.items():
        if key in known:
            out[key] = known[key].check(value)
        elif extra is None:
            accepted = [*known, "x0"]
            raise InputError(f"method {method!r} takes the options {accepted}, got unknown option {key!r}")
        else:
            out[key] = value
    for option in options:
        out.setdefault(option.name, option.default)
    return out
