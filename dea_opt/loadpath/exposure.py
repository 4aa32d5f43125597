"""Contact-stress exposure over a load path: what a cycle exposes each site of the cartilage to.

The time integral of pressure, the time above a threshold and the integral of the excess
over it (Kern & Anderson, J Biomech 2015, and Anderson's group before them), exact for
pressure piecewise linear in time between frames. Units: MPa, s, MPa s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError

__all__ = ["Exposure", "exposure"]


@dataclass(frozen=True, eq=False)
class Exposure:
    """Contact-stress exposure of every site (spring, or face of mesh 1 when body 2's mesh moves).

    Pressure is taken as piecewise linear in time between frames, and every integral is
    exact for that.

    Attributes
    ----------
    threshold : float
        Pressure threshold (MPa).
    pressure_time_integral : ndarray
        ``int p dt`` (MPa s).
    time_above : ndarray
        Time with ``p > threshold`` (s).
    exposure_above : ndarray
        ``int max(p - threshold, 0) dt`` (MPa s): the exposure over a threshold.
    peak : ndarray
        Largest pressure over the path (MPa).
    duration : float
        Time from the first to the last frame (s).
    """

    threshold: float
    pressure_time_integral: np.ndarray
    time_above: np.ndarray
    exposure_above: np.ndarray
    peak: np.ndarray
    duration: float

    def fields(self) -> dict:
        """The per-site arrays by name (for files)."""
        return {
            "pressure_time_integral": self.pressure_time_integral,
            "time_above_threshold": self.time_above,
            "exposure_above_threshold": self.exposure_above,
            "peak_pressure": self.peak,
        }

    def summary(self) -> dict:
        return {
            "threshold": self.threshold,
            "duration": self.duration,
            "max_pressure_time_integral": float(self.pressure_time_integral.max(initial=0.0)),
            "max_time_above_threshold": float(self.time_above.max(initial=0.0)),
            "max_exposure_above_threshold": float(self.exposure_above.max(initial=0.0)),
            "sites_above_threshold": int((self.time_above > 0).sum()),
        }


def exposure(times, pressures, sites=None, threshold: float = 1.0, n_sites: int | None = None) -> Exposure:
    """Contact-stress exposure over a path.

    Parameters
    ----------
    times : array_like (T,)
        Frame times (s), increasing.
    pressures : sequence of T arrays
        Pressure per spring at each frame (MPa).
    sites : sequence of T integer arrays, optional
        The site of each spring at each frame (default: spring ``i`` is site ``i``).
    threshold : float
        MPa.
    n_sites : int, optional
        Number of sites (default: the largest site index + 1).
    """
    times = np.asarray(times, dtype=float)
    threshold = float(threshold)
    if not threshold >= 0:
        raise InputError(f"threshold must be a pressure >= 0 (MPa), got {threshold!r}")
    if sites is None:
        sites = [np.arange(len(p)) for p in pressures]
    if n_sites is None:
        n_sites = int(max((s.max(initial=-1) for s in sites), default=-1)) + 1
    P = np.zeros((len(times), n_sites))
    for k, (p, s) in enumerate(zip(pressures, sites)):
        np.maximum.at(P[k], s, np.nan_to_num(p, nan=0.0))
    dt = np.diff(times)[:, None]
    p0, p1 = P[:-1], P[1:]
    integral = (0.5 * (p0 + p1) * dt).sum(axis=0)
    above, excess = _above(p0, p1, dt, threshold)
    return Exposure(threshold, integral, above, excess, P.max(axis=0, initial=0.0),
                    float(times[-1] - times[0]) if len(times) else 0.0)


def _above(p0, p1, dt, threshold):
    """Time above ``threshold`` and the integral of the excess, segment by segment, exact for linear p(t)."""
    e0, e1 = p0 - threshold, p1 - threshold
    both = (e0 > 0) & (e1 > 0)
    one = (e0 > 0) ^ (e1 > 0)
    high = np.maximum(e0, e1)
    with np.errstate(invalid="ignore", divide="ignore"):
        fraction = np.where(one, high / np.abs(p1 - p0), 0.0)
    time_above = np.where(both, dt, np.where(one, fraction * dt, 0.0)).sum(axis=0)
    excess = np.where(both, 0.5 * (e0 + e1) * dt, np.where(one, 0.5 * high * fraction * dt, 0.0)).sum(axis=0)
    return time_above, excess
