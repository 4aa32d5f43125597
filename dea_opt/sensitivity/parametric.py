"""CasADi's parametric sensitivities of the IPOPT solution: the second solver checking the first.

Written math: ``formulations/sensitivity.md`` ("Cross-checks"). The reduced NLP of
:mod:`dea_opt.formulations.nlp` (``form="reduced"``) is built again with the parameters as CasADi symbols (the law's through
:meth:`~dea_opt.laws.base.Law._twin`, so its ``energy_expr`` is the same code), solved by IPOPT, and
CasADi differentiates the solution through IPOPT's KKT system at the optimum. Nothing is shared
with :func:`dea_opt.sensitivity.sensitivities` but the problem's arrays: no tangent, no active
set, no scaling of the derivative. Meant for checks on small problems (the Jacobian is dense).
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..formulations._parts.scaling import scaling
from ..kinematics import DOFS
from .derivatives import LOADS, PER_SPRING

__all__ = ["nlp_sensitivities"]


def _namespace():
    import casadi

    from ..laws.base import _namespace as law_namespace

    return law_namespace(casadi.MX.sym("probe"))


def nlp_sensitivities(problem, wrt, *, x0=None, tol: float = 1e-14) -> dict:
    """``{name: {"u": ..., "pressure": ...}}`` from CasADi's sensitivities of the IPOPT solution.

    Parameters
    ----------
    problem : ContactProblem
    wrt : sequence of str
        Names as for :func:`dea_opt.sensitivity.sensitivities`.
    x0 : ndarray, shape (m,), optional
        A start for IPOPT (e.g. Newton's free dofs).
    tol : float
        IPOPT's tolerance.

    Returns
    -------
    dict
        ``u`` (12,) and ``pressure`` (N,) per scalar parameter, (12, N) and (N, N) per
        per-spring one, in the units of :func:`~dea_opt.sensitivity.parameter_unit`; and
        ``"x"``: IPOPT's free dofs.
    """
    import casadi as ca

    law, layer = problem.law, problem.layer
    n = len(layer)
    system = problem.system()
    sc = scaling(system, law.modulus)
    free = problem.free_indices
    GT = problem.normal_operator.T
    symbols, nominal = [], []

    def symbol(name, size, value):
        s = ca.MX.sym(name, size)
        symbols.append(s)
        nominal.append(np.broadcast_to(np.asarray(value, dtype=float), (size,)))
        return s

    law_symbols = {}
    h = ca.DM(layer.thickness)
    gap = ca.DM(layer.gap)
    up = ca.DM(problem.prescribed_u)
    r = ca.DM(problem.load_vector)
    for name in wrt:
        if name in law.parameter_names:
            law_symbols[name] = symbol(name, 1, getattr(law, name))
        elif name == "thickness_scale":
            h = h * symbol(name, 1, 1.0)
        elif name in PER_SPRING:
            if name == "thickness":
                h = h + symbol(name, n, 0.0)
            else:
                gap = gap + symbol(name, n, 0.0)
        else:
            body, dof = name.split(".") if "." in name else ("body2", name)
            if body not in ("body1", "body2") or (dof not in LOADS and dof not in DOFS):
                raise InputError(f"wrt holds {name!r}, which is no parameter of this problem")
            k = 0 if body == "body1" else 6
            e = np.zeros(12)
            if dof in LOADS:
                e[k + LOADS.index(dof)] = 1.0
                r = r + ca.DM(e) * symbol(name, 1, 0.0)
            else:
                e[k + DOFS.index(dof)] = 1.0
                up = up + ca.DM(e) * symbol(name, 1, 0.0)
    twin = law._twin(law_symbols)
    xp = _namespace()
    xi = ca.MX.sym("xi", sc.n_dofs)
    x = ca.mtimes(ca.DM(sc.T), xi)
    eps = (gap + ca.mtimes(ca.DM(GT[free].T), x) + ca.mtimes(ca.DM(GT.T), up)) / h
    compressed = ca.fmin(eps, 0)
    volume = ca.DM(layer.areas) * h
    energy = ca.dot(volume, twin.energy_expr(compressed, xp)) - ca.dot(r[free.tolist()], x)
    P = ca.vertcat(*symbols)
    solver = ca.nlpsol(
        "dea_sensitivity",
        "ipopt",
        {"x": xi, "p": P, "f": energy / sc.energy_scale},
        {"print_time": False, "ipopt": {"print_level": 0, "sb": "yes", "tol": tol}},
    )
    u = up + ca.mtimes(ca.DM(np.eye(12)[:, free]), x)
    pressure = -twin.stress_expr(compressed, xp)
    outputs = ca.Function("outputs", [xi, P], [u, pressure])
    Pv = ca.MX.sym("P", P.shape[0])
    xi_star = solver(x0=np.zeros(sc.n_dofs) if x0 is None else sc.to_xi(x0), p=Pv)["x"]
    u_star, p_star = outputs(xi_star, Pv)
    J = ca.Function("J", [Pv], [ca.jacobian(ca.vertcat(u_star, p_star), Pv), xi_star])
    jac, xi_value = (np.asarray(v, dtype=float) for v in J(np.concatenate(nominal)))
    out: dict = {"x": sc.to_u_free(xi_value.reshape(-1))}
    start = 0
    for name, value in zip(wrt, nominal):
        block = jac[:, start : start + value.size]
        start += value.size
        if value.size == 1:
            out[name] = {"u": block[:12, 0], "pressure": block[12:, 0]}
        else:
            out[name] = {"u": block[:12], "pressure": block[12:]}
    return out
