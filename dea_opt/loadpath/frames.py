"""The frames of a load path: how many (read from a shape or a length alone), the loads and times
checked, and the memory the path will keep, checked before the first frame.

:func:`frame_count` reads no frame, so :func:`check_frames` runs before any work that grows with
the frames (:func:`~dea_opt.loadpath.solve.solve_path` calls them in that order, then
:func:`read_frames`). Units: N, N mm, s, bytes.
"""

from __future__ import annotations

import numpy as np

from .._checks.inputs import as_numeric
from .._checks.memory import check_memory
from ..errors import InputError
from ..problem import Load
from .table import REGION_COLUMNS, TABLE_COLUMNS

__all__ = ["check_frames", "frame_count", "path_memory", "read_frames"]


# --- frames -----------------------------------------------------------------------------


class _ArrayLoads:
    """The loads of a (T, 3) or (T, 6) array, a :class:`Load` made per frame when asked."""

    def __init__(self, array: np.ndarray):
        self.array = array

    def __len__(self) -> int:
        return len(self.array)

    def __getitem__(self, k: int) -> Load:
        row = self.array[k]
        return Load(force=tuple(row[:3]), moment=tuple(row[3:6]) if len(row) == 6 else (0.0, 0.0, 0.0))

    def __iter__(self):
        return (self[k] for k in range(len(self)))


def frame_count(loads) -> int:
    """How many frames ``loads`` holds, from its length or shape alone: no frame is read, copied
    or converted, so the size check comes before any work that grows with the frames (a
    broadcast array of 1e9 rows is 48 bytes of data until something walks it)."""
    import pandas as pd

    if isinstance(loads, (np.ndarray, pd.DataFrame)):
        shape = loads.shape
        if isinstance(loads, np.ndarray) and (len(shape) != 2 or shape[1] not in (3, 6)):
            raise InputError(
                f"loads must be a sequence of Load, or an array of shape (T, 3) or (T, 6) "
                f"(Fx, Fy, Fz[, Mx, My, Mz]), got shape {shape}"
            )
        return int(shape[0]) if shape else 0
    try:
        return len(loads)
    except TypeError:
        raise InputError(
            f"loads must be a sequence of Load, an array of shape (T, 3) or (T, 6), or a DataFrame, "
            f"got {type(loads).__name__} (without a length)"
        ) from None


def read_frames(loads, times) -> tuple:
    """Loads as a sequence of :class:`Load` and the frame times (s)."""
    import pandas as pd

    if isinstance(loads, pd.DataFrame):
        missing = [c for c in ("Fx", "Fy", "Fz") if c not in loads]
        if missing:
            raise InputError(
                f"loads must have columns Fx, Fy, Fz (and optionally time, Mx, My, Mz); missing {', '.join(missing)}"
            )
        if times is None and "time" in loads:
            times = loads["time"].to_numpy(dtype=float)
        columns = [loads[c] if c in loads else 0.0 * loads["Fx"] for c in ("Fx", "Fy", "Fz", "Mx", "My", "Mz")]
        loads = np.column_stack([np.asarray(c, dtype=float) for c in columns])
    if isinstance(loads, np.ndarray) or (len(loads) and not isinstance(loads[0], Load)):
        array = as_numeric("loads", loads)
        if array.ndim != 2 or array.shape[1] not in (3, 6):
            raise InputError(
                f"loads must be a sequence of Load, or an array of shape (T, 3) or (T, 6) "
                f"(Fx, Fy, Fz[, Mx, My, Mz]), got shape {array.shape}"
            )
        loads = _ArrayLoads(array)
    else:
        loads = list(loads)
    if not loads:
        raise InputError("loads is empty: a load path needs at least one frame")
    if not isinstance(loads, _ArrayLoads):
        for i, load in enumerate(loads):
            if not isinstance(load, Load):
                raise InputError(f"loads[{i}] must be a dea_opt.Load, got {type(load).__name__}")
    times = np.arange(len(loads), dtype=float) if times is None else np.asarray(times, dtype=float)
    if times.shape != (len(loads),) or not np.isfinite(times).all():
        raise InputError(f"times must be {len(loads)} finite numbers (one per frame), got shape {times.shape}")
    if len(times) > 1 and not (np.diff(times) > 0).all():
        raise InputError("times must increase from frame to frame")
    return loads, times


# --- memory -----------------------------------------------------------------------------

#: Bytes per frame and table column (a row's dict entry, its value and the DataFrame cell).
_CELL_BYTES = 160.0
#: Bytes per frame of a Load and the frame's bookkeeping.
_FRAME_BYTES = 2000.0


def path_memory(
    n_frames: int,
    n_springs: int,
    *,
    n_sites: int | None = None,
    keep_solutions: bool = True,
    keep_pressures: bool = True,
    moving: bool = False,
    n_regions: int = 0,
) -> float:
    """Bytes a load path of ``n_frames`` x ``n_springs`` keeps until it returns (an estimate).

    The table (about 50 columns: the fixed ones, the validity checks and the free dofs;
    :data:`~dea_opt.loadpath.table.REGION_COLUMNS` more per region, per frame), the pressures (8 bytes per
    spring and frame) and the solutions (strain and pressure; with ``moving`` meshes each
    frame's layer and its operator too, about 250 bytes per spring). The exposure and one
    frame's work are O(springs) and not counted.
    """
    n_frames, n_springs = int(n_frames), int(n_springs)
    columns = len(TABLE_COLUMNS) + 12 + 12 + len(REGION_COLUMNS) * int(n_regions)  # + validity checks + free dofs
    need = n_frames * (_FRAME_BYTES + _CELL_BYTES * columns)
    if keep_pressures:
        need += 8.0 * n_frames * n_springs
    if keep_solutions:
        need += n_frames * n_springs * (250.0 if moving else 24.0)
    return float(need)


def check_frames(n_frames: int, n_springs: int = 0, *, what: str | None = None, **options) -> None:
    """Raise :class:`~dea_opt.errors.SizeLimitError` before a path too large for this machine.

    Parameters
    ----------
    n_frames, n_springs : int
    what : str, optional
        How the user asked for it, for the message (e.g. ``"load_path.frames = 1000000000"``);
        default ``"a load path of <n> frames"``.
    **options
        ``keep_solutions``, ``keep_pressures`` (of :class:`~dea_opt.loadpath.outputs.PathOutputs`), ``moving``,
        ``n_regions`` of :func:`path_memory`.
    """
    need = path_memory(n_frames, n_springs, **options)
    what = what or f"a load path of {int(n_frames)} frames x {int(n_springs)} springs"
    keeps = [name for name in ("keep_solutions", "keep_pressures") if options.get(name, True) and n_springs]
    advice = "use fewer frames"
    if keeps:
        advice += (
            f", or outputs=PathOutputs({', '.join(f'{k}=False' for k in keeps)}, series=<folder>) (the outputs "
            f"are then written frame by frame)"
        )
    check_memory(need, what, advice)
