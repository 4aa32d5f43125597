"""What a run tells its user: dea-opt's own warnings as one line each, everything else into a log.

Nothing raw reaches the terminal: a Python warning that dea-opt issued (a
:class:`~dea_opt.errors.ValidityWarning`, a mesh's dropped springs, ...) becomes one line
(``dea-opt: warning: ...`` at the command line); warnings of the libraries underneath
(numpy, cvxpy, CasADi, Dask, ...) and their log records go to the run's log file
(``dea-opt.log`` in the output folder, written with the other outputs).
"""

from __future__ import annotations

import contextlib
import logging
import time
import warnings
from dataclasses import dataclass, field
from pathlib import Path

__all__ = ["LOG_NAME", "Messages", "captured", "is_own_warning", "one_line"]

#: The run's log file, in its output folder.
LOG_NAME = "dea-opt.log"
_PACKAGE = Path(__file__).resolve().parents[1]  # dea_opt/


def one_line(text) -> str:
    """``text`` with every run of white space (newlines too) made one space."""
    return " ".join(str(text).split())


def is_own_warning(message: warnings.WarningMessage) -> bool:
    """A user-facing warning dea-opt issued itself (a ``UserWarning`` from dea_opt's code).

    A ``RuntimeWarning`` of numpy is attributed to the dea_opt line that called numpy, so the
    file alone does not decide: only ``UserWarning`` and its subclasses count as dea-opt's.
    """
    if not issubclass(message.category, UserWarning):
        return False
    try:
        return Path(message.filename).resolve().is_relative_to(_PACKAGE)
    except (OSError, ValueError):
        return False


@dataclass
class Messages:
    """What a run said: ``own`` one-line warnings (in order, without repeats) and ``log`` lines."""

    own: list = field(default_factory=list)
    log: list = field(default_factory=list)
    #: The category name of each of ``own`` (``"ValidityWarning"``, ``"UserWarning"``, ...).
    categories: dict = field(default_factory=dict)
    _caught: list = field(default_factory=list, repr=False)

    def collect(self) -> Messages:
        """Sort the warnings recorded so far into ``own`` and ``log``."""
        caught, self._caught[:] = list(self._caught), []
        for message in caught:
            self.add_warning(message)
        return self

    def add_warning(self, message: warnings.WarningMessage) -> None:
        if is_own_warning(message):
            text = one_line(message.message)
            if text not in self.own:
                self.own.append(text)
                self.categories[text] = message.category.__name__
        else:
            where = f"{Path(message.filename).name}:{message.lineno}"
            self.log.append(f"{message.category.__name__} ({where}): {one_line(message.message)}")

    def log_text(self, title: str) -> str:
        """The log file's text: a header, then every library message; empty if there are none."""
        if not self.log:
            return ""
        return f"# {title}, {time.strftime('%Y-%m-%dT%H:%M:%S%z')}\n" + "\n".join(self.log) + "\n"


#: The :class:`Messages` of the blocks of :func:`captured` under way, innermost last.
_ACTIVE: list = []


class _ListHandler(logging.Handler):
    def __init__(self, messages: Messages):
        super().__init__(logging.WARNING)
        self.messages = messages

    def emit(self, record: logging.LogRecord) -> None:
        # Only the innermost block records: a run inside a command logs into its own folder.
        if _ACTIVE and _ACTIVE[-1] is not self.messages:
            return
        with contextlib.suppress(Exception):
            self.messages.log.append(f"{record.levelname} {record.name}: {one_line(record.getMessage())}")


@contextlib.contextmanager
def captured():
    """Record the warnings and log records of the block into a :class:`Messages`.

    Warnings are recorded (each once per place, ``"always"``), not printed; log records of
    level WARNING and above reach the root logger's handler here instead of Python's
    last-resort printing to stderr.
    """
    messages = Messages()
    handler = _ListHandler(messages)
    root = logging.getLogger()
    root.addHandler(handler)
    _ACTIVE.append(messages)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            messages._caught = caught
            try:
                yield messages
            finally:
                messages.collect()
    finally:
        _ACTIVE.remove(messages)
        root.removeHandler(handler)
