"""What a run did: :class:`RunOutcome`, its status (a :class:`~dea_opt.status.RunStatus`) and its exit code."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from ..status import RunStatus

__all__ = ["EXIT_CODES", "RunOutcome", "status_of"]

#: Exit status of a run, by its status (:attr:`RunStatus.exit_code`).
EXIT_CODES = {status: status.exit_code for status in RunStatus}


@dataclass(eq=False)
class RunOutcome:
    """What :func:`run_scenario` did.

    Attributes
    ----------
    kind : {"static", "path"}
    success : bool
        Every answer passed its certificate.
    message : str
        One line for the user.
    files : dict {name: Path}
    headline : dict
        The numbers a sweep puts in its table (with ``valid`` and ``validity_failed``).
    result : Solution, PathResult, JointSolution or dict
        The answer. A whole joint's path keeps ``{"frames": rows, "shown": shown}``: the rows of
        ``frames.csv`` and ``(frame, time_s, JointSolution, force_N)`` of the certified frame with
        the largest contact force, which its report shows (None without one).
    warnings : list of str
        dea-opt's own warnings of the run (validity, dropped springs, ...), one line each.
    valid : bool or None
        Every answer lies inside its model's validity (None: not assessed).
    validity : list of str
        Lines describing the validity (each check of a static answer; the frames outside
        validity of a load path).
    reasons : list of str
        Why the answer is outside validity (each failed check with its value, limit and
        advice; for a load path, the frames); empty when valid.
    regions : list of str
        One line per labelled region (compartment): its share of the load, peak pressure and
        contact area (for a load path: over the frames); empty without labels.
    allow_outside_validity : bool
        ``[solve] allow_outside_validity``: an answer outside validity exits 0.
    failures : dict {Status: int}
        The statuses of the answers without a certificate (a load path's frames), counted.
    folder : Path or None
        The output folder; ``manifest`` its manifest once published.
    suspicions : list of str
        What the check before solving found plausible but suspicious (a modulus in kPa, a load
        in kN; :mod:`dea_opt.run.preflight`), one line each: said first among the warnings.
    """

    kind: str
    success: bool
    message: str
    files: dict
    headline: dict
    result: object = None
    warnings: list = field(default_factory=list)
    valid: bool | None = True
    validity: list = field(default_factory=list)
    reasons: list = field(default_factory=list)
    regions: list = field(default_factory=list)
    allow_outside_validity: bool = False
    failures: dict = field(default_factory=dict)
    folder: Path | None = None
    manifest: dict | None = None
    suspicions: list = field(default_factory=list)

    @property
    def status(self) -> RunStatus:
        """``ok``, ``outside_validity``, or why an answer has no certificate
        (:meth:`RunStatus.of_run`)."""
        return status_of(self.success, self.valid, self.failures)

    @property
    def exit_code(self) -> int:
        """0, 1 or 3 (see :mod:`dea_opt.run`)."""
        if self.status is RunStatus.OUTSIDE_VALIDITY and self.allow_outside_validity:
            return 0
        return self.status.exit_code


def status_of(success: bool, valid: bool | None, failures=()) -> RunStatus:
    """The status of a run (:meth:`RunStatus.of_run`): a failure outranks an answer outside validity."""
    return RunStatus.of_run(success, valid, failures)
