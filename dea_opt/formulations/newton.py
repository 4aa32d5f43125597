"""Newton active set: the paper's Eq. (12)-(20), made globally convergent.

Written math: ``formulations/newton.md``. Each iteration evaluates the strains once,
builds the gradient ``g = A^T (V sigma(min(eps, 0))) - r`` (Eq. 12) and the closed-form
tangent ``K = A_act^T diag(V_i sigma'(eps_i)) A_act`` over the compressed springs
(Eq. 15-18, one matrix product) and solves ``K d = -g`` (Eq. 19). The first iteration is the
paper's extended range: every spring active, tension included, which also closes open
gaps in one step. A line search on the directional derivative of the convex ``Phi``
(Wolfe conditions, expanding too-short steps and bisecting overshoots) makes it converge
from any start; where the active tangent misses a direction, the all-spring tangent is
added. The problem is solved in the variables of :class:`~dea_opt.formulations._parts.scaling.Scaling`,
so units and reference points do not matter.
"""

from __future__ import annotations

import time

import numpy as np

from .._checks.threads import single_threaded_blas
from ..status import Status
from ._parts import sweeps
from ._parts.crush import CRUSHED_MESSAGE, crushed
from ._parts.options import Capabilities, Option, validate
from ._parts.recentre import RECENTRE
from ._parts.resistance import UNRESISTED, modulus_scale, require_finite, unresisted
from ._parts.scaling import scaling
from ._parts.system import ROUNDING, FormulationResult, SpringSystem, start_vector, trivial_result

PAGE = "formulations/newton.md"

_WOLFE_DECREASE = 1e-4  # accept phi'(a) <= -this |phi'(0)| ...
_WOLFE_CURVATURE = 0.9  # ... and >= -this |phi'(0)|
_WOLFE_CURVATURE_SAFE = 0.01  # ... or this, after a safe step
_EXACT_STEP = 1e-8  # a unit step whose phi'(1) is below this |phi'(0)| is accepted at once


def _tangent(AT, weight) -> np.ndarray:
    """``AT diag(weight) AT^T``, shape (k, k): Eq. (16), summed by blocks of springs
    (:func:`~dea_opt.formulations._parts.sweeps.tangent`)."""
    return sweeps.tangent(AT, weight)


def _solve_step(K, g, K_all_fn) -> tuple[np.ndarray, bool]:
    """``(d, safe)``: Newton's ``d = -K^{-1} g``, or a safe step where ``K`` is singular.

    A singular active tangent (too few springs in contact) is harmless when ``g`` lies in its
    range: the step ``-K^+ g`` then moves only along what the compressed springs resist. When
    ``g`` pushes along directions ``N`` that ``K`` misses, ``d = -K^+ g - N (N^T K_all N)^{-1}
    N^T g`` (``safe``): the missing directions take a long step toward the next springs to
    touch, one that moves no compressed spring (``formulations/newton.md``, "Safe step").
    """
    if not g.size:
        return g.copy(), False
    require_finite("Newton's tangent", K, g)
    vals, vecs = np.linalg.eigh(K)
    # In the scaled variables the bonded layer's stiffness is the identity: a direction the
    # compressed springs miss is one the one test calls unresisted against that (or against
    # the largest eigenvalue, below which rounding hides everything).
    keep = ~unresisted(vals, max(float(vals[-1]), 1.0))
    if keep.all():
        return -np.linalg.solve(K, g), False
    coeff = vecs[:, keep].T @ g
    outside = g - vecs[:, keep] @ coeff
    if keep.any() and np.linalg.norm(outside) <= 1e-9 * np.linalg.norm(g):
        return -(vecs[:, keep] @ (coeff / vals[keep])), False
    # Newton on what the compressed springs resist, or, where g pushes more along what they miss,
    # Newton there with every spring's stiffness: that step moves no compressed spring, and its line
    # search lands on the next to touch. One at a time: the two taken as one step and scaled by one
    # line search overshoot the compressed springs long before the missing part reaches the next
    # spring (an iterate rocking between two poses, none converging).
    if keep.any() and float(np.linalg.norm(coeff)) > float(np.linalg.norm(outside)):
        return -(vecs[:, keep] @ (coeff / vals[keep])), False
    null = vecs[:, ~keep]
    K_null = null.T @ K_all_fn() @ null
    require_finite("Newton's tangent", K_null)
    try:
        beyond = np.linalg.solve(K_null, null.T @ g)
    except np.linalg.LinAlgError:
        beyond = np.linalg.lstsq(K_null, null.T @ g, rcond=UNRESISTED)[0]
    return -(null @ beyond), True


class _Line:
    """``phi'(a) = g(x + a d) . d`` along one Newton direction: one pass per evaluation, which
    reads the strains, the direction and the volumes once and writes the trial strains to
    ``out`` (a buffer of N values that is not ``eps``; ``slope`` returns it)."""

    def __init__(self, law, V, r, eps, Ad, d, out=None, energy_scale=1.0):
        self.law, self.V, self.eps, self.Ad = law, V, eps, Ad
        self.rd = float(r @ d)
        self.out = np.empty_like(eps) if out is None else out
        self.E0 = energy_scale  # (``V`` unscaled: the sums are divided by it)

    def phi(self, alpha) -> float:
        """``phi(a) = Phi(x + a d)`` up to a constant (one pass)."""
        value = sweeps.energy(self.law, self.V, self.eps, self.Ad, alpha) / self.E0 - alpha * self.rd
        return value if np.isfinite(value) else np.inf

    def touch(self, alpha) -> float | None:
        """The step from which a spring whose strain falls along the line is compressed (``alpha``
        where one already is), or None where no strain falls: only then does ``Phi`` decrease
        without bound along the line (a spring compressed ever deeper stores more than the
        load's work). Strain rates below rounding (1e-12 of the largest) count as none."""
        size = float(np.abs(self.Ad).max(initial=0.0))
        falls = self.Ad < -1e-12 * size
        if not falls.any():
            return None
        at = -self.eps[falls] / self.Ad[falls]
        return max(float(at.min()), alpha)

    def slope(self, alpha):
        # (inf beyond a bounded law's domain: an overshoot)
        value = sweeps.slope(self.law, self.V, self.eps, self.Ad, alpha, self.out) / self.E0 - self.rd
        return (value if np.isfinite(value) else np.inf), self.out


#: The step (in units of the Newton step) beyond which a line on which ``Phi`` still descends
#: steeply counts as one along which it decreases without bound.
UNBOUNDED_STEP = 1e12


def _line_search(line, slope0, curvature=0.9, max_evaluations=60):
    """A step ``a`` with ``curvature phi'(0) <= phi'(a) <= 1e-4 phi'(0)`` (``phi'(0) < 0``).

    Returns ``(a, state at a, evaluations)``; ``a`` is None where no step is acceptable and
    ``inf`` where ``phi`` still descends steeply at every step up to :data:`UNBOUNDED_STEP`
    (``Phi`` decreases without bound along the line: the load does work nothing resists there).

    ``phi`` is convex, so ``phi'`` increases: such a step decreases ``Phi`` by at least
    ``1e-4 a |phi'(0)|`` and is not too short. Only derivatives are used, never differences
    of ``Phi``, which lose every digit near convergence.
    """
    upper_ok, lower_ok = _WOLFE_DECREASE * slope0, curvature * slope0
    value, trial = line.slope(1.0)
    if value <= abs(slope0) * _EXACT_STEP and value >= lower_ok:
        return 1.0, trial, 1
    # A slight overshoot of the full Newton step: accept it on Armijo's condition, checked
    # with energies while they still resolve the decrease.
    if (
        value > upper_ok
        and np.isfinite(value)
        and value <= abs(slope0)
        and line.phi(1.0) - line.phi(0.0) <= _WOLFE_DECREASE * slope0
    ):
        return 1.0, trial, 3
    lo, hi = 0.0, None
    alpha, limit = 1.0, UNBOUNDED_STEP
    for evaluation in range(2, max_evaluations + 1):
        if value > upper_ok:
            hi = alpha  # overshoot (or out of the law's domain)
        elif value < lower_ok:
            lo = alpha  # too short: still descending steeply
        else:
            return alpha, trial, evaluation - 1
        alpha = 4.0 * alpha if hi is None else 0.5 * (lo + hi)
        if hi is not None and hi - lo <= 1e-14 * hi:
            break
        if alpha > limit:
            touch = getattr(line, "touch", lambda _: None)(lo)
            if touch is None or not np.isfinite(touch):
                return np.inf, None, evaluation  # Phi decreases without bound along d
            # a spring's strain falls along d, only far out (a tiny load's scale, where the gaps
            # are 1e9 of its strain units): past where it is compressed, and grow from there
            alpha, limit = max(alpha, 2.0 * touch), np.inf
        value, trial = line.slope(alpha)
    if lo > 0.0:
        value, trial = line.slope(lo)
        return lo, trial, max_evaluations
    return None, None, max_evaluations


#: The options of :class:`NewtonModel` (checked by :func:`~dea_opt.formulations._parts.options.validate`).
OPTIONS = (
    Option(
        "xtol",
        float,
        1e-12,
        "relative step of Eq. (20) that counts as converged once the contact set is unchanged (the paper uses 1e-6)",
        range=(0, 1),
        tolerance=True,
        build=False,
    ),
    Option(
        "gtol",
        float,
        1e-12,
        "equilibrium residual, the gradient over the larger of the load and the springs' net force "
        "(without a load, and 1: the overlap) in the scaled variables, that counts as converged",
        range=(0, 1),
        tolerance=True,
        build=False,
    ),
    Option("max_iter", int, 100, "iteration limit", range=(1, None), build=False),
    Option(
        "extended_start",
        bool,
        True,
        "treat every spring as active, tension included, in the first iteration "
        "of a cold start (the paper's extended range)",
        build=False,
    ),
)
CAPABILITIES = Capabilities(laws="any", warm_start=True, duals=False, checks_load_first=False)
EXTRA_OPTIONS = None
VARIANT = None

#: Newton's own statuses, as dea-opt's vocabulary (formulations/newton.md, "Statuses").
NATIVE_STATUS = {
    "converged": Status.CONVERGED,
    "max_iter": Status.MAX_ITERATIONS,
    "nan": Status.NON_FINITE,
    "stalled": Status.STALLED,
    "line_search": Status.LINE_SEARCH_FAILED,
    "crushed": Status.CRUSHED,
}


class NewtonModel:
    """Newton's method for one spring system: nothing to build, re-solvable for new loads.

    Parameters
    ----------
    system : SpringSystem
    law : Law
    **options
        :data:`OPTIONS`: ``xtol``, ``gtol``, ``max_iter``, ``extended_start``.

    ``solve(load, x0=None)`` starts from ``x0`` or, without one, from the last answer this model
    converged to (a warm start: a load path's previous frame), else cold (Eq. 19).
    """

    def __init__(self, system: SpringSystem, law, **options):
        self.system, self.law = system, law
        self.options = validate("newton", OPTIONS, options)
        self.build_time = 0.0
        self._last: np.ndarray | None = None

    def solve(self, load=None, *, x0=None) -> FormulationResult:
        system = self.system if load is None else self.system.with_load(load)
        start = start_vector(system, x0)
        if start is None:
            start = self._last
        require_finite("the load", system.load)
        trivial = trivial_result(system, self.law)
        if trivial is not None:
            return trivial
        with single_threaded_blas():
            result = _solve(system, self.law, x0=start, **self.options)
        if result.success:
            self._last = result.u_free
        return result


Model = NewtonModel


def solve(system: SpringSystem, law, *, x0=None, **options) -> FormulationResult:
    """Minimize ``Phi`` by a damped semismooth Newton method with an active set, once.

    Parameters
    ----------
    system : SpringSystem
    law : Law
    x0 : ndarray, shape (m,), optional
        Start (e.g. the previous frame of a load path; mm, rad); default cold (Eq. 19).
    **options
        :data:`OPTIONS`: ``xtol`` (default 1e-12), ``gtol`` (1e-12, relative to the load in the
        scaled variables, or without one to the overlap at the stage's origin, of size 1 there:
        :func:`~dea_opt.formulations._parts.scaling.scaling`), ``max_iter`` (100), ``extended_start``.
    """
    return NewtonModel(system, law, **options).solve(x0=x0)


#: Stages a solve may take (each divides the scale by at least ``1 / RECENTRE``: from
#: an overlap of 1e3 to a load of 1e-30 in scale units takes 33).
_MAX_STAGES = 40


def _solve(
    system: SpringSystem,
    law,
    *,
    x0=None,
    xtol: float = 1e-12,
    gtol: float = 1e-12,
    max_iter: int = 100,
    extended_start: bool = True,
) -> FormulationResult:
    """Newton in stages: each in the scaling of its origin (:func:`~dea_opt.formulations._parts.scaling.scaling`),
    the next from the iterate where what is in equilibrium there has fallen below ``RECENTRE`` of that
    scale (``formulations/newton.md``, "Stopping"): an overlap that set the scale and opened under a
    smaller load is then solved on in the load's scale, never stopped at the overlap's."""
    start = time.perf_counter()
    base = np.zeros(system.n_dofs)
    stage, cold = system, x0 is None
    history: list = []
    evaluations = it = stages = 0
    while True:
        scale = scaling(stage, law.modulus)
        may_recentre = stages + 1 < _MAX_STAGES

        def noise(xi, eps, scale=scale, base=base):
            return _rounding(system, law, scale, base + scale.to_u_free(xi), eps)

        run = _iterate(stage, law, scale, x0, cold and extended_start, xtol, gtol, max_iter - it, may_recentre, noise)
        it += run.iterations
        evaluations += run.evaluations
        history += run.history
        u_free = base + scale.to_u_free(run.xi)
        if not run.recentre or it >= max_iter:
            break
        stages += 1
        base, x0, cold = u_free, None, False
        stage = system.recentred(base)
    status, message, success = run.status, run.message, run.success
    if status == "max_iter":  # (also where the last stage ended to re-centre, its iterations spent)
        message = f"no convergence in {max_iter} iterations"
    eps = system.strain_at(u_free) if stages else run.eps
    if not success and crushed(law, eps):
        status, message = "crushed", f"{message}; {CRUSHED_MESSAGE.format(eps=np.nanmin(eps))}"
    with np.errstate(over="ignore", invalid="ignore"):
        stress = law.stress(np.minimum(eps, 0.0))
    return FormulationResult(
        u_free=u_free,
        stress=stress,
        success=success,
        status=NATIVE_STATUS[status],
        message=message,
        iterations=it,
        solve_time=time.perf_counter() - start,
        info={
            "native_status": status,
            "residual_history": history,
            "line_evaluations": evaluations,
            "stages": stages + 1,
        },
    )


class _Run:
    """What one stage of :func:`_iterate` ended with."""

    def __init__(self, xi, eps, status, message, success, iterations, history, evaluations, recentre=False):
        self.xi, self.eps, self.status, self.message, self.success = xi, eps, status, message, success
        self.iterations, self.history, self.evaluations, self.recentre = iterations, history, evaluations, recentre


def _rounding(system, law, scale, u_free, eps) -> float:
    """How far the rounding of the strains can move the gradient, ``|rho|`` in the scaled variables of
    ``scale``: each strain ``e0_i + A_i x`` is known to ``ROUNDING`` ulps of ``|e0_i| + sum_j |A_ij
    x_j|`` (``x = u_free``; the certificate's bound, ``formulations/newton.md``, "Stopping"), which moves the
    force of a spring within that of contact by up to ``V_i max |sigma(eps_i +- delta_i) -
    sigma(eps_i)|``."""
    delta = ROUNDING * np.finfo(float).eps * (np.abs(system.e0) + np.abs(u_free) @ np.abs(system.AT))
    near = np.flatnonzero(eps - delta < 0)
    if not near.size:
        return 0.0
    e, dl = eps[near], delta[near]
    with np.errstate(over="ignore", invalid="ignore"):
        sigma = law.stress(np.minimum(e, 0.0))
        spread = np.maximum(
            np.abs(law.stress(np.minimum(e - dl, 0.0)) - sigma), np.abs(law.stress(np.minimum(e + dl, 0.0)) - sigma)
        )
    columns = np.abs(scale.T.T @ scale.system_AT[:, near])  # the scaled A^T's, of these springs only
    return float(np.linalg.norm(columns @ (scale.system_volume[near] * spread)) / scale.energy_scale)


#: Iterations without halving the best residual after which Newton asks whether the strains' rounding
#: is what stops it.
_STAGNANT = 3


def _iterate(system, law, scale, x0, extended_start, xtol, gtol, max_iter, may_recentre, noise) -> _Run:
    """Newton's iterations in the scaled variables of ``scale``, from ``x0`` (or zero): a :class:`_Run`,
    with ``recentre`` where the iterate's own scale fell below ``RECENTRE`` of ``scale``'s (when
    ``may_recentre``). Under a load the residual is judged against the load (and the springs' net
    force), which is what the certificate measures; ``noise(xi, eps)`` is the residual's rounding
    (:func:`_rounding`), asked when the residual stagnates."""
    # The sums run over the system's own A^T and V; T and E0 act on the k-vectors and k x k
    # matrices only (sweeps.scaled): a scaled copy of A^T would cost a pass of its own.
    AT, V, e0 = system.AT, system.volume, system.e0
    T, E0 = scale.T, scale.energy_scale
    r = scale.load(system.load)
    r_norm = float(np.linalg.norm(r))
    stiffness_scale = modulus_scale(law.modulus)
    k = scale.n_dofs
    xi = np.zeros(k) if x0 is None else scale.to_xi(x0)
    eps = e0.copy() if x0 is None else e0 + (T @ xi) @ AT
    if law.bounded_strain and (eps <= -1).any():
        xi = np.zeros(k)  # a warm start outside the law's domain is no start
        eps = e0.copy()
    previous_active = None
    spare = np.empty_like(eps)  # the line search's trial strains: two buffers, swapped per step
    Ad = np.empty_like(eps)
    status, message, success = "max_iter", f"no convergence in {max_iter} iterations", False
    history: list = []
    evaluations = 0
    it = 0
    # A linear law's full Newton step that kept the contact set lands on the answer: the next sweep
    # then sums the residual alone, and the tangent only where that residual is not converged.
    expect_converged = False
    for it in range(1, max_iter + 1):
        # The extended range (first iteration) uses the law in tension too.
        extended = it == 1 and extended_start and x0 is None
        # One sweep: the residual, the tangent over the compressed springs and (extended) the
        # bilateral ones (formulations/newton.md).
        tangent = extended or not expect_converged
        here = sweeps.scaled(sweeps.state(AT, V, eps, law, tangent=tangent, extended=extended), T, E0)
        internal = here.internal
        g = internal - r
        # Without a load, the scaling makes the overlap at this stage's origin of size 1: that floor
        # keeps a press fit (internal forces cancelling, r = 0) from being judged against rounding.
        norm = max(r_norm, float(np.linalg.norm(internal)), 0.0 if r_norm else 1.0)
        gnorm = np.linalg.norm(g) / norm
        if not np.isfinite(gnorm):
            status, message = "nan", "the law returned a non-finite stress"
            break
        history.append(gnorm)
        if len(history) > _STAGNANT and min(history[-_STAGNANT:]) > 0.5 * min(history[:-_STAGNANT]):
            rounding = noise(xi, eps)  # (infinite at a bounded law's edge: no verdict from it there)
            if np.isfinite(rounding) and np.linalg.norm(g) <= 4.0 * rounding:
                status, message = (
                    "stalled",
                    (
                        f"the residual stopped at the rounding of the strains ({rounding / norm:.3g} of the load "
                        f"or the springs' force): the gaps and the motion cancel to strains float64 does not resolve"
                    ),
                )
                break
        if may_recentre and it > 1:
            # What is in equilibrium here, in units of the stage's scale: the load and the springs'
            # compression (the scaled volumes are V / s^2).
            size = max(r_norm, float(np.sqrt(stiffness_scale * here.compression)))
            if 0.0 < size <= RECENTRE:
                return _Run(xi, eps, status, "re-centred", False, it - 1, history[:-1], evaluations, recentre=True)
        if gnorm <= gtol:
            status, message, success = "converged", "equilibrium residual below gtol", True
            break
        if here.K is None:  # (not converged after all: the tangent at these strains)
            here = sweeps.scaled(sweeps.state(AT, V, eps, law), T, E0)

        def all_springs(eps=eps):  # this iteration's strains
            return T.T @ _tangent(AT, V * law.tangent(np.minimum(eps, 0.0))) @ T / E0

        d = None
        if extended and here.bilateral is not None and here.K_all is not None:
            bilateral, K = here.bilateral - r, here.K_all
            if np.isfinite(K).all() and np.isfinite(bilateral).all():
                d, safe = _solve_step(K, bilateral, all_springs)
                if not (g @ d < 0):
                    d = None  # the bilateral step is no descent for the unilateral Phi
        if d is None:
            K = here.K if here.K is not None else np.zeros((k, k))
            if not np.isfinite(K).all():
                status, message = "nan", "the law returned a non-finite tangent"
                break
            d, safe = _solve_step(K, g, all_springs)
        slope = float(g @ d)
        if not slope < 0:
            status, message = "stalled", "no descent direction (a load along a direction no spring resists?)"
            break
        np.matmul(T @ d, AT, out=Ad)
        # A safe step only knows the missing directions roughly: search the line closely, so
        # that the next spring to touch is reached rather than crept up on.
        curvature = _WOLFE_CURVATURE_SAFE if safe else _WOLFE_CURVATURE
        alpha, trial, used = _line_search(_Line(law, V, r, eps, Ad, d, spare, E0), slope, curvature)
        evaluations += used
        if alpha is None or not np.isfinite(alpha):
            # (springs at eps = -1 make it "crushed" below)
            status, message = "line_search", "the line search found no acceptable step"
            if alpha is not None:
                message = "the energy decreases without bound along the search direction (the load does work no spring resists)"
            break
        step = alpha * d
        xi = xi + step
        eps, spare = trial, eps
        active = eps < 0
        settled = previous_active is not None and np.array_equal(active, previous_active)
        previous_active = active
        expect_converged = bool(getattr(law, "is_linear", False) and alpha == 1.0 and settled)
        if alpha == 1.0 and settled and np.linalg.norm(step) <= xtol * max(float(np.linalg.norm(xi)), 1e-300):
            # Eq. (20) with the contact set unchanged: one more residual check confirms.
            internal = T.T @ sweeps.state(AT, V, eps, law, tangent=False).internal / E0
            norm = max(r_norm, float(np.linalg.norm(internal)), 0.0 if r_norm else 1.0)
            if np.linalg.norm(internal - r) / norm <= max(gtol, 1e-9):
                status, message, success = "converged", "step below xtol (Eq. 20)", True
                break
    return _Run(xi, eps, status, message, success, it, history, evaluations)
