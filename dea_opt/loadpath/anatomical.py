"""A load path's centre of pressure and found motion along the joint's anatomical axes.

The per-frame table (:mod:`~dea_opt.loadpath.table`) gives the centre of pressure
(``cop_x_mm, cop_y_mm, cop_z_mm``) and the motion of every free dof (``body2_uz_mm``,
``body2_ry_rad``, ...) in the meshes' frame. :func:`anatomical_frame_table` gives the same per frame along the
medial, anterior and proximal axes of an :class:`~dea_opt.anatomy.AnatomicalFrame`: where
the contact is, and how each body moved along and about those axes. Each column's name ends
with its unit (:mod:`dea_opt.units`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..anatomy.frame import AXES, AnatomicalFrame
from .table import motion_columns

if TYPE_CHECKING:
    import pandas as pd

    from ..problem import ContactProblem

__all__ = [
    "ANATOMICAL_UNITS",
    "AXIS_NAMES",
    "COP_COLUMNS",
    "anatomical_columns",
    "anatomical_frame_table",
    "anatomical_origin",
]

#: The anatomical axes, in the order of every group of columns.
AXIS_NAMES = tuple(AXES)
#: The centre of pressure along each axis, from the frame's origin (mm).
COP_COLUMNS = tuple(f"cop_{axis}_mm" for axis in AXIS_NAMES)
#: Units of the anatomical columns by the kind in their name: ``cop_<axis>_mm`` (from the
#: frame's origin), ``body<b>_translation_<axis>_mm`` (along the axis) and
#: ``body<b>_rotation_<axis>_rad`` (the rotation vector's component about the axis).
ANATOMICAL_UNITS = {"cop": "mm", "translation": "mm", "rotation": "rad"}
#: The dofs each kind of motion gathers into a vector, in the order of ``Solution.u``.
_MOTION_DOFS = {"translation": ("ux", "uy", "uz"), "rotation": ("rx", "ry", "rz")}


def anatomical_origin(problem: ContactProblem, anatomy) -> tuple[AnatomicalFrame, np.ndarray]:
    """The anatomical frame and the origin its coordinates are measured from.

    Parameters
    ----------
    problem : ContactProblem
        The problem the path started from.
    anatomy : AnatomicalFrame or dict
        Anything :meth:`AnatomicalFrame.from_dict` takes.

    Returns
    -------
    frame : AnatomicalFrame
    origin : ndarray, shape (3,)
        mm: the frame's own origin, or the area-weighted centroid of the problem's springs
        (as a single solve's ``center_of_pressure_anatomical`` uses).
    """
    frame = AnatomicalFrame.from_dict(anatomy)
    return frame, frame.layer_origin(problem.layer)


def _free_motion(problem: ContactProblem) -> dict:
    """``{(body, kind): {component index: motion column}}`` for every body and kind of motion
    (translation, rotation) with at least one free dof, in the order of the motion columns."""
    found: dict = {}
    for column in motion_columns(problem):
        body, dof, _ = column.split("_")  # "body2", "uz", "mm"
        kind = next(k for k, dofs in _MOTION_DOFS.items() if dof in dofs)
        found.setdefault((body, kind), {})[_MOTION_DOFS[kind].index(dof)] = column
    return found


def anatomical_columns(problem: ContactProblem) -> dict:
    """``{column: unit}``: the anatomical columns a path of ``problem`` gets, in order.

    ``cop_medial_mm, cop_anterior_mm, cop_proximal_mm``, then for each body with a free
    translation ``body<b>_translation_<axis>_mm`` and with a free rotation
    ``body<b>_rotation_<axis>_rad``, ``<axis>`` each of medial, anterior, proximal.
    """
    columns = dict.fromkeys(COP_COLUMNS, ANATOMICAL_UNITS["cop"])
    for body, kind in _free_motion(problem):
        columns.update({_column(body, kind, axis): ANATOMICAL_UNITS[kind] for axis in AXIS_NAMES})
    return columns


def _column(body: str, kind: str, axis: str) -> str:
    from ..units import with_unit

    return with_unit(f"{body}_{kind}_{axis}", ANATOMICAL_UNITS[kind])


def anatomical_frame_table(table: pd.DataFrame, problem: ContactProblem, anatomy) -> pd.DataFrame:
    """The centre of pressure and the motion found, per frame, along the anatomical axes.

    The motion is the free dofs' part only: each body's free translation (its reference
    point's, mm) and free rotation (rad) as the frames found them (``Solution.u``), held
    components taken as zero, so a prescribed motion or a frame's pose is not included (with
    finite kinematics and poses the motion is on top of the frame's pose). A rotation's
    columns are the components of its rotation vector along the axes (the linearised
    rotation of small kinematics, the exact rotation's vector of finite kinematics): not a
    Grood-Suntay decomposition into joint angles, and no clinical name (flexion, varus) is
    claimed for them. A frame without a certified answer (NaN in the table) stays NaN.

    Parameters
    ----------
    table : pandas.DataFrame, T rows
        A path's per-frame table (:attr:`PathResult.table`): ``cop_x_mm, cop_y_mm, cop_z_mm``
        and the motion columns of ``problem`` (:func:`~dea_opt.loadpath.table.motion_columns`;
        mm, rad).
    problem : ContactProblem
        The problem the path started from: its free dofs name the motion columns and its
        springs place the origin when the frame names none (:func:`anatomical_origin`).
    anatomy : AnatomicalFrame or dict
        The anatomical frame (:meth:`AnatomicalFrame.from_dict` takes it).

    Returns
    -------
    pandas.DataFrame, T rows
        The columns of :func:`anatomical_columns`, on ``table``'s index: ``cop_medial_mm,
        cop_anterior_mm, cop_proximal_mm`` (from the origin), ``body<b>_translation_<axis>_mm``
        and ``body<b>_rotation_<axis>_rad``.
    """
    import pandas as pd

    frame, origin = anatomical_origin(problem, anatomy)
    axes = np.array([frame.medial, frame.anterior, frame.proximal])  # (3, 3), one axis per row
    cop = table[["cop_x_mm", "cop_y_mm", "cop_z_mm"]].to_numpy(dtype=float)
    columns = dict(zip(COP_COLUMNS, frame.coordinates(cop, origin).T))
    for (body, kind), components in _free_motion(problem).items():
        vectors = np.zeros((len(table), 3))
        for index, column in components.items():
            vectors[:, index] = table[column].to_numpy(dtype=float)
        # A failed frame's NaN reaches every axis: NaN times a zero weight stays NaN.
        along = vectors @ axes.T
        columns.update({_column(body, kind, axis): along[:, i] for i, axis in enumerate(AXIS_NAMES)})
    return pd.DataFrame(columns, index=table.index)
