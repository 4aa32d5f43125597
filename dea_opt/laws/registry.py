"""The registry of law kinds: names, classes and parameters, read from the classes themselves.

:data:`dea_opt.laws.LAWS` is the one registry; this module holds its machinery. A kind's
parameters are its class's dataclass fields (or its constructor's keywords), typed by their
annotations, with the unit, range and meaning of the class attribute ``ranges``
(``{name: Range(low, high, unit, meaning)}``). The scenario schema, ``build_law``, the
command line and ``dea-opt schema`` read the registry; nothing else lists laws.
"""

from __future__ import annotations

import dataclasses
import math
import typing
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from .._checks.inputs import LARGEST
from ..errors import InputError

__all__ = ["HUGE", "LawKind", "LawParameter", "LawRegistry", "Range", "kind_name", "label"]

#: Largest magnitude of a law parameter: products with volumes, strains and lever arms stay finite.
HUGE = LARGEST


class Range(typing.NamedTuple):
    """A parameter's range ``low <= value <= high`` (``low < value`` with ``low_open``; None: no
    bound), its unit and its meaning, for the registry, the scenario schema and the docs."""

    low: float | None
    high: float | None
    unit: str = ""
    meaning: str = ""
    low_open: bool = False


def label(value) -> str:
    if isinstance(value, (bool, np.bool_)):
        return str(bool(value))
    if isinstance(value, (int, float, np.integer, np.floating)):
        return f"{value:g}"
    return repr(value)


def kind_name(cls) -> str:
    """The kind name of a law class: its own ``name`` attribute, else its class name in lower case."""
    own = cls.__dict__.get("name")
    return own if isinstance(own, str) and own else cls.__name__.lower()


_REQUIRED = object()


@dataclass(frozen=True)
class LawParameter:
    """One parameter of a law kind, read from its class: the dataclass field and its ``ranges`` entry.

    Attributes
    ----------
    name : str
    type : type
        ``float`` or ``int`` (from the field's annotation; ``float`` when it says nothing else).
    default : object
        The field's default; :attr:`required` when it has none.
    range : Range or None
    """

    name: str
    type: type
    default: object = _REQUIRED
    range: Range | None = None

    @property
    def required(self) -> bool:
        return self.default is _REQUIRED

    def bounds(self) -> str:
        """``> 0``, ``>= 0 and <= 40``, ...: the range in words (the overflow bound HUGE left out)."""
        r = self.range
        if r is None:
            return "any value"
        parts = []
        if r.low is not None:
            parts.append(f"{'>' if r.low_open else '>='} {r.low:g}")
        if r.high is not None and r.high < HUGE:
            parts.append(f"<= {r.high:g}")
        return " and ".join(parts) or "any value"

    def describe(self) -> str:
        """``aggregate modulus (MPa), > 0`` for the docs."""
        r = self.range
        kind = "an integer" if self.type is int else "a number"
        if r is None:
            return kind
        unit = f" ({r.unit})" if r.unit else ""
        return f"{r.meaning or self.name}{unit}, {kind} {self.bounds()}"

    def check(self, value, where: str = ""):
        """``value`` as this parameter's type, within its range, or a named :class:`InputError`."""
        name = where or self.name
        expected = "an integer" if self.type is int else "a number"
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float, np.integer, np.floating))
            or (self.type is int and not float(value).is_integer())
        ):
            raise InputError(f"{name} must be {expected}, got {value!r}")
        value = int(value) if self.type is int else float(value)
        r = self.range
        unit = f" {r.unit}" if r is not None and r.unit else ""
        if not math.isfinite(value):
            raise InputError(f"{name} must be a finite number, got {value!r}")
        if r is not None and r.high is not None and value > r.high:
            why = " (larger values overflow in the solvers)" if r.high >= HUGE else ""
            raise InputError(f"{name} must be at most {r.high:g}{unit}{why}, got {value!r}")
        if r is not None and r.low is not None and (value < r.low or (r.low_open and value == r.low)):
            raise InputError(f"{name} must be {self.bounds()}{unit}, got {value!r}")
        return value


@dataclass(frozen=True)
class LawKind:
    """One registered law kind: its name, its class and its parameters (in the class's order)."""

    name: str
    cls: type
    parameters: tuple

    @property
    def doc(self) -> str:
        """The first paragraph of the class's docstring, on one line."""
        return " ".join((self.cls.__doc__ or "").strip().split("\n\n")[0].split())

    def parameter(self, name: str) -> LawParameter | None:
        return next((p for p in self.parameters if p.name == name), None)

    def build(self, values: Mapping, prefix: str = ""):
        """The law with ``values`` (checked against the parameters, named ``prefix + name``)."""
        names = [p.name for p in self.parameters]
        unknown = [k for k in values if k not in names]
        if unknown:
            raise InputError(
                f"law kind {self.name!r} takes {', '.join(names) or 'no parameters'}, not "
                f"{', '.join(f'{prefix}{k}' for k in unknown)}"
            )
        checked = {}
        for p in self.parameters:
            if p.name in values:
                checked[p.name] = p.check(values[p.name], f"{prefix}{p.name}")
            elif p.required:
                raise InputError(f"law kind {self.name!r} needs {prefix}{p.name} ({p.describe()})")
        return self.cls(**checked)


def _parameters_of(cls) -> tuple:
    try:
        hints = typing.get_type_hints(cls)
    except Exception:  # noqa: BLE001 - an annotation that does not resolve means "a number"
        hints = {}
    ranges = getattr(cls, "ranges", None) or {}
    if dataclasses.is_dataclass(cls):
        fields = [
            (f.name, f.default if f.default is not dataclasses.MISSING else _REQUIRED)
            for f in dataclasses.fields(cls)
            if f.init
        ]
    else:
        import inspect

        signature = inspect.signature(cls)
        fields = [
            (n, q.default if q.default is not q.empty else _REQUIRED)
            for n, q in signature.parameters.items()
            if q.kind in (q.POSITIONAL_OR_KEYWORD, q.KEYWORD_ONLY)
        ]
    return tuple(
        LawParameter(name, int if hints.get(name) is int else float, default, ranges.get(name))
        for name, default in fields
    )


class LawRegistry(Mapping):
    """Law kinds by name: ``LAWS["ateshian"].cls is AteshianLaw``. Add one with :meth:`register`."""

    def __init__(self, base: type):
        self.base = base
        self._kinds: dict[str, LawKind] = {}
        #: Grows with every change, so readers can tell that the registry changed.
        self.version = 0

    def __getitem__(self, name: str) -> LawKind:
        return self._kinds[name]

    def __iter__(self):
        return iter(self._kinds)

    def __len__(self) -> int:
        return len(self._kinds)

    def register(self, cls=None, *, name: str | None = None, replace: bool = False):
        """Register a :class:`Law` subclass under ``name`` (default: its ``name`` attribute, else
        its class name in lower case); usable as a class decorator. Returns the class."""
        if cls is None:
            return lambda c: self.register(c, name=name, replace=replace)
        if not (isinstance(cls, type) and issubclass(cls, self.base)):
            raise InputError(f"only subclasses of dea_opt.Law can be registered as laws, got {cls!r}")
        name = name or kind_name(cls)
        if not isinstance(name, str) or not name.isidentifier():
            raise InputError(f"a law kind's name must be an identifier (letters, digits, _), got {name!r}")
        if name in self._kinds and self._kinds[name].cls is not cls and not replace:
            raise InputError(
                f"law kind {name!r} is already registered for {self._kinds[name].cls.__name__}; "
                f"pass replace=True to replace it"
            )
        self._kinds[name] = LawKind(name, cls, _parameters_of(cls))
        self.version += 1
        return cls

    def unregister(self, name: str) -> None:
        """Remove the kind ``name`` (no error if it is not registered)."""
        if self._kinds.pop(name, None) is not None:
            self.version += 1

    def kind_of(self, law) -> str | None:
        """The registered kind name of ``law``'s class, or None."""
        return next((k.name for k in self._kinds.values() if type(law) is k.cls), None)

    def build(self, kind: str, values: Mapping, prefix: str = ""):
        """The law of ``kind`` with parameter ``values``; a named :class:`InputError` otherwise."""
        if kind not in self._kinds:
            raise InputError(f"unknown law kind {kind!r}; the registered kinds are {', '.join(self._kinds)}")
        return self._kinds[kind].build(values, prefix)
