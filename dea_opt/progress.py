"""What a long run shows on a terminal: the stage it is in, then a bar over its frames, cases,
runs or evaluations with the time left, all on stderr; nothing when stderr is not a terminal.

One mechanism for the command line and the Python API. Every function that takes
``progress=`` (:func:`dea_opt.run.run_scenario`, :func:`dea_opt.solve_path`,
:func:`dea_opt.study.run_study`, :func:`dea_opt.sweep.run_sweep`,
:func:`dea_opt.sensitivity.calibrate`, ...) shows it through this module, which is tqdm
(already the bars' library) with ``disable=None``: tqdm draws only when its stream is a
terminal, so a pipe, a log file or a test's captured stream receives nothing. ``progress=False``
(``--quiet``) shows nothing anywhere.

The stages (``reading meshes``, ``casting springs``, ``solving``, ``writing outputs``) are told
by :func:`stage`, which code deep inside a run (reading a scenario's meshes, casting its
springs) calls without being handed anything: it reaches the :class:`Progress` of the run under
way (a context variable), or does nothing when there is none.
"""

from __future__ import annotations

import contextlib
import contextvars
import sys
import time
from typing import Any

__all__ = ["Progress", "bar", "note", "showing", "stage"]

_CURRENT: contextvars.ContextVar[Progress | None] = contextvars.ContextVar("dea_opt_progress", default=None)


class Progress:
    """The stage line of one run on a terminal (tqdm, ``disable=None``: only on a terminal).

    Use it as a context: inside, :func:`stage` and :func:`note` reach it, and :func:`bar` makes
    the bars it shows below its stage.

    Parameters
    ----------
    enabled : bool
        False shows nothing (``--quiet``).
    file : file object, optional
        Default ``sys.stderr`` (looked up when the progress starts, so a redirected stderr counts).
    """

    def __init__(self, enabled: bool = True, file=None):
        self.enabled = bool(enabled)
        self.file = file
        self._line: Any = None
        self._token: contextvars.Token | None = None
        self._start = time.perf_counter()

    def _stream(self):
        return self.file if self.file is not None else sys.stderr

    def stage(self, text: str) -> None:
        """Show ``text`` as the run's current stage (replacing the one before)."""
        if not self.enabled or not _is_terminal(self._stream()):
            return
        if self._line is None:
            from tqdm.auto import tqdm

            # total=None and a description only: a status line, redrawn in place.
            self._line = tqdm(
                total=None, bar_format="{desc}", leave=False, file=self._stream(), disable=None, dynamic_ncols=True
            )
        elapsed = time.perf_counter() - self._start
        self._line.set_description_str(f"dea-opt: {text} ({elapsed:.0f} s so far)", refresh=True)

    def note(self, text: str) -> None:
        """Print ``text`` as a line of its own above the stage line (on a terminal only)."""
        if self.enabled and _is_terminal(self._stream()):
            from tqdm.auto import tqdm

            tqdm.write(text, file=self._stream())

    def clear(self) -> None:
        """Remove the stage line (a bar takes its place)."""
        if self._line is not None:
            self._line.close()
            self._line = None

    def close(self) -> None:
        self.clear()

    def __enter__(self) -> Progress:
        self._token = _CURRENT.set(self)
        return self

    def __exit__(self, *exc) -> None:
        self.close()
        if self._token is not None:
            _CURRENT.reset(self._token)
            self._token = None


def _is_terminal(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # a closed or file-less stream
        return False


def current() -> Progress | None:
    """The :class:`Progress` of the run under way in this context, or None."""
    return _CURRENT.get()


def stage(text: str) -> None:
    """Tell the run under way (if any, and on a terminal) that it has reached stage ``text``."""
    progress = _CURRENT.get()
    if progress is not None:
        progress.stage(text)


def note(text: str) -> None:
    """Print ``text`` above the progress of the run under way (on a terminal; else nothing)."""
    progress = _CURRENT.get()
    if progress is not None:
        progress.note(text)


def showing(enabled: bool):
    """A :class:`Progress` context when ``enabled`` and no run's progress is under way; else a
    context that leaves the one under way (or none) in place."""
    if enabled and _CURRENT.get() is None:
        return Progress(True)
    return contextlib.nullcontext(_CURRENT.get())


def bar(total: int | None, desc: str, unit: str, enabled: bool, *, file=None, **options):
    """A tqdm bar over ``total`` items (None: a counter without an end), with the time left when
    ``total`` is known; drawn only on a terminal and when ``enabled``. It takes the place of the
    stage line of the run under way."""
    from tqdm.auto import tqdm

    progress = _CURRENT.get()
    if enabled and progress is not None:
        progress.clear()
    return tqdm(
        total=total,
        desc=desc,
        unit=unit,
        disable=None if enabled else True,
        leave=False,
        file=file if file is not None else sys.stderr,
        dynamic_ncols=True,
        **options,
    )
