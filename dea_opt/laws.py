"""Spring laws: stress, tangent and strain energy of one cartilage spring.

Strain ``eps = dh/h`` is positive in tension and stress ``sigma`` has the same sign
(Volokh, Chao & Armand, Eq. 2), so compression gives ``sigma < 0`` and pressure ``-sigma``.
Every law writes its formulas once, in :meth:`Law.stress_expr`, :meth:`Law.tangent_expr` and
:meth:`Law.energy_expr`, against an array namespace ``xp``: NumPy for arrays, CasADi for the
symbolic expressions of the NLP formulation, so the two can never drift apart.
The written math is in ``formulations/energy.md``.

:data:`LAWS` is the registry of law kinds (``"linear"`` -> :class:`LinearLaw`, ...): each kind's
parameters come from the class itself (its dataclass fields and its ``ranges``), and the
scenario schema, ``build_law``, the command line and ``dea-opt schema`` read it.
:func:`register_law` adds a law of your own to it.

Units: ``H`` in MPa, stress and energy density in MPa (= N/mm^2 = mJ/mm^3).
"""

from __future__ import annotations

import dataclasses
import math
import typing
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from ._tolerances import LINEAR_VALIDITY
from ._validate import LARGEST, SMALLEST, check_range
from .errors import InputError
from .law_registry import HUGE as _HUGE
from .law_registry import LawKind, LawParameter, LawRegistry, Range, kind_name, label

__all__ = [
    "LAWS",
    "LawKind",
    "LawParameter",
    "Range",
    "register_law",
    "Law",
    "LinearLaw",
    "AteshianLaw",
    "CubicLaw",
    "PolynomialLaw",
    "BlankevoortLaw",
]


def _namespace(eps):
    """NumPy for numbers and arrays, CasADi for CasADi symbols (imported only then)."""
    if isinstance(eps, (np.ndarray, float, int, np.floating, np.integer)):
        return np
    import casadi

    return SimpleNamespace(
        exp=casadi.exp, log=casadi.log, log1p=casadi.log1p, expm1=casadi.expm1
    )


def _positive(name, value, *, allow_zero=False, unit="MPa", sets_scale=True):
    """A law parameter: a finite number > 0 (or >= 0) of magnitude at most
    :data:`~dea_opt._validate.LARGEST` and, when it ``sets_scale`` (a modulus), at least
    :data:`~dea_opt._validate.SMALLEST`, so that ``H`` times volumes, strains and lever arms can
    neither overflow nor underflow."""
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise InputError(f"{name} must be a finite number {bound}, got {value!r}")
    check_range(name, v, unit, positive=sets_scale)
    return v


@dataclass(frozen=True)
class Law:
    """Base of every spring law; subclass it for a law of your own.

    A subclass implements the three ``*_expr`` methods with ``xp.exp``, ``xp.log``,
    ``xp.log1p``, ``xp.expm1`` and arithmetic only, so that they work for NumPy arrays
    and CasADi symbols alike. ``energy`` must be the antiderivative of ``stress`` with
    ``energy(0) == 0``, and it must be convex on compression for the equilibrium to be a
    minimum of the total energy.
    """

    #: Laws with ``bounded_strain`` are defined for ``eps > -1`` only: the solvers keep
    #: every iterate inside, and the NLP bounds compressive strain below 1.
    bounded_strain = False
    #: True for the one law the QP formulation accepts.
    is_linear = False
    #: Largest compressive strain (a positive fraction) over which the law describes
    #: cartilage, or ``None`` if it states no range of its own: :mod:`dea_opt.validity` then
    #: applies only its crushing limit to it. Override it in a law of your own.
    valid_compression = None
    #: ``{parameter: Range(low, high, unit, meaning)}``: what the registry (:data:`LAWS`), the
    #: scenario schema and ``dea-opt schema`` say of each parameter; a parameter without one
    #: takes any number and is checked by the class alone.
    ranges: typing.ClassVar[dict] = {}

    @property
    def modulus(self) -> float:
        """Small-strain stiffness ``d sigma / d eps`` at ``eps = 0`` (MPa)."""
        return float(self.tangent(np.zeros(1))[0])

    def stress_expr(self, eps, xp):  # pragma: no cover - abstract
        raise NotImplementedError

    def tangent_expr(self, eps, xp):  # pragma: no cover - abstract
        raise NotImplementedError

    def energy_expr(self, eps, xp):  # pragma: no cover - abstract
        raise NotImplementedError

    def _evaluate(self, expr, eps, outside):
        xp = _namespace(eps)
        if xp is not np:
            return expr(eps, xp)
        eps = np.asarray(eps, dtype=float)
        if not self.bounded_strain:
            with np.errstate(over="ignore", invalid="ignore"):
                return expr(eps, np)
        crushed = eps <= -1.0
        if not crushed.any():
            with np.errstate(over="ignore", invalid="ignore"):
                return expr(eps, np)
        safe = np.where(crushed, 0.0, eps)
        with np.errstate(over="ignore", invalid="ignore"):
            value = np.asarray(expr(safe, np), dtype=float)
        return np.where(crushed, outside, value)

    def stress(self, eps):
        """Stress ``sigma(eps)`` in MPa (tension positive); ``-inf`` where crushed."""
        return self._evaluate(self.stress_expr, eps, -np.inf)

    def tangent(self, eps):
        """Tangent stiffness ``d sigma / d eps`` in MPa; ``+inf`` where crushed."""
        return self._evaluate(self.tangent_expr, eps, np.inf)

    def energy(self, eps):
        """Strain energy density ``w(eps)`` in MPa with ``w(0) = 0``; ``+inf`` where crushed."""
        return self._evaluate(self.energy_expr, eps, np.inf)

    # --- derivatives with respect to the law's parameters (formulations/sensitivity.md) ---
    @property
    def parameter_names(self) -> tuple:
        """The law's real-valued parameters (its ``float`` dataclass fields, e.g. ``("H", "beta")``):
        those :meth:`stress_derivatives` differentiates. Integer fields (``order``) are left out."""
        if not dataclasses.is_dataclass(self):
            return ()
        return tuple(f.name for f in dataclasses.fields(self) if f.init and f.type in (float, "float"))

    def _twin(self, values: dict) -> Law:
        """A copy whose parameters in ``values`` are replaced, unchecked, by other numbers or
        symbols (complex numbers, CasADi symbols): the same ``*_expr`` code then yields the
        parameter derivatives. Override it when ``__post_init__`` derives more from them."""
        twin = object.__new__(type(self))
        for f in dataclasses.fields(self):
            object.__setattr__(twin, f.name, values.get(f.name, getattr(self, f.name)))
        return twin

    def stress_derivatives(self, eps, method: str = "complex") -> dict:
        """``d sigma / d theta`` at the strains ``eps`` for each of :attr:`parameter_names` (MPa
        per unit of the parameter, e.g. 1/1 for ``H`` of a law linear in it).

        ``method="complex"`` (default) evaluates :meth:`stress_expr` once per parameter with that
        parameter moved by ``i t``: the imaginary part over ``t`` is the derivative to rounding,
        with no difference taken. ``method="casadi"`` differentiates the same expression
        symbolically with CasADi (slower; the cross-check). Crushed strains (``eps <= -1`` of a
        bounded law) give NaN.
        """
        eps = np.asarray(eps, dtype=float)
        bad = eps <= -1.0 if self.bounded_strain else np.zeros(eps.shape, dtype=bool)
        safe = np.where(bad, 0.0, eps)
        out = {}
        if method == "casadi":
            for name, value in zip(self.parameter_names, _casadi_stress_jacobian(self, safe)):
                out[name] = np.where(bad, np.nan, value)
            return out
        if method != "complex":
            raise InputError(f"method must be 'complex' or 'casadi', got {method!r}")
        for name in self.parameter_names:
            value = float(getattr(self, name))
            step = 1e-30 * max(abs(value), 1.0)
            twin = self._twin({name: complex(value, step)})
            with np.errstate(over="ignore", invalid="ignore"):
                stress = np.asarray(twin.stress_expr(safe.astype(complex), np), dtype=complex)
            out[name] = np.where(bad, np.nan, np.broadcast_to(stress.imag / step, eps.shape))
        return out

    def describe(self) -> str:
        """A short label for tables, e.g. ``ateshian(H=0.6, beta=0.05)``; works for any subclass."""
        args = ", ".join(f"{k}={label(v)}" for k, v in self._parameters().items())
        return f"{kind_name(type(self))}({args})"

    def _parameters(self) -> dict:
        """The law's parameters by name: its dataclass fields (none for a class that is not one)."""
        if not dataclasses.is_dataclass(self):
            return {}
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if f.init}


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
        Aggregate modulus ``H_A0`` in MPa (> 0; 0.3 to 0.6 for human cartilage).
    beta : float
        Stiffening exponent (>= 0; 0.05 to 0.6 for human cartilage).
    """

    H: float
    beta: float
    ranges: typing.ClassVar[dict] = {
        "H": Range(0.0, _HUGE, "MPa", "aggregate modulus H_A0 (0.3-0.6 for human cartilage)", low_open=True),
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
    kind = float if real else (complex if all(isinstance(v, (int, float, complex, np.number)) for v in (H, beta))
                               else object)
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

    def __post_init__(self):
        object.__setattr__(self, "H", _positive("H", self.H))
        object.__setattr__(self, "beta", _positive("beta", self.beta, allow_zero=True, unit="", sets_scale=False))
        if isinstance(self.order, bool) or not isinstance(self.order, (int, np.integer)) or not (
            1 <= self.order <= 40
        ):
            raise InputError(f"order must be an integer from 1 to 40, got {self.order!r}")
        coefficients = ateshian_taylor_coefficients(self.H, self.beta, int(self.order))
        if not (np.isfinite(coefficients).all() and np.abs(coefficients).max() <= LARGEST):
            raise InputError(
                f"PolynomialLaw(H={self.H:g}, beta={self.beta:g}, order={self.order}) has Taylor coefficients "
                f"beyond {LARGEST:g} MPa (largest {np.abs(coefficients).max():g}): use a smaller beta or order")
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
        raise InputError(f"the law's small-strain stiffness (tangent at eps = 0) must be 0 or between {SMALLEST:g} "
                         f"and {LARGEST:g} MPa, got {modulus!r} from {law.describe()}")
    return law


#: The registry of law kinds: ``LAWS[name]`` is a :class:`~dea_opt.law_registry.LawKind`.
LAWS = LawRegistry(Law)
for _cls in (LinearLaw, AteshianLaw, CubicLaw, PolynomialLaw, BlankevoortLaw):
    LAWS.register(_cls)
#: Register a law of your own: ``@register_law`` on a :class:`Law` subclass (see ``LawRegistry.register``).
register_law = LAWS.register


def _casadi_stress_jacobian(law: Law, eps: np.ndarray) -> list:
    """``[d sigma / d theta_k (eps)]`` by CasADi's symbolic derivative of :meth:`Law.stress_expr`."""
    import casadi

    names = law.parameter_names
    if not names:
        return []
    symbols = {name: casadi.SX.sym(name) for name in names}
    e = casadi.SX.sym("eps")
    stress = law._twin(symbols).stress_expr(e, _namespace(e))
    theta = casadi.vertcat(*symbols.values())
    f = casadi.Function("dsigma", [e, theta], [casadi.jacobian(stress, theta).T])
    values = np.array([float(getattr(law, n)) for n in names])
    flat = eps.reshape(-1)
    out = np.asarray(f.map(max(flat.size, 1))(flat.reshape(1, -1), values), dtype=float) if flat.size else \
        np.zeros((len(names), 0))
    return [row.reshape(eps.shape) for row in out]
