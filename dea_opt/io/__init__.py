"""The file formats: ParaView files, CSV tables, JSON summaries and pictures a user can look at.

Every file goes through :func:`dea_opt.files.write_atomic` (a temporary file in the target's
directory, ``fsync``, then :func:`os.replace`), so an interrupted run leaves either the old file
or the new one, never half of one. How a run's files are staged and published together, and the
picture worker, are :mod:`dea_opt.run`'s; this package only knows formats.

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

The modules: :mod:`~dea_opt.io.surface`
(the contact surface as a mesh with cell data), :mod:`~dea_opt.io.vtk` (VTK files),
:mod:`~dea_opt.io.tables` (CSV: results, springs and numeric tables),
:mod:`~dea_opt.io.summary` (JSON), :mod:`~dea_opt.io.plots` (pressure maps),
:mod:`~dea_opt.io.cycle` (cycle and exposure plots), :mod:`~dea_opt.io.mapframe` (the frame a
map is drawn in: anatomical or best-fit), :mod:`~dea_opt.io.draw` (vector or raster drawing),
:mod:`~dea_opt.io.triangulate` (a surface through the springs of a layer without a mesh),
:mod:`~dea_opt.io.vtkxml` (the streamed VTK XML writer), :mod:`~dea_opt.io.results`
(everything at once).

Units: mm, mm^2, N, N mm, MPa; strain is dimensionless. Every column and JSON key of the files
names its unit (``pressure_MPa``; :mod:`dea_opt.units`), and every picture of a result outside
validity is stamped so (:mod:`~dea_opt.io.marks`).
"""

from .cycle import plot_cycle, plot_exposure
from .mapframe import MapFrame, best_fit_frame, map_frame
from .plots import plot_pressure
from .results import write_results
from .summary import read_json, summary_dict, to_json
from .surface import SurfaceData, contact_surface, label_codes, layer_surface
from .tables import CSV_COLUMNS, read_csv, to_csv
from .triangulate import point_triangulation
from .vtk import read_vtk, to_vtk, vtk_differences, write_surface

__all__ = [
    "CSV_COLUMNS",
    "MapFrame",
    "SurfaceData",
    "best_fit_frame",
    "contact_surface",
    "label_codes",
    "layer_surface",
    "map_frame",
    "plot_cycle",
    "plot_exposure",
    "plot_pressure",
    "point_triangulation",
    "read_csv",
    "read_json",
    "read_vtk",
    "summary_dict",
    "to_csv",
    "to_json",
    "to_vtk",
    "vtk_differences",
    "write_results",
    "write_surface",
]
