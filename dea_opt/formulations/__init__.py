"""The formulations of the DEA problem, by name: the registry every caller reads.

A formulation is a module (or any object with these attributes):

``Model``
    ``Model(system, law, **options)`` builds once for a
    :class:`~dea_opt.formulations.system.SpringSystem` and a law;
    ``model.solve(load=None, *, x0=None)`` re-solves for a new load (default the system's
    own) and returns a :class:`~dea_opt.formulations.system.FormulationResult` whose
    ``status`` is a :class:`~dea_opt.status.Status` (the solver's own in
    ``info["native_status"]``) and whose ``build_time`` is the build's on the first solve
    and 0 after. ``x0`` (one value per free dof) is a start; without it a formulation that
    warm-starts begins from its own last answer.
``OPTIONS``
    A tuple of :class:`Option` (names, types, ranges, defaults), checked by
    :func:`check_options`, the one place options are validated.
``CAPABILITIES``
    A :class:`Capabilities`: the laws it takes, warm starts, kinematics, duals, and whether the
    cone test of the load runs before it.
``EXTRA_OPTIONS`` (optional)
    Where options it does not declare go (``qp``: to the QP solver); ``None`` rejects them.
``VARIANT`` (optional)
    The :class:`Variant` a comparison study varies (``qp``: the solver).
``PAGE`` (optional)
    Its written math, ``formulations/<name>.md`` at the repository's top.

Nothing outside this package names a formulation: ``dea_opt.solve`` (``auto``'s fallback is
:func:`fallback_for`), load paths, studies and scenarios ask the functions below. The option
and capability declarations live in :mod:`dea_opt.formulations._parts.options`.
"""

from __future__ import annotations

from importlib import import_module
from typing import NamedTuple

from ..errors import InputError
from ._parts.options import Capabilities, Option, Variant, validate
from .system import FormulationResult, SpringSystem, start_vector

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
    """Whether ``name`` solves problems with ``law`` in ``kinematics``."""
    caps = capabilities(name)
    return caps.takes(law) and kinematics in caps.kinematics


def stands_for(name: str, kinematics: str = "small") -> str:
    """The formulation method ``name`` runs in ``kinematics``: for finite kinematics ``newton`` and
    ``nlp`` stand for ``finite`` and ``finite_nlp`` (:data:`dea_opt.formulations.finite.ALIASES`,
    while those are registered); any other name is itself."""
    if kinematics != "finite" or name not in ("newton", "nlp"):
        return name
    from .finite import ALIASES

    target = ALIASES.get(name, name)
    return target if target in FORMULATIONS else name


def aliases(kinematics: str = "small") -> dict:
    """``{name: formulation}`` for the names that stand for another formulation in ``kinematics``."""
    return {n: t for n in ("newton", "nlp") if n in FORMULATIONS and (t := stands_for(n, kinematics)) != n}


def alternatives(law, kinematics: str = "small", *, prefix: str = "method=", auto: bool = True) -> str:
    """The methods that solve ``law`` in ``kinematics``, for messages: ``method='finite' or
    method='finite_nlp' (or 'newton' and 'nlp', which stand for 'finite' and 'finite_nlp' here),
    or 'auto'``."""
    able = [n for n in FORMULATIONS if takes(n, law, kinematics)]
    if not able:
        return "another method"
    text = " or ".join(f"{prefix}{n!r}" for n in able)
    alias = {n: t for n, t in aliases(kinematics).items() if t in able}
    if alias:
        names_ = " and ".join(repr(n) for n in alias)
        text += f" (or {names_}, which stand for {' and '.join(repr(t) for t in alias.values())} here)"
    return text + (", or 'auto'" if auto else "")


def check_takes(name: str, law, kinematics: str = "small") -> None:
    """An :class:`InputError` when ``name`` cannot solve ``law`` (naming the methods that can)."""
    if takes(name, law, kinematics):
        return
    able = alternatives(law, kinematics)
    solved = capabilities(name).kinematics
    if kinematics not in solved:
        only = " and ".join(solved)
        raise InputError(
            f"method {name!r} cannot solve {kinematics!r} kinematics: it is a {only}-kinematics method; use {able}"
        )
    able = " or ".join(f"method={n!r}" for n in FORMULATIONS if takes(n, law, kinematics))
    raise InputError(
        f"method {name!r} needs a LinearLaw, got {law.describe()}: use {able or 'another method'} for this law"
    )


def why_not(name: str, law, kinematics: str = "small") -> str | None:
    """Why ``name`` does not apply to ``law`` (for the ``skipped`` lists), or None."""
    if takes(name, law, kinematics):
        return None
    if kinematics not in capabilities(name).kinematics:
        return f"{name} does not solve {kinematics} kinematics"
    return f"{name} needs a linear law"


def _why_skipped(name: str, law, kinematics: str) -> str | None:
    """:func:`why_not`, saying for a method of other kinematics which methods solve these."""
    reason = why_not(name, law, kinematics)
    solved = capabilities(name).kinematics
    if reason is None or kinematics in solved:
        return reason
    return (
        f"{name} is a {' and '.join(solved)}-kinematics method and this problem has kinematics={kinematics!r}: "
        f"use {alternatives(law, kinematics, prefix='', auto=False)}"
    )


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
    (:func:`stands_for`); a method that does not solve the problem (``qp`` for a nonlinear law or
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
        name = stands_for(method, kinematics)
        note = f"{method} stands for {name} with {kinematics} kinematics"
        if name != method and note not in notes:
            notes.append(note)
        reason = _why_skipped(name, law, kinematics)
        if reason is not None:
            skipped.setdefault(name, reason)
        elif name not in run:
            run.append(name)
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
    accepted ones, unless the formulation passes them on (:func:`extra_options`)."""
    return validate(name, options(name), dict(given), extra_options(name))


def tolerance_options(name: str, tol: float | None) -> dict:
    """The options of ``name`` that one accuracy setting ``tol`` sets (``{}`` for None)."""
    if tol is None:
        return {}
    return {option.name: tol for option in options(name) if option.tolerance}


def build(name: str, system: SpringSystem, law, **given):
    """``Model(system, law, **options)`` of ``name``, options checked first."""
    check_takes(name, law)
    return get(name).Model(system, law, **check_options(name, given))


def solve(name: str, system: SpringSystem, law, *, x0=None, **given) -> FormulationResult:
    """Build ``name``'s model and solve it once."""
    x0 = start_vector(system, x0)
    model = build(name, system, law, **given)
    return model.solve(x0=x0)


__all__ = [
    "DEFAULT",
    "FORMULATIONS",
    "Capabilities",
    "FormulationResult",
    "Option",
    "Selection",
    "SpringSystem",
    "Variant",
    "aliases",
    "alternatives",
    "build",
    "capabilities",
    "check_options",
    "check_takes",
    "extra_options",
    "fallback_for",
    "get",
    "names",
    "options",
    "register",
    "select",
    "solve",
    "stands_for",
    "takes",
    "tolerance_options",
    "unregister",
    "variant",
    "why_not",
]
