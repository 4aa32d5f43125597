"""dea-opt: discrete element analysis of cartilage contact, solved three ways and certified."""

from ._version import __version__
from .calibrate import calibrate
from .errors import (
    DeaError,
    InputError,
    LoadNotSupportedError,
    MissingDependencyError,
    OutputFolderError,
    ScenarioError,
    SizeLimitError,
    SolverError,
    ValidityWarning,
)
from .kinematics import DOFS
from .laws import LAWS, AteshianLaw, BlankevoortLaw, CubicLaw, Law, LinearLaw, PolynomialLaw, register_law
from .layer import SpringLayer
from .loadpath import solve_path
from .problem import Body, ContactProblem, Load
from .sensitivity import Sensitivities, sensitivities
from .solution import Certificate, Solution, certify
from .solver import METHODS, check_load_supported, compare, solve
from .status import Status
from .uncertainty import propagate

__all__ = [
    "LAWS", "AteshianLaw", "BlankevoortLaw", "Body", "Certificate", "ContactProblem", "CubicLaw",
    "DOFS", "DeaError", "InputError", "Law", "LinearLaw", "Load", "LoadNotSupportedError",
    "METHODS", "MissingDependencyError", "OutputFolderError", "ScenarioError", "PolynomialLaw", "Sensitivities",
    "SizeLimitError", "Solution", "SolverError", "SpringLayer", "Status", "ValidityWarning", "calibrate", "certify",
    "check_load_supported", "compare", "propagate", "register_law", "sensitivities", "solve", "solve_path",
    "__version__",
]
