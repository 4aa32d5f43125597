"""Keep library noise off the terminal during a sweep: Dask's logs, tracebacks and Python warnings
go to ``sweep.log`` in the sweep's folder."""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import time
import warnings
from pathlib import Path

__all__ = ["routed_to_log"]

_LOGGERS = ("distributed", "dask", "tornado", "asyncio", "bokeh")


@contextlib.contextmanager
def routed_to_log(path):
    """While the block runs, send noise to ``path`` (appended) instead of the terminal.

    - Python warnings (``warnings.showwarning``) and the loggers of Dask, distributed,
      tornado and asyncio go to the log.
    - File descriptor 2 (stderr) is pointed at the log, so the worker processes a Dask
      LocalCluster starts inherit it: their tracebacks and shutdown messages
      (``CommClosedError`` and the like) land there too. Anything else this process writes
      to stderr meanwhile lands there as well; dea-opt's own report goes to stdout.

    Everything is put back when the block ends, also on an exception or Ctrl-C.

    Yields
    ------
    file object
        The log, open for appending (line-buffered text).
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    log = open(path, "a", buffering=1, encoding="utf-8", errors="replace")  # noqa: SIM115 - closed in finally
    log.write(f"--- {time.strftime('%Y-%m-%dT%H:%M:%S')} pid {os.getpid()}: {' '.join(sys.argv)}\n")
    handler = logging.StreamHandler(log)
    handler.setFormatter(logging.Formatter("%(asctime)s %(name)s %(levelname)s %(message)s"))
    saved_loggers = []
    for name in _LOGGERS:
        logger = logging.getLogger(name)
        saved_loggers.append((logger, logger.handlers[:], logger.propagate))
        logger.handlers = [handler]
        logger.propagate = False
    saved_showwarning = warnings.showwarning

    def showwarning(message, category, filename, lineno, file=None, line=None):
        log.write(warnings.formatwarning(message, category, filename, lineno, line))

    warnings.showwarning = showwarning
    for stream in (sys.stderr, sys.__stderr__):
        with contextlib.suppress(Exception):
            stream.flush()
    saved_fd = None
    with contextlib.suppress(OSError):
        saved_fd = os.dup(2)
        os.dup2(log.fileno(), 2)
    try:
        yield log
    finally:
        if saved_fd is not None:
            with contextlib.suppress(Exception):
                sys.__stderr__.flush()
            os.dup2(saved_fd, 2)
            os.close(saved_fd)
        warnings.showwarning = saved_showwarning
        for logger, handlers, propagate in saved_loggers:
            logger.handlers = handlers
            logger.propagate = propagate
        log.close()
