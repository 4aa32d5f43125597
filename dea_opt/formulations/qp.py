"""The linear-law DEA problem as a convex QP: Clarabel's own API by default, cvxpy for the others.

Written math: ``formulations/qp.md``. Variables: the free dofs ``x`` (``u_free`` in the code) and
the compressive strain ``c``; ``min 1/2 sum V_i H c_i^2 - r . x`` s.t. ``c >= 0``,
``c + e0 + A x >= 0``: ``k + N`` variables, a diagonal ``P`` and ``2N`` rows of the
nonnegative cone, and nothing else. The default solver, Clarabel, gets exactly these matrices
through its Python API (cvxpy's canonicalization cost more than the 10 % the speed issue
allows); any other QP solver cvxpy knows gets the same problem through cvxpy, written so that
cvxpy adds no variable or row (qp.md, "What the solver sees"). Only the load changes between
re-solves (Clarabel's ``update(q=...)``; cvxpy's one Parameter); spring forces come from the
duals of ``c + e0 + A x >= 0`` (``lambda_i = V_i H c_i``).
"""

from __future__ import annotations

import time
import warnings
from functools import lru_cache

import numpy as np

from ..errors import InputError, MissingDependencyError, SolverError
from ..status import Status
from ._parts.options import Capabilities, Option, Variant, validate
from ._parts.recentre import recentred_solve
from ._parts.resistance import require_finite
from ._parts.scaling import scaling
from ._parts.system import FormulationResult, SpringSystem, start_vector, trivial_result

PAGE = "formulations/qp.md"

#: The solver called through its own API, without cvxpy.
DIRECT = "CLARABEL"

#: Tolerance options of each solver, as functions of one tolerance.
TOLERANCE_OPTIONS = {
    "CLARABEL": lambda tol: {"tol_gap_abs": tol, "tol_gap_rel": tol, "tol_feas": tol, "tol_ktratio": tol * 1e-2},
    "OSQP": lambda tol: {"eps_abs": tol, "eps_rel": tol, "polishing": True, "max_iter": 200_000},
    "SCS": lambda tol: {"eps_abs": tol, "eps_rel": tol, "max_iters": 200_000},
    "PIQP": lambda tol: {"eps_abs": tol, "eps_rel": tol, "eps_duality_gap_abs": tol, "eps_duality_gap_rel": tol},
    "ECOS": lambda tol: {"abstol": tol, "reltol": tol, "feastol": tol},
}


@lru_cache(maxsize=1)
def _installed_solvers() -> tuple:
    """Clarabel and the QP solvers cvxpy has installed (asked only when a solver is named
    other than the default: importing cvxpy costs most of a second)."""
    try:
        import cvxpy as cp
    except ImportError:  # pragma: no cover - cvxpy is a core dependency
        return (DIRECT,)
    return tuple(dict.fromkeys((DIRECT, *cp.installed_solvers())))


OPTIONS = (
    Option(
        "solver",
        str,
        DIRECT,
        "CLARABEL (called directly) or a QP solver cvxpy has installed",
        choices=_installed_solvers,
        normalize=str.upper,
    ),
    Option(
        "tol",
        float,
        1e-10,
        "the solver's own tolerances (TOLERANCE_OPTIONS)",
        range=(0, 1),
        tolerance=True,
        build=False,
    ),
    Option(
        "warm_start",
        bool,
        True,
        "cvxpy's warm_start for the solvers called through cvxpy (Clarabel starts "
        "cold; re-solves reuse the factorization's structure either way)",
        build=False,
    ),
)
CAPABILITIES = Capabilities(laws="linear", warm_start=False, duals=True, checks_load_first=True)
EXTRA_OPTIONS = "passed to the QP solver (Clarabel's settings, or through cvxpy's solve)"
VARIANT = Variant("solver")

#: Below this tolerance, Clarabel's insufficient progress is followed by a solve 100 times looser
#: (``_Clarabel.solve``).
RELAXED = 1e-9

#: The solvers' own statuses, as dea-opt's vocabulary (formulations/qp.md, "Statuses"): Clarabel's
#: words when it is called directly, cvxpy's for the others; any other is a solver error.
NATIVE_STATUS = {
    "Solved": Status.CONVERGED,
    "AlmostSolved": Status.INACCURATE,
    "PrimalInfeasible": Status.INFEASIBLE,
    "AlmostPrimalInfeasible": Status.INFEASIBLE,
    "DualInfeasible": Status.UNBOUNDED,
    "AlmostDualInfeasible": Status.UNBOUNDED,
    "MaxIterations": Status.MAX_ITERATIONS,
    "MaxTime": Status.MAX_ITERATIONS,
    "InsufficientProgress": Status.STALLED,
    "NumericalError": Status.SOLVER_ERROR,
    "optimal": Status.CONVERGED,
    "optimal_inaccurate": Status.INACCURATE,
    "infeasible": Status.INFEASIBLE,
    "infeasible_inaccurate": Status.INFEASIBLE,
    "unbounded": Status.UNBOUNDED,
    "unbounded_inaccurate": Status.UNBOUNDED,
    "user_limit": Status.MAX_ITERATIONS,
    "solver_error": Status.SOLVER_ERROR,
}

#: Clarabel's statuses whose iterate is an answer to judge (the others' is a certificate of
#: infeasibility or nothing); cvxpy draws the same line.
_WITH_ITERATE = ("Solved", "AlmostSolved", "MaxIterations", "MaxTime", "InsufficientProgress")
#: Clarabel's statuses whose x is a ray of unbounded decrease (a certificate dea-opt checks).
_UNBOUNDED = ("DualInfeasible", "AlmostDualInfeasible")


def _false_ray(ray, scale, scaled_load) -> str | None:
    """Why Clarabel's ray (k,) is no direction along which ``Phi`` decreases without bound, or None
    where it is one. Such a ray ``xi`` does work against the load (``r . xi > 0``) and compresses
    no spring (``d eps = xi A >= 0``, up to rounding): else the energy of the springs it
    compresses grows as its square (a tiny load's scale, where the gaps are 1e6 strain units,
    fooled Clarabel's tolerances on the knee)."""
    strain = ray @ scale.AT
    size = float(np.abs(strain).max(initial=0.0))
    work = float(scaled_load @ ray)
    if np.isfinite(size) and work > 0 and strain.min(initial=0.0) >= -1e-9 * size:
        return None
    return (
        f"its ray compresses springs (strain change down to {strain.min(initial=0.0) / max(size, 1e-300):.3g} of "
        f"its largest) or does no work ({work:.3g}): no direction the load drives unresisted, a failure of "
        f"its tolerances at this problem's scale (try method='newton')"
    )


def check_extra_options(checked: dict) -> None:
    """The :class:`InputError` a model would raise for ``checked`` (qp's options, validated, the
    solver's among them), raised before any model is built: Clarabel's settings (the default
    solver, called directly) against its ``DefaultSettings``. A solver reached through cvxpy
    checks its own when it solves (cvxpy has no list of them)."""
    known = {option.name for option in OPTIONS}
    extra = {k: v for k, v in checked.items() if k not in known}
    if not extra or checked.get("solver", DIRECT) != DIRECT:
        return
    import clarabel

    _clarabel_settings(clarabel, extra, extra)


def _clarabel_settings(clarabel, values: dict, options: dict):
    """Clarabel's ``DefaultSettings`` with ``values`` set (quiet); a setting it refuses is the
    :class:`InputError` naming the caller's ``options``."""
    settings = clarabel.DefaultSettings()
    settings.verbose = False
    for name, value in values.items():
        try:
            setattr(settings, name, value)
        except (AttributeError, TypeError, ValueError) as exc:
            raise _rejected(DIRECT, options, exc) from None
    return settings


def _rejected(solver: str, options: dict, exc: Exception) -> InputError:
    own = ", ".join(option.name for option in OPTIONS)
    return InputError(
        f"{solver} rejected the options {sorted(options)}: {exc} (dea_opt's own qp options are "
        f"{own}; the rest go to the solver)"
    )


def _contact_rows(AT, s0: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(data, indices, indptr)`` of Clarabel's ``G`` (2N, k + N), CSC with int32 indices, written
    in place in one pass per column: rows 0..N-1 are ``-c_hat`` (``c >= 0``), rows N..2N-1 are
    ``-(M xi + c_hat)`` with ``M = A T / s0``, so that ``s = b - G z`` is ``c_hat`` and
    ``c_hat + M xi + e0 / s0``. Column ``j < k`` (a dof) holds ``-M[:, j]`` in rows N..2N-1, without
    its zeros: a dof a spring does not feel (a face parallel to a translation) is a structural zero,
    which stored would cost Clarabel's KKT fill-in (10 % more time on the box). Column ``k + i`` (a
    spring) holds -1 in rows ``i`` and ``N + i``. Built here rather than by scipy's blocks and
    ``eliminate_zeros``, which copy every entry two or three times around a solve that is all of a
    large problem's time."""
    k, n = AT.shape
    felt = [np.flatnonzero(row) if not row.all() else None for row in AT]
    counts = [n if f is None else f.size for f in felt]
    nnz = sum(counts) + 2 * n
    if nnz >= np.iinfo(np.int32).max:  # pragma: no cover - beyond Clarabel's memory anyway
        raise InputError(f"the QP has {nnz} nonzeros, more than its int32 indices hold")
    data = np.empty(nnz)
    rows = np.empty(nnz, dtype=np.int32)
    indptr = np.empty(k + n + 1, dtype=np.int32)
    indptr[0] = 0
    at = 0
    for j, (row, f, count) in enumerate(zip(AT, felt, counts)):
        if f is None:
            np.divide(row, -s0, out=data[at : at + count])
            rows[at : at + count] = np.arange(n, 2 * n, dtype=np.int32)
        else:
            np.divide(row[f], -s0, out=data[at : at + count])
            np.add(f, n, out=rows[at : at + count], casting="unsafe")
        at += count
        indptr[j + 1] = at
    data[at:] = -1.0
    rows[at::2] = np.arange(n, dtype=np.int32)
    rows[at + 1 :: 2] = np.arange(n, 2 * n, dtype=np.int32)
    indptr[k + 1 :] = at + 2 * np.arange(1, n + 1, dtype=np.int32)
    return data, rows, indptr


class _Clarabel:
    """The minimal QP in Clarabel's own form: ``min 1/2 z'Pz + q'z`` s.t. ``Gz + s = b``,
    ``s >= 0``, with ``z = (xi, c_hat)``; the matrices are built in place as CSC arrays."""

    def __init__(self, scale, e0, modulus: float, tol: float, options: dict):
        try:
            import clarabel
        except ImportError as exc:  # pragma: no cover - clarabel is a core dependency
            raise MissingDependencyError("method 'qp' needs clarabel: pip install clarabel") from exc
        import scipy.sparse as sp

        self.clarabel = clarabel
        k, n, s0 = scale.n_dofs, e0.size, scale.strain_scale
        self.k, self.n = k, n
        self.tol, self.options = tol, options
        self.settings = self._settings(tol)
        self.relaxed: float | None = None  # the looser tolerance the last solve ended at, if any
        # P: diag(0_k, Vs H s0^2), upper triangle, only the c columns stored.
        p_ptr = np.zeros(k + n + 1, dtype=np.int32)
        p_ptr[k + 1 :] = np.arange(1, n + 1, dtype=np.int32)
        self.P = sp.csc_array(
            (scale.volume * modulus * s0**2, np.arange(k, k + n, dtype=np.int32), p_ptr), shape=(k + n, k + n)
        )
        self.G = sp.csc_array(_contact_rows(scale.AT, s0), shape=(2 * n, k + n))
        self.b = np.concatenate([np.zeros(n), e0 / s0])
        self.cones = [clarabel.NonnegativeConeT(2 * n)]
        self.solver = None
        self.ray = np.zeros(k)  # the last DualInfeasible answer's ray

    def _settings(self, tol: float):
        """Clarabel's settings for the tolerance ``tol`` (``TOLERANCE_OPTIONS``) and the caller's options."""
        return _clarabel_settings(self.clarabel, {**TOLERANCE_OPTIONS[DIRECT](tol), **self.options}, self.options)

    def solve(self, scaled_load):
        """``(xi, lambda_hat, native status, iterations, Clarabel's solve_time)``.

        Where Clarabel makes insufficient progress toward a tolerance below ``RELAXED`` (rounding in its
        KKT solves stops it short of 1e-12 on some layers, at an iterate 5 % off), it is solved once
        more to a tolerance 100 times looser, and that answer kept where it is solved (``relaxed``);
        the certificate judges it either way."""
        q = np.concatenate([-scaled_load, np.zeros(self.n)])
        if self.solver is not None and self.solver.is_data_update_allowed():
            self.solver.update(q=q)
        else:
            self.solver = self.clarabel.DefaultSolver(self.P, q, self.G, self.b, self.cones, self.settings)
        out = self.solver.solve()
        native = str(out.status)
        self.relaxed = None
        if native == "InsufficientProgress" and self.tol < RELAXED:
            looser = self.clarabel.DefaultSolver(self.P, q, self.G, self.b, self.cones, self._settings(100 * self.tol))
            second = looser.solve()
            if str(second.status) in ("Solved", "AlmostSolved"):
                iterations = int(out.iterations) + int(second.iterations)
                out, native, self.relaxed = second, str(second.status), 100 * self.tol
                return self._answer(out, native, iterations)
        return self._answer(out, native, int(out.iterations))

    def _answer(self, out, native: str, iterations: int):
        """The iterate of Clarabel's ``out`` (or NaN where it holds none, keeping a ray of unbounded
        decrease to be checked)."""
        if native in _WITH_ITERATE:
            z = np.asarray(out.x, dtype=float)
            xi, lam = z[: self.k], np.asarray(out.z, dtype=float)[self.n :]
        else:
            xi, lam = np.full(self.k, np.nan), np.full(self.n, np.nan)
            if native in _UNBOUNDED:  # its x is the ray along which the energy falls: kept to be checked
                self.ray = np.asarray(out.x, dtype=float)[: self.k]
        return xi, lam, native, iterations, float(out.solve_time)


class _Cvxpy:
    """The same QP modelled in cvxpy, for the solvers other than Clarabel.

    The variable is ``d = w c_hat`` with ``w = sqrt(Vs H) s0``, so the objective is
    ``1/2 sum_squares(d)`` of a variable (cvxpy adds no auxiliary variable or row for it) and
    the contact rows are multiplied by ``w``: their duals are ``lambda_hat / w``.
    """

    def __init__(self, scale, e0, modulus: float, solver: str, tol: float, warm_start: bool, options: dict):
        try:
            import cvxpy as cp
        except ImportError as exc:  # pragma: no cover - cvxpy is a core dependency
            raise MissingDependencyError(f"qp with solver {solver!r} needs cvxpy: pip install cvxpy") from exc
        self.cp, self.solver, self.warm_start = cp, solver, warm_start
        self.options = options
        self.settings = {**TOLERANCE_OPTIONS.get(solver, lambda t: {})(tol), **options}
        k, n, s0 = scale.n_dofs, e0.size, scale.strain_scale
        self.w = np.sqrt(scale.volume * modulus) * s0
        self.xi = cp.Variable(k, name="xi")
        self.d = cp.Variable(n, nonneg=True, name="d")
        self.load = cp.Parameter(k, name="r")
        weighted = np.ascontiguousarray((scale.AT * (self.w / s0)).T)
        self.contact = self.d + weighted @ self.xi >= -self.w * e0 / s0
        self.problem = cp.Problem(cp.Minimize(0.5 * cp.sum_squares(self.d) - self.load @ self.xi), [self.contact])

    def solve(self, scaled_load):
        cp = self.cp
        self.load.value = scaled_load
        try:
            with warnings.catch_warnings():
                # dea_opt certifies every answer itself; cvxpy's own doubt adds nothing.
                warnings.filterwarnings("ignore", message="Solution may be inaccurate")
                self.problem.solve(solver=self.solver, warm_start=self.warm_start, **self.settings)
        except (cp.error.SolverError, TypeError, ValueError, KeyError) as exc:
            # An option the solver does not know is the caller's input (PIQP raises TypeError,
            # SCS a TypeError of its own, OSQP a SolverError naming the setting).
            named = any(str(key) in str(exc) for key in self.options)
            if self.options and (named or not isinstance(exc, cp.error.SolverError)):
                raise _rejected(self.solver, self.options, exc) from None
            raise SolverError(f"{self.solver} failed: {exc}", status=Status.SOLVER_ERROR) from exc
        stats = self.problem.solver_stats
        xi, dual = self.xi.value, self.contact.dual_value
        n = self.w.size
        if xi is None or dual is None:
            xi, lam = np.full(self.load.size, np.nan), np.full(n, np.nan)
        else:
            xi, lam = np.asarray(xi, dtype=float).reshape(-1), np.asarray(dual, dtype=float).reshape(n) * self.w
        solver_time = stats.solve_time if stats and stats.solve_time is not None else float("nan")
        return xi, lam, str(self.problem.status), int(stats.num_iters or 0) if stats else 0, solver_time


class QPModel:
    """A QP of one spring system, built once and re-solvable for new loads.

    Parameters
    ----------
    system : SpringSystem
    law : LinearLaw
    **options
        :data:`OPTIONS` (``solver``, default ``"CLARABEL"``, called through its own API;
        ``tol``, default 1e-10; ``warm_start``, cvxpy's); any other option goes to the solver
        (an unknown Clarabel setting is an :class:`InputError` when the model is built).
    """

    def __init__(self, system: SpringSystem, law, **options):
        known = {option.name for option in OPTIONS}
        checked = validate("qp", OPTIONS, options, EXTRA_OPTIONS)
        self.solver_options = {k: v for k, v in checked.items() if k not in known}
        self.tol, self.warm_start = checked["tol"], checked["warm_start"]
        if not CAPABILITIES.takes(law):
            raise InputError(f"method 'qp' needs a LinearLaw, got {law.describe()}: use another method for this law")
        start = time.perf_counter()
        self._options = dict(options)
        self.solver = checked["solver"]
        self.system, self.law = system, law
        # Solved in the scaled variables xi (u_free = T xi) and c = s0 c_hat, so that the
        # solver's absolute tolerances mean the same for every unit and load size.
        self.scale = sc = scaling(system, law.H)
        self.trivial = sc.n_dofs == 0  # nothing resisted: no model (a solver must not see an empty one)
        self.compiled = False
        self.backend: _Clarabel | _Cvxpy | None = None
        if not self.trivial:
            require_finite("the QP's data", sc.volume, sc.AT, system.e0)
            if self.solver == DIRECT:
                self.backend = _Clarabel(sc, system.e0, law.H, self.tol, self.solver_options)
            else:
                self.backend = _Cvxpy(sc, system.e0, law.H, self.solver, self.tol, self.warm_start, self.solver_options)
        self.build_time = time.perf_counter() - start

    def solve(self, load=None, *, x0=None) -> FormulationResult:
        """Solve for ``load`` (default: the system's own load); ``x0`` is checked and then
        ignored: interior-point solvers start cold.

        Where the answer's own scale (the load, the springs' compression there) is below ``RECENTRE``
        of the scale the QP was solved in (an overlap that opened under a smaller load), the QP is
        solved again from that answer in its scale (:func:`~dea_opt.formulations._parts.recentre.recentred_solve`),
        so that its tolerances are the answer's."""
        start_vector(self.system, x0)
        load = self.system.load if load is None else np.asarray(load, dtype=float)
        trivial = trivial_result(self.system, self.law, load)
        if trivial is not None:
            return trivial
        first = self._solve_once(load)
        return recentred_solve(
            first,
            self.system.with_load(load),
            self.law,
            np.sqrt(self.scale.energy_scale),
            lambda system: QPModel(system, self.law, **self._options),
        )

    def _solve_once(self, load) -> FormulationResult:
        scaled = self.scale.load(load)
        require_finite("the load", scaled)
        start = time.perf_counter()
        try:
            assert self.backend is not None  # a system with resisted dofs has one
            xi, lam, native, iterations, solver_time = self.backend.solve(scaled)
        except (InputError, SolverError, KeyboardInterrupt, SystemExit):
            raise
        except BaseException as exc:
            # A solver's own failure, whatever its type: a panic in Clarabel's Rust arrives as
            # pyo3's PanicException, which derives from BaseException.
            raise SolverError(f"{self.solver} failed: {exc}", status=Status.SOLVER_ERROR) from exc
        elapsed = time.perf_counter() - start
        first, self.compiled = not self.compiled, True
        n = self.system.n_springs
        # lambda_hat = Vs H s0^2 c_hat = Vs H s0 c, so sigma = -H c = -lambda_hat / (Vs s0)
        stress = -lam / (self.scale.volume * self.scale.strain_scale)
        status = NATIVE_STATUS.get(native, Status.SOLVER_ERROR)
        message = f"{self.solver}: {native}"
        relaxed = getattr(self.backend, "relaxed", None)
        if relaxed is not None:
            message = f"{self.solver}: InsufficientProgress at tol={self.tol:g}, then {native} at tol={relaxed:g}"
        if native in _UNBOUNDED and isinstance(self.backend, _Clarabel):
            why = _false_ray(self.backend.ray, self.scale, scaled)
            if why is not None:
                status, message = Status.INACCURATE, f"{message}, but {why}"
        return FormulationResult(
            u_free=self.scale.to_u_free(xi).reshape(-1),
            stress=stress.reshape(n),
            success=status is Status.CONVERGED,
            status=status,
            message=message,
            iterations=iterations,
            build_time=self.build_time if first else 0.0,
            solve_time=elapsed,
            info={
                "native_status": native,
                "solver": self.solver,
                "solver_time": solver_time,
                "compile_and_solve": first,
            },
        )


Model = QPModel


def solve(system: SpringSystem, law, *, x0=None, **options) -> FormulationResult:
    """Build and solve the QP once (``x0`` is ignored: interior-point solvers start cold)."""
    return QPModel(system, law, **options).solve(x0=x0)
