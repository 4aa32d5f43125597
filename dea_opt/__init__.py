"""dea-opt: discrete element analysis of cartilage contact, solved three ways and certified."""

import sys as _sys
from importlib import import_module as _import_module

from ._version import __version__

#: Former module paths, kept importable: ``from dea_opt.calibrate import calibrate`` loads
#: :mod:`dea_opt.sensitivity.calibrate`. Modules that became part of a subpackage are listed
#: here, old name -> new; ``tests/core/test_structure.py`` imports every one and reads this table to
#: draw the import graph.
FORMER_MODULES = {
    "dea_opt._validate": "dea_opt._checks.inputs",
    "dea_opt._tolerances": "dea_opt._checks.thresholds",
    "dea_opt._memory": "dea_opt._checks.memory",
    "dea_opt._optional": "dea_opt._checks.dependencies",
    "dea_opt.law_registry": "dea_opt.laws.registry",
    "dea_opt.regions": "dea_opt.anatomy.regions",
    "dea_opt.onesided": "dea_opt.sensitivity.onesided",
    "dea_opt.parametric": "dea_opt.sensitivity.parametric",
    "dea_opt.calibrate": "dea_opt.sensitivity.calibrate",
    "dea_opt.measurements": "dea_opt.sensitivity.measurements",
    "dea_opt.uncertainty": "dea_opt.sensitivity.uncertainty",
    "dea_opt.runlog": "dea_opt.run.log",
    "dea_opt.demo": "dea_opt.run.demo",
    "dea_opt.path": "dea_opt.loadpath",
}


def _keep_former_modules(private: bool) -> None:
    """Make each former module path (the private ones, or the public ones) name its module."""
    for old, new in FORMER_MODULES.items():
        name = old.rpartition(".")[2]
        if name.startswith("_") == private:
            module = _import_module(new)
            _sys.modules.setdefault(old, module)
            # ``import dea_opt.regions`` then ``dea_opt.regions.x``: the attribute, unless the
            # package already has one by that name (``dea_opt.calibrate`` is the function)
            globals().setdefault(name, module)


# The private ones first: modules of branches written before the move import them while
# this package initialises.
_keep_former_modules(private=True)
from .certificate import Certificate, certify
from .errors import (
    DeaError,
    ImplausibleInputError,
    InputError,
    LoadNotSupportedError,
    MissingDependencyError,
    OpenSimModelError,
    OutputFolderError,
    ScenarioError,
    SizeLimitError,
    SolverError,
    ValidityWarning,
)
from .joint import Contact, Joint, JointSolution, Ligament
from .kinematics import DOFS
from .laws import LAWS, AteshianLaw, BlankevoortLaw, CubicLaw, Law, LinearLaw, PolynomialLaw, register_law
from .layer import SpringLayer
from .loadpath import solve_path
from .problem import Body, ContactProblem, Load
from .sensitivity import Sensitivities, sensitivities
from .sensitivity.calibrate import calibrate
from .sensitivity.uncertainty import propagate
from .solution import Solution
from .solver import METHODS, check_load_supported, compare, solve
from .status import Status

__all__ = [
    "DOFS",
    "LAWS",
    "METHODS",
    "AteshianLaw",
    "BlankevoortLaw",
    "Body",
    "Certificate",
    "Contact",
    "ContactProblem",
    "CubicLaw",
    "DeaError",
    "ImplausibleInputError",
    "InputError",
    "Joint",
    "JointSolution",
    "Law",
    "Ligament",
    "LinearLaw",
    "Load",
    "LoadNotSupportedError",
    "MissingDependencyError",
    "OpenSimModelError",
    "OutputFolderError",
    "PolynomialLaw",
    "ScenarioError",
    "Sensitivities",
    "SizeLimitError",
    "Solution",
    "SolverError",
    "SpringLayer",
    "Status",
    "ValidityWarning",
    "__version__",
    "calibrate",
    "certify",
    "check_load_supported",
    "compare",
    "propagate",
    "register_law",
    "sensitivities",
    "solve",
    "solve_path",
]

_keep_former_modules(private=False)
