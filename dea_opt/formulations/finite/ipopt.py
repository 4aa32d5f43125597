"""Finite kinematics by IPOPT: the solver behind the formulation ``"finite_nlp"``, built in CasADi.

Written math: ``formulations/finite_nlp.md`` (the registry's entry is
:mod:`~dea_opt.formulations.finite.nlp`). An independent cross-check of the finite Newton
(:mod:`~dea_opt.formulations.finite.newton`): :func:`solve` takes the same
:class:`~dea_opt.formulations.finite.system.FiniteSystem` and scaled directions ``T`` (m, k) and
returns the same :class:`~dea_opt.formulations.finite.newton.InnerResult`.

The springs push along their own directions, and the moment on body 2 is constant in space:
neither is the gradient of an energy of the pose, so IPOPT minimises, at each outer iteration
``k``, a conservative surrogate re-centred at the current iterate ``x_k`` (m,; mm, rad):

    Phi_k(x) = sum_i V_i w(min(sh_i(x) / h_i, 0)) - r_k . (x - x_k)
    sh_i(x) = s_i(x) + (g_i - grad s_i(x_k)) . (x - x_k)

with ``s_i`` the exact gap (CasADi: the rotation of the rotation vector as a polynomial exact to
rounding up to 120 degrees, the tangent plane or sphere of each target), ``g_i`` the direction
spring ``i`` pushes along on the free coordinates and ``r_k`` the load on them at ``x_k``. The
gradient of ``Phi_k`` at ``x_k`` is the physical residual, so ``x_k`` is the minimiser exactly
when it is an equilibrium; ``x_{k+1} = argmin Phi_k`` contracts to it. Springs are constrained to
compression as in :mod:`~dea_opt.formulations.nlp` (``form="constrained"``: their forces are the
multipliers) or enter through ``min(eps, 0)`` (``form="reduced"``). Nothing is shared with the
Newton but the targets and the law.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ...errors import InputError
from ..nlp import _casadi, ipopt_solver
from .geometry import FACING
from .newton import InnerResult
from .system import generalized

__all__ = ["ROTATION_RANGE", "solve"]

_TERMS = 16  # Taylor terms of the rotation's coefficients: exact to rounding below 120 degrees
_CRUSH_MARGIN = 1e-9
_OPEN = 1e6  # mm: the gap of a spring whose ray misses its target (open, as in the Newton's inf)
#: Largest scaled step of one outer iteration: the surrogate may be unbounded where springs are
#: open (a sphere passing through the bed), so each solve stays in a box and the next re-centres.
_STEP_BOUND = 4.0
#: IPOPT's statuses that still give a usable centre for the next outer iteration: the residual
#: test of the fixed point, and the certificate, judge the end.
_ACCEPTABLE = ("Solved_To_Acceptable_Level", "Search_Direction_Becomes_Too_Small")
#: IPOPT's statuses of a limit reached (its iterations or time): the solve ran out, it did not fail.
_LIMITS = ("Maximum_Iterations_Exceeded", "Maximum_CpuTime_Exceeded", "Maximum_WallTime_Exceeded")
#: The largest turn (rad) of body 2 the surrogate's rotation is exact for (its Taylor terms): an
#: outer iterate beyond it ends the solve, and no accelerated centre may lie beyond it.
ROTATION_RANGE = 2.0 * math.pi / 3.0
#: An accelerated centre replaces the plain map's only where its residual is lower by this factor:
#: a tie decided by the last digit of two sums would make the iterates hinge on a CPU's rounding.
_BETTER = 1.0 - 1e-9


def _series(ca, tau, first):
    """``sum_k (-tau)^k / (2k + first)!``: ``sin t / t`` (first=1), ``(1 - cos t) / t^2`` (2)."""
    total, term = 0, 1.0 / math.factorial(first)
    power = 1
    for k in range(_TERMS):
        total = total + term * power
        power = power * (-tau)
        term = term * math.factorial(2 * k + first) / math.factorial(2 * k + 2 + first)
    return total


def _rotation(ca, theta):
    tau = ca.dot(theta, theta)
    W = ca.skew(theta)
    return ca.DM.eye(3) + _series(ca, tau, 1) * W + _series(ca, tau, 2) * ca.mtimes(W, W)


class _Surrogate:
    """The CasADi model of ``Phi_k`` for one system, re-solved for each outer iteration."""

    def __init__(self, system, law, T, energy_scale, form, tol, max_iter, ipopt_options, max_time=None):
        ca = _casadi()
        self.system, self.law, self.T, self.E0, self.form = system, law, T, energy_scale, form
        m, k = T.shape
        n = len(system)
        self.k, self.n = k, n
        xi = ca.MX.sym("xi", k)
        base = ca.MX.sym("x_k", m)  # the free coordinates at the centre
        correction = ca.MX.sym("C", n, k)  # (g_i - grad s_i(x_k)) T, per spring
        load = ca.MX.sym("r", k)  # T^T r_k / E0
        x = base + ca.mtimes(ca.DM(T), xi)
        y = ca.vertcat(
            *[x[list(system.free).index(j)] if j in system.free else float(system.base[j]) for j in range(6)]
        )
        s = self._gaps(ca, y) + ca.mtimes(correction, xi)
        eps = s / ca.DM(system.thickness)
        V = ca.DM(system.areas * system.thickness / energy_scale)
        self.strain_scale = s0 = max(
            float(np.sqrt(energy_scale / np.sum(system.areas * system.thickness * law.modulus))), 1e-12
        )
        params = ca.vertcat(base, ca.vec(correction), load)
        if form == "constrained":
            c = ca.MX.sym("c", n)
            z = ca.vertcat(xi, c)
            energy = ca.dot(V, law.energy(-s0 * c))
            g = c + eps / s0
            upper = (1.0 - _CRUSH_MARGIN) / s0 if law.bounded_strain else np.inf
            self.lbx = np.concatenate([np.full(k, -_STEP_BOUND), np.zeros(n)])
            self.ubx = np.concatenate([np.full(k, _STEP_BOUND), np.full(n, upper)])
            self.lbg, self.ubg = np.zeros(n), np.full(n, np.inf)
            nlp = {"x": z, "p": params, "f": energy - ca.dot(load, xi), "g": g}
        else:
            energy = ca.dot(V, law.energy(ca.fmin(eps, 0)))
            self.lbx, self.ubx = np.full(k, -_STEP_BOUND), np.full(k, _STEP_BOUND)
            self.lbg = self.ubg = np.zeros(0)
            nlp = {"x": xi, "p": params, "f": energy - ca.dot(load, xi)}
        limit = {} if max_time is None else {"max_wall_time": float(max_time)}
        self.solver = ipopt_solver("dea_finite_nlp", nlp, tol, max_iter, {**limit, **(ipopt_options or {})})
        self.gap_jacobian = ca.Function("gap_jacobian", [xi, base], [ca.jacobian(self._gaps(ca, y), xi)])
        self._warm = None

    def _gaps(self, ca, y):
        """The exact gaps ``s_i(y)`` (N,): each ray to its target moved by the pose."""
        system = self.system
        targets = system.targets
        c = ca.DM(system.reference)
        R = _rotation(ca, y[3:6])
        frame = targets.frame
        p = ca.DM(system.points)
        nrm = ca.DM(system.normals)
        plane = targets.is_plane
        q0 = targets.points @ frame[:3, :3].T + frame[:3, 3]  # body 2's targets at zero displacement
        out = []
        centre = c + y[0:3]
        if plane.any():
            rows = np.flatnonzero(plane)
            m0 = targets.normals[rows] @ frame[:3, :3].T
            mq = ca.mtimes(ca.DM(m0), R.T)  # (n, 3) moved normals
            moved = ca.repmat(centre.T, len(rows), 1) + ca.mtimes(ca.DM(q0[rows]) - ca.repmat(c.T, len(rows), 1), R.T)
            ahead = ca.sum2((moved - p[rows, :]) * mq)
            along = ca.sum2(nrm[rows, :] * mq)
            facing = along < -FACING
            out.append((rows, ca.if_else(facing, ahead / ca.if_else(facing, along, -1), _OPEN)))
        if (~plane).any():
            rows = np.flatnonzero(~plane)
            o = ca.repmat(centre.T, len(rows), 1) + ca.mtimes(ca.DM(q0[rows]) - ca.repmat(c.T, len(rows), 1), R.T)
            d = p[rows, :] - o
            beta = ca.sum2(nrm[rows, :] * d)
            gamma = ca.sum2(d * d) - ca.DM(targets.radius[rows] ** 2)
            rho = ca.DM(targets.radius[rows])
            disc = beta**2 - gamma
            meets = disc > (FACING * rho) ** 2
            root = ca.sqrt(ca.if_else(meets, disc, 1))
            near = ca.if_else(beta <= 0, gamma / (root - beta), -beta - root)
            far = ca.if_else(beta >= 0, -gamma / (beta + root), root - beta)
            concave = ca.DM(targets.concave[rows].astype(float))
            behind = (1 - concave) * (gamma > 0) * (beta > 0)
            gap = concave * far + (1 - concave) * near
            out.append((rows, ca.if_else(meets * (1 - behind), gap, _OPEN)))
        if len(out) == 1:
            return out[0][1]
        order = np.argsort(np.concatenate([r for r, _ in out]))
        stacked = ca.vertcat(*[e for _, e in out])
        return stacked[order.tolist()]

    def solve(self, x_k, state):
        """One IPOPT solve of ``Phi_k`` centred at ``x_k`` (``state`` the springs there):
        ``(x_{k+1}, stress, stats)``."""
        T, E0, k = self.T, self.E0, self.k
        grad_s = np.asarray(self.gap_jacobian(np.zeros(k), x_k), dtype=float)  # (N, k), by CasADi's AD
        push = generalized(state)[self.system.free].T @ T  # (N, k): the direction each spring pushes along
        correction = push - grad_s
        load = T.T @ state.load6[self.system.free] / E0
        params = np.concatenate([x_k, correction.T.reshape(-1), load])
        args = {"p": params, "lbx": self.lbx, "ubx": self.ubx, "lbg": self.lbg, "ubg": self.ubg}
        if self.form == "constrained":
            c0 = np.maximum(-state.eps, 0.0)
            c0 = np.where(np.isfinite(c0), c0, 0.0)
            if self.law.bounded_strain:
                c0 = np.minimum(c0, 0.5)
            args["x0"] = np.concatenate([np.zeros(k), c0 / self.strain_scale])
        else:
            args["x0"] = np.zeros(k)
        out = self.solver(**args)
        stats = self.solver.stats()
        z = np.asarray(out["x"], dtype=float).reshape(-1)
        stress = None
        if self.form == "constrained":
            lam = np.asarray(out["lam_g"], dtype=float).reshape(-1)
            volume = self.system.areas * self.system.thickness / E0
            stress = lam / (volume * self.strain_scale)
        return x_k + T @ z[:k], z[:k], stress, stats


def _turn(system, x) -> float:
    """The turn (rad) of body 2 at the free coordinates ``x``."""
    return float(np.linalg.norm(system.coordinates(x)[3:6]))


def _scaled_residual(state, T, energy_scale) -> float:
    """The physical residual in the scaled variables, relative to the load and the springs' force."""
    free = state.system.free
    g = T.T @ state.residual() / energy_scale
    norm = max(
        float(np.linalg.norm(T.T @ state.load6[free])) / energy_scale,
        float(np.linalg.norm(T.T @ state.internal6[free])) / energy_scale,
        1.0,
    )
    value = float(np.linalg.norm(g)) / norm
    return value if np.isfinite(value) else np.inf


class _Anderson:
    """Anderson acceleration of the fixed-point map ``x_k -> argmin Phi_k`` (in the scaled
    variables): the next centre combines the last few maps so that their residuals cancel."""

    def __init__(self, T, memory: int = 5):
        self.T, self.memory = T, memory
        self.points: list = []
        self.maps: list = []

    def next(self, x, mapped) -> np.ndarray:
        to_xi = np.linalg.pinv(self.T)
        self.points.append(to_xi @ x)
        self.maps.append(to_xi @ mapped)
        self.points, self.maps = self.points[-self.memory - 1 :], self.maps[-self.memory - 1 :]
        if len(self.points) < 2:
            return mapped
        X = np.array(self.points).T
        F = np.array(self.maps).T - X  # residuals of the map
        dF, dX = np.diff(F, axis=1), np.diff(X, axis=1)
        gamma = np.linalg.lstsq(dF, F[:, -1], rcond=1e-12)[0]
        xi = X[:, -1] + F[:, -1] - (dX + dF) @ gamma
        return x + self.T @ (xi - X[:, -1])


def solve(
    system,
    law,
    T,
    energy_scale,
    *,
    x0,
    form="constrained",
    tol=1e-14,
    outer_tol=1e-12,
    max_outer=60,
    max_iter=3000,
    max_time=3600.0,
    ipopt_options=None,
) -> InnerResult:
    """The fixed point of the re-centred IPOPT solves (targets fixed): body 2's equilibrium.

    ``system``, ``law``, ``T`` (m, k), ``energy_scale`` (N mm) and ``x0`` (m,; mm, rad) as for
    :func:`~dea_opt.formulations.finite.newton.solve`; the other keywords are the IPOPT options of
    :data:`dea_opt.formulations.finite.nlp.OPTIONS` (not the re-casting ones).

    Stops when the scaled step of an outer iteration is below ``outer_tol`` and the physical
    residual is below ``max(outer_tol, 1e-9)`` relative to the load; or, as ``max_iterations``,
    after ``max_outer`` outer iterations, an IPOPT solve that reached ``max_iter``, or ``max_time``
    seconds (each IPOPT solve is bounded by it too, so a solve ends within about twice that).
    """
    if form not in ("constrained", "reduced"):
        raise InputError(f"form must be 'constrained' or 'reduced', got {form!r}")
    start = time.perf_counter()
    model = _Surrogate(system, law, T, energy_scale, form, tol, max_iter, ipopt_options, max_time)
    x = np.array(x0, dtype=float)
    state = system.state(system.coordinates(x), law)
    status, message, success = "max_iterations", f"no fixed point in {max_outer} outer iterations", False
    history, iterations, stress = [], 0, None
    anderson = _Anderson(T)
    for outer in range(1, max_outer + 1):
        x_new, step, stress, stats = model.solve(x, state)
        iterations += int(stats.get("iter_count", 0))
        if not np.isfinite(x_new).all():
            status, message = "non_finite", f"IPOPT returned NaN ({stats.get('return_status')})"
            break
        native = str(stats.get("return_status"))
        if native in _LIMITS:
            status = "max_iterations"
            limit = dict(zip(_LIMITS, (f"max_iter = {max_iter}", "max_cpu_time", f"max_time = {max_time:g} s")))[native]
            message = f"IPOPT ({form}) stopped at its limit ({native}, {limit}) in outer iteration {outer}"
            break
        if not stats.get("success", False) and native not in _ACCEPTABLE:
            status, message = "solver_error", f"IPOPT ({form}): {native}"
            break
        if _turn(system, x_new) > ROTATION_RANGE:
            x, state = x_new, system.state(system.coordinates(x_new), law)
            status = "max_iterations"
            message = (
                f"IPOPT's ({form}) outer iterate {outer} turned body 2 {math.degrees(_turn(system, x_new)):.4g} deg, "
                f"past the {math.degrees(ROTATION_RANGE):.0f} deg its rotation is exact for: no fixed point within them"
            )
            break
        converged = float(np.linalg.norm(step)) <= outer_tol
        plain = system.state(system.coordinates(x_new), law)
        best = (_scaled_residual(plain, T, energy_scale), x_new, plain)
        # Anderson's centre, within the rotation's range (extrapolating steps that all reached the
        # box, as with no spring in contact, it once leapt 1e15 degrees, where the residual read 1
        # as at the plain map's point), and only where clearly better: not by the rounding of two sums
        if not converged:
            candidate = anderson.next(x, x_new)
            if np.isfinite(candidate).all() and _turn(system, candidate) <= ROTATION_RANGE:
                trial = system.state(system.coordinates(candidate), law)
                value = _scaled_residual(trial, T, energy_scale)
                if value < _BETTER * best[0]:
                    best = (value, candidate, trial)
        residual, x, state = best
        history.append(residual)
        if converged and residual <= max(outer_tol, 1e-9):
            status, message, success = "converged", f"IPOPT ({form}) fixed point in {outer} outer iterations", True
            break
        if time.perf_counter() - start > max_time:
            status = "max_iterations"
            message = f"no fixed point within max_time = {max_time:g} s ({outer} outer iterations)"
            break
    info = {"residual_history": history, "outer_iterations": outer, "form": form}
    if form == "constrained" and stress is not None:
        info["stress"] = stress
    return InnerResult(x, state, success, status, message, iterations, time.perf_counter() - start, info)
