"""Optional dependencies: import one where it is needed, or say how to install it."""

from __future__ import annotations

import functools
import importlib
from typing import Any

from ..errors import MissingDependencyError


def require(module: str, feature: str):
    """The imported ``module``, or a :class:`MissingDependencyError` naming ``feature`` and the fix."""
    try:
        return importlib.import_module(module)
    except ImportError:
        package = module.split(".")[0]
        raise MissingDependencyError(
            f"{feature} needs {package}; install it with `pip install {package}` "
            f"(or reinstall dea-opt with its dependencies)"
        ) from None


@functools.cache
def compiled(module: str) -> Any:
    """The compiled extension ``module`` (declared in ``setup.py``, built at install where a C
    compiler is at hand), or None where it was not built: its caller then runs the same loop in
    numpy. Looked for once."""
    try:
        return importlib.import_module(module)
    except ImportError:
        return None
