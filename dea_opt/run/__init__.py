"""Running scenarios: one static solve or a load path, with every output published together.

The modules: :mod:`~dea_opt.run.runner` (:func:`run_scenario`: method, options, the solve and
the publication), :mod:`~dea_opt.run.static` (one load), :mod:`~dea_opt.run.path` (a load
path), :mod:`~dea_opt.run.outcome` (:class:`RunOutcome`, statuses and exit codes),
:mod:`~dea_opt.run.log` (what a run tells its user, and its log file) and
:mod:`~dea_opt.run.demo` (``dea-opt demo``).

The command line (:mod:`dea_opt.cli`) and the sweep workers (:mod:`dea_opt.sweep`) call
:func:`run_scenario`; ``dea-opt demo`` calls :func:`dea_opt.run.demo.run_demo`.

Outputs of a static load (in the output folder): ``contact.vtu`` (the contact surface with
pressure, strain, gap, thickness, ...), ``contact.csv`` (one row per spring),
``contact.json`` (summary, regions, certificate, validity) and ``contact.png`` (pressure map).
Outputs of a load path: ``frames.csv`` (one row per frame), ``series.pvd`` with
``series_frames/frame_NNNN.vtu`` (ParaView time series, each frame written as it is solved:
nothing is kept per frame), ``exposure.vtu`` (exposure fields), ``cycle.png`` (force, moment,
pressure and contact area over time), ``exposure.png`` (exposure maps), ``peak.png`` (the peak
frame's map) and ``map_frame_NNNN.png`` (``[output] maps``), and ``summary.json``. Either writes
``report.html`` (:mod:`dea_opt.report`), the run on one page. Every column and JSON key names
its unit (:mod:`dea_opt.units`).
``[output] anatomy`` draws the maps in the joint's anatomical frame. When the springs were cast
from meshes they are re-cast at the solved pose (a load path: its peak frame), which evaluates
the ``dropped_springs`` validity check and adds ``recast`` to ``contact.json``/``summary.json``. Every run also writes ``manifest.json`` (last: the
run id, dea-opt version, scenario hash and every file with its size and SHA-256) and, when
a library had something to say, ``dea-opt.log`` (:mod:`dea_opt.run.publish`,
:mod:`dea_opt.run.log`).

Exit status of a run (:attr:`RunOutcome.exit_code`): 0 every answer certified and inside
validity; 1 an answer failed its certificate; 3 certified but outside the model's validity
(0 with ``[solve] allow_outside_validity = true``). Bad input raises a ``DeaError`` (exit 2
at the command line).
"""

from .outcome import EXIT_CODES, RunOutcome, status_of
from .path import peak_recast, run_path_outputs
from .runner import check_method, prepare_run, publish_run, run_info, run_scenario, solve_options
from .static import recast_solution

__all__ = [
    "EXIT_CODES",
    "RunOutcome",
    "check_method",
    "peak_recast",
    "prepare_run",
    "publish_run",
    "recast_solution",
    "run_info",
    "run_path_outputs",
    "run_scenario",
    "solve_options",
    "status_of",
]
