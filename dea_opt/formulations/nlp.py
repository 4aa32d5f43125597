"""The DEA problem for any law as a nonlinear program, built in CasADi, solved by IPOPT.

Written math: ``formulations/nlp.md``.

* ``form="constrained"`` (default): variables ``x`` (``u_free`` in the code) and compressive
  strain ``c``;
  ``min sum V_i w(-c_i) - r . x`` s.t. ``c >= 0``, ``c + e0 + A x >= 0`` and, for laws
  defined only for ``eps > -1``, ``c <= 1 - margin``. Spring stress from the duals.
* ``form="reduced"``: ``min_x sum V_i w(min(e0 + A x, 0)) - r . x`` with no constraints
  (the energy is C1); spring stress from the law at the optimum.

Both are built with vectorized MX (``A @ x`` is one node), without ``expand``. The constrained
form's first solve starts from Newton's answer (``_parts/nlp_start.py``; nlp.md, "Start from
Newton's answer").
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from ..errors import InputError, MissingDependencyError, SolverError
from ..status import Status
from ._parts.nlp_start import WARM_OPTIONS, newton_start
from ._parts.options import Capabilities, Option, Variant, validate
from ._parts.recentre import recentred_solve
from ._parts.resistance import require_finite
from ._parts.scaling import scaling
from ._parts.system import FormulationResult, SpringSystem, start_vector, trivial_result

PAGE = "formulations/nlp.md"

_CRUSH_MARGIN = 1e-9

OPTIONS = (
    Option(
        "form",
        str,
        "constrained",
        "'constrained': contact constraints and duals; 'reduced': the free dofs only",
        choices=("constrained", "reduced"),
    ),
    Option("tol", float, 1e-14, "IPOPT's tol", range=(0, 1), tolerance=True),
    Option("max_iter", int, 3000, "IPOPT's iteration limit", range=(1, None)),
    Option("ipopt_options", dict, None, "IPOPT option names to values"),
)
CAPABILITIES = Capabilities(laws="any", warm_start=True, duals=True, checks_load_first=True)
EXTRA_OPTIONS = None
VARIANT = Variant("form", {"constrained": "IPOPT", "reduced": "IPOPT-reduced"})

#: IPOPT's return statuses, as dea-opt's vocabulary (formulations/nlp.md, "Statuses"); any
#: other is a solver error.
NATIVE_STATUS = {
    "Solve_Succeeded": Status.CONVERGED,
    "Solved_To_Acceptable_Level": Status.INACCURATE,
    "Feasible_Point_Found": Status.INACCURATE,
    "Maximum_Iterations_Exceeded": Status.MAX_ITERATIONS,
    "Maximum_CpuTime_Exceeded": Status.MAX_ITERATIONS,
    "Maximum_WallTime_Exceeded": Status.MAX_ITERATIONS,
    "Restoration_Failed": Status.LINE_SEARCH_FAILED,
    "Search_Direction_Becomes_Too_Small": Status.STALLED,
    "Infeasible_Problem_Detected": Status.INFEASIBLE,
    "Diverging_Iterates": Status.UNBOUNDED,
    "Invalid_Number_Detected": Status.NON_FINITE,
}


def _casadi():
    try:
        import casadi
    except ImportError as exc:  # pragma: no cover - casadi is a core dependency
        raise MissingDependencyError("method 'nlp' needs casadi: pip install casadi") from exc
    return casadi


def ipopt_solver(name: str, nlp: dict, tol: float, max_iter: int, ipopt_options: dict | None = None):
    """CasADi's IPOPT solver of ``nlp`` with dea-opt's settings (quiet, adaptive barrier, no bound
    relaxation), ``ipopt_options`` on top; options IPOPT rejects are an :class:`InputError`."""
    ca = _casadi()
    options = {
        "print_time": False,
        "error_on_fail": False,
        # IPOPT answers an evaluation outside a law's domain by cutting its step; the
        # NaN that triggered it is expected, not news.
        "show_eval_warnings": False,
        "ipopt": {
            "print_level": 0,
            "sb": "yes",
            "tol": tol,
            "max_iter": max_iter,
            "mu_strategy": "adaptive",
            "bound_relax_factor": 0.0,
            **(ipopt_options or {}),
        },
    }
    try:
        return ca.nlpsol(name, "ipopt", nlp, options)
    except RuntimeError as exc:
        # IPOPT checks its options when the solver is built: an unknown name or a value
        # out of range is the caller's input, not a solver failure.
        reason = str(exc).strip().splitlines()[-1].split(": ", 1)[-1]
        raise InputError(f"ipopt_options {ipopt_options or {}} were rejected by IPOPT: {reason}") from None


class NLPModel:
    """A compiled IPOPT problem of one spring system, re-solvable for new loads.

    Parameters
    ----------
    system : SpringSystem
    law : Law
    **options
        :data:`OPTIONS`: ``form`` (``"constrained"`` or ``"reduced"``), ``tol`` (1e-14),
        ``max_iter`` (3000), ``ipopt_options`` (IPOPT checks them when the model is built).
    """

    def __init__(self, system: SpringSystem, law, **options):
        checked = validate("nlp", OPTIONS, options)
        form, tol, max_iter, ipopt_options = (checked[k] for k in ("form", "tol", "max_iter", "ipopt_options"))
        ca = _casadi()
        start = time.perf_counter()
        self._options = dict(options)
        self.system, self.law, self.form = system, law, form
        # Solved in the scaled variables xi (u_free = T xi) and c = s0 c_hat, with the
        # energy divided by E0: IPOPT's tolerances then mean the same for every unit.
        self.scale = sc = scaling(system, law.modulus)
        k, n, s0 = sc.n_dofs, system.n_springs, sc.strain_scale
        self._warm: dict[str, Any] | None = None
        self._solved = False
        self._cold = None
        self.trivial = k == 0  # nothing resisted: no model (IPOPT must not see an empty one)
        if self.trivial:
            self.build_time = time.perf_counter() - start
            return
        require_finite("the NLP's data", sc.AT, sc.volume, system.e0)
        V = ca.DM(sc.volume)
        e0 = system.e0
        r = ca.MX.sym("r", k)
        if form == "constrained":
            # Each block of about sqrt(N) springs sees its own copy of the dofs, tied to the
            # first block's copy (which is xi) by equalities: the KKT matrix then has no row as
            # long as N, which MUMPS's ordering handles badly (formulations/nlp.md, "Block copies").
            size = max(int(np.ceil(np.sqrt(n))), 1)
            self.n_blocks = nb = max(int(np.ceil(n / size)), 1)
            self._block = block = np.arange(n) // size
            select = ca.DM(ca.Sparsity.triplet(nb, n, block.tolist(), list(range(n))), 1.0)
            copies = ca.MX.sym("xi_blocks", k, nb)
            xi = copies[:, 0]
            c = ca.MX.sym("c_hat", n)
            z = ca.vertcat(ca.vec(copies), c)
            stored = ca.dot(V, law.energy(-s0 * c))
            contact = c + ca.sum1(ca.DM(sc.AT / s0) * ca.mtimes(copies, select)).T
            tie = ca.vec(copies[:, 1:] - ca.repmat(xi, 1, nb - 1))
            g = ca.vertcat(contact, tie)
            self.lbg = np.concatenate([-e0 / s0, np.zeros(k * (nb - 1))])
            self.ubg = np.concatenate([np.full(n, np.inf), np.zeros(k * (nb - 1))])
            self._upper = upper = (1.0 - _CRUSH_MARGIN) / s0 if law.bounded_strain else np.inf
            self.lbx = np.concatenate([np.full(k * nb, -np.inf), np.zeros(n)])
            self.ubx = np.concatenate([np.full(k * nb, np.inf), np.full(n, upper)])
            nlp = {"x": z, "p": r, "f": stored - ca.dot(r, xi), "g": g}
        else:
            xi = ca.MX.sym("xi", k)
            eps = ca.DM(e0) + ca.mtimes(ca.DM(sc.AT.T), xi)
            stored = ca.dot(V, law.energy(ca.fmin(eps, 0)))
            self.lbg = self.ubg = np.zeros(0)
            self.lbx, self.ubx = np.full(k, -np.inf), np.full(k, np.inf)
            nlp = {"x": xi, "p": r, "f": stored - ca.dot(r, xi)}
        self._nlp, self._tol, self._max_iter = nlp, tol, max_iter
        # AMD ordering: the dense dof columns of A make MUMPS's default ordering slow.
        self._ipopt_options = {"mumps_pivot_order": 0, **(ipopt_options or {})}
        if form == "constrained":
            # The first solve starts from Newton's answer (``_parts/nlp_start.py``), with IPOPT's
            # options of a warm start; IPOPT checks the caller's options here, when the model is built.
            self.solver = ipopt_solver("dea_nlp_warm", nlp, tol, max_iter, {**WARM_OPTIONS, **self._ipopt_options})
        else:
            self.solver = self._cold = ipopt_solver("dea_nlp", nlp, tol, max_iter, self._ipopt_options)
        self.build_time = time.perf_counter() - start

    def _cold_solver(self):
        """CasADi's IPOPT solver of a cold start (from ``x0``, or from this model's last answer),
        built on first use."""
        if self._cold is None:
            self._cold = ipopt_solver("dea_nlp", self._nlp, self._tol, self._max_iter, self._ipopt_options)
        return self._cold

    def _start(self, x0):
        sc = self.scale
        xi0 = np.zeros(sc.n_dofs) if x0 is None else sc.to_xi(x0)
        if self.form == "reduced":
            return xi0
        c0 = np.maximum(-(self.system.e0 + xi0 @ sc.AT), 0.0)
        if self.law.bounded_strain:
            c0 = np.minimum(c0, 0.5)
        return np.concatenate([np.tile(xi0, self.n_blocks), c0 / sc.strain_scale])

    def solve(self, load=None, *, x0=None, warm_start: bool = True) -> FormulationResult:
        """Solve for ``load`` (default: the system's own) from ``x0`` or, without one (and with
        ``warm_start``), from this model's last answer, duals included.

        Where the answer's own scale (the load, the springs' compression there) is below ``RECENTRE``
        of the scale IPOPT solved in (an overlap that opened under a smaller load), the problem is
        solved again from that answer in its scale (:func:`~dea_opt.formulations._parts.recentre.recentred_solve`),
        so that IPOPT's tolerances are the answer's."""
        x0 = start_vector(self.system, x0)
        load = self.system.load if load is None else np.asarray(load, dtype=float)
        trivial = trivial_result(self.system, self.law, load)
        if trivial is not None:
            return trivial
        first = self._solve_once(load, x0, warm_start)
        return recentred_solve(
            first,
            self.system.with_load(load),
            self.law,
            np.sqrt(self.scale.energy_scale),
            lambda system: NLPModel(system, self.law, **self._options),
        )

    def _solve_once(self, load, x0, warm_start: bool) -> FormulationResult:
        system, sc = self.system, self.scale
        scaled = sc.load(load)
        require_finite("the load", scaled)
        args = {"p": scaled, "lbx": self.lbx, "ubx": self.ubx, "lbg": self.lbg, "ubg": self.ubg}
        start = time.perf_counter()
        newton = None
        if x0 is None and self.form == "constrained" and not (warm_start and self._warm is not None):
            newton = newton_start(system, self.law, load, self._start, sc, self._block, self.n_blocks, self._upper)
        if newton is not None:
            solved = self._solved
            found = self._ipopt(self.solver, {**args, **newton}, start, "Newton's answer")
            if found.success:
                return found
            # IPOPT did not settle from there: the cold start decides, as without one.
            self._solved, self._warm, start = solved, None, time.perf_counter()
        if x0 is None and warm_start and self._warm is not None:
            args.update(self._warm)
        else:
            args["x0"] = self._start(x0)
        return self._ipopt(self._cold_solver(), args, start, "cold")

    def _ipopt(self, solver, args: dict, start: float, began: str) -> FormulationResult:
        """IPOPT's answer by ``solver`` from ``args`` (begun at ``start``, from ``began``) as a
        :class:`FormulationResult`; this model's last answer (its warm start) becomes it."""
        system, sc = self.system, self.scale
        try:
            out = solver(**args)
        except RuntimeError as exc:
            raise SolverError(f"IPOPT raised: {exc}", status=Status.SOLVER_ERROR, native_status="exception") from exc
        elapsed = time.perf_counter() - start
        stats = solver.stats()
        z = np.asarray(out["x"], dtype=float).reshape(-1)
        u_free = sc.to_u_free(z[: sc.n_dofs])
        if self.form == "constrained":
            # d/dc_hat of V' w(-s0 c_hat) is -V' s0 sigma; CasADi's lam_g balances it.
            lam = np.asarray(out["lam_g"], dtype=float).reshape(-1)[: system.n_springs]
            stress = lam / (sc.volume * sc.strain_scale)
            self._warm = {"x0": z, "lam_x0": out["lam_x"], "lam_g0": out["lam_g"]}
        else:
            stress = self.law.stress(np.minimum(system.strain_at(u_free), 0.0))
            self._warm = {"x0": z}
        native = str(stats.get("return_status", "unknown"))
        success = bool(stats.get("success", False))
        status, message = NATIVE_STATUS.get(native, Status.SOLVER_ERROR), f"IPOPT ({self.form}): {native}"
        first, self._solved = not self._solved, True
        return FormulationResult(
            u_free=u_free,
            stress=np.asarray(stress, dtype=float),
            success=success,
            status=status,
            message=message,
            iterations=int(stats.get("iter_count", 0)),
            build_time=self.build_time if first else 0.0,
            solve_time=elapsed,
            info={"native_status": native, "form": self.form, "start": began},
        )


Model = NLPModel


def solve(system: SpringSystem, law, *, x0=None, **options) -> FormulationResult:
    """Build and solve the NLP once (options: :data:`OPTIONS`)."""
    return NLPModel(system, law, **options).solve(x0=x0)
