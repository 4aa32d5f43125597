"""Exact derivatives of a certified equilibrium with respect to the problem's parameters.

Written math: ``formulations/sensitivity.md``. The equilibrium minimizes the convex
``Phi(x) = sum_i V_i w(min(eps_i, 0)) - r . x``; on the active set the implicit function
theorem gives ``K dx/dp = -dR/dp`` with Newton's tangent ``K = A_act^T diag(V sigma') A_act``,
solved in the resisted basis of :class:`~dea_opt.formulations._parts.resistance.Resistance` (the
formulations' scaling), so unresisted directions and units are handled as the solvers handle
them. Springs on the edge of contact (strain within the certificate's precision of 0) make the
derivative one-sided: each direction of change solves its own small piecewise-quadratic
problem (:func:`dea_opt.sensitivity.onesided.edge_solve`), and both one-sided derivatives are returned.

Parameters (``wrt``): the law's (``"H"``, ``"beta"``, any of ``Law.parameter_names``),
``"thickness_scale"`` (every thickness times ``c``, at ``c = 1``), ``"thickness"`` and ``"gap"``
(per spring, mm), the load components ``"Fx" ... "Mz"`` (body 2; ``"body1.Fx"`` for body 1;
moments about the body's reference point), and prescribed dofs (``"body2.uz"``, or ``"uz"`` for
body 2).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .._checks.threads import single_threaded_blas
from ..errors import InputError
from ..formulations._parts.resistance import modulus_scale
from ..kinematics import DOFS
from . import outputs as output_rates
from .onesided import edge_solve, pinv_solve

__all__ = ["LOADS", "OUTPUTS", "PER_SPRING", "Sensitivities", "parameter_unit", "path_sensitivities", "sensitivities"]

PAGE = "formulations/sensitivity.md"

LOADS = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")
PER_SPRING = ("thickness", "gap")
OUTPUTS = (
    "u",
    "strain",
    "pressure",
    "peak_pressure",
    "mean_pressure",
    "contact_force",
    "contact_moment",
    "center_of_pressure",
    "contact_area",
)
#: Outputs' units, for ``Sensitivities.unit``.
OUTPUT_UNITS = {
    "u": "mm or rad",
    "strain": "1",
    "pressure": "MPa",
    "peak_pressure": "MPa",
    "mean_pressure": "MPa",
    "contact_force": "N",
    "contact_moment": "N mm",
    "center_of_pressure": "mm",
    "contact_area": "mm^2",
}
#: Per-spring parameters give dense (N, N) pressure and strain derivatives up to this many
#: springs, a ``scipy.sparse.linalg.LinearOperator`` beyond.
DENSE_LIMIT = 4096


@dataclass(frozen=True, eq=False)
class Sensitivities:
    """Derivatives of a solution's outputs, each a dict from a name in ``wrt`` to an array.

    For a scalar parameter each derivative has the output's shape (``u`` (12,), ``strain`` and
    ``pressure`` (N,), ``contact_force``, ``contact_moment`` and ``center_of_pressure`` (3,),
    floats otherwise); for a per-spring parameter (``thickness``, ``gap``) the output's shape
    times N (``strain`` and ``pressure`` (N, N), dense up to :data:`DENSE_LIMIT` springs, a
    ``LinearOperator`` beyond). Units: the output's over the parameter's (:meth:`unit`).

    These are the derivatives as the parameter *increases*. When the answer is one-sided
    (``one_sided``: springs on the edge of contact, or several springs sharing the peak),
    :attr:`decreasing` holds those as it decreases (``out(p - t) = out(p) - t * D``); else it is
    this object.

    ``contact_area`` (a step function of the springs) is differentiated through the strain
    rates of the springs within ``area_band`` of zero strain: the rate at which the contact
    sweeps area (formulations/sensitivity.md). ``mean_pressure`` uses that rate too.

    Attributes
    ----------
    wrt : tuple of str
    u, strain, pressure, peak_pressure, mean_pressure, contact_force, contact_moment,
    center_of_pressure, contact_area : dict
    edge : ndarray of int
        Springs on the edge of contact.
    edge_state : dict
        ``{name: bool array (E,) or (E, N)}``: which edge springs are in contact as the
        parameter increases (for :attr:`decreasing`: as it decreases).
    area_band : float
        The strain band of the contact-area rate.
    notes : tuple of str
        Derivatives that do not exist (NaN), and why.
    """

    wrt: tuple
    u: dict
    strain: dict
    pressure: dict
    peak_pressure: dict
    mean_pressure: dict
    contact_force: dict
    contact_moment: dict
    center_of_pressure: dict
    contact_area: dict
    units: dict
    edge: np.ndarray
    edge_state: dict
    area_band: float
    notes: tuple = ()
    one_sided: bool = False
    decreasing: Sensitivities | None = field(default=None, repr=False)

    def unit(self, output: str, name: str) -> str:
        """The unit of ``d output / d name``, e.g. ``"MPa/MPa"``."""
        return f"{OUTPUT_UNITS[output]}/{self.units[name]}"

    def table(self) -> dict:
        """``{name: {output: value}}`` of the scalar outputs of the scalar parameters (for JSON)."""
        scalar = ("peak_pressure", "mean_pressure", "contact_area")
        vector = ("contact_force", "contact_moment", "center_of_pressure")
        out = {}
        for name in self.wrt:
            if name in PER_SPRING:
                continue
            row = {k: float(getattr(self, k)[name]) for k in scalar}
            row.update({k: np.asarray(getattr(self, k)[name]).tolist() for k in vector})
            row["u"] = np.asarray(self.u[name]).tolist()
            out[name] = row
        return out


def parameter_unit(law, name: str) -> str:
    """The unit of parameter ``name`` (``"MPa"``, ``"N"``, ``"mm"``, ...)."""
    if name in law.parameter_names:
        spec = getattr(type(law), "ranges", {}).get(name)
        unit = getattr(spec, "unit", None)
        return unit or ("MPa" if name == "H" else "1")
    if name == "thickness_scale":
        return "1"
    if name in PER_SPRING:
        return "mm"
    dof = name.split(".")[-1]
    if dof in LOADS:
        return "N" if dof[0] == "F" else "N mm"
    return "mm" if dof[0] == "u" else "rad"


@dataclass
class _Columns:
    """The explicit dependence of the equilibrium equations on q parameters.

    ``b`` strain rate and ``s`` stress rate (N, q), or, ``diagonal``, (N,) for per-spring
    parameters (column j moves spring j only); ``dr`` load rate (m, q); ``du`` the prescribed
    motion (12, q).
    """

    b: np.ndarray
    s: np.ndarray | None
    dr: np.ndarray
    du: np.ndarray
    diagonal: bool = False


def _columns(problem, names, eps, strict, law) -> list:
    """``[(name, _Columns)]`` for every parameter, with a named error for unknown names."""
    layer, n = problem.layer, len(problem.layer)
    free = problem.free_indices
    h = layer.thickness
    out = []
    law_rates = None
    for name in names:
        b, s, dr, du = np.zeros(n), None, np.zeros(len(free)), np.zeros(12)
        if name in law.parameter_names:
            if law_rates is None:
                law_rates = {
                    k: np.where(strict, v, 0.0) for k, v in law.stress_derivatives(np.where(strict, eps, 0.0)).items()
                }
            s = law_rates[name]
        elif name == "thickness_scale":
            b = -eps
        elif name in PER_SPRING:
            diag = -eps / h if name == "thickness" else 1.0 / h
            out.append((name, _Columns(diag, None, np.zeros((len(free), n)), np.zeros((12, n)), diagonal=True)))
            continue
        else:
            body, dof = name.split(".") if "." in name else ("body2", name)
            if body not in ("body1", "body2") or (dof not in LOADS and dof not in DOFS):
                raise InputError(
                    f"wrt holds {name!r}, which is no parameter of this problem: give the law's parameters "
                    f"{law.parameter_names}, 'thickness_scale', 'thickness', 'gap', the load components {LOADS} "
                    f"(body 2; 'body1.Fx' for body 1) or a prescribed dof ('body2.uz')"
                )
            k = 0 if body == "body1" else 6
            if dof in LOADS:
                index = k + LOADS.index(dof)
                dr = (free == index).astype(float)
            else:
                index = k + DOFS.index(dof)
                if dof not in getattr(problem, body).prescribed:
                    raise InputError(
                        f"wrt holds {name!r}, but {body}.{dof} is not prescribed: only prescribed "
                        f"dofs are parameters (free dofs are unknowns, fixed ones are 0)"
                    )
                du[index] = 1.0
                b = problem.normal_operator[:, index] / h
        out.append((name, _Columns(b[:, None], None if s is None else s[:, None], dr[:, None], du[:, None])))
    return out


def _groups(columns) -> list:
    """``[(names, _Columns)]``: every scalar parameter in one group of columns (one solve, one pass
    over the springs for all of them), each per-spring parameter in its own."""
    scalar = [(n, c) for n, c in columns if not c.diagonal]
    groups = []
    if scalar:
        s_all = None
        if any(c.s is not None for _, c in scalar):
            s_all = np.hstack([np.zeros_like(c.b) if c.s is None else c.s for _, c in scalar])
        merged = _Columns(
            np.hstack([c.b for _, c in scalar]),
            s_all,
            np.hstack([c.dr for _, c in scalar]),
            np.hstack([c.du for _, c in scalar]),
        )
        groups.append(([n for n, _ in scalar], merged))
    groups += [([n], c) for n, c in columns if c.diagonal]
    return groups


def sensitivities(solution, wrt=("H",), *, area_band: float | None = None, edge: str = "auto") -> Sensitivities:
    """Derivatives of every output of a certified ``solution`` with respect to ``wrt``.

    Parameters
    ----------
    solution : Solution
        A certified answer (``solution.success``) of any method.
    wrt : sequence of str
        Parameter names (module docstring); per-spring ones give one column per spring.
    area_band : float, optional
        The strain band of the contact-area rate (default: about four rows of springs at
        the contact's edge, formulations/sensitivity.md).
    edge : {"auto", "in", "out"}
        Springs on the edge of contact: each direction decides (``"auto"``, exact), or all
        held in contact, or all out of it.

    Returns
    -------
    Sensitivities
    """
    if not getattr(solution, "success", False):
        raise InputError(
            f"sensitivities need a certified solution; this one has status "
            f"{getattr(solution, 'status', '?')!r} (certificate not passed)"
        )
    if getattr(getattr(solution, "problem", None), "kinematics", "small") == "finite":
        raise InputError(
            "sensitivities are derivatives of the small kinematics of Eq. (9)-(11); a solution of "
            "kinematics='finite' has none here: differentiate a small-kinematics solve (kinematics='small'; "
            'a scenario: set solve.kinematics = "small")'
        )
    if isinstance(wrt, str):
        wrt = (wrt,)
    wrt = tuple(wrt)
    if not wrt or len(set(wrt)) != len(wrt):
        raise InputError(f"wrt must name at least one parameter, each once, got {wrt!r}")
    if edge not in ("auto", "in", "out"):
        raise InputError(f"edge must be 'auto', 'in' or 'out', got {edge!r}")
    if area_band is not None and not (isinstance(area_band, (int, float)) and 0 < area_band < 1):
        raise InputError(f"area_band must be a strain in (0, 1), got {area_band!r}")
    with single_threaded_blas():
        return _sensitivities(solution, wrt, area_band, edge)


def _sensitivities(solution, wrt, area_band, edge_mode) -> Sensitivities:
    problem, law = solution.problem, solution.problem.law
    layer = problem.layer
    system = problem.system()
    eps = np.asarray(solution.strain, dtype=float)
    tol = solution.certificate.tolerance
    delta = tol * max(float(-eps.min(initial=0.0)), float(-system.e0.min(initial=0.0)))
    on_edge = np.abs(eps) <= delta
    strict = (eps < 0) & ~on_edge
    edge = np.flatnonzero(on_edge)
    columns = _columns(problem, wrt, eps, strict, law)
    T1 = system.resistance.basis(modulus_scale(law.modulus))  # (m, k)
    ATk = T1.T @ system.AT  # (k, N): strain per unit xi
    V = system.volume
    tangent = np.zeros(len(eps))
    tangent[strict] = law.tangent(eps[strict])
    tangent[edge] = float(law.tangent(np.zeros(1))[0])
    Ks = (ATk[:, strict] * (V * tangent)[strict]) @ ATk[:, strict].T
    band = output_rates.band(layer, eps, strict, area_band)
    notes = []
    res = system.resistance
    results: dict[int, dict] = {+1: {}, -1: {}}
    states: dict[int, dict] = {+1: {}, -1: {}}
    peak_set = output_rates.peak_set(solution.pressure)
    one_sided = bool(edge.size) or peak_set.size > 1
    weight = np.where(strict, V * tangent, 0.0)
    for names, col in _groups(columns):
        if col.diagonal:
            c = ATk * (weight * col.b)
        else:
            rate = weight[:, None] * col.b + (0.0 if col.s is None else V[:, None] * col.s)
            c = ATk @ rate
        along = np.zeros(c.shape[1])
        if col.dr.any():
            c = c - T1.T @ col.dr
            along = np.array([res.load_fraction(col.dr[:, j]) for j in range(col.dr.shape[1])])
            for j in np.flatnonzero(along > 1e-7):
                notes.append(f"{names[j]}: the load moves along a direction no spring resists; no derivative (NaN)")
        for sign in (+1, -1) if one_sided else (+1,):
            if edge.size:
                if col.diagonal:
                    be = np.zeros((edge.size, c.shape[1]))
                    be[np.arange(edge.size), edge] = col.b[edge]
                else:
                    be = col.b[edge]
                dxi, state, lost = edge_solve(Ks, sign * c, ATk[:, edge], (V * tangent)[edge], sign * be, edge_mode)
                dxi = sign * dxi
            else:
                sol, lost = pinv_solve(Ks, c)
                dxi, state = -sol, np.zeros((0, c.shape[1]), dtype=bool)
            bad = np.flatnonzero(lost & ~(along > 1e-7))
            way = "" if not one_sided else (" as it increases" if sign > 0 else " as it decreases")
            for name in [names[0]] if col.diagonal and bad.size else [names[j] for j in bad]:
                notes.append(
                    f"{name}{way}: the contact resists no motion along the direction it pushes (the "
                    f"springs would separate or jump); no derivative (NaN)"
                )
            dxi[:, lost | (along > 1e-7)] = np.nan
            out = output_rates.outputs(
                solution, problem, col, dxi, T1, ATk, tangent, strict, edge, state, band, sign, peak_set, DENSE_LIMIT
            )
            if col.diagonal:
                results[sign][names[0]] = out
                states[sign][names[0]] = state
                continue
            for column, name in enumerate(names):
                results[sign][name] = {
                    k: (float(v[column]) if np.ndim(v) == 1 else v[:, column]) for k, v in out.items()
                }
                states[sign][name] = state[:, column]
    units = {name: parameter_unit(law, name) for name in wrt}
    made = {}
    for side in (s for s in results if results[s]):
        fields: dict = {k: {n: results[side][n][k] for n in wrt} for k in OUTPUTS}
        made[side] = Sensitivities(
            wrt=wrt,
            units=units,
            edge=edge,
            edge_state=states[side],
            area_band=band[1],
            notes=tuple(dict.fromkeys(notes)),
            one_sided=one_sided,
            **fields,
        )
    if (
        -1 in made
        and not edge.size
        and all(
            np.allclose(made[+1].peak_pressure[k], made[-1].peak_pressure[k], rtol=1e-12, atol=0, equal_nan=True)
            for k in wrt
        )
    ):
        del made[-1]  # a shared peak whose springs all change alike: two-sided after all
        object.__setattr__(made[+1], "one_sided", False)
    object.__setattr__(made[+1], "decreasing", made.get(-1, made[+1]))
    if -1 in made:
        object.__setattr__(made[-1], "decreasing", made[-1])
    return made[+1]


def path_sensitivities(path, wrt=("H",), **options) -> list:
    """``[Sensitivities]`` of every frame of a load path (kept by default, ``PathOutputs(keep_solutions=True)``),
    each from its own certified solution; ``None`` for a frame that failed its certificate."""
    if not getattr(path, "solutions", None):
        raise InputError(
            "path_sensitivities needs the frames' solutions: solve_path(..., outputs=PathOutputs(keep_solutions=True))"
        )
    return [sensitivities(s, wrt, **options) if s is not None and s.success else None for s in path.solutions]
