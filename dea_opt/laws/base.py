"""The base of every spring law: :class:`Law`, whose formulas are written once for NumPy and CasADi.

Strain ``eps = dh/h`` is positive in tension and stress ``sigma`` has the same sign
(Volokh, Chao & Armand, Eq. 2), so compression gives ``sigma < 0`` and pressure ``-sigma``.
Every law writes its formulas once, in :meth:`Law.stress_expr`, :meth:`Law.tangent_expr` and
:meth:`Law.energy_expr`, against an array namespace ``xp``: NumPy for arrays, CasADi for the
symbolic expressions of the NLP formulation, so the two can never drift apart.
The written math is in ``formulations/energy.md``.

Units: ``H`` in MPa, stress and energy density in MPa (= N/mm^2 = mJ/mm^3).
"""

from __future__ import annotations

import dataclasses
import math
import typing
from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np

from .._checks.inputs import check_range
from ..errors import InputError
from .registry import kind_name, label

__all__ = ["Law"]


def _namespace(eps):
    """NumPy for numbers and arrays, CasADi for CasADi symbols (imported only then)."""
    if isinstance(eps, (np.ndarray, float, int, np.floating, np.integer)):
        return np
    import casadi

    return SimpleNamespace(exp=casadi.exp, log=casadi.log, log1p=casadi.log1p, expm1=casadi.expm1)


def _positive(name, value, *, allow_zero=False, unit="MPa", sets_scale=True):
    """A law parameter: a finite number > 0 (or >= 0) of magnitude at most
    :data:`~dea_opt._checks.inputs.LARGEST` and, when it ``sets_scale`` (a modulus), at least
    :data:`~dea_opt._checks.inputs.SMALLEST`, so that ``H`` times volumes, strains and lever arms can
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
    valid_compression: typing.ClassVar[float | None] = None
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
    out = (
        np.asarray(f.map(max(flat.size, 1))(flat.reshape(1, -1), values), dtype=float)
        if flat.size
        else np.zeros((len(names), 0))
    )
    return [row.reshape(eps.shape) for row in out]
