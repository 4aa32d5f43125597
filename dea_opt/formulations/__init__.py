"""The formulations of the DEA problem, by name.

Each module takes a :class:`~dea_opt.formulations.energy.SpringSystem` (arrays) and a law and
returns a :class:`~dea_opt.formulations.energy.FormulationResult`; each names its written
math in ``PAGE`` (``formulations/<name>.md`` at the repository's top).
"""

from __future__ import annotations

from importlib import import_module

from .energy import FormulationResult, SpringSystem

#: name -> module path; modules are imported on first use (cvxpy and CasADi are heavy).
FORMULATIONS = {
    "newton": "dea_opt.formulations.newton",
    "qp": "dea_opt.formulations.qp",
    "nlp": "dea_opt.formulations.nlp",
}


def get(name: str):
    """The module of formulation ``name`` (a key of :data:`FORMULATIONS`)."""
    return import_module(FORMULATIONS[name])


__all__ = ["FORMULATIONS", "FormulationResult", "SpringSystem", "get"]
