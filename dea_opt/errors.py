"""One exception tree for every failure dea-opt reports.

``DeaError`` is the base; catch it to catch everything dea-opt raises on purpose.
The guide's error catalogue (``docs/guide/errors.md``) lists every subclass, when it is raised and what to do;
``tests/test_docs.py`` checks that the catalogue and this module agree.
"""

from __future__ import annotations


class DeaError(Exception):
    """Base of every error dea-opt raises on purpose."""


class InputError(DeaError, ValueError):
    """An argument has the wrong type, shape or value.

    The message names the argument, what was expected and what came.
    """


class ScenarioError(InputError):
    """A scenario file (or a value set on the command line) is invalid.

    The message names the file, the key path (``law.H``) and, where known, the TOML line.
    """


class ImplausibleInputError(ScenarioError):
    """A scenario's input is implausible for a joint, and was stopped before anything was solved.

    Raised by the checks a run makes before solving (:mod:`dea_opt.run.preflight`): meshes whose
    size says metres or micrometres, a body free to turn about a reference point left at the
    origin far from the contact, a load that lies along the contact's surface or whose moments
    are far beyond what the contact's size allows. The message names the cause first and the
    scenario key to change; ``[solve] check_inputs = false`` solves such a scenario anyway.
    ``key`` is that key (``"geometry.scale"``).
    """

    def __init__(self, message: str, key: str = ""):
        super().__init__(message)
        self.key = key


class OpenSimModelError(InputError):
    """An OpenSim model file (``.osim``) cannot be read, or uses what dea-opt cannot evaluate.

    Raised for a file that is missing, not XML, malformed (the message gives its line), holds a
    document type declaration or entities (refused: a model from elsewhere is untrusted input), or
    whose components are incomplete or inconsistent (a socket naming no frame, an axis of zero
    length, collinear rotation axes, a joint type or function dea-opt does not evaluate asked for).
    The message names the file, the component (its path in the model) and, where known, the line.
    """


class OutputFolderError(InputError):
    """A run may not write into the output folder it was given.

    The folder holds files dea-opt did not write and no manifest of an earlier dea-opt run
    (``--force`` writes there anyway), is a file, or another run is writing into it. The
    message names the folder.
    """


class LoadNotSupportedError(DeaError):
    """Compression-only springs cannot carry the load.

    Raised when the load pulls the bodies apart, or loads a direction (a translation or a
    rotation) that no spring resists. ``direction`` is the unbalanced part of the
    generalized load over the free degrees of freedom, as a dict ``{dof name: value}``.
    """

    def __init__(self, message: str, direction: dict | None = None):
        super().__init__(message)
        self.direction = direction or {}


class SolverError(DeaError):
    """A solver did not return an answer dea-opt can certify.

    ``status`` is a :class:`~dea_opt.status.Status` (a ``str``), ``native_status`` the
    solver's own where it had one; ``solution`` (when there is one) is the uncertified
    :class:`~dea_opt.solution.Solution`, for inspection only.
    """

    def __init__(self, message: str, status: str = "", solution=None, native_status: str | None = None):
        super().__init__(message)
        self.status = status
        self.solution = solution
        self.native_status = native_status


class MissingDependencyError(DeaError, ImportError):
    """An optional extra is needed for this feature and is not installed.

    The message names the ``pip install`` command that adds it.
    """


class ValidityWarning(UserWarning):
    """A certified result lies outside the model it solved.

    Issued by :func:`dea_opt.solve` when ``solution.validity`` (:mod:`dea_opt.validity`)
    has a failed check: compressive strain beyond the law's range (30 % for the linear law,
    the limit of validity stated by Volokh, Chao & Armand) or near crushing (80 % for every
    law), rotations beyond the small-rotation kinematics (3 deg, or a gap error above 1 % of
    the thickness), a layer whose size looks like metres or micrometres, or a peak pressure
    above what cartilage survives (35 MPa). One warning names every failed check with its
    value, limit and advice.
    """


class SizeLimitError(InputError):
    """A request would need more memory than the machine has free, so nothing was allocated.

    Raised before the allocation (a load path of 1e9 frames, a table of every spring at every
    frame), with the estimate: ``needed`` and ``available`` are in bytes, ``what`` names the
    argument or scenario key that asked for it.
    """

    def __init__(self, message: str, needed: float = 0.0, available: float = 0.0, what: str = ""):
        super().__init__(message)
        self.needed = needed
        self.available = available
        self.what = what
