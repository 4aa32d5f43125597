"""Finite kinematics by IPOPT: the registry's entry ``"finite_nlp"``, the independent cross-check.

Written math: ``formulations/finite_nlp.md``. The same arrays as
:mod:`~dea_opt.formulations.finite` (a :class:`~dea_opt.formulations.finite.FiniteSystem`: springs,
targets, body 2's coordinates, the load; exact rotation, gaps at the current pose, forces along
the springs), solved by IPOPT on a conservative surrogate re-centred at each outer iteration,
built in CasADi with its own derivatives (:mod:`~dea_opt.formulations.finite.ipopt`); the
springs are constrained to compression and their forces are the multipliers. Newton and IPOPT
agree to 1e-6 on every test problem (``tests/finite/test_finite.py``).
"""

from __future__ import annotations

import numpy as np

from .._parts.options import Capabilities, Option, Variant
from . import RECAST_OPTIONS, FiniteModel, InnerResult

__all__ = ["CAPABILITIES", "OPTIONS", "Model", "solve"]

PAGE = "formulations/finite_nlp.md"

#: The options of ``dea_opt.solve`` with ``method="finite_nlp"`` on a finite problem.
OPTIONS = (
    Option(
        "form",
        str,
        "constrained",
        "constrained (each spring's compression a variable, its force the "
        "multiplier) or reduced (min(eps, 0) in the energy)",
        choices=("constrained", "reduced"),
    ),
    Option("tol", float, 1e-14, "IPOPT's tolerance in the scaled variables", range=(0, 1), tolerance=True),
    Option(
        "outer_tol",
        float,
        1e-12,
        "scaled step of an outer iteration that counts as the fixed point",
        range=(0, 1),
        tolerance=True,
    ),
    Option("max_outer", int, 60, "outer iterations (re-centred IPOPT solves) per solve, at most", range=(1, None)),
    Option("max_iter", int, 3000, "IPOPT iterations per outer iteration, at most", range=(1, None)),
    Option(
        "max_time",
        float,
        3600.0,
        "wall-clock seconds the IPOPT solves of one set of springs may take, at most (an update starts anew)",
        range=(0, float("inf")),
    ),
    Option("ipopt_options", dict, None, "IPOPT option names to values, passed on"),
    *RECAST_OPTIONS,
)
CAPABILITIES = Capabilities(laws="any", warm_start=True, kinematics=("finite",), duals=True, checks_load_first=True)
EXTRA_OPTIONS = None
VARIANT = Variant("form", {"constrained": "IPOPT-finite", "reduced": "IPOPT-finite-reduced"})
_IPOPT = ("form", "tol", "outer_tol", "max_outer", "max_iter", "max_time", "ipopt_options")


def solve(system, law, T, energy_scale: float, *, x0=None, cold=None, start_state=None, **options) -> InnerResult:
    """The equilibrium of ``system``'s free coordinates for its targets, by IPOPT.

    As :func:`dea_opt.formulations.finite.solve` (``cold`` and ``start_state`` are ignored: IPOPT
    has no extended start, and evaluates the springs in CasADi); ``options`` are :data:`OPTIONS` (the re-casting ones are ignored here). The springs'
    stresses IPOPT reports (its multipliers) are ``info["stress"]``.
    """
    from . import ipopt  # CasADi, imported when IPOPT runs

    x = np.zeros(len(system.free)) if x0 is None else np.asarray(x0, dtype=float)
    if not len(system.free):
        state = system.state(system.base, law)
        return InnerResult(np.zeros(0), state, True, "no_free_dofs", "every dof is fixed or prescribed")
    defaults = {option.name: option.default for option in OPTIONS}
    return ipopt.solve(system, law, T, energy_scale, x0=x, **{k: options.get(k, defaults[k]) for k in _IPOPT})


class Model(FiniteModel):
    """:class:`~dea_opt.formulations.finite.FiniteModel` solved by IPOPT."""

    method = "finite_nlp"
    run = staticmethod(solve)
