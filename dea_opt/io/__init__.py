"""Results a user can look at: ParaView files, CSV tables, JSON summaries and pictures.

Every file goes through :func:`write_atomic` (a temporary file in the target's directory,
``fsync``, then :func:`os.replace`), so an interrupted run leaves either the old file or
the new one, never half of one. The temporary files are hidden (``.name.<random>.tmp.ext``)
and removed when the writer fails.

=====================  ===========================================================
``to_vtk``             the contact surface with cell data, ``.vtu`` or ``.vtp``
``to_csv``             one row per spring (columns in :data:`CSV_COLUMNS`)
``to_json``            the headline numbers, regions and certificate
``plot_pressure``      a PNG pressure map
``write_results``      all four into one directory
``read_vtk``,          read back what the writers wrote, for round trips
``read_csv``,
``read_json``
=====================  ===========================================================

The modules: :mod:`~dea_opt.io.atomic` (the atomic writer), :mod:`~dea_opt.io.surface`
(the contact surface as a mesh with cell data), :mod:`~dea_opt.io.vtk` (VTK files),
:mod:`~dea_opt.io.tables` (CSV: results, springs and numeric tables),
:mod:`~dea_opt.io.summary` (JSON), :mod:`~dea_opt.io.plots` (pressure maps, cycle and
exposure plots), :mod:`~dea_opt.io.results` (everything at once).

Units: mm, mm^2, N, N mm, MPa; strain is dimensionless.
"""

from .atomic import atomic_open, atomic_path, write_atomic, write_data
from .plots import best_fit_frame, plot_cycle, plot_exposure, plot_pressure
from .results import write_results
from .summary import read_json, summary_dict, to_json
from .surface import SurfaceData, contact_surface, label_codes
from .tables import CSV_COLUMNS, read_csv, to_csv
from .vtk import read_vtk, to_vtk, vtk_differences

__all__ = [
    "CSV_COLUMNS",
    "SurfaceData",
    "atomic_open",
    "atomic_path",
    "best_fit_frame",
    "contact_surface",
    "label_codes",
    "plot_cycle",
    "plot_exposure",
    "plot_pressure",
    "read_csv",
    "read_json",
    "read_vtk",
    "summary_dict",
    "to_csv",
    "to_json",
    "to_vtk",
    "vtk_differences",
    "write_atomic",
    "write_data",
    "write_results",
]
