"""Derivatives of a certified answer, and what they serve: calibration and uncertainty.

Written math: ``formulations/sensitivity.md``. The modules:
:mod:`~dea_opt.sensitivity.derivatives` (:func:`sensitivities`: exact derivatives of an
equilibrium with respect to the law's parameters, thicknesses, gaps, loads and prescribed
dofs), :mod:`~dea_opt.sensitivity.onesided` (the one-sided derivatives at springs on the edge
of contact), :mod:`~dea_opt.sensitivity.parametric` (CasADi's parametric sensitivities of the
IPOPT solution, the cross-check), :mod:`~dea_opt.sensitivity.measurements` (measured data: a
pressure map, a force-displacement curve, contact data), :mod:`~dea_opt.sensitivity.calibrate`
(:func:`calibrate`: fitting parameters to them; :mod:`~dea_opt.sensitivity.scenario_fit`, the
same from a scenario), :mod:`~dea_opt.sensitivity.covariance` (the
fitted parameters' standard errors, :func:`spatial_correlation`) and :mod:`~dea_opt.sensitivity.uncertainty`
(:func:`propagate`, :func:`monte_carlo`: parameter uncertainty carried to the answer).
"""

from .calibrate import Calibration, apply_parameters, calibrate
from .covariance import spatial_correlation
from .derivatives import (
    LOADS,
    OUTPUTS,
    PAGE,
    PER_SPRING,
    Sensitivities,
    parameter_unit,
    path_sensitivities,
    sensitivities,
)
from .measurements import FILMS, ContactData, Film, ForceDisplacement, PressureMap
from .parametric import nlp_sensitivities
from .uncertainty import SCALARS, MonteCarlo, Propagation, monte_carlo, propagate

__all__ = [
    "FILMS",
    "LOADS",
    "OUTPUTS",
    "PAGE",
    "PER_SPRING",
    "SCALARS",
    "Calibration",
    "ContactData",
    "Film",
    "ForceDisplacement",
    "MonteCarlo",
    "PressureMap",
    "Propagation",
    "Sensitivities",
    "apply_parameters",
    "calibrate",
    "monte_carlo",
    "nlp_sensitivities",
    "parameter_unit",
    "path_sensitivities",
    "propagate",
    "sensitivities",
    "spatial_correlation",
]
