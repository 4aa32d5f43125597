"""Several bones, several contacts, ligaments: the whole joint as one energy, solved and certified.

A :class:`Joint` names its rigid bodies (:class:`~dea_opt.Body`: reference, free, fixed and
prescribed dofs, loads), the contact layers between them (:class:`Contact`: a
:class:`~dea_opt.SpringLayer` and its law between two named bodies) and the ligament bundles
(:class:`Ligament`: a straight line between two insertions, tension only, Blankevoort 1991 or
linear). :func:`dea_opt.solve` finds its equilibrium (:func:`solve_joint`) and returns a
:class:`JointSolution`. The math is in ``formulations/joint.md``; the array-level energy and its
solvers in :mod:`dea_opt.formulations.joint`.

Also :class:`Spring` and :class:`Bushing` (linear, two-sided, between points and between body
frames), :class:`BodyLoad` (a force and a moment at a point of a body, in the ground or the body's
frame) and :class:`Coordinates` (finite kinematics: a body's six coordinates as an OpenSim
``CustomJoint``'s, so that a motion file prescribes some and leaves the others free).

Modules: ``elements`` (Contact, Ligament), ``elastic`` (Spring, Bushing), ``coordinates``
(Coordinates, BodyLoad), ``rows`` (the elements' rows), ``model`` (Joint: checks and arrays),
``solve`` (the methods, the load checks), ``certificate`` (per body and element), ``results``
(the answer), ``validity`` (per layer, bundle and body), ``configuration`` and ``finite``
(exact motions).
"""

from .certificate import JointCertificate, certify_joint
from .coordinates import BodyLoad, Coordinates
from .elastic import Bushing, Spring
from .elements import Contact, Ligament
from .model import Joint
from .results import BodyResult, JointSolution, LigamentResults
from .solve import JOINT_METHODS, solve_joint
from .validity import JointValidity, LigamentLimits

__all__ = [
    "JOINT_METHODS",
    "BodyLoad",
    "BodyResult",
    "Bushing",
    "Contact",
    "Coordinates",
    "Joint",
    "JointCertificate",
    "JointSolution",
    "JointValidity",
    "Ligament",
    "LigamentLimits",
    "LigamentResults",
    "Spring",
    "certify_joint",
    "solve_joint",
]
