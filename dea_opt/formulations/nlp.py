"""The DEA problem for any law as a nonlinear program, built in CasADi, solved by IPOPT.

Written math: ``formulations/nlp.md``.

* ``form="constrained"`` (default): variables ``x`` and compressive strain ``c``;
  ``min sum V_i w(-c_i) - r . x`` s.t. ``c >= 0``, ``c + e0 + A x >= 0`` and, for laws
  defined only for ``eps > -1``, ``c <= 1 - margin``. Spring stress from the duals.
* ``form="reduced"``: ``min_x sum V_i w(min(e0 + A x, 0)) - r . x`` with no constraints
  (the energy is C1); spring stress from the law at the optimum.

Both are built with vectorized MX (``A @ x`` is one node), without ``expand``.
"""

from __future__ import annotations

import time

import numpy as np

from ..errors import InputError, MissingDependencyError, SolverError
from .base import FormulationResult, SpringSystem

PAGE = "formulations/nlp.md"
LINEAR_ONLY = False

_CRUSH_MARGIN = 1e-9


def _casadi():
    try:
        import casadi
    except ImportError as exc:  # pragma: no cover - casadi is a core dependency
        raise MissingDependencyError("method 'nlp' needs casadi: pip install casadi") from exc
    return casadi


class NLPModel:
    """A compiled IPOPT problem of one spring system, re-solvable for new loads."""

    def __init__(self, system: SpringSystem, law, *, form: str = "constrained", tol: float = 1e-12,
                 max_iter: int = 3000, ipopt_options: dict | None = None):
        if form not in ("constrained", "reduced"):
            raise InputError(f"form must be 'constrained' or 'reduced', got {form!r}")
        ca = _casadi()
        start = time.perf_counter()
        self.system, self.law, self.form = system, law, form
        m, n = system.n_dofs, system.n_springs
        V = ca.DM(system.volume)
        e0 = system.e0
        r = ca.MX.sym("r", m)
        x = ca.MX.sym("x", m)
        if form == "constrained":
            # Each block of about sqrt(N) springs sees its own copy of x, tied to x by
            # equalities: the KKT matrix then has no row as long as N, which MUMPS's ordering
            # handles badly (formulations/nlp.md, "Block copies").
            size = max(int(np.ceil(np.sqrt(n))), 1)
            self.n_blocks = nb = max(int(np.ceil(n / size)), 1)
            block = np.arange(n) // size
            select = ca.DM(ca.Sparsity.triplet(nb, n, block.tolist(), list(range(n))), 1.0)
            copies = ca.MX.sym("x_blocks", m, nb)
            c = ca.MX.sym("c", n)
            z = ca.vertcat(x, ca.vec(copies), c)
            energy = ca.dot(V, law.energy(-c))
            contact = c + ca.sum1(ca.DM(system.AT) * ca.mtimes(copies, select)).T
            tie = ca.vec(copies - ca.repmat(x, 1, nb))
            g = ca.vertcat(contact, tie)
            self.lbg = np.concatenate([-e0, np.zeros(m * nb)])
            self.ubg = np.concatenate([np.full(n, np.inf), np.zeros(m * nb)])
            upper = 1.0 - _CRUSH_MARGIN if law.bounded_strain else np.inf
            self.lbx = np.concatenate([np.full(m * (nb + 1), -np.inf), np.zeros(n)])
            self.ubx = np.concatenate([np.full(m * (nb + 1), np.inf), np.full(n, upper)])
            nlp = {"x": z, "p": r, "f": energy - ca.dot(r, x), "g": g}
        else:
            eps = ca.DM(e0) + ca.mtimes(ca.DM(system.A), x)
            energy = ca.dot(V, law.energy(ca.fmin(eps, 0)))
            self.lbg = self.ubg = np.zeros(0)
            self.lbx, self.ubx = np.full(m, -np.inf), np.full(m, np.inf)
            nlp = {"x": x, "p": r, "f": energy - ca.dot(r, x)}
        options = {
            "print_time": False,
            "error_on_fail": False,
            "ipopt": {
                "print_level": 0,
                "sb": "yes",
                "tol": tol,
                "max_iter": max_iter,
                "mu_strategy": "adaptive",
                "bound_relax_factor": 0.0,
                # AMD ordering: the dense dof columns of A make MUMPS's default ordering slow.
                "mumps_pivot_order": 0,
                **(ipopt_options or {}),
            },
        }
        self.solver = ca.nlpsol("dea_nlp", "ipopt", nlp, options)
        self.build_time = time.perf_counter() - start
        self._warm = None

    def _start(self, x0):
        system = self.system
        m = system.n_dofs
        x0 = np.zeros(m) if x0 is None else np.asarray(x0, dtype=float)
        if self.form == "reduced":
            return x0
        c0 = np.maximum(-system.strain(x0), 0.0)
        if self.law.bounded_strain:
            c0 = np.minimum(c0, 0.5)
        return np.concatenate([x0, np.tile(x0, self.n_blocks), c0])

    def solve(self, load=None, *, x0=None, warm_start: bool = True) -> FormulationResult:
        system = self.system
        m = system.n_dofs
        load = system.load if load is None else np.asarray(load, dtype=float)
        args = {"p": load, "lbx": self.lbx, "ubx": self.ubx, "lbg": self.lbg, "ubg": self.ubg}
        if x0 is None and warm_start and self._warm is not None:
            args.update(self._warm)
        else:
            args["x0"] = self._start(x0)
        start = time.perf_counter()
        try:
            out = self.solver(**args)
        except RuntimeError as exc:
            raise SolverError(f"IPOPT raised: {exc}", status="exception") from exc
        elapsed = time.perf_counter() - start
        stats = self.solver.stats()
        z = np.asarray(out["x"], dtype=float).reshape(-1)
        x = z[:m]
        if self.form == "constrained":
            stress = np.asarray(out["lam_g"], dtype=float).reshape(-1)[: system.n_springs] / system.volume
            self._warm = {"x0": z, "lam_x0": out["lam_x"], "lam_g0": out["lam_g"]}
        else:
            stress = self.law.stress(np.minimum(system.strain(x), 0.0))
            self._warm = {"x0": z}
        status = str(stats.get("return_status", "unknown"))
        return FormulationResult(
            x=x,
            stress=np.asarray(stress, dtype=float),
            success=bool(stats.get("success", False)),
            status=status,
            message=f"IPOPT ({self.form}): {status}",
            iterations=int(stats.get("iter_count", 0)),
            build_time=self.build_time,
            solve_time=elapsed,
            info={"form": self.form},
        )


def solve(system: SpringSystem, law, *, form: str = "constrained", tol: float = 1e-12, x0=None,
          max_iter: int = 3000, ipopt_options: dict | None = None) -> FormulationResult:
    """Build and solve the NLP once."""
    model = NLPModel(system, law, form=form, tol=tol, max_iter=max_iter, ipopt_options=ipopt_options)
    return model.solve(x0=x0)
