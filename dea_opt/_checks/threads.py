"""BLAS threads: the passes over the springs run on one (:func:`single_threaded_blas`).

threadpoolctl (a dependency) does the work; this module keeps one controller per process.
"""

from __future__ import annotations

import contextlib
from functools import lru_cache

__all__ = ["single_threaded_blas"]


@lru_cache(maxsize=1)
def _blas_controller():
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:  # pragma: no cover - threadpoolctl is a dependency
        return None
    return ThreadpoolController()


def single_threaded_blas():
    """A context in which BLAS runs on one thread.

    The passes over the springs are matrix-vector products bound by memory bandwidth: a second
    BLAS thread does not make them faster, and its start-up costs more than the product itself
    at 1e4 springs (a 101-frame load path ran 4x faster on one thread).
    """
    controller = _blas_controller()
    if controller is None:
        return contextlib.nullcontext()
    return controller.limit(limits=1, user_api="blas")
