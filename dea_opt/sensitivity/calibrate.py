"""Fit parameters (``H``, ``beta``, a thickness scale, load components) to measured data.

Written math: ``formulations/sensitivity.md`` ("Calibration"). ``scipy.optimize.least_squares``
with the exact Jacobian: every evaluation solves the problem (Newton, warm-started from the
previous one) and takes :func:`~dea_opt.sensitivity.sensitivities` of the answer. The data are
:class:`~dea_opt.sensitivity.measurements.PressureMap` (film or sensor, censored to the film's range),
:class:`~dea_opt.sensitivity.measurements.ForceDisplacement` and :class:`~dea_opt.sensitivity.measurements.ContactData`.
Standard errors and correlations come from the Jacobian at the optimum: the data's stated noise
(and correlation) carried through it, or, when a datum's noise is not stated, the noise's scale
estimated from the residuals (:mod:`~dea_opt.sensitivity.covariance`).
"""

from __future__ import annotations

import dataclasses
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import InputError, SolverError, ValidityWarning
from .covariance import parameter_covariance
from .derivatives import LOADS, sensitivities
from .measurements import FILMS, ContactData, Film, ForceDisplacement, PressureMap

__all__ = [
    "FILMS",
    "Calibration",
    "ContactData",
    "Film",
    "ForceDisplacement",
    "PressureMap",
    "apply_parameters",
    "calibrate",
]


def _fitted_in_logs(problem, name) -> bool:
    """Law parameters and the thickness scale are positive: fitted as ``log theta``."""
    return name in problem.law.parameter_names or name == "thickness_scale"


def _current(problem, name) -> float:
    if name in problem.law.parameter_names:
        return float(getattr(problem.law, name))
    if name == "thickness_scale":
        return 1.0
    return float(problem.body2.load_vector[LOADS.index(name)])


def apply_parameters(problem, values: dict):
    """``problem`` with the law's parameters, the thickness scale and body 2's load components
    (``Fx ... Mz``) in ``values`` set; the law checks its own values."""
    law_values = {k: v for k, v in values.items() if k in problem.law.parameter_names}
    out = problem
    if law_values:
        out = out.with_law(dataclasses.replace(problem.law, **law_values))
    if "thickness_scale" in values:
        layer = problem.layer
        out = out.with_layer(
            dataclasses.replace(layer, thickness=np.asarray(layer.thickness) * values["thickness_scale"])
        )
    loads = {k: v for k, v in values.items() if k in LOADS}
    if loads:
        vector = problem.body2.load_vector.copy()
        for k, v in loads.items():
            vector[LOADS.index(k)] = v
        out = out.with_body(
            2,
            dataclasses.replace(
                out.body2, force=tuple(vector[:3]), moment=tuple(vector[3:]), prescribed=dict(out.body2.prescribed)
            ),
        )
    return out


def _check_parameters(problem, parameters) -> tuple:
    if isinstance(parameters, str):
        parameters = (parameters,)
    parameters = tuple(parameters)
    allowed = (*problem.law.parameter_names, "thickness_scale", *LOADS)
    bad = [p for p in parameters if p not in allowed]
    if not parameters or bad or len(set(parameters)) != len(parameters):
        raise InputError(f"parameters must name distinct parameters among {', '.join(allowed)}, got {parameters!r}")
    return parameters


@dataclass(frozen=True, eq=False)
class Calibration:
    """The fitted parameters and how well the data determine them.

    Attributes
    ----------
    parameters : tuple of str
    values, start, standard_errors : dict
        Fitted values, where the fit started, and standard errors (the parameters' units); a
        standard error is NaN when it is undefined (``notes`` says why).
    correlation, covariance : ndarray, shape (p, p)
    errors : str
        Which standard errors: ``"stated"`` (every datum's stated noise and correlation carried
        through the Jacobian) or ``"estimated"`` (some datum's noise was not stated: the noise's
        scale estimated from the residuals' scatter).
    degrees_of_freedom : float
        The residuals taking part less what the fit absorbs (``n - p`` for independent data).
    notes : tuple of str
        Why the standard errors are undefined, when they are.
    residuals : ndarray
        Weighted residuals at the optimum (measured minus predicted over their standard deviation,
        sign reversed: predicted minus measured).
    cost : float
        ``|residuals|^2 / 2``.
    success : bool
    message : str
    nfev : int
        Solves made.
    solution : Solution
        The fitted problem's solution (body 2 as given, without prescribed curve points).
    data : tuple
    """

    parameters: tuple
    values: dict
    start: dict
    standard_errors: dict
    correlation: np.ndarray
    covariance: np.ndarray
    residuals: np.ndarray
    cost: float
    success: bool
    message: str
    nfev: int
    solution: Any
    data: tuple
    errors: str = "stated"
    degrees_of_freedom: float = float("nan")
    notes: tuple = ()
    info: dict = field(default_factory=dict)

    def summary(self) -> dict:
        """JSON-ready (through :func:`dea_opt.io.summary.jsonable`: an undefined standard error is
        ``null``): values, standard errors and which they are, correlation, cost, the outcome.
        ``values``, ``start`` and ``standard_errors`` name each parameter with its unit
        (``H_MPa``, ``beta``; :mod:`dea_opt.units`)."""
        named = {p: self.unit_name(p) for p in self.parameters}
        return {
            "parameters": list(self.parameters),
            "values": {named[p]: v for p, v in self.values.items()},
            "start": {named[p]: v for p, v in self.start.items()},
            "standard_errors": {named[p]: v for p, v in self.standard_errors.items()},
            "errors": self.errors,
            "degrees_of_freedom": self.degrees_of_freedom,
            "notes": list(self.notes),
            "correlation": self.correlation.tolist(),
            "cost": self.cost,
            "n_residuals": int(self.residuals.size),
            "success": self.success,
            "message": self.message,
            "nfev": self.nfev,
            "peak_pressure_MPa": self.solution.peak_pressure,
            "contact_area_mm2": self.solution.contact_area,
        }

    def unit_of(self, parameter: str) -> str:
        """The unit of a fitted parameter (``"MPa"`` for ``H``; ``"1"`` for ``beta``)."""
        from .derivatives import parameter_unit

        return parameter_unit(self.solution.problem.law, parameter)

    def unit_name(self, parameter: str) -> str:
        """A parameter's name with its unit, as tables and JSON write it: ``H_MPa``, ``beta``."""
        from ..units import SUFFIXES, with_unit

        unit = self.unit_of(parameter)
        return with_unit(parameter.replace(".", "_"), unit) if unit in SUFFIXES else parameter

    def residual_map(self):
        """One row per matched point of every pressure map: ``dataset``, ``x_mm, y_mm, z_mm``,
        ``measured_MPa``, ``predicted_MPa``, ``state`` (``measured``, ``below``, ``saturated``),
        ``spring`` and ``residual`` (weighted by the point's standard deviation: no unit; 0 for a
        censored point the model agrees with)."""
        import pandas as pd

        rows = []
        for k, data in enumerate(self.data):
            if not isinstance(data, PressureMap):
                continue
            springs, kept = data.matched(self.solution.problem.layer)
            r, _ = data.residuals(self.solution, None, (), {"match": (springs, kept)})
            state = np.array(["below", "measured", "saturated"])[data.state[kept] + 1]
            rows.append(
                pd.DataFrame(
                    {
                        "dataset": k,
                        "x_mm": data.points[kept, 0],
                        "y_mm": data.points[kept, 1],
                        "z_mm": data.points[kept, 2],
                        "measured_MPa": data.pressure[kept],
                        "predicted_MPa": self.solution.pressure[springs],
                        "state": state,
                        "spring": springs,
                        "residual": r,
                    }
                )
            )
        return pd.concat(rows, ignore_index=True) if rows else pd.DataFrame()

    def plot(self, path, title: str | None = None):
        """Measured against predicted pressure (censored points at their film limit) and the map
        of residuals, to a PNG (written atomically). ``title`` (the scenario's, say) heads the
        figure above the fitted values with their standard errors and units; a fitted answer
        outside validity is stamped so (:func:`dea_opt.io.marks.stamp`)."""
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.figure import Figure

        from ..files.atomic import write_atomic
        from ..io.marks import solution_verdict, stamp, verdict_lines

        table = self.residual_map()
        if table.empty:
            raise InputError("plot needs a pressure map among the data")
        fig = Figure(figsize=(10.5, 4.8), layout="constrained")
        FigureCanvasAgg(fig)
        ax1, ax2 = fig.subplots(1, 2)
        films = {data.film for data in self.data if isinstance(data, PressureMap) and data.film is not None}
        film = films.pop() if len(films) == 1 else None
        for state, marker, label in (
            ("measured", "o", "within the film's range"),
            ("below", "v", "read 'below'"),
            ("saturated", "^", "read 'saturated'"),
        ):
            rows = table[table.state == state]
            if not len(rows):
                continue
            # a censored reading says only "beyond the limit": drawn at the limit
            shown = (
                rows.measured_MPa
                if film is None or state == "measured"
                else np.full(len(rows), film.lower if state == "below" else film.upper)
            )
            ax1.scatter(rows.predicted_MPa, shown, s=5, marker=marker, alpha=0.5, label=label)
        top = float(max(table.measured_MPa.max(), table.predicted_MPa.max()))
        ax1.plot([0, top], [0, top], "k-", lw=0.8)
        if film is not None:
            for limit in (film.lower, film.upper):
                ax1.axhline(limit, color="0.5", ls="--", lw=0.8)
        ax1.set(xlabel="predicted pressure (MPa)", ylabel="measured pressure (MPa)", title="measured vs predicted")
        ax1.legend(loc="upper left", fontsize=8, markerscale=2)
        xyz = table[["x_mm", "y_mm", "z_mm"]].to_numpy()
        centred = xyz - xyz.mean(axis=0)
        axes = np.linalg.svd(centred, full_matrices=False)[2][:2] if len(xyz) > 2 else np.eye(3)[:2]
        plane = centred @ axes.T
        limit = float(np.abs(table.residual).max()) or 1.0
        sc = ax2.scatter(plane[:, 0], plane[:, 1], c=table.residual, cmap="RdBu_r", vmin=-limit, vmax=limit, s=6)
        ax2.set(
            aspect="equal",
            xlabel="in-plane axis 1 (mm)",
            ylabel="in-plane axis 2 (mm)",
            title="residuals on the map's best-fit plane",
        )
        fig.colorbar(sc, ax=ax2, shrink=0.85, label="residual: (predicted - measured) / sd (1)")
        text = ", ".join(
            f"{p} = {self.values[p]:.4g} ± {_se_text(self.standard_errors[p])}{_unit_text(self.unit_of(p))}"
            for p in self.parameters
        )
        verdict = solution_verdict(self.solution)
        heading = f"calibration: {text}" + verdict_lines(verdict, 110)
        fig.suptitle(f"{title}\n{heading}" if title else heading, fontsize=10)
        stamp(fig, verdict)
        return write_atomic(path, lambda tmp: fig.savefig(tmp, format="png", dpi=110))


def _unit_text(unit: str) -> str:
    return "" if unit in ("", "1") else f" {unit}"


def _se_text(value: float) -> str:
    return f"{value:.2g}" if np.isfinite(value) else "undefined"


def _correlation(model, used):
    """The correlation of the residuals taking part (block diagonal: data sets are independent of
    each other), or None when no datum states one."""
    import scipy.sparse as sp

    blocks = [data.correlation_of(cache) for data, cache in zip(model.data, model.caches)]
    if all(block is None for block in blocks):
        return None
    sizes = model.sizes
    full = sp.block_diag(
        [
            sp.identity(size, format="csr") if block is None else sp.csr_matrix(block)
            for block, size in zip(blocks, sizes)
        ],
        format="csr",
    )
    return full[used][:, used]


def _errors(errors, data) -> str:
    unstated = [k for k, d in enumerate(data) if not d.noise_stated]
    if errors is None:
        return "estimated" if unstated else "stated"
    if errors not in ("stated", "estimated"):
        raise InputError(f"errors must be 'stated', 'estimated' or None, got {errors!r}")
    if errors == "stated" and unstated:
        names = ", ".join(f"data[{k}] ({type(data[k]).__name__})" for k in unstated)
        raise InputError(
            f"errors='stated' needs every datum's noise, and {names} states none: give noise= "
            f"(area_std=, center_std= for ContactData), or errors='estimated'"
        )
    return errors


def calibrate(
    problem,
    data,
    parameters=("H",),
    *,
    start=None,
    max_nfev: int = 60,
    errors: str | None = None,
    method: str = "newton",
    ftol: float = 1e-10,
    xtol: float = 1e-10,
    progress: bool = False,
) -> Calibration:
    """Fit ``parameters`` of ``problem`` to ``data`` by least squares with the exact Jacobian.

    Parameters
    ----------
    problem : ContactProblem
        The model; its law's values (or ``start``) are where the fit starts.
    data : PressureMap, ForceDisplacement, ContactData, or a sequence of them
    parameters : sequence of str
        Law parameters (``"H"``, ``"beta"``), ``"thickness_scale"``, body 2's ``"Fx" ... "Mz"``.
    start : dict, optional
        Starting values (default: the problem's).
    max_nfev : int
        Largest number of evaluations (each one or more solves).
    errors : {"stated", "estimated"}, optional
        ``"stated"``: the data's stated standard deviations (and correlations) are the noise's,
        carried through the Jacobian (``(J^T J)^-1`` for independent data). ``"estimated"``:
        the noise's scale is estimated from the residuals' scatter, ``|r|^2`` over the degrees
        of freedom left; with none left (as many data as parameters) the standard errors are
        NaN and ``notes`` says so. Default: ``"stated"`` when every datum states its noise,
        else ``"estimated"``.
    method : str
        The solve method (``newton``; others are tried when it fails).
    ftol, xtol : float
        ``least_squares``'s tolerances.
    progress : bool
        Count the solves on a terminal (:mod:`dea_opt.progress`; their number is not known
        ahead, so no time left is shown).

    Returns
    -------
    Calibration
    """
    from scipy.optimize import least_squares

    if getattr(problem, "kinematics", "small") == "finite":
        raise InputError(
            "calibrate fits with the sensitivities of the small kinematics (Eq. (9)-(11)), and this problem "
            "has kinematics='finite': build it with kinematics='small' (a scenario: solve.kinematics = \"small\")"
        )
    parameters = _check_parameters(problem, parameters)
    data = (data,) if isinstance(data, (PressureMap, ForceDisplacement, ContactData)) else tuple(data)
    if not data or not all(isinstance(x, (PressureMap, ForceDisplacement, ContactData)) for x in data):
        raise InputError("data must be a PressureMap, ForceDisplacement or ContactData, or a sequence of them")
    errors = _errors(errors, data)
    values = {p: _current(problem, p) for p in parameters}
    values.update({k: float(v) for k, v in (start or {}).items() if k in parameters})
    unknown = set(start or {}) - set(parameters)
    if unknown:
        raise InputError(f"start names {sorted(unknown)}, which are not among the parameters {parameters}")
    logs = np.array([_fitted_in_logs(problem, p) for p in parameters])
    theta0 = np.array([values[p] for p in parameters])
    if (theta0[logs] <= 0).any():
        raise InputError(
            f"the start of {', '.join(np.array(parameters)[logs])} must be > 0 (fitted in logarithms), "
            f"got {theta0[logs].tolist()}"
        )
    from ..progress import bar

    model = _Model(problem, data, parameters, logs, method)
    z0 = np.where(logs, np.log(np.where(logs, theta0, 1.0)), theta0)
    with warnings.catch_warnings(), bar(None, "fitting", "solve", progress) as counted:
        model.on_solve = counted.update
        warnings.simplefilter("ignore", ValidityWarning)
        # within three decades of the start: a step can never leave the law's range
        span = np.where(logs, np.log(1e3), np.inf)
        fit = least_squares(
            model.residuals,
            z0,
            jac=model.jacobian,
            bounds=(z0 - span, z0 + span),
            method="trf",
            x_scale="jac",
            max_nfev=max_nfev,
            ftol=ftol,
            xtol=xtol,
            gtol=1e-12,
        )
        r, Jz, solution = model.evaluate(fit.x)
    theta = np.where(logs, np.exp(fit.x), fit.x)
    J = Jz / np.where(logs, theta, 1.0)  # d r / d theta
    # a censored reading the model agrees with neither costs nor moves anything: it takes no part
    used = (np.abs(J).sum(axis=1) > 0) | (r != 0)
    found = parameter_covariance(r[used], J[used], _correlation(model, used), errors=errors)
    covariance = found.covariance
    se = np.sqrt(np.maximum(np.diag(covariance), 0.0))  # NaN stays NaN: undefined
    with np.errstate(invalid="ignore", divide="ignore"):
        correlation = covariance / np.outer(se, se)
    return Calibration(
        parameters,
        dict(zip(parameters, theta.tolist())),
        dict(zip(parameters, theta0.tolist())),
        dict(zip(parameters, se.tolist())),
        correlation,
        covariance,
        r,
        float(r @ r) / 2,
        bool(fit.success),
        str(fit.message),
        int(model.solves),
        solution,
        data,
        errors=found.errors,
        degrees_of_freedom=found.degrees_of_freedom,
        notes=(found.note,) if found.note else (),
        info={"optimality": float(fit.optimality), "nfev": int(fit.nfev), "njev": int(fit.njev or 0)},
    )


class _Model:
    """Residuals and Jacobian at ``z``, computed once per point and cached (least_squares asks for
    both at the same point)."""

    def __init__(self, problem, data, parameters, logs, method):
        self.problem, self.data, self.parameters, self.logs, self.method = problem, data, parameters, logs, method
        self.last = None
        self.solves = 0
        self.on_solve = None  # called after each solve (a progress counter)
        self.caches = [{} for _ in data]
        self.starts = {}
        self.sizes = [0] * len(data)

    def _solve(self, problem, key):
        from ..solver import solve

        x0 = self.starts.get(key)
        try:
            options = {"x0": x0} if (self.method == "newton" and x0 is not None) else {}
            solution = solve(problem, self.method, **options)
        except SolverError:
            solution = solve(problem, "auto")
        self.solves += 1
        if self.on_solve is not None:
            self.on_solve()
        self.starts[key] = solution.u[problem.free_indices]
        return solution

    def evaluate(self, z):
        if self.last is not None and np.array_equal(self.last[0], z):
            return self.last[1:]
        theta = np.where(self.logs, np.exp(z), z)
        problem = apply_parameters(self.problem, dict(zip(self.parameters, theta.tolist())))
        names = self.parameters
        solution = None
        rs, Js = [], []
        for k, data in enumerate(self.data):
            if isinstance(data, ForceDisplacement):
                r, J = self._curve(problem, data, k)
            else:
                if solution is None:
                    solution = self._solve(problem, "main")
                    sens = sensitivities(solution, names)
                r, J = data.residuals(solution, sens, names, self.caches[k])
            rs.append(r)
            Js.append(J)
            self.sizes[k] = len(r)
        if solution is None:
            solution = self._solve(problem, "main")
        r = np.concatenate(rs)
        Jz = np.vstack(Js) * np.where(self.logs, theta, 1.0)  # d/dz = theta d/dtheta in logs
        self.last = (z.copy(), r, Jz, solution)
        return r, Jz, solution

    def _curve(self, problem, data, k):
        r, J = [], []
        for i, (d, f, sd) in enumerate(zip(data.displacement, data.force, data.standard_deviations())):
            body = problem.body2.with_prescribed(**{data.dof: float(d)})
            solution = self._solve(problem.with_body(2, body), ("curve", k, i))
            sens = sensitivities(solution, self.parameters)
            r.append((solution.contact_force[data.axis] - f) / sd)
            J.append([np.asarray(sens.contact_force[n])[data.axis] / sd for n in self.parameters])
        return np.array(r), np.array(J)

    def residuals(self, z):
        return self.evaluate(z)[0]

    def jacobian(self, z):
        return self.evaluate(z)[1]
