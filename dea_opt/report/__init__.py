"""One HTML page per run and per sweep: ``report.html``, self-contained and offline.

A run's report (:mod:`~dea_opt.report.run`, written by ``dea-opt run`` and ``dea-opt demo`` when
``[output] formats`` holds ``html``, the default) puts the whole answer on one page: the verdict
first, the validity checks, each compartment's share, an interactive 3-D pressure map
(:mod:`~dea_opt.report.view3d`, drawn by Plotly), the cycle plots, the certificate, the inputs
with their SHA-256, the timings and the software. A sweep's report (:mod:`~dea_opt.report.sweep`)
has a sortable table of the cases and a plot of any output against any swept value. Both open
from ``file://`` with nothing loaded from the network (:mod:`~dea_opt.report.page`).
"""

from .run import REPORT_NAME, run_report, write_run_report
from .sweep import sweep_report, write_sweep_report

__all__ = ["REPORT_NAME", "run_report", "sweep_report", "write_run_report", "write_sweep_report"]
