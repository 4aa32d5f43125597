"""dea-opt: discrete element analysis of cartilage contact, solved three ways and certified."""

from ._version import __version__
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
from .loadpath import PathOutputs, solve_path
from .problem import Body, ContactProblem, Load
from .sensitivity import Sensitivities, sensitivities
from .sensitivity.calibrate import calibrate
from .sensitivity.uncertainty import propagate
from .solution import Solution
from .solver import Comparison, check_load_supported, compare, solve
from .status import Status

__all__ = [
    "DOFS",
    "LAWS",
    "AteshianLaw",
    "BlankevoortLaw",
    "Body",
    "Certificate",
    "Comparison",
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
    "PathOutputs",
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
