"""One status vocabulary for every formulation, every solve and every frame of a load path.

Each formulation maps its solver's own status (Newton's, cvxpy's, IPOPT's) to a
:class:`Status` and keeps the original in ``info["native_status"]``; the same situation gets
the same status from every method. :class:`Status` is a ``str`` enum: ``Status.CONVERGED ==
"converged"``, and JSON, CSV and old string comparisons see the plain value.

A status says how the solve ended; ``Solution.success`` says whether dea-opt's own
certificate passed. A certified answer (``success``) has one of the statuses of
:data:`CERTIFIABLE`: :attr:`Status.CONVERGED` also where the solver doubted an answer that
passes the certificate all the same (its own word stays in ``info["native_status"]`` and
``info["solver_success"]``). An uncertified one has any other status. Written math:
``formulations/energy.md`` ("Statuses").
"""

from __future__ import annotations

from enum import StrEnum

__all__ = ["CERTIFIABLE", "Status"]


class Status(StrEnum):
    """How a solve ended. ``Status.X.description`` says it in one line (the README's table)."""

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

    def __repr__(self) -> str:
        # As the plain string it stands for: messages written as f"status {status!r}" read
        # the same as before statuses were an enum.
        return repr(self.value)

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
    Status.MAX_ITERATIONS: "the iteration (or time) limit was reached before convergence",
    Status.LINE_SEARCH_FAILED: "no step along the search direction decreased the energy enough (Newton's line "
                               "search, IPOPT's failed restoration)",
    Status.STALLED: "no descent direction, or a search direction too small to make progress",
    Status.CRUSHED: "springs reach a strain of -1 (crushed through their thickness) before the load is carried: "
                    "the load is beyond what the layer can bear",
    Status.INFEASIBLE: "the solver found its problem infeasible",
    Status.UNBOUNDED: "the solver found its problem unbounded (its iterates diverged)",
    Status.NON_FINITE: "a NaN or an infinity: in the data bound for compiled code (never passed on) or from the law",
    Status.SOLVER_ERROR: "the solver failed or raised without an answer",
    Status.NOT_SUPPORTED: "compression-only springs cannot carry the load: a load path's frame or a study's row "
                          "whose solve raised LoadNotSupportedError",
    Status.POSE_ERROR: "the springs could not be cast at a load path frame's pose (none there, or a pose the mesh "
                       "check refuses)",
    Status.INVALID_INPUT: "an argument or option was rejected before anything was solved: a study's row whose solve "
                          "raised InputError",
}

#: The statuses of an answer a solver (or no solver) produced as intended.
CERTIFIABLE = frozenset({Status.CONVERGED, Status.NO_FREE_DOFS, Status.HELD, Status.UNLOADED, Status.PRELOADED})
