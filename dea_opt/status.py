"""One status vocabulary for every formulation, every solve and every frame of a load path, and
one for every run.

Each formulation maps its solver's own status (Newton's, cvxpy's, IPOPT's) to a
:class:`Status` and keeps the original in ``info["native_status"]``; the same situation gets
the same status from every method. :class:`Status` is a ``str`` enum: ``Status.CONVERGED ==
"converged"``, and JSON, CSV and string comparisons see the plain value.

A status says how the solve ended; ``Solution.success`` says whether dea-opt's own
certificate passed. A certified answer (``success``) has one of the statuses of
:data:`CERTIFIABLE`: :attr:`Status.CONVERGED` also where the solver doubted an answer that
passes the certificate all the same (its own word stays in ``info["native_status"]`` and
``info["solver_success"]``). An uncertified one has any other status. Written math:
``formulations/energy.md`` ("Statuses").

A run (``dea-opt run``, ``demo``, ``compare``, ``calibrate``, a sweep's case) ends with a
:class:`RunStatus`: the ``status`` of its ``manifest.json``, of a sweep's row, and the source of
its exit code. A run that has an answer without a certificate says why, in the words of the
frames' :class:`Status` where one cause covers them (``load_not_supported``, ``pose_error``).
"""

from __future__ import annotations

from enum import StrEnum

__all__ = ["CERTIFIABLE", "RunStatus", "Status"]


class Status(StrEnum):
    """How a solve ended. ``Status.X.description`` says it in one line (the table of the guide's concepts page)."""

    CONVERGED = "converged"
    NO_FREE_DOFS = "no_free_dofs"
    HELD = "held"
    UNLOADED = "unloaded"
    PRELOADED = "preloaded"
    INACCURATE = "inaccurate"
    MAX_ITERATIONS = "max_iterations"
    LINE_SEARCH_FAILED = "line_search_failed"
    STALLED = "stalled"
    CRUSHED = "crushed"
    INFEASIBLE = "infeasible"
    UNBOUNDED = "unbounded"
    NON_FINITE = "non_finite"
    SOLVER_ERROR = "solver_error"
    NOT_SUPPORTED = "load_not_supported"
    POSE_ERROR = "pose_error"
    INVALID_INPUT = "invalid_input"

    @property
    def description(self) -> str:
        """One line: when this status is given."""
        return _DESCRIPTIONS[self]

    @classmethod
    def of_error(cls, exc: BaseException) -> Status:
        """The status of a run that raised ``exc`` instead of returning an answer (a study's
        row, a frame of a load path): a :class:`~dea_opt.errors.SolverError` keeps its own."""
        from .errors import InputError, LoadNotSupportedError, SolverError

        if isinstance(exc, SolverError) and exc.status in cls._value2member_map_:
            return cls(exc.status)
        if isinstance(exc, LoadNotSupportedError):
            return cls.NOT_SUPPORTED
        if isinstance(exc, InputError):
            return cls.INVALID_INPUT
        return cls.SOLVER_ERROR


_DESCRIPTIONS = {
    Status.CONVERGED: "the solver converged; for a Solution, its answer passed dea-opt's certificate (also where "
    "the solver doubted it: info['native_status'] keeps its word)",
    Status.NO_FREE_DOFS: "every dof is fixed or prescribed: no solver runs, u is as prescribed",
    Status.HELD: "no spring resists any free dof and no load acts along them: every free dof is held at zero "
    "motion, no solver runs",
    Status.UNLOADED: "no load and no overlap: nothing moves and no spring carries anything, no solver runs",
    Status.PRELOADED: "no load, but springs overlap (a press fit): the equilibrium of the overlap alone by the "
    "default formulation (Newton), the same answer for every method",
    Status.INACCURATE: "the solver stopped at an answer it doubts (Clarabel's AlmostSolved, cvxpy's "
    "optimal_inaccurate, IPOPT's acceptable level), or claimed one that fails dea-opt's certificate",
    Status.MAX_ITERATIONS: "the iteration (or time) limit was reached before convergence; for finite kinematics "
    "also: the springs still changed at the last update max_recasts allows, or the solve did not converge where "
    "its iterates met crushed springs or ran away, which proves nothing about the load (info['unproved'])",
    Status.LINE_SEARCH_FAILED: "no step along the search direction decreased the energy enough (Newton's line "
    "search, IPOPT's failed restoration)",
    Status.STALLED: "no descent direction, or a search direction too small to make progress",
    Status.CRUSHED: "springs reach a strain of -1 (crushed through their thickness) before the load is carried: "
    "the load is beyond what the layer can bear (for finite kinematics proved: every spring the layer can have, "
    "crushed to strain -1, carries less than the load along a balance that holds at every pose)",
    Status.INFEASIBLE: "the solver found its problem infeasible",
    Status.UNBOUNDED: "the solver found its problem unbounded (its iterates diverged); not given with finite "
    "kinematics, where iterates that ran away prove nothing about the load (max_iterations)",
    Status.NON_FINITE: "a NaN or an infinity: in the data bound for compiled code (never passed on) or from the law",
    Status.SOLVER_ERROR: "the solver failed or raised without an answer",
    Status.NOT_SUPPORTED: "compression-only springs cannot carry the load: a load path's frame or a study's row "
    "whose solve raised LoadNotSupportedError",
    Status.POSE_ERROR: "the springs could not be cast at a load path frame's pose (none there, or a pose the mesh "
    "check refuses), or, with finite kinematics, at the pose a solve reached (none left there)",
    Status.INVALID_INPUT: "an argument or option was rejected before anything was solved: a study's row whose solve "
    "raised InputError",
}

#: The statuses of an answer a solver (or no solver) produced as intended.
CERTIFIABLE = frozenset({Status.CONVERGED, Status.NO_FREE_DOFS, Status.HELD, Status.UNLOADED, Status.PRELOADED})


class RunStatus(StrEnum):
    """How a run ended: ``manifest.json``'s ``status``, a sweep row's, and the exit code's source.

    ``RunStatus.X.description`` says it in one line and ``RunStatus.X.exit_code`` is the exit
    code of the command (the table of the guide's concepts page). A ``str`` enum: JSON and CSV see the plain value.
    """

    OK = "ok"
    OUTSIDE_VALIDITY = "outside_validity"
    CERTIFICATE_FAILED = "certificate_failed"
    LOAD_NOT_SUPPORTED = "load_not_supported"
    POSE_ERROR = "pose_error"
    NOT_CONVERGED = "not_converged"
    ERROR = "error"

    @property
    def description(self) -> str:
        """One line: when a run ends with this status."""
        return _RUN_DESCRIPTIONS[self]

    @property
    def exit_code(self) -> int:
        """The command's exit code: 0 ok, 3 outside validity, 2 error, 1 any answer without a
        certificate (or a fit that did not converge)."""
        return {RunStatus.OK: 0, RunStatus.OUTSIDE_VALIDITY: 3, RunStatus.ERROR: 2}.get(self, 1)

    @property
    def failed(self) -> bool:
        """The run has an answer without a certificate, or could not run (exit code 1 or 2)."""
        return self.exit_code in (1, 2)

    @classmethod
    def of_frame(cls, status) -> RunStatus:
        """The run status a failed answer (or frame) of :class:`Status` ``status`` gives its run."""
        return {Status.NOT_SUPPORTED: cls.LOAD_NOT_SUPPORTED, Status.POSE_ERROR: cls.POSE_ERROR}.get(
            status, cls.CERTIFICATE_FAILED
        )

    @classmethod
    def of_run(cls, success: bool, valid: bool | None, failures=()) -> RunStatus:
        """The status of a run: a failure outranks an answer outside validity.

        ``failures`` are the :class:`Status` of its answers (a load path's frames) without a
        certificate. When they differ in cause, ``certificate_failed`` outranks ``pose_error``,
        which outranks ``load_not_supported``.
        """
        if not success:
            causes = {cls.of_frame(status) for status in failures} or {cls.CERTIFICATE_FAILED}
            return next(s for s in (cls.CERTIFICATE_FAILED, cls.POSE_ERROR, cls.LOAD_NOT_SUPPORTED) if s in causes)
        return cls.OUTSIDE_VALIDITY if valid is False else cls.OK


_RUN_DESCRIPTIONS = {
    RunStatus.OK: "every answer passed its certificate and lies inside its model's validity",
    RunStatus.OUTSIDE_VALIDITY: "every answer passed its certificate, but one lies outside its model's validity "
    "(exit 0 with [solve] allow_outside_validity)",
    RunStatus.CERTIFICATE_FAILED: "an answer (a load path: a frame) has no certificate: the solver's answer failed "
    "it, or the solver gave up without one (finite kinematics also: a crushed layer, or springs not brought up "
    "to date at the answer's pose)",
    RunStatus.LOAD_NOT_SUPPORTED: "every frame without a certificate has a load the springs cannot carry "
    "(frame status load_not_supported)",
    RunStatus.POSE_ERROR: "the frames without a certificate are frames whose springs could not be cast at their pose "
    "(or loads the springs cannot carry)",
    RunStatus.NOT_CONVERGED: "a calibration's least squares did not converge",
    RunStatus.ERROR: "the run could not be done (a sweep's case: its message says why); at the command line, bad "
    "input is one paragraph and no outputs",
}
