"""Spring laws: stress, tangent and strain energy of one cartilage spring, and their registry.

Every law writes its formulas once, against an array namespace (NumPy or CasADi):
:mod:`~dea_opt.laws.base` holds :class:`Law`, the base a law of your own subclasses;
:mod:`~dea_opt.laws.kinds` the built-in laws and :data:`LAWS`, the registry of law kinds
(``"linear"`` -> :class:`LinearLaw`, ...) whose machinery is :mod:`~dea_opt.laws.registry`:
each kind's parameters come from the class itself (its dataclass fields and its ``ranges``),
and the scenario schema, ``build_law``, the command line and ``dea-opt schema`` read it.
:func:`register_law` adds a law of your own. The written math is in ``formulations/energy.md``.

Units: ``H`` in MPa, stress and energy density in MPa (= N/mm^2 = mJ/mm^3).
"""

from .base import Law
from .kinds import (
    LAWS,
    AteshianLaw,
    BlankevoortLaw,
    CubicLaw,
    LinearLaw,
    PolynomialLaw,
    ateshian_taylor_coefficients,
    check_law,
    register_law,
)
from .registry import LawKind, LawParameter, Range

__all__ = [
    "LAWS",
    "AteshianLaw",
    "BlankevoortLaw",
    "CubicLaw",
    "Law",
    "LawKind",
    "LawParameter",
    "LinearLaw",
    "PolynomialLaw",
    "Range",
    "ateshian_taylor_coefficients",
    "check_law",
    "register_law",
]
