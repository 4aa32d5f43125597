"""The formulations of the DEA problem, by name: the registry every caller reads.

A formulation is a module (or any object with these attributes):

``Model``
    ``Model(system, law, **options)`` builds once for a system and a law;
    ``model.solve(load=None, *, x0=None)`` re-solves for a new load (default the system's
    own) and returns a result whose ``status`` is a :class:`~dea_opt.status.Status` (the
    solver's own in ``info["native_status"]``). ``x0`` (one value per free dof) is a start;
    without it a formulation that warm-starts begins from its own last answer. The system and
    the result are the :class:`Contract` of the kinematics the formulation solves
    (:data:`CONTRACTS`): for small kinematics a
    :class:`SpringSystem` in and a
    :class:`FormulationResult` out (whose ``build_time`` is the
    build's on the first solve and 0 after); for finite kinematics a
    :class:`~dea_opt.formulations.finite.system.FiniteSystem` in and an
    :class:`~dea_opt.formulations.finite.newton.InnerResult` out, which
    :mod:`dea_opt.finite` re-casts and certifies at the solved pose.
``OPTIONS``
    A tuple of :class:`Option` (names, types, ranges, defaults), checked by
    :func:`check_options`, the one place options are validated.
``CAPABILITIES``
    A :class:`Capabilities`: the laws it takes, warm starts, kinematics, duals, and whether the
    cone test of the load runs before it.
``EXTRA_OPTIONS`` (optional)
    Where options it does not declare go (``qp``: to the QP solver); ``None`` rejects them.
``check_extra_options`` (optional)
    ``check_extra_options(checked)`` raises the :class:`InputError` its solver would raise for
    the options it passes on, before any model is built (``qp``: Clarabel's settings): checked
    with its options, so that an option no solver knows is refused even where the formulation
    never runs (``auto``'s fallback).
``VARIANT`` (optional)
    The :class:`Variant` a comparison study varies (``qp``: the solver).
``PAGE`` (optional)
    Its written math, ``formulations/<name>.md`` at the repository's top.

Nothing outside this package names a formulation: ``dea_opt.solve`` (``auto``'s fallback is
:func:`fallback_for`), load paths, studies and scenarios ask the functions below; what a method
name runs in given kinematics, and why it cannot, is :func:`resolve`'s alone. The option and
capability declarations live in :mod:`dea_opt.formulations._parts.options`. A formulation of
your own finds its contract here: :class:`SpringSystem`, :class:`FormulationResult`,
:func:`scaling` (the scaled variables every formulation solves in), :func:`trivial_result` (no
load, or nothing resisted: no solver) and :func:`start_vector`.
"""

from __future__ import annotations

from importlib import import_module
from typing import NamedTuple

from ..errors import InputError
from ._parts.options import Capabilities, Option, Variant, validate
from ._parts.scaling import Scaling, scaling
from ._parts.system import FormulationResult, SpringSystem, start_vector, trivial_result

#: name -> module, or its import path (imported on first use: cvxpy and CasADi are heavy).
#: The order is the order of preference where several fit (:func:`fallback_for`).
FORMULATIONS: dict = {
    "newton": "dea_opt.formulations.newton",
    "qp": "dea_opt.formulations.qp",
    "nlp": "dea_opt.formulations.nlp",
    # Finite kinematics (exact rotation, gaps at the current pose): kinematics="finite" problems only.
    "finite": "dea_opt.formulations.finite",
    "finite_nlp": "dea_opt.formulations.finite.nlp",
}

#: The formulation ``method="auto"`` runs first, the reference of comparison studies, and the
#: one whose equilibrium answers a press fit under no load for every method: it takes any
#: law, warm-starts, and needs no compiled solver.
DEFAULT = "newton"

_REQUIRED = ("Model", "OPTIONS", "CAPABILITIES")


class Contract(NamedTuple):
    """What the formulations of one kinematics are built on and give back: ``Model(system, law,
    **options)`` takes a ``system`` and ``model.solve(...)`` returns a ``result``."""

    system: type
    result: type


#: kinematics -> ``(system, result)`` of its :class:`Contract`, as ``"module:name"`` (finite
#: kinematics' types are imported when first asked for).
CONTRACTS: dict = {
    "small": (
        "dea_opt.formulations._parts.system:SpringSystem",
        "dea_opt.formulations._parts.system:FormulationResult",
    ),
    "finite": ("dea_opt.formulations.finite.system:FiniteSystem", "dea_opt.formulations.finite.newton:InnerResult"),
}

#: Per kinematics, the method names that stand there for another formulation: under finite
#: kinematics the small kinematics' ``newton`` and ``nlp`` run ``finite`` and ``finite_nlp``.
#: Read by :func:`resolve` alone.
STANDS_FOR: dict = {"finite": {"newton": "finite", "nlp": "finite_nlp"}}


def register(name: str, module, *, replace: bool = False) -> None:
    """Add formulation ``name``: a module (or its import path) with the attributes above.

    Raises
    ------
    InputError
        ``name`` is taken (and not ``replace``), is ``"auto"``, or ``module`` lacks
        ``Model``, ``OPTIONS`` or ``CAPABILITIES``.
    """
    if not (isinstance(name, str) and name.isidentifier()) or name == "auto":
        raise InputError(f"a formulation's name must be an identifier other than 'auto', got {name!r}")
    if name in FORMULATIONS and not replace:
        raise InputError(f"formulation {name!r} is already registered (pass replace=True to replace it)")
    if not isinstance(module, str):
        _check_module(name, module)
    FORMULATIONS[name] = module


def unregister(name: str) -> None:
    """Remove formulation ``name`` (the built-in ones too)."""
    get(name)
    del FORMULATIONS[name]


def _check_module(name, module) -> None:
    missing = [attr for attr in _REQUIRED if not hasattr(module, attr)]
    if missing:
        raise InputError(
            f"formulation {name!r} must define {', '.join(_REQUIRED)}; {module!r} lacks {', '.join(missing)}"
        )
    if not isinstance(module.CAPABILITIES, Capabilities):
        raise InputError(f"formulation {name!r}: CAPABILITIES must be a Capabilities, got {module.CAPABILITIES!r}")
    if not all(isinstance(option, Option) for option in module.OPTIONS):
        raise InputError(f"formulation {name!r}: OPTIONS must be a tuple of Option")


def names() -> tuple:
    """The registered formulations, in order of preference (for scenario method lists)."""
    return tuple(FORMULATIONS)


def get(name: str):
    """The module of formulation ``name``; an :class:`InputError` naming the registered ones."""
    if not isinstance(name, str) or name not in FORMULATIONS:
        raise InputError(f"method must be one of {('auto', *FORMULATIONS)}, got {name!r}")
    module = FORMULATIONS[name]
    if isinstance(module, str):
        module = import_module(module)
        _check_module(name, module)
        FORMULATIONS[name] = module
    return module


def capabilities(name: str) -> Capabilities:
    return get(name).CAPABILITIES


def options(name: str) -> tuple:
    """The :class:`Option` tuple of ``name``."""
    return tuple(get(name).OPTIONS)


def extra_options(name: str) -> str | None:
    """Where ``name`` sends options it does not declare, or None (it rejects them)."""
    return getattr(get(name), "EXTRA_OPTIONS", None)


def variant(name: str) -> Variant | None:
    """The option a comparison study varies for ``name`` (None: one row)."""
    return getattr(get(name), "VARIANT", None)


def takes(name: str, law, kinematics: str = "small") -> bool:
    """Whether ``name`` solves problems with ``law`` (None: any law) in ``kinematics``."""
    caps = capabilities(name)
    return kinematics in caps.kinematics and (law is None or caps.takes(law))


def contract(kinematics: str) -> Contract:
    """The :class:`Contract` (system and result types) of the formulations of ``kinematics``."""
    if kinematics not in CONTRACTS:
        raise InputError(f"kinematics must be one of {tuple(CONTRACTS)}, got {kinematics!r}")
    loaded = []
    for path in CONTRACTS[kinematics]:
        module, _, attr = path.partition(":")
        loaded.append(getattr(import_module(module), attr))
    return Contract(*loaded)


class Resolution(NamedTuple):
    """What :func:`resolve` makes of a method name for a law in given kinematics.

    ``method`` the name given; ``name`` the formulation it runs there (``finite`` for ``newton``
    under finite kinematics, else itself); ``reason`` why ``name`` does not solve the problem,
    short, for the ``skipped`` lists (None: it does); ``able`` the formulations that do.
    """

    method: str
    name: str
    kinematics: str
    reason: str | None
    able: tuple
    law: object = None

    @property
    def note(self) -> str | None:
        """``"newton stands for finite with finite kinematics"``, or None for a name that is itself."""
        if self.name == self.method:
            return None
        return f"{self.method} stands for {self.name} with {self.kinematics} kinematics"

    def use(self, prefix: str = "method=", auto: bool = True) -> str:
        """The methods that solve the problem, for messages: ``method='finite' or
        method='finite_nlp' (or 'newton' and 'nlp', which stand for 'finite' and 'finite_nlp'
        here), or 'auto'``."""
        if not self.able:
            return "another method"
        text = " or ".join(f"{prefix}{n!r}" for n in self.able)
        alias = {n: t for n, t in STANDS_FOR.get(self.kinematics, {}).items() if n in FORMULATIONS and t in self.able}
        if alias:
            said = " and ".join(repr(n) for n in alias)
            text += f" (or {said}, which stand for {' and '.join(repr(t) for t in alias.values())} here)"
        return text + (", or 'auto'" if auto else "")

    def check(self) -> str:
        """``name``, or an :class:`InputError` saying why it does not solve the problem and what does."""
        if self.reason is None:
            return self.name
        solved = capabilities(self.name).kinematics
        if self.kinematics not in solved:
            raise InputError(
                f"method {self.name!r} cannot solve {self.kinematics!r} kinematics: it is a "
                f"{' and '.join(solved)}-kinematics method; use {self.use()}"
            )
        able = " or ".join(f"method={n!r}" for n in self.able) or "another method"
        described = self.law.describe() if hasattr(self.law, "describe") else repr(self.law)
        raise InputError(f"method {self.name!r} needs a LinearLaw, got {described}: use {able} for this law")


def resolve(method: str, law=None, kinematics: str = "small") -> Resolution:
    """The formulation method name ``method`` runs for ``law`` (None: any law) in ``kinematics``,
    and whether it solves that problem: the one place a name is read.

    Under finite kinematics ``newton`` and ``nlp`` stand for ``finite`` and ``finite_nlp``
    (:data:`STANDS_FOR`, while those are registered); any other name is itself. The
    :class:`Resolution` says why the formulation does not solve the problem (``reason``, for
    skip lists) and raises that as an :class:`InputError` naming what does (``check()``).

    Raises
    ------
    InputError
        ``method`` is not a registered formulation.
    """
    if not isinstance(method, str) or method not in FORMULATIONS:
        raise InputError(f"method must be one of {('auto', *FORMULATIONS)}, got {method!r}")
    target = STANDS_FOR.get(kinematics, {}).get(method, method)
    name = target if target in FORMULATIONS else method
    able = tuple(n for n in FORMULATIONS if takes(n, law, kinematics))
    reason = None
    if not takes(name, law, kinematics):
        solved = capabilities(name).kinematics
        if kinematics in solved:
            reason = f"{name} needs a linear law"
        else:
            others = Resolution(method, name, kinematics, "", able).use(prefix="", auto=False)
            reason = (
                f"{name} is a {' and '.join(solved)}-kinematics method and this problem has "
                f"kinematics={kinematics!r}: use {others}"
            )
    return Resolution(method, name, kinematics, reason, able, law)


class Selection(NamedTuple):
    """The formulations a comparison of several methods runs (:func:`select`).

    ``run``: the formulations, each once, in the order named; ``skipped``: ``{name: why}`` for
    those that do not solve the problem, saying what does; ``notes``: the names that stand for
    another formulation (``"newton stands for finite with finite kinematics"``).
    """

    run: list
    skipped: dict
    notes: list


def select(methods, law, kinematics: str = "small", *, what: str = "methods") -> Selection:
    """What ``dea_opt.compare`` and comparison studies run of ``methods`` for ``law`` in ``kinematics``.

    For finite kinematics ``newton`` and ``nlp`` stand for ``finite`` and ``finite_nlp``
    (:func:`resolve`); a method that does not solve the problem (``qp`` for a nonlinear law or
    finite kinematics) is skipped, with why. ``what`` names ``methods`` in errors.

    Raises
    ------
    InputError
        A name that is not a registered formulation, no name, or no method named that solves
        the problem (the message says why each does not, and what does).
    """
    known, methods = names(), [methods] if isinstance(methods, str) else list(methods)
    bad = [m for m in methods if m not in known]
    if bad or not methods:
        raise InputError(f"{what} must be taken from {', '.join(known)}, got {', '.join(map(str, bad)) or 'none'}")
    run: list = []
    skipped: dict = {}
    notes: list = []
    for method in methods:
        resolved = resolve(method, law, kinematics)
        if resolved.note is not None and resolved.note not in notes:
            notes.append(resolved.note)
        if resolved.reason is not None:
            skipped.setdefault(resolved.name, resolved.reason)
        elif resolved.name not in run:
            run.append(resolved.name)
    if not run:
        raise InputError(f"no method in {what} solves this problem: {'; '.join(skipped.values())}")
    return Selection(run, skipped, notes)


def fallback_for(law, kinematics: str = "small") -> str | None:
    """``auto``'s second choice for ``law``: the first registered formulation other than
    :data:`DEFAULT` that takes it (``qp`` for a linear law, ``nlp`` otherwise, as registered)."""
    for name in FORMULATIONS:
        if name != DEFAULT and takes(name, law, kinematics):
            return name
    return None


def check_options(name: str, given: dict) -> dict:
    """``given`` checked against the options of ``name``, defaults filled in (``x0`` is not an
    option of the model: leave it out). Unknown names are an :class:`InputError` naming the
    accepted ones, unless the formulation passes them on (:func:`extra_options`), and then those
    its solver would refuse are (``check_extra_options`` of the module)."""
    checked = validate(name, options(name), dict(given), extra_options(name))
    check_extra = getattr(get(name), "check_extra_options", None)
    if check_extra is not None:
        check_extra(checked)
    return checked


def tolerance_options(name: str, tol: float | None) -> dict:
    """The options of ``name`` that one accuracy setting ``tol`` sets (``{}`` for None)."""
    if tol is None:
        return {}
    return {option.name: tol for option in options(name) if option.tolerance}


def build(name: str, system, law, **given):
    """``Model(system, law, **options)`` of ``name``, options checked first: ``name`` must solve
    ``law`` in the kinematics whose :class:`Contract` ``system`` is (a
    :class:`~dea_opt.formulations._parts.system.SpringSystem`: small kinematics)."""
    kinematics = "small" if isinstance(system, SpringSystem) else None
    if kinematics is None:
        kinematics = next((k for k in CONTRACTS if isinstance(system, contract(k).system)), None)
    if kinematics is None:
        systems = ", ".join(path.rpartition(":")[2] for path, _ in CONTRACTS.values())
        raise InputError(f"system must be one of {systems}, got {type(system).__name__}")
    resolved = resolve(name, law, kinematics).check()
    if resolved != name:
        raise InputError(f"method {name!r} stands for {resolved!r} with {kinematics} kinematics: build {resolved!r}")
    return get(name).Model(system, law, **check_options(name, given))


def solve(name: str, system: SpringSystem, law, *, x0=None, **given) -> FormulationResult:
    """Build ``name``'s model and solve it once."""
    x0 = start_vector(system, x0)
    model = build(name, system, law, **given)
    return model.solve(x0=x0)


__all__ = [
    "DEFAULT",
    "FORMULATIONS",
    "CONTRACTS",
    "STANDS_FOR",
    "Capabilities",
    "Contract",
    "FormulationResult",
    "Option",
    "Resolution",
    "Selection",
    "Scaling",
    "SpringSystem",
    "Variant",
    "build",
    "capabilities",
    "check_options",
    "contract",
    "extra_options",
    "fallback_for",
    "get",
    "names",
    "options",
    "register",
    "resolve",
    "scaling",
    "select",
    "solve",
    "takes",
    "trivial_result",
    "tolerance_options",
    "unregister",
    "variant",
]
