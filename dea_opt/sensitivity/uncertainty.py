"""Parameter uncertainty carried to the answer: first order from the exact derivatives, checked by
a Monte Carlo sweep on Dask.

Written math: ``formulations/sensitivity.md`` ("Uncertainty"). :func:`propagate` takes one call of
:func:`~dea_opt.sensitivity.sensitivities`; :func:`monte_carlo` draws the same parameters normally
and solves every draw as a Dask task (synchronous, threads, processes or a ``distributed`` client,
e.g. of a ``LocalCluster``).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..errors import InputError, ValidityWarning
from .derivatives import PER_SPRING, sensitivities

__all__ = ["SCALARS", "MonteCarlo", "Propagation", "monte_carlo", "propagate"]

#: The scalar outputs both report (the centre of pressure per coordinate, mm).
SCALARS = ("peak_pressure", "mean_pressure", "contact_area", "cop_x", "cop_y", "cop_z")


def _scalars(solution) -> dict:
    cop = solution.center_of_pressure
    return {
        "peak_pressure": solution.peak_pressure,
        "mean_pressure": solution.mean_pressure,
        "contact_area": solution.contact_area,
        "cop_x": float(cop[0]),
        "cop_y": float(cop[1]),
        "cop_z": float(cop[2]),
    }


def _check_std(std) -> dict:
    if not hasattr(std, "items") or not std:
        raise InputError(f"std must be a mapping {{parameter: standard deviation}}, got {std!r}")
    out = {}
    for name, value in std.items():
        if name in PER_SPRING:
            raise InputError(f"std: {name!r} is a per-spring parameter; give 'thickness_scale' instead")
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float, np.integer, np.floating))
            or not (np.isfinite(value) and value >= 0)
        ):
            raise InputError(f"std[{name!r}] must be a finite number >= 0 (the parameter's units), got {value!r}")
        out[str(name)] = float(value)
    return out


@dataclass(frozen=True)
class Propagation:
    """First-order standard deviations of the scalar outputs.

    Attributes
    ----------
    std : dict
        The parameters' standard deviations (their units).
    value : dict
        Each output of :data:`SCALARS` at the solution.
    output_std : dict
        ``sqrt(sum_k (dy/dp_k std_k)^2)`` per output; with one-sided derivatives (edge springs, a
        shared peak) ``(dy/dp_k)^2`` is the mean of the two sides' squares.
    derivatives : dict
        ``{output: {parameter: dy/dp}}`` (as the parameter increases).
    """

    std: dict
    value: dict
    output_std: dict
    derivatives: dict

    def table(self):
        """One row per output: ``output, value, std, relative``."""
        import pandas as pd

        return pd.DataFrame(
            [
                {
                    "output": k,
                    "value": v,
                    "std": self.output_std[k],
                    "relative": self.output_std[k] / abs(v) if v else np.nan,
                }
                for k, v in self.value.items()
            ]
        )


def propagate(solution, std) -> Propagation:
    """First-order propagation of independent parameter standard deviations to the outputs.

    Parameters
    ----------
    solution : Solution
        A certified answer.
    std : mapping {str: float}
        Standard deviation per parameter (names as for :func:`~dea_opt.sensitivity.sensitivities`:
        ``"H"``, ``"beta"``, ``"thickness_scale"``, ``"Fz"``, ...).

    Returns
    -------
    Propagation
    """
    std = _check_std(std)
    sens = sensitivities(solution, tuple(std))
    sides = (sens, sens.decreasing) if sens.one_sided else (sens,)
    derivatives, output_std = {}, {}
    for output in SCALARS:
        key, index = ("center_of_pressure", "xyz".index(output[-1])) if output.startswith("cop_") else (output, None)
        values = {}
        variance = 0.0
        for name, sd in std.items():
            arrays = [np.asarray(getattr(s, key)[name], dtype=float) for s in sides]
            rates = [float(r[index]) if index is not None else float(r) for r in arrays]
            values[name] = rates[0]
            variance += float(np.mean(np.square(rates))) * sd * sd
        derivatives[output] = values
        output_std[output] = float(np.sqrt(variance))
    return Propagation(std, _scalars(solution), output_std, derivatives)


@dataclass(frozen=True)
class MonteCarlo:
    """Sample statistics of a Monte Carlo sweep.

    Attributes
    ----------
    samples : pandas.DataFrame
        One row per draw: the parameters, ``success`` and every output of :data:`SCALARS`.
    mean, std : dict
        Over the certified draws, per output.
    """

    samples: Any
    mean: dict
    std: dict

    @property
    def n_failed(self) -> int:
        return int((~self.samples["success"]).sum())


def _draw(problem, rows, x0):
    """Solve the problem at every row of parameters (one Dask task)."""
    from ..solver import solve
    from .calibrate import apply_parameters

    out = []
    for row in rows:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", ValidityWarning)
                options = {"x0": x0} if x0 is not None else {}
                s = solve(apply_parameters(problem, row), "newton", strict=False, **options)
            out.append({**row, "success": bool(s.success), **_scalars(s)})
        except Exception as exc:  # noqa: BLE001 - a draw that fails is a row, not the end of the sweep
            out.append({**row, "success": False, "error": f"{type(exc).__name__}: {exc}"})
    return out


def monte_carlo(
    problem, std, n: int = 200, *, seed: int = 0, scheduler="synchronous", client=None, chunks: int = 8
) -> MonteCarlo:
    """Solve ``n`` draws of the parameters, independent normals about the problem's values.

    Parameters
    ----------
    problem : ContactProblem
    std : mapping {str: float}
        Standard deviations of law parameters, ``"thickness_scale"`` or body 2's ``"Fx" ... "Mz"``.
        Positive parameters (the law's, the thickness scale) are clipped at 1e-6 of their value.
    n : int
        Number of draws.
    seed : int
        For :func:`numpy.random.default_rng`.
    scheduler : str
        Dask's scheduler: ``"synchronous"``, ``"threads"`` or ``"processes"`` (ignored with ``client``).
    client : distributed.Client, optional
        E.g. ``Client(LocalCluster(n_workers=2))``: the draws run on its workers.
    chunks : int
        Draws are grouped into this many tasks.

    Returns
    -------
    MonteCarlo
    """
    import dask
    import pandas as pd

    from .calibrate import _current, _fitted_in_logs

    std = _check_std(std)
    allowed = (*problem.law.parameter_names, "thickness_scale", "Fx", "Fy", "Fz", "Mx", "My", "Mz")
    bad = [k for k in std if k not in allowed]
    if bad:
        raise InputError(f"monte_carlo draws {', '.join(allowed)}; not {', '.join(bad)}")
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 2:
        raise InputError(f"n must be an integer >= 2, got {n!r}")
    rng = np.random.default_rng(seed)
    draws = {}
    for name, sd in std.items():
        centre = _current(problem, name)
        values = centre + sd * rng.standard_normal(n)
        if _fitted_in_logs(problem, name):
            values = np.maximum(values, 1e-6 * abs(centre))
        draws[name] = values
    rows = [{k: float(v[i]) for k, v in draws.items()} for i in range(n)]
    from ..solver import solve

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ValidityWarning)
        x0 = solve(problem, "newton").u[problem.free_indices]
    groups = [rows[i :: max(1, int(chunks))] for i in range(min(max(1, int(chunks)), n))]
    tasks = [dask.delayed(_draw)(problem, group, x0) for group in groups]
    if client is not None:
        results = client.compute(tasks, sync=True)
    else:
        results = dask.compute(*tasks, scheduler=scheduler)
    table = pd.DataFrame([row for group in results for row in group])
    good = table[table["success"]]
    return MonteCarlo(
        table, {k: float(good[k].mean()) for k in SCALARS}, {k: float(good[k].std(ddof=1)) for k in SCALARS}
    )
