"""The built-in spring laws (linear, Ateshian, cubic, polynomial, Blankevoort) and their registry.

Each law is a :class:`~dea_opt.laws.base.Law` subclass whose formulas are written once for
NumPy and CasADi; ``formulations/energy.md`` has the math. :data:`LAWS` maps each kind's name
to its class and parameters, read from the class itself.

Units: ``H`` in MPa, stress and energy density in MPa (= N/mm^2 = mJ/mm^3).
"""

from __future__ import annotations

import dataclasses
import math
import typing
from dataclasses import dataclass

import numpy as np

from .._checks.inputs import LARGEST, SMALLEST
from .._checks.thresholds import LINEAR_VALIDITY
from ..errors import InputError
from .base import Law, _positive
from .registry import HUGE as _HUGE
from .registry import LawRegistry, Range

__all__ = [
    "LAWS",
    "AteshianLaw",
    "BlankevoortLaw",
    "CubicLaw",
    "LinearLaw",
    "PolynomialLaw",
    "ateshian_taylor_coefficients",
    "check_law",
    "register_law",
]


@dataclass(frozen=True)
class LinearLaw(Law):
    """The classical DEA spring, ``sigma = H eps``.

    Parameters
    ----------
    H : float
        Aggregate modulus in MPa (> 0).
    """

    H: float
    ranges: typing.ClassVar[dict] = {"H": Range(0.0, _HUGE, "MPa", "aggregate modulus", low_open=True)}
    name = "linear"
    is_linear = True
    #: The paper's limit of validity: Eq. (2) is almost linear up to 30 % strain.
    valid_compression = LINEAR_VALIDITY

    def __post_init__(self):
        object.__setattr__(self, "H", _positive("H", self.H))

    def stress_expr(self, eps, xp):
        return self.H * eps

    def tangent_expr(self, eps, xp):
        return self.H + 0.0 * eps

    def energy_expr(self, eps, xp):
        return 0.5 * self.H * eps * eps


@dataclass(frozen=True)
class AteshianLaw(Law):
    """Ateshian's confined-compression law, Eq. (2) of Volokh, Chao & Armand.

    ``sigma = H (lam^2 - 1) / (2 lam^(2 beta + 1)) exp(beta (lam^2 - 1))`` with
    ``lam = 1 + eps``; energy ``w = H/(4 beta) (lam^(-2 beta) exp(beta (lam^2 - 1)) - 1)``
    and, for ``beta = 0``, its limit ``w = H/4 (lam^2 - 1 - 2 ln lam)``.
    Defined for ``eps > -1``; it stiffens without bound as the cartilage is crushed.

    Parameters
    ----------
    H : float
        Aggregate modulus ``H_A0`` in MPa (> 0). Under gait-rate loading cartilage carries load
        at its instantaneous modulus: hip and knee DEA use about 5-20 MPa (every knee example
        here uses 10). The paper's 0.3-0.6 MPa is the equilibrium modulus of slow, drained
        compression, which lets body weight crush a knee's cartilage (the tutorial "Your own
        joint" gives values from the literature).
    beta : float
        Stiffening exponent (>= 0; 0.05 to 0.6 for human cartilage).
    """

    H: float
    beta: float
    ranges: typing.ClassVar[dict] = {
        "H": Range(
            0.0,
            _HUGE,
            "MPa",
            "aggregate modulus H_A0; for gait-rate loads the instantaneous modulus, about 5-20 for hip and knee "
            "DEA (0.3-0.6 is the equilibrium modulus of slow compression, which crushes a knee)",
            low_open=True,
        ),
        "beta": Range(0.0, _HUGE, "", "stiffening exponent (0.05-0.6 for human cartilage)"),
    }
    name = "ateshian"
    bounded_strain = True

    def __post_init__(self):
        object.__setattr__(self, "H", _positive("H", self.H))
        object.__setattr__(self, "beta", _positive("beta", self.beta, allow_zero=True, unit="", sets_scale=False))

    def _parameters(self):
        return {"H": self.H, "beta": self.beta}

    def stress_expr(self, eps, xp):
        b = self.beta
        g = eps * (2.0 + eps)  # lam^2 - 1
        return 0.5 * self.H * g * xp.exp(b * g - (2.0 * b + 1.0) * xp.log1p(eps))

    def tangent_expr(self, eps, xp):
        b = self.beta
        g = eps * (2.0 + eps)
        lam2 = g + 1.0
        bracket = 2.0 * lam2 + g * (2.0 * b * lam2 - (2.0 * b + 1.0))
        return 0.5 * self.H * xp.exp(b * g - (2.0 * b + 2.0) * xp.log1p(eps)) * bracket

    def energy_expr(self, eps, xp):
        # q = ln(lam^-2 exp(lam^2 - 1)); w = H/(4 beta) expm1(beta q) -> H q / 4 as beta -> 0
        q = eps * (2.0 + eps) - 2.0 * xp.log1p(eps)
        if isinstance(self.beta, (int, float)) and self.beta < 1e-12:
            # The beta -> 0 limit; it differs from the exact form by O(beta q), and it does
            # not divide by a beta that may underflow.
            return 0.25 * self.H * q
        return 0.25 * self.H / self.beta * xp.expm1(self.beta * q)


def _polynomial(coefficients, eps):
    """Horner's rule for ``sum_k c_k eps^k`` with ``coefficients = (c_0, c_1, ...)``."""
    result = 0.0 * eps + coefficients[-1]
    for c in coefficients[-2::-1]:
        result = result * eps + c
    return result


@dataclass(frozen=True, eq=False)
class _PolynomialStress(Law):
    """A law whose stress is ``sum_{k>=1} c_k eps^k`` (``coefficients = (c_1, ..., c_n)``)."""

    @property
    def coefficients(self) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def stress_expr(self, eps, xp):
        return _polynomial((0.0, *self.coefficients), eps)

    def tangent_expr(self, eps, xp):
        c = self.coefficients
        return _polynomial(tuple(k * c[k - 1] for k in range(1, len(c) + 1)), eps)

    def energy_expr(self, eps, xp):
        c = self.coefficients
        return _polynomial((0.0, 0.0, *(c[k - 1] / (k + 1) for k in range(1, len(c) + 1))), eps)

    def _key(self):
        return tuple(float(f"{c:.12e}") for c in self.coefficients)

    def __eq__(self, other):
        if not isinstance(other, _PolynomialStress):
            return NotImplemented
        return self._key() == other._key()

    def __hash__(self):
        return hash(self._key())


@dataclass(frozen=True, eq=False)
class CubicLaw(_PolynomialStress):
    """The cubic law of Eq. (3), energy Eq. (4) with the alphas of Eq. (5).

    ``sigma = H/2 (2 eps - eps^2 + (1 + 4 beta) eps^3)``: the third-order Taylor
    polynomial of :class:`AteshianLaw`. Its tangent is positive for every strain.
    """

    H: float
    beta: float
    ranges: typing.ClassVar[dict] = {
        "H": Range(0.0, _HUGE, "MPa", "aggregate modulus", low_open=True),
        "beta": Range(0.0, _HUGE, "", "Ateshian's stiffening exponent"),
    }
    name = "cubic"

    def __post_init__(self):
        object.__setattr__(self, "H", _positive("H", self.H))
        object.__setattr__(self, "beta", _positive("beta", self.beta, allow_zero=True, unit="", sets_scale=False))

    def _parameters(self):
        return {"H": self.H, "beta": self.beta}

    @property
    def coefficients(self) -> np.ndarray:
        """``(alpha_1, alpha_2, alpha_3)`` of Eq. (5), in MPa."""
        H, b = self.H, self.beta
        return np.array([H, -H / 2.0, H * (1.0 + 4.0 * b) / 2.0])


def ateshian_taylor_coefficients(H: float, beta: float, order: int) -> np.ndarray:
    """Taylor coefficients ``(c_1, ..., c_order)`` of Eq. (2) about ``eps = 0``.

    Computed by truncated power-series arithmetic on
    ``sigma = H/2 (2 eps + eps^2) (1 + eps)^(-(2 beta + 1)) exp(beta (2 eps + eps^2))``
    (Remark 2 of the paper), not typed in.
    """
    n = order + 1
    # Complex numbers or CasADi symbols (parameter derivatives, formulations/sensitivity.md)
    # go through the same arithmetic in an array of their own kind.
    real = all(isinstance(v, (int, float, np.integer, np.floating)) for v in (H, beta))
    kind = (
        float
        if real
        else (complex if all(isinstance(v, (int, float, complex, np.number)) for v in (H, beta)) else object)
    )
    g = np.zeros(n, dtype=kind)  # beta (2 eps + eps^2)
    g[1] = 2.0 * beta
    if n > 2:
        g[2] = beta
    exp_g = np.zeros(n, dtype=kind)  # exp(g) by f' = g' f
    exp_g[0] = 1.0
    for k in range(1, n):
        exp_g[k] = sum(j * g[j] * exp_g[k - j] for j in range(1, k + 1)) / k
    a = -(2.0 * beta + 1.0)
    binomial = np.ones(n, dtype=kind)  # (1 + eps)^a
    for k in range(1, n):
        binomial[k] = binomial[k - 1] * (a - k + 1) / k
    front = np.zeros(n, dtype=kind)  # H/2 (2 eps + eps^2)
    front[1] = H
    if n > 2:
        front[2] = H / 2.0
    series = np.convolve(np.convolve(front, binomial)[:n], exp_g)[:n]
    return series[1:]


@dataclass(frozen=True, eq=False)
class PolynomialLaw(_PolynomialStress):
    """The Taylor polynomial of Eq. (2) to any order (Remark 2 of the paper).

    ``PolynomialLaw(H, beta, 3)`` equals :class:`CubicLaw` ``(H, beta)``; higher orders
    approach :class:`AteshianLaw` on ``-0.4 <= eps <= 0.4``. Even orders may soften under
    large compression: check ``tangent`` over the strains you expect.
    """

    H: float
    beta: float
    order: int = 5
    ranges: typing.ClassVar[dict] = {
        "H": Range(0.0, _HUGE, "MPa", "aggregate modulus", low_open=True),
        "beta": Range(0.0, _HUGE, "", "Ateshian's stiffening exponent"),
        "order": Range(1, 40, "", "Taylor order"),
    }
    name = "polynomial"
    # Set by __post_init__ (and _twin): the Taylor coefficients of H and beta.
    _coefficients: np.ndarray = dataclasses.field(init=False, repr=False, compare=False)

    def __post_init__(self):
        object.__setattr__(self, "H", _positive("H", self.H))
        object.__setattr__(self, "beta", _positive("beta", self.beta, allow_zero=True, unit="", sets_scale=False))
        if isinstance(self.order, bool) or not isinstance(self.order, (int, np.integer)) or not (1 <= self.order <= 40):
            raise InputError(f"order must be an integer from 1 to 40, got {self.order!r}")
        coefficients = ateshian_taylor_coefficients(self.H, self.beta, int(self.order))
        if not (np.isfinite(coefficients).all() and np.abs(coefficients).max() <= LARGEST):
            raise InputError(
                f"PolynomialLaw(H={self.H:g}, beta={self.beta:g}, order={self.order}) has Taylor coefficients "
                f"beyond {LARGEST:g} MPa (largest {np.abs(coefficients).max():g}): use a smaller beta or order"
            )
        object.__setattr__(self, "_coefficients", coefficients)

    def _parameters(self):
        return {"H": self.H, "beta": self.beta, "order": self.order}

    def _twin(self, values):
        twin = super()._twin(values)
        object.__setattr__(twin, "_coefficients", ateshian_taylor_coefficients(twin.H, twin.beta, int(self.order)))
        return twin

    @property
    def coefficients(self) -> np.ndarray:
        """``(c_1, ..., c_order)`` in MPa, from :func:`ateshian_taylor_coefficients`."""
        return self._coefficients


@dataclass(frozen=True)
class BlankevoortLaw(Law):
    """The logarithmic law ``sigma = H ln(1 + eps)`` (Blankevoort et al.; OpenSim-JAM).

    Energy ``w = H ((1 + eps) ln(1 + eps) - eps)``; defined for ``eps > -1``.
    """

    H: float
    ranges: typing.ClassVar[dict] = {"H": Range(0.0, _HUGE, "MPa", "modulus", low_open=True)}
    name = "blankevoort"
    bounded_strain = True

    def __post_init__(self):
        object.__setattr__(self, "H", _positive("H", self.H))

    def stress_expr(self, eps, xp):
        return self.H * xp.log1p(eps)

    def tangent_expr(self, eps, xp):
        return self.H / (1.0 + eps)

    def energy_expr(self, eps, xp):
        return self.H * ((1.0 + eps) * xp.log1p(eps) - eps)


def check_law(law) -> Law:
    """Validate that ``law`` is a :class:`Law` (an :class:`InputError` otherwise)."""
    if not isinstance(law, Law):
        raise InputError(
            f"law must be a dea_opt Law (one of the registered kinds {', '.join(LAWS)}, or a subclass of Law), "
            f"got {type(law).__name__}"
        )
    modulus = law.modulus
    if not (math.isfinite(modulus) and modulus >= 0 and (modulus == 0 or SMALLEST <= modulus <= LARGEST)):
        raise InputError(
            f"the law's small-strain stiffness (tangent at eps = 0) must be 0 or between {SMALLEST:g} "
            f"and {LARGEST:g} MPa, got {modulus!r} from {law.describe()}"
        )
    return law


#: The registry of law kinds: ``LAWS[name]`` is a :class:`~dea_opt.laws.registry.LawKind`.
LAWS = LawRegistry(Law)
for _cls in (LinearLaw, AteshianLaw, CubicLaw, PolynomialLaw, BlankevoortLaw):
    LAWS.register(_cls)
#: Register a law of your own: ``@register_law`` on a :class:`Law` subclass (see ``LawRegistry.register``).
register_law = LAWS.register
