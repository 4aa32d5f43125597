"""Contact-stress exposure over a load path: what a cycle exposes each site of the cartilage to.

The time integral of pressure, the time above a threshold and the integral of the excess
over it (Kern & Anderson, J Biomech 2015, and Anderson's group before them), exact for
pressure piecewise linear in time between frames. Units: MPa, s, MPa s.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError

__all__ = ["Exposure", "ExposureAccumulator", "exposure"]


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
        """The headline numbers, each name ending with its unit (:mod:`dea_opt.units`)."""
        return {
            "threshold_MPa": self.threshold,
            "duration_s": self.duration,
            "max_pressure_time_integral_MPa_s": float(self.pressure_time_integral.max(initial=0.0)),
            "max_time_above_threshold_s": float(self.time_above.max(initial=0.0)),
            "max_exposure_above_threshold_MPa_s": float(self.exposure_above.max(initial=0.0)),
            "sites_above_threshold": int((self.time_above > 0).sum()),
        }


class ExposureAccumulator:
    """The exposure of every site, accumulated one frame at a time (no frames x sites array).

    Memory is six arrays of ``n_sites`` whatever the number of frames. Frames must come in
    increasing time. A frame without a certified answer is left out with :meth:`skip`: the
    pressure is then taken as linear between the certified frames on either side of it, and
    nothing is counted before the first certified frame or after the last.

    Parameters
    ----------
    n_sites : int
        Number of sites.
    threshold : float
        Pressure threshold (MPa).
    """

    def __init__(self, n_sites: int, threshold: float = 1.0):
        threshold = float(threshold)
        if not threshold >= 0:
            raise InputError(f"threshold must be a pressure >= 0 (MPa), got {threshold!r}")
        self.n_sites = int(n_sites)
        self.threshold = threshold
        self.integral = np.zeros(self.n_sites)
        self.time_above = np.zeros(self.n_sites)
        self.excess = np.zeros(self.n_sites)
        self.peak = np.zeros(self.n_sites)
        self._last: tuple[float, np.ndarray] | None = None  # the last counted frame: (time, pressure per site)
        self._span: tuple[float, float] | None = None  # (first, last) time of the frames seen

    def _note(self, t: float) -> None:
        if self._span is not None and not t > self._span[1]:
            raise InputError(f"exposure frames must come in increasing time, got {t!r} after {self._span[1]!r}")
        self._span = (t if self._span is None else self._span[0], t)

    def add(self, t: float, pressure, sites=None) -> None:
        """Add the frame at time ``t`` (s): ``pressure`` (MPa) per spring, ``sites`` its site (default: spring i is site i)."""
        t = float(t)
        self._note(t)
        pressure = np.nan_to_num(np.asarray(pressure, dtype=float), nan=0.0)
        if sites is None:
            if pressure.shape != (self.n_sites,):
                raise InputError(f"pressure must have shape ({self.n_sites},), one per site, got {pressure.shape}")
            p1 = pressure
        else:
            p1 = np.zeros(self.n_sites)
            np.maximum.at(p1, np.asarray(sites), pressure)
        if self._last is not None:
            dt = t - self._last[0]
            p0 = self._last[1]
            self.integral += 0.5 * (p0 + p1) * dt
            above, excess = _above(p0, p1, dt, self.threshold)
            self.time_above += above
            self.excess += excess
        np.maximum(self.peak, p1, out=self.peak)
        self._last = (t, p1)

    def skip(self, t: float) -> None:
        """A frame at time ``t`` without a certified answer: bridged, not counted."""
        self._note(float(t))

    def result(self) -> Exposure:
        duration = 0.0 if self._span is None else float(self._span[1] - self._span[0])
        return Exposure(self.threshold, self.integral, self.time_above, self.excess, self.peak, duration)


def exposure(times, pressures, sites=None, threshold: float = 1.0, n_sites: int | None = None) -> Exposure:
    """Contact-stress exposure over a path, accumulated frame by frame (:class:`ExposureAccumulator`).

    Parameters
    ----------
    times : array_like (T,)
        Frame times (s), increasing.
    pressures : sequence of T arrays
        Pressure per spring at each frame (MPa); ``None`` for a frame without an answer
        (bridged, see :class:`ExposureAccumulator`).
    sites : sequence of T integer arrays, optional
        The site of each spring at each frame (default: spring ``i`` is site ``i``).
    threshold : float
        MPa.
    n_sites : int, optional
        Number of sites (default: the largest site index + 1).
    """
    times = np.asarray(times, dtype=float)
    pressures = list(pressures)
    if len(pressures) != len(times):
        raise InputError(f"pressures must be {len(times)} arrays (one per time), got {len(pressures)}")
    if sites is not None:
        sites = [np.asarray(s) for s in sites]
    if n_sites is None:
        if sites is not None:
            n_sites = int(max((s.max(initial=-1) for s in sites), default=-1)) + 1
        else:
            n_sites = max((len(p) for p in pressures if p is not None), default=0)
    accumulator = ExposureAccumulator(n_sites, threshold)
    for k, (t, p) in enumerate(zip(times, pressures)):
        if p is None:
            accumulator.skip(t)
        elif sites is None and len(p) != n_sites:
            # Springs beyond a short frame's length carry nothing at that frame.
            full = np.zeros(n_sites)
            full[: len(p)] = p
            accumulator.add(t, full)
        else:
            accumulator.add(t, p, None if sites is None else sites[k])
    return accumulator.result()


def _above(p0, p1, dt, threshold):
    """Time above ``threshold`` and the integral of the excess over one segment, exact for linear p(t)."""
    e0, e1 = p0 - threshold, p1 - threshold
    both = (e0 > 0) & (e1 > 0)
    one = (e0 > 0) ^ (e1 > 0)
    high = np.maximum(e0, e1)
    with np.errstate(invalid="ignore", divide="ignore"):
        fraction = np.where(one, high / np.abs(p1 - p0), 0.0)
    time_above = np.where(both, dt, np.where(one, fraction * dt, 0.0))
    excess = np.where(both, 0.5 * (e0 + e1) * dt, np.where(one, 0.5 * high * fraction * dt, 0.0))
    return time_above, excess
