"""The model :func:`~dea_opt.opensim.read_model` returns, and what it computes at a pose."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType

import numpy as np

from ..errors import OpenSimModelError
from . import kinematics, ligaments

__all__ = ["LigamentState", "OsimModel"]


@dataclass(frozen=True)
class LigamentState:
    """Every bundle of a model at one pose (arrays in the order of ``names``).

    ``length`` (mm) is dea-opt's straight line between the first and last path point;
    ``path_length`` (mm) the polyline through every fixed path point (OpenSim's length without
    wrap objects); ``strain`` and ``force`` (N) are OpenSim's Blankevoort law of ``length``, and
    ``path_strain``/``path_force`` of ``path_length``.
    """

    names: tuple
    length: np.ndarray
    path_length: np.ndarray
    strain: np.ndarray
    force: np.ndarray
    path_strain: np.ndarray
    path_force: np.ndarray


@dataclass(frozen=True)
class OsimModel:
    """An OpenSim model, read without OpenSim (:func:`~dea_opt.opensim.read_model`).

    Attributes
    ----------
    path : Path
        The model file.
    name : str
    bodies : tuple of str
        The bodies, in the model's order ("ground" is the ground frame, not listed).
    frames : mapping path -> :class:`~dea_opt.opensim.model.Frame`
        Ground, the bodies and every ``PhysicalOffsetFrame``.
    joints, coordinates : mappings name -> Joint, Coordinate
    contact_meshes, contact_pairs : mappings name -> ContactMesh, ContactPair
    ligaments : mapping name -> Ligament
    wrap_objects : mapping name -> WrapObject
    not_modelled : tuple of :class:`~dea_opt.opensim.model.NotModelled`
        Everything of the model dea-opt does not model, by name, never dropped silently.
    """

    path: Path
    name: str
    bodies: tuple
    frames: Mapping
    joints: Mapping
    coordinates: Mapping
    contact_meshes: Mapping
    contact_pairs: Mapping
    ligaments: Mapping
    wrap_objects: Mapping
    not_modelled: tuple

    # --- coordinates and poses ------------------------------------------------------------------

    def default_coordinates(self) -> dict:
        """``{name: default value}`` of every coordinate (OpenSim's units: rad, m)."""
        return {name: c.default_value for name, c in self.coordinates.items()}

    def values(self, coordinates: Mapping | None = None) -> dict:
        """Every coordinate's value: the defaults, with ``coordinates`` (name -> value) set."""
        values = self.default_coordinates()
        for name, value in (coordinates or {}).items():
            if name not in values:
                raise OpenSimModelError(f"{self.path}: has no coordinate {name!r}")
            value = float(value)
            if not np.isfinite(value):
                raise OpenSimModelError(f"{self.path}: coordinate {name} must be a finite number, got {value}")
            values[name] = value
        return values

    def poses(self, coordinates: Mapping | None = None, bodies=None) -> dict:
        """``{body: X_G_body}`` (4, 4, mm) with the default coordinates, ``coordinates`` set.

        ``bodies`` limits the result (and the walk) to those bodies; None: every body a joint
        dea-opt evaluates connects to ground, and "ground".
        """
        return kinematics.pose_bodies(self, self.values(coordinates), bodies)

    def frame_in_body(self, path: str) -> np.ndarray:
        """``X_body_frame`` (4, 4, mm): the frame ``path`` in the body (or ground) it is fixed to."""
        T = np.eye(4)
        frame = self._frame(path)
        while frame.kind == "offset":
            T = frame.transform @ T
            frame = self._frame(frame.parent)
        return T

    def frame_pose(self, path: str, coordinates: Mapping | None = None, poses: dict | None = None) -> np.ndarray:
        """``X_G_frame`` (4, 4, mm) of the frame ``path`` (given ``poses`` from :meth:`poses`, or
        at ``coordinates``)."""
        body = self._frame(path).body
        if poses is None:
            poses = self.poses(coordinates, bodies=[body])
        return poses[body] @ self.frame_in_body(path)

    def _frame(self, path: str):
        try:
            return self.frames[path]
        except KeyError:
            raise OpenSimModelError(f"{self.path}: has no frame {path!r}") from None

    # --- ligaments ----------------------------------------------------------------------------

    def ligament_state(self, coordinates: Mapping | None = None, poses: dict | None = None) -> LigamentState:
        """Every bundle's lengths, strains and forces at ``coordinates`` (or ``poses``)."""
        names = tuple(self.ligaments)
        if poses is None:
            needed = sorted({p.body for lig in self.ligaments.values() for p in lig.points} - {"ground"})
            poses = {"ground": np.eye(4), **self.poses(coordinates, bodies=needed)}
        straight = ligaments.lengths(self, poses)
        path = ligaments.path_lengths(self, poses)
        L = np.array([straight[n] for n in names])
        P = np.array([path[n] for n in names])
        L0 = np.array([self.ligaments[n].slack_length for n in names])
        k = np.array([self.ligaments[n].stiffness for n in names])
        et = np.array([self.ligaments[n].transition_strain for n in names])
        strain, path_strain = L / L0 - 1.0, P / L0 - 1.0
        return LigamentState(
            names,
            L,
            P,
            strain,
            ligaments.blankevoort_force(strain, k, et),
            path_strain,
            ligaments.blankevoort_force(path_strain, k, et),
        )

    def report(self) -> str:
        """The ``not_modelled`` list, one line each, grouped by kind."""
        lines = [f"{len(self.not_modelled)} things of {self.path.name} that dea-opt does not model:"]
        lines += [f"  {item.describe()}" for item in self.not_modelled]
        return "\n".join(lines)

    def summary(self) -> MappingProxyType:
        """Counts of what was read: bodies, joints, coordinates, contact meshes and pairs,
        ligaments, not-modelled items by kind."""
        kinds: dict = {}
        for item in self.not_modelled:
            kinds[item.kind] = kinds.get(item.kind, 0) + 1
        return MappingProxyType(
            {
                "bodies": len(self.bodies),
                "joints": len(self.joints),
                "coordinates": len(self.coordinates),
                "contact_meshes": len(self.contact_meshes),
                "contact_pairs": len(self.contact_pairs),
                "ligaments": len(self.ligaments),
                "not_modelled": MappingProxyType(kinds),
            }
        )


def model_dir(model: OsimModel) -> Path:
    """The folder of the model file (where OpenSim looks for its meshes first)."""
    return Path(model.path).resolve().parent
