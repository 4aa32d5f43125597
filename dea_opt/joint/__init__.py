"""Several bones, several contacts, ligaments: the whole joint as one energy, solved and certified.

A :class:`Joint` names its rigid bodies (:class:`~dea_opt.Body`: reference, free, fixed and
prescribed dofs, loads), the contact layers between them (:class:`Contact`: a
:class:`~dea_opt.SpringLayer` and its law between two named bodies) and the ligament bundles
(:class:`Ligament`: a straight line between two insertions, tension only, Blankevoort 1991 or
linear). :func:`dea_opt.solve` finds its equilibrium (:func:`solve_joint`) and returns a
:class:`JointSolution`. The math is in ``formulations/joint.md``; the array-level energy and its
solvers in :mod:`dea_opt.formulations.joint`.

Modules: ``elements`` (Contact, Ligament), ``model`` (Joint: checks and arrays), ``solve`` (the
methods, the load checks), ``certificate`` (per body and element), ``results`` (the answer),
``validity`` (per layer, bundle and body), ``finite`` (exact motions).
"""

from .certificate import JointCertificate, certify_joint
from .elements import Contact, Ligament
from .model import Joint
from .results import BodyResult, JointSolution, LigamentResults
from .solve import JOINT_METHODS, solve_joint
from .validity import JointValidity, LigamentLimits

__all__ = [
    "JOINT_METHODS",
    "BodyResult",
    "Contact",
    "Joint",
    "JointCertificate",
    "JointSolution",
    "JointValidity",
    "Ligament",
    "LigamentLimits",
    "LigamentResults",
    "certify_joint",
    "solve_joint",
]
