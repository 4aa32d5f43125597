"""Load paths of a scenario: the frames of ``[load_path]`` (forces, moments and poses over time).

The table is a CSV with columns ``time, Fx, Fy, Fz`` and optionally ``Mx, My, Mz`` and the six
pose columns (``pose_tx, pose_ty, pose_tz`` in mm, ``pose_rx, pose_ry, pose_rz`` in degrees
about the fixed x, y, z axes), an OpenSim Storage file (``.sto``/``.mot``, columns named in
the scenario: :mod:`~dea_opt.opensim.storage`), or the shipped synthetic hip cycle.
Units: s, N, N mm, mm.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import ScenarioError
from ..io.tables import read_numeric_csv
from .schema import LoadPathSection

__all__ = ["LoadPathData", "pose_matrices", "read_load_path"]

_FORCE_COLUMNS = ("Fx", "Fy", "Fz")
_MOMENT_COLUMNS = ("Mx", "My", "Mz")
_POSE_COLUMNS = ("pose_tx", "pose_ty", "pose_tz", "pose_rx", "pose_ry", "pose_rz")


@dataclass(frozen=True, eq=False)
class LoadPathData:
    """The frames of a load path.

    Attributes
    ----------
    times : ndarray (T,)
        s.
    loads : ndarray (T, 6)
        ``Fx, Fy, Fz`` (N), ``Mx, My, Mz`` (N mm), already scaled.
    poses : ndarray (T, 4, 4) or None
        Rigid transforms of body 2's mesh.
    body : int
        The body the loads act on.
    point : tuple or None
        Where the forces act (mm).
    """

    times: np.ndarray
    loads: np.ndarray
    poses: np.ndarray | None = None
    body: int = 2
    point: tuple | None = None

    def __len__(self) -> int:
        return len(self.times)

    def load_objects(self) -> Sequence:
        """One :class:`~dea_opt.problem.Load` per frame, each made when it is read: a path's size
        is checked from its length before any frame's Load exists."""
        return _FrameLoads(self.loads, self.point)


class _FrameLoads(Sequence):
    """The rows of a (T, 6) array as :class:`~dea_opt.problem.Load` objects, made one at a time."""

    def __init__(self, loads: np.ndarray, point):
        self.loads, self.point = loads, point

    def __len__(self) -> int:
        return len(self.loads)

    def __getitem__(self, k):
        from ..problem import Load

        if isinstance(k, slice):
            return [self[i] for i in range(*k.indices(len(self)))]
        row = self.loads[k]
        return Load(force=row[:3], moment=row[3:], point=self.point)


def read_load_path(section: LoadPathSection) -> LoadPathData:
    """Read (or make) the frames of ``[load_path]``, scaled and resampled as asked."""
    if section.builtin == "hip_gait":
        from ..gait import HIP_GAIT_CSV

        source: Path | str | None = HIP_GAIT_CSV
    else:
        source = section.file
    if section.columns is not None:
        from ..opensim.storage import load_path_columns

        table = load_path_columns(section)
    else:
        frame = read_numeric_csv(source, ("time", *_FORCE_COLUMNS), _MOMENT_COLUMNS + _POSE_COLUMNS, "load path")
        table = {c: frame[c].to_numpy(dtype=float) for c in frame.columns}
    name = section.file or "the hip_gait load path"
    times = table["time"]
    if len(times) > 1 and not (np.diff(times) > 0).all():
        i = int(np.argmax(np.diff(times) <= 0)) + 1
        raise ScenarioError(
            f"{name}: column time must increase, but row {i + 1} has time {times[i]:g} after {times[i - 1]:g}"
        )
    loads = np.column_stack([table.get(c, 0.0 * times) for c in _FORCE_COLUMNS + _MOMENT_COLUMNS]) * section.scale
    present = [c for c in _POSE_COLUMNS if c in table]
    if present and len(present) != len(_POSE_COLUMNS):
        missing = [c for c in _POSE_COLUMNS if c not in table]
        raise ScenarioError(f"{name}: pose columns must come all six together; missing {', '.join(missing)}")
    poses = pose_matrices(np.column_stack([table[c] for c in _POSE_COLUMNS])) if present else None
    if section.frames is not None and section.frames != len(times):
        from ..loadpath import check_frames

        # Before any array of that length exists: a path of 1e9 frames is a named error, not the OOM killer.
        check_frames(section.frames, what=f"load_path.frames = {section.frames}")
        times, loads, poses = _resample(times, loads, poses, section.frames)
    point = None if section.point is None else tuple(section.point)
    return LoadPathData(times=times, loads=loads, poses=poses, body=section.body, point=point)


def pose_matrices(columns: np.ndarray) -> np.ndarray:
    """4x4 transforms from rows ``tx, ty, tz`` (mm), ``rx, ry, rz`` (degrees, fixed axes x, y, z)."""
    from scipy.spatial.transform import Rotation

    columns = np.atleast_2d(columns)
    poses = np.tile(np.eye(4), (len(columns), 1, 1))
    poses[:, :3, :3] = Rotation.from_euler("xyz", columns[:, 3:6], degrees=True).as_matrix()
    poses[:, :3, 3] = columns[:, :3]
    return poses


def _resample(times, loads, poses, n):
    new = np.linspace(times[0], times[-1], n)
    loads = np.column_stack([np.interp(new, times, col) for col in loads.T])
    if poses is not None:
        # Nearest frame: interpolating rotation matrices entry by entry would not stay rigid.
        nearest = np.abs(new[:, None] - times[None, :]).argmin(axis=1)
        poses = poses[nearest]
    return new, loads, poses
