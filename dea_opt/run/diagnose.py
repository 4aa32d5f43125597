"""Causes in words, with the scenario key that fixes them: for the check before a run
(:mod:`dea_opt.run.preflight`) and for a load path's failed frames, grouped by cause into one
complete line each (:func:`failure_lines`) instead of one cut-off message per frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .contact_shape import ContactShape, frame_cause, vector_text

__all__ = ["LoadSource", "cause_text", "failure_lines", "frames_text", "who_text"]

_AXES = "xyz"


@dataclass(frozen=True)
class LoadSource:
    """Where a scenario's load comes from, for messages that name the key to change.

    ``kind``: ``"load"`` (``[load]``), ``"csv"``, ``"sto"`` (an OpenSim ``.sto``/``.mot``) or
    ``"builtin"``; ``name``: how to name it; ``units``: a ``.sto``'s ``units``; ``columns``:
    its ``columns`` table.
    """

    kind: str
    name: str
    file: str | None = None
    units: str | None = None
    columns: tuple = ()

    @classmethod
    def of(cls, scenario) -> LoadSource:
        section = scenario.load_path
        if section is None:
            return cls("load", "the load")
        if section.file is None:
            return cls("builtin", f"the {section.builtin} load path")
        name = Path(section.file).name
        if section.columns is not None:
            return cls("sto", name, section.file, section.units or "SI", tuple(section.columns.items()))
        return cls("csv", name, section.file)

    @property
    def table(self) -> str:
        return "[load]" if self.kind == "load" else "[load_path]"

    def key(self, cause: str) -> str:
        """The scenario key that fixes ``cause``."""
        if self.kind == "load":
            return "load.moment" if cause == "moment_units" else "load.force"
        if cause == "moment_units" and self.kind == "sto":
            return "load_path.units"
        return "load_path.columns" if (cause == "along_surface" and self.kind == "sto") else "load_path.scale"

    def unread_moments(self) -> list[str]:
        """The moment columns of a ``.sto`` that ``columns`` does not name (guessed from the
        names of its force columns: ``..._fx`` beside ``..._mx``)."""
        if self.kind != "sto" or any(q in ("Mx", "My", "Mz") for q, _ in self.columns):
            return []
        from ..opensim.storage import read_storage

        named = [spec.lstrip("-") for q, spec in self.columns if q in ("Fx", "Fy", "Fz")]
        present = set(read_storage(self.file).labels)
        guesses = [name[:-2] + "m" + name[-1] for name in named if name[-2:-1].lower() == "f"]
        return [g for g in guesses if g in present]

    def moment_fix(self) -> str:
        if self.kind == "sto":
            return 'columns = {Mx = "...", My = "...", Mz = "..."}'
        if self.kind == "csv":
            return f"columns Mx, My, Mz of {self.name}, N mm about the reference point"
        return "[load] moment, N mm about the reference point"


def frames_text(frames, total: int, time: float | None = None) -> str:
    """``frames 0-4, 9 (6 of 51)``, ``every frame (51 of 51)``, or ``frame 2 (0.2 s, 1 of 5)``
    (one frame, at ``time`` s)."""
    frames = sorted(int(f) for f in frames)
    if len(frames) == total:
        return f"every frame ({total} of {total})"
    if len(frames) == 1 and time is not None:
        return f"frame {frames[0]} ({time:g} s, 1 of {total})"
    runs, start = [], frames[0]
    for a, b in zip(frames, [*frames[1:], None]):
        if b != a + 1:
            runs.append(f"{start}" if start == a else f"{start}-{a}")
            start = b
    shown = ", ".join(runs[:8]) + (", ..." if len(runs) > 8 else "")
    return f"frame{'s' if len(frames) > 1 else ''} {shown} ({len(frames)} of {total})"


def _pressing_axis(shape: ContactShape) -> int:
    return int(np.argmax(np.abs(shape.normal))) if shape.normal is not None else 2


def _normal_sign(shape: ContactShape, axis: int) -> float:
    return math.copysign(1.0, float(shape.normal[axis])) if shape.normal is not None else 1.0


def who_text(source: LoadSource, n_bad: int, total: int) -> str:
    """``the load``, ``every frame of walk.csv`` or ``every loaded frame of walk.csv (40 of 51)``."""
    if source.kind == "load":
        return "the load"
    if n_bad == total:
        return f"every frame of {source.name}"
    return f"every loaded frame of {source.name} ({n_bad} of {total})"


def cause_text(cause: str, source: LoadSource, shape: ContactShape, forces, who: str, body: int, arm: float) -> str:
    """One line: ``who`` (the load, or frames of a path) has ``cause``, and its fix, naming the
    scenario key. ``forces``: (T, 3) N of those frames; ``arm``: their typical
    :func:`~dea_opt.run.contact_shape.moment_arm` (mm)."""
    forces = np.atleast_2d(np.asarray(forces, dtype=float))
    normal = vector_text(np.round(shape.normal, 3)) if shape.normal is not None else "undefined"
    other = "body 1" if body == 2 else "body 2"
    if cause in ("pulls_apart", "pulls_apart_proven"):
        text = (
            f"{who} pulls the bodies apart: its force on body {body} points away from {other} (the contact's "
            f"normal, from body 1 to body 2, is {normal}); negate it? "
        )
        if source.kind == "load":
            return text + f"[load] force = {_toml(-forces[0])} (N; a joint's load presses the bodies together)"
        also = ' (or a leading "-" on each name in columns)' if source.kind == "sto" else ""
        return text + f"[load_path] scale = -1 negates every force and moment{also}"
    if cause == "along_surface":
        largest = int(np.argmax(np.abs(forces).mean(axis=0)))
        axis = _pressing_axis(shape)
        text = (
            f"{who} lies along the contact's surface: its force is largest along {_AXES[largest]} and the "
            f"contact's normal is {normal}, so it hardly presses the bodies together; "
        )
        if source.kind == "load":
            moved = np.zeros(3)
            pressing = -1.0 if body == 2 else 1.0
            moved[axis] = pressing * _normal_sign(shape, axis) * float(np.linalg.norm(forces[0]))
            return text + f"a force in the wrong component? [load] force = {_toml(moved)} presses along the normal"
        column = {"csv": "column", "sto": "column named in columns"}.get(source.kind, "column")
        return (
            text + f"the compressive force in the wrong {column}? It belongs in F{_AXES[axis]} "
            f"(now in F{_AXES[largest]})"
        )
    if cause == "moment_units":
        ratio = arm / max(shape.radius, 1e-12)
        # a thousand times too large when a thousandth is an arm inside the contact
        factor = 1000 if ratio / 1000.0 <= 2.0 and ratio >= 100.0 else None
        size = f"{factor}x" if factor else f"{ratio:.3g} layer radii"
        text = (
            f"the moments of {who.removeprefix('every frame of ')} look {size} too large: about the contact's "
            f"centre they need a lever arm of {arm:.4g} mm on a contact {2 * shape.radius:.3g} mm across; "
        )
        if source.kind == "sto" and source.units == "SI":
            return text + '[load_path] units = "mm"? (the file\'s moments are N mm already; "SI" reads N m)'
        if source.kind == "load":
            return text + "[load] moment is in N mm about the reference point: divide it by 1000?"
        return text + f"the moment columns of {source.name} are N mm about the reference point: divide them by 1000?"
    raise ValueError(f"no text for the cause {cause!r}")


def _toml(vector) -> str:
    """``[0.0, 0.0, -1000.0]``: a vector as a scenario writes it (floats, 6 significant digits)."""
    return "[" + ", ".join(repr(float(f"{float(v) + 0.0:.6g}")) for v in vector) + "]"


def failure_lines(failures, loads, problem, source: LoadSource, body: int, total: int) -> list[str]:
    """A load path's frames without a certified answer, grouped by cause: one complete line per
    group (its frames, the cause in words and its fix), or per status with the first frame's
    whole message when no cause is recognised.

    Parameters
    ----------
    failures : list of dict
        :meth:`~dea_opt.loadpath.PathResult.failures` (``frame``, ``status``, ``message``).
    loads : sequence of Load
        Every frame's load (the failed ones are read).
    problem : ContactProblem
    source : LoadSource
    body : int
        The body the loads act on.
    total : int
        The path's frames.
    """
    if not failures:
        return []
    from .contact_shape import moment_arm

    shape = ContactShape.of(problem.layer) if len(problem.layer) else None
    groups: dict = {}
    for failure in failures:
        load = loads[int(failure["frame"])]
        # no springs: nothing to say about the loads
        cause = None if shape is None else frame_cause(shape, problem, load.force, load.moment, load.point, body)
        groups.setdefault((str(failure["status"]), cause), []).append(failure)
    lines = []
    for (status, cause), members in groups.items():
        frames = [int(f["frame"]) for f in members]
        who = f"{frames_text(frames, total, members[0].get('time_s'))} {status}"
        if cause is None or shape is None:
            lines.append(f"{who}: {' '.join(str(members[0]['message']).split())}")
            continue
        forces = np.array([np.asarray(loads[k].force, dtype=float) for k in frames])
        arms = [moment_arm(shape, problem, loads[k].force, loads[k].moment, loads[k].point, body) for k in frames]
        each = "each frame" if len(frames) > 1 else "the frame"
        lines.append(f"{who}: {cause_text(cause, source, shape, forces, each, body, float(np.median(arms)))}")
    return lines
