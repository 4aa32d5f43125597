"""OpenSim models and files, read without OpenSim: ``.osim`` models, ``.sto``/``.mot`` tables.

- :func:`read_model` (:mod:`~dea_opt.opensim.reader`): a model file read safely into plain,
  immutable objects in mm, N, MPa (:mod:`~dea_opt.opensim.model`,
  :class:`~dea_opt.opensim.osimmodel.OsimModel`): bodies and frames, joints and coordinates,
  ``Smith2018ContactMesh`` surfaces and ``Smith2018ArticularContactForce`` pairs,
  ``Blankevoort1991Ligament`` bundles, and ``not_modelled``: every part dea-opt does not model,
  by name.
- :mod:`~dea_opt.opensim.kinematics`: the pose of every body for given coordinate values,
  walking the joint tree as OpenSim (Simbody) does; :mod:`~dea_opt.opensim.ligaments`: the
  bundles' lengths, strains and forces (OpenSim's Blankevoort law).
- :mod:`~dea_opt.opensim.motion`: a motion as per-frame poses of chosen bodies, from a table of
  relative 4x4 poses or from a ``.sto``/``.mot`` of the model's coordinates.
- :mod:`~dea_opt.opensim.storage`: OpenSim Storage files (``.sto``, ``.mot``), also the load
  paths of scenarios.
- :mod:`~dea_opt.opensim.export`: the model as a scenario (``dea-opt import-osim``).

Conventions (frames, units, the CustomJoint transform, what is not modelled):
``formulations/opensim.md``.
"""

from .model import ContactMesh, ContactPair, Coordinate, Frame, Joint, Ligament, NotModelled, PathPoint, WrapObject
from .osimmodel import LigamentState, OsimModel
from .reader import read_model

__all__ = [
    "ContactMesh",
    "ContactPair",
    "Coordinate",
    "Frame",
    "Joint",
    "Ligament",
    "LigamentState",
    "NotModelled",
    "OsimModel",
    "PathPoint",
    "WrapObject",
    "read_model",
]
