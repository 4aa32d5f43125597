"""Measured data a model is calibrated against: pressure maps (film, sensors), force-displacement
curves, contact area and centre of pressure.

Written math: ``formulations/sensitivity.md`` ("Calibration", "Standard errors"). Each kind turns
a solution and its :class:`~dea_opt.sensitivity.Sensitivities` into weighted residuals and their
Jacobian (:meth:`PressureMap.residuals`, ...), which :func:`dea_opt.sensitivity.calibrate.calibrate`
stacks. Each states its noise or not (``noise=None``: not stated; the fit then weights it by
a nominal value, :data:`NOMINAL`, and the standard errors come from the residuals' scatter), and
a map or a curve may state the correlation of its noise (``correlation=``).

Units: mm, N, MPa.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import InputError
from .covariance import check_correlation

__all__ = ["FILMS", "NOMINAL", "ContactData", "Film", "ForceDisplacement", "PressureMap"]

#: The weights of data whose noise is not stated (the fit needs one; the standard errors then
#: come from the residuals' scatter, not from these): a map's relative noise, a curve's force
#: noise (N; relative: 5 %), a contact area's (mm^2) and a centre of pressure's (mm).
NOMINAL = {"pressure": 0.05, "force": 1.0, "force_relative": 0.05, "area": 10.0, "center": 0.5}


@dataclass(frozen=True)
class Film:
    """A pressure-sensitive film's measurable range (MPa): below ``lower`` it shows nothing,
    above ``upper`` it is saturated."""

    lower: float
    upper: float
    name: str = ""

    def __post_init__(self):
        if not (np.isfinite(self.lower) and np.isfinite(self.upper) and 0 <= self.lower < self.upper):
            raise InputError(f"a film's range must be 0 <= lower < upper (MPa), got {self.lower!r} to {self.upper!r}")


#: Fuji Prescale grades (MPa), by the names on their packets.
FILMS = {
    "LLLW": Film(0.2, 0.6, "Fuji Prescale LLLW"),
    "LLW": Film(0.5, 2.5, "Fuji Prescale LLW"),
    "LW": Film(2.5, 10.0, "Fuji Prescale LW"),
    "MS": Film(10.0, 50.0, "Fuji Prescale MS"),
    "HS": Film(50.0, 130.0, "Fuji Prescale HS"),
}


def _film(film) -> Film | None:
    if film is None or isinstance(film, Film):
        return film
    if isinstance(film, str) and film.upper() in FILMS:
        return FILMS[film.upper()]
    if isinstance(film, (tuple, list)) and len(film) == 2:
        return Film(float(film[0]), float(film[1]))
    raise InputError(f"film must be one of {', '.join(FILMS)}, a Film or (lower, upper) in MPa, got {film!r}")


def finite_array(name, value, unit="") -> np.ndarray:
    """``value`` as a float array of finite numbers, or an :class:`InputError` naming it."""
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must hold numbers{f' ({unit})' if unit else ''}, got {value!r:.80}") from None
    if not np.isfinite(arr).all():
        raise InputError(f"{name} must be finite{f' ({unit})' if unit else ''}; it holds NaN or infinite values")
    return arr


def _optional_positive(name, value):
    return None if value is None else _positive(name, value)


def _positive(name, value):
    if (
        isinstance(value, bool)
        or not isinstance(value, (int, float, np.integer, np.floating))
        or not (np.isfinite(value) and value > 0)
    ):
        raise InputError(f"{name} must be a finite number > 0, got {value!r}")
    return float(value)


@dataclass(frozen=True, eq=False)
class PressureMap:
    """Points with a measured pressure, read through a film's range or a sensor.

    Parameters
    ----------
    points : array_like, shape (n, 3)
        Where each pressure was read (mm), in the springs' frame.
    pressure : array_like, shape (n,)
        The reading (MPa). With a ``film``, a reading at or below its lower limit counts as
        "below" and one at or above its upper limit as "saturated" (censored, see
        formulations/sensitivity.md).
    film : Film, str or (lower, upper), optional
        ``"LLW"`` (0.5-2.5 MPa), ``"LW"`` (2.5-10 MPa), ... (:data:`FILMS`); None: a sensor with
        no range.
    noise : float, optional
        Relative standard deviation of a reading (0.05: 5 %). None (default): not stated; the
        fit weights the readings by ``NOMINAL["pressure"]`` (5 %) and the standard errors come
        from the residuals' scatter.
    max_distance : float, optional
        Points farther than this from every spring (mm) are dropped (default: twice the
        springs' typical spacing).
    correlation : array_like or scipy.sparse matrix, shape (n, n), optional
        The correlation of the readings' noise, one row per point (neighbouring pixels of a
        scanned film: :func:`~dea_opt.sensitivity.covariance.spatial_correlation`); None:
        independent readings.
    """

    points: np.ndarray
    pressure: np.ndarray
    film: Film | None = None
    noise: float | None = None
    max_distance: float | None = None
    source: str = field(default="", compare=False)
    correlation: object = field(default=None, compare=False)

    def __post_init__(self):
        points = finite_array("points", self.points, "mm")
        if points.ndim != 2 or points.shape[1] != 3 or not len(points):
            raise InputError(f"points must have shape (n, 3) with n >= 1, got shape {points.shape}")
        pressure = finite_array("pressure", self.pressure, "MPa")
        if pressure.shape != (len(points),):
            raise InputError(f"pressure must hold one value per point ({len(points)}), got shape {pressure.shape}")
        if (pressure < 0).any():
            raise InputError(f"pressure must be >= 0 (MPa), got {pressure.min():g}")
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "pressure", pressure)
        object.__setattr__(self, "film", _film(self.film))
        object.__setattr__(self, "noise", _optional_positive("noise", self.noise))
        if self.max_distance is not None:
            object.__setattr__(self, "max_distance", _positive("max_distance", self.max_distance))
        if self.correlation is not None:
            object.__setattr__(self, "correlation", check_correlation("correlation", self.correlation, len(points)))

    @property
    def noise_stated(self) -> bool:
        return self.noise is not None

    @property
    def weight_noise(self) -> float:
        """The relative standard deviation the residuals are divided by: ``noise``, or the nominal
        5 % when it is not stated."""
        return NOMINAL["pressure"] if self.noise is None else float(self.noise)

    def correlation_of(self, cache):
        """The correlation of the residuals :meth:`residuals` returns (the matched points), or None."""
        if self.correlation is None:
            return None
        kept = cache["match"][1]
        return self.correlation[kept][:, kept]

    @property
    def state(self) -> np.ndarray:
        """Per point: 0 read within the range, -1 "below", +1 "saturated"."""
        if self.film is None:
            return np.where(self.pressure <= self.floor, -1, 0)
        return np.where(self.pressure <= self.film.lower, -1, np.where(self.pressure >= self.film.upper, 1, 0))

    @classmethod
    def from_csv(cls, path, film=None, noise: float | None = None, max_distance=None) -> PressureMap:
        """Read a CSV with columns ``x, y, z, p`` (mm, MPa; other columns are ignored)."""
        import pandas as pd

        path = Path(path)
        try:
            table = pd.read_csv(path)
        except FileNotFoundError:
            raise InputError(f"pressure data {path}: no such file") from None
        except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError, IsADirectoryError) as exc:
            raise InputError(f"pressure data {path}: not a CSV table ({exc})") from None
        table.columns = [str(c).strip().lower() for c in table.columns]
        missing = [c for c in ("x", "y", "z", "p") if c not in table.columns]
        if missing:
            raise InputError(
                f"pressure data {path}: needs the columns x, y, z, p (mm, MPa); missing "
                f"{', '.join(missing)} (found {', '.join(table.columns) or 'none'})"
            )
        try:
            values = table[["x", "y", "z", "p"]].to_numpy(dtype=float)
        except (TypeError, ValueError):
            raise InputError(f"pressure data {path}: the columns x, y, z, p must hold numbers") from None
        try:
            return cls(values[:, :3], values[:, 3], film, noise, max_distance, source=str(path))
        except InputError as exc:
            raise InputError(f"pressure data {path}: {exc}") from None

    @classmethod
    def from_grid(
        cls, values, origin, axis_u, axis_v, spacing, film=None, noise: float | None = None, max_distance=None
    ) -> PressureMap:
        """A scanned map: ``values[j, i]`` (MPa, NaN where nothing was read) at the centre of cell
        ``(i, j)`` of a grid on a plane, ``origin + (i + 1/2) du axis_u + (j + 1/2) dv axis_v``.

        ``origin`` (mm) is the grid's corner, ``axis_u``/``axis_v`` its in-plane directions (made
        unit; must not be parallel) and ``spacing`` the cell size ``du`` or ``(du, dv)`` (mm).
        """
        grid = np.asarray(values, dtype=float)
        if grid.ndim != 2:
            raise InputError(f"values must be a 2-D grid, got shape {grid.shape}")
        origin = finite_array("origin", origin, "mm").reshape(-1)
        u, v = (finite_array(n, a, "").reshape(-1) for n, a in (("axis_u", axis_u), ("axis_v", axis_v)))
        if origin.shape != (3,) or u.shape != (3,) or v.shape != (3,):
            raise InputError("origin, axis_u and axis_v must each hold 3 numbers")
        u, v = u / max(np.linalg.norm(u), 1e-300), v / max(np.linalg.norm(v), 1e-300)
        if np.linalg.norm(np.cross(u, v)) < 1e-6:
            raise InputError("axis_u and axis_v must span a plane (they are parallel or zero)")
        du, dv = (spacing, spacing) if np.ndim(spacing) == 0 else tuple(spacing)
        du, dv = _positive("spacing", du), _positive("spacing", dv)
        j, i = np.nonzero(np.isfinite(grid))
        points = origin + np.outer((i + 0.5) * du, u) + np.outer((j + 0.5) * dv, v)
        return cls(points, grid[j, i], film, noise, max_distance, source="grid")

    # --- residuals ---------------------------------------------------------------------
    def matched(self, layer) -> tuple:
        """``(spring index per kept point, kept points)``: each point's nearest spring."""
        from scipy.spatial import cKDTree

        distance, index = (np.asarray(a) for a in cKDTree(layer.points).query(self.points))
        limit = self.max_distance
        if limit is None:
            limit = 2.0 * float(np.sqrt(np.median(layer.areas)))
        keep = distance <= limit
        if not keep.any():
            raise InputError(
                f"none of the {len(self.points)} measured points lies within {limit:g} mm of a spring: "
                f"are they in the springs' frame and units (mm)?"
            )
        return index[keep], np.flatnonzero(keep)

    def residuals(self, solution, sens, names, cache) -> tuple:
        """``(r, J)``: residuals (n,) and their derivatives (n, p) of the censored log-normal
        likelihood (formulations/sensitivity.md, "Calibration"): ``(log m - log p) / noise`` for a
        reading within the range, ``sqrt(-2 log Phi(z))`` for one read "below" or "saturated"."""
        from scipy.special import log_ndtr

        if "match" not in cache:
            cache["match"] = self.matched(solution.problem.layer)
        springs, kept = cache["match"]
        measured, state = self.pressure[kept], self.state[kept]
        floor = self.floor
        raw = solution.pressure[springs]
        model = np.hypot(raw, floor)  # log of a pressure that may be 0: smoothed below the floor
        jac = (
            np.column_stack([np.asarray(sens.pressure[n])[springs] for n in names])
            if names
            else np.zeros((len(springs), 0))
        )
        dlog = jac * (raw / model**2)[:, None]  # d log(model) / d theta
        noise = self.weight_noise
        read = np.where(state == 0, np.maximum(measured, floor), 1.0)
        r = (np.log(model) - np.log(read)) / noise
        J = dlog / noise
        if self.film is not None or (state != 0).any():
            for side, limit in (
                (-1, self.film.lower if self.film else floor),
                (1, self.film.upper if self.film else 0),
            ):
                rows = state == side
                if not rows.any():
                    continue
                # P(reading beyond the limit): Phi(z), z = side (log m - log limit) / noise
                z = side * (np.log(model[rows]) - np.log(max(limit, floor))) / noise
                log_cdf = log_ndtr(z)
                rr = np.sqrt(np.maximum(-2.0 * log_cdf, 0.0))
                log_pdf = -0.5 * z * z - 0.5 * np.log(2 * np.pi)
                with np.errstate(divide="ignore", invalid="ignore"):
                    slope = np.where(rr > 1e-150, -np.exp(log_pdf - log_cdf) / rr, 0.0)  # d r / d z
                r[rows] = rr
                J[rows] = (slope * (side / noise))[:, None] * dlog[rows]
        return r, J

    @property
    def floor(self) -> float:
        """The pressure below which the log residual is smoothed (MPa): a thousandth of the film's
        lower limit, or 1e-4 of the largest reading."""
        if self.film is not None and self.film.lower > 0:
            return 1e-3 * self.film.lower
        return 1e-4 * max(float(self.pressure.max(initial=0.0)), 1e-12)


@dataclass(frozen=True, eq=False)
class ForceDisplacement:
    """A force-displacement curve: body 2 moved to ``displacement[k]`` along a translation dof, the
    force the layer then exerts on it along that axis measured as ``force[k]`` (N, positive when
    it pushes body 2 back along the axis' positive direction).

    ``noise`` is the standard deviation of a force reading (N), or relative with ``relative=True``;
    None (default): not stated, the fit weights the readings by ``NOMINAL["force"]`` (1 N; 5 %
    relative) and the standard errors come from the residuals' scatter. ``correlation`` (k, k),
    optional: the correlation of the readings' noise (a drifting load cell, a filtered signal).
    """

    dof: str
    displacement: np.ndarray
    force: np.ndarray
    noise: float | None = None
    relative: bool = False
    correlation: object = field(default=None, compare=False)

    def __post_init__(self):
        dof = self.dof.split(".")[-1]
        if dof not in ("ux", "uy", "uz") or not self.dof.startswith(("body2.", "u")):
            raise InputError(f"dof must be a translation of body 2 (ux, uy, uz), got {self.dof!r}")
        d = finite_array("displacement", self.displacement, "mm").reshape(-1)
        f = finite_array("force", self.force, "N").reshape(-1)
        if not d.size or d.shape != f.shape:
            raise InputError(f"displacement and force must be equally long and not empty, got {d.size} and {f.size}")
        object.__setattr__(self, "dof", dof)
        object.__setattr__(self, "displacement", d)
        object.__setattr__(self, "force", f)
        object.__setattr__(self, "noise", _optional_positive("noise", self.noise))
        if self.correlation is not None:
            object.__setattr__(self, "correlation", check_correlation("correlation", self.correlation, d.size))

    @property
    def axis(self) -> int:
        return "xyz".index(self.dof[1])

    @property
    def noise_stated(self) -> bool:
        return self.noise is not None

    def standard_deviations(self) -> np.ndarray:
        """The standard deviation of each force reading the residuals are divided by (N)."""
        if self.noise is None:
            noise = NOMINAL["force_relative" if self.relative else "force"]
        else:
            noise = float(self.noise)
        return noise * (np.maximum(np.abs(self.force), 1e-12) if self.relative else np.ones(self.force.size))

    def correlation_of(self, cache):
        return self.correlation


@dataclass(frozen=True, eq=False)
class ContactData:
    """A measured contact area (mm^2) and/or centre of pressure (mm), with standard deviations.

    ``area_std`` (mm^2) and ``center_std`` (mm, each coordinate) None (default): not stated; the
    fit weights the data by ``NOMINAL["area"]`` and ``NOMINAL["center"]`` and the standard
    errors come from the residuals' scatter (undefined with as many data as parameters).
    """

    area: float | None = None
    center: np.ndarray | None = None
    area_std: float | None = None
    center_std: float | None = None

    def __post_init__(self):
        if self.area is None and self.center is None:
            raise InputError("ContactData needs an area, a center or both")
        if self.area is not None:
            object.__setattr__(self, "area", _positive("area", self.area))
        if self.center is not None:
            center = finite_array("center", self.center, "mm").reshape(-1)
            if center.shape != (3,):
                raise InputError(f"center must hold 3 numbers (mm), got {center.size}")
            object.__setattr__(self, "center", center)
        object.__setattr__(self, "area_std", _optional_positive("area_std", self.area_std))
        object.__setattr__(self, "center_std", _optional_positive("center_std", self.center_std))

    @property
    def noise_stated(self) -> bool:
        return (self.area is None or self.area_std is not None) and (self.center is None or self.center_std is not None)

    def correlation_of(self, cache):
        return None

    def residuals(self, solution, sens, names, cache) -> tuple:
        area_std = NOMINAL["area"] if self.area_std is None else self.area_std
        center_std = NOMINAL["center"] if self.center_std is None else self.center_std
        r, J = [], []
        if self.area is not None:
            r.append((solution.contact_area - self.area) / area_std)
            J.append([sens.contact_area[n] / area_std for n in names])
        if self.center is not None:
            r.extend((solution.center_of_pressure - self.center) / center_std)
            J.extend(np.column_stack([np.asarray(sens.center_of_pressure[n]) for n in names]) / center_std)
        return np.asarray(r, dtype=float), np.asarray(J, dtype=float).reshape(len(r), len(names))
