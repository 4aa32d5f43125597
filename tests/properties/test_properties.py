"""Property-based tests: generated problems, every method, and the invariants.

Every example is a small generated contact problem (10 to 200 springs) on a plate grid, a
spherical cap, a cylindrical trough or a triaxial ellipsoidal bowl, with random areas
(spread over up to three decades), thicknesses, gaps (negative ones included), any law, and
a load drawn inside the cone the springs can carry (``r = -A^T lambda``, ``lambda >= 0``) or
outside it. The properties:

* every applicable method either returns a certified success, and they agree in
  displacement and pressure to 1e-6 relative, or they all raise the same ``DeaError``
  subclass (``LoadNotSupportedError`` whenever an independent linear program proves the
  load is outside the cone);
* a manufactured equilibrium (a displacement and the load that balances it, computed with
  kinematics written here, independently of ``dea_opt``) is found again;
* rigid motions rotate the solution, mirrors mirror it (moments and rotations are
  pseudovectors), the contact force balances the load, and a bonded layer in full
  compression under the linear law superposes loads.

Profiles (hypothesis settings registered in this module, independent of the pytest
configuration, chosen with the environment variable ``DEA_HYPOTHESIS_PROFILE``):

* ``ci`` (default): 900 generated problems in total, shared among the property tests by
  ``WEIGHTS`` (210 + 72 + 102 + 72 + 72 + 72 here, 200 + 100 in
  ``tests/properties/test_properties_unresisted.py``: layers with unresisted free dofs and zero loads
  with overlap), derandomized (the same examples on every run, so CI is reproducible), no
  deadline; about a minute on two cores;
* ``thorough``: 3 000 generated problems, derandomized as well; about 4 minutes::

      DEA_HYPOTHESIS_PROFILE=thorough python -m pytest tests/properties/test_properties.py -q

Also: ``DEA_HYPOTHESIS_SEED=<int>`` draws a different, seeded set of examples instead of
the derandomized one, and ``DEA_HYPOTHESIS_SHRINK=1`` shrinks a failure to a minimal
example (off by default: every example runs three or four solvers, and shrinking one
failure takes minutes). A failing example prints its ``Case`` (every parameter and the seed
of its arrays), so ``make_problem(Case(...))`` rebuilds the problem for a reproducer.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, replace

import numpy as np
import pytest
from conftest import TIGHT
from hypothesis import HealthCheck, Phase, assume, given, note, settings
from hypothesis import strategies as st
from scipy.optimize import linprog

import dea_opt as d

# --- hypothesis profiles ------------------------------------------------------------------

#: Total number of generated problems per profile, shared among the tests by weight.
PROFILE_TOTALS = {"ci": 900, "thorough": 3000}
_SHRINK = os.environ.get("DEA_HYPOTHESIS_SHRINK", "") not in ("", "0")
_COMMON = dict(
    deadline=None,
    # No shrinking unless asked for: every example runs three or four solvers and shrinking
    # one failure takes minutes; the failing Case is printed whole and, derandomized, it
    # comes back on every run.
    phases=tuple(Phase) if _SHRINK else (Phase.explicit, Phase.reuse, Phase.generate, Phase.target),
    derandomize=True,
    database=None,
    print_blob=True,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.filter_too_much],
)
for _name, _total in PROFILE_TOTALS.items():
    settings.register_profile(f"dea-{_name}", max_examples=_total, **_COMMON)

PROFILE = os.environ.get("DEA_HYPOTHESIS_PROFILE", "ci")
if PROFILE not in PROFILE_TOTALS:
    raise RuntimeError(f"DEA_HYPOTHESIS_PROFILE must be one of {sorted(PROFILE_TOTALS)}, got {PROFILE!r}")
if os.environ.get("DEA_HYPOTHESIS_SEED"):
    settings.register_profile(f"dea-{PROFILE}-seeded", settings.get_profile(f"dea-{PROFILE}"), derandomize=False)
    _BASE = settings.get_profile(f"dea-{PROFILE}-seeded")
else:
    _BASE = settings.get_profile(f"dea-{PROFILE}")

#: Share of the profile's total each property test draws (sums to 1).
WEIGHTS = {
    name: count / 900
    for name, count in {
        "agree": 210,
        "outside": 72,
        "manufactured": 102,
        "rigid": 72,
        "mirror": 72,
        "superpose": 72,
        # tests/properties/test_properties_unresisted.py
        "unresisted": 200,
        "preload": 100,
    }.items()
}
assert abs(sum(WEIGHTS.values()) - 1.0) < 1e-12


def budget(name: str) -> settings:
    """The profile's settings with this test's share of the examples."""
    return settings(_BASE, max_examples=max(1, round(PROFILE_TOTALS[PROFILE] * WEIGHTS[name])))


def _seed_decorator():
    seed = os.environ.get("DEA_HYPOTHESIS_SEED")
    if seed:
        from hypothesis import seed as hseed

        return hseed(int(seed))
    return lambda f: f


SEEDED = _seed_decorator()

# --- generated problems -------------------------------------------------------------------

METHODS = ("newton", "qp", "nlp", "auto")
#: Dofs each geometry's springs resist (any non-empty subset is resisted too).
RESISTED = {
    "plate": ("uz", "rx", "ry"),
    "cap": ("ux", "uy", "uz"),
    "trough": ("uy", "uz", "ry", "rz"),
    "bowl": d.DOFS,
}
MAX_STRAIN = 0.5


@dataclass(frozen=True)
class Case:
    """Everything that defines a generated problem; ``make_problem`` builds it."""

    geometry: str
    shape: tuple  # geometry parameters (sizes, angles in degrees, grid counts)
    law: d.Law
    moving: int  # the body that moves (the other one is fixed)
    free: tuple
    lever: tuple  # reference point minus the geometry's natural centre (mm)
    area_spread: float  # areas = cell area * 10**U(-spread, spread)
    thickness: float
    thickness_spread: float  # thickness = h * U(1 - s, 1 + s)
    gap_kind: str  # bonded, uniform, random, curved
    gap_level: float  # gap scale, as a fraction of the thickness (may be negative)
    strain: float  # target compressive strain of the load
    sparsity: float  # fraction of springs lambda loads
    seed: int
    pull: bool = False  # negate the load (pull instead of push)
    extra_dof: str | None = None  # an unresisted free dof carrying part of the load


def _grid_plate(lx, ly, nx, ny):
    xs = -lx / 2 + lx / nx * (np.arange(nx) + 0.5)
    ys = -ly / 2 + ly / ny * (np.arange(ny) + 0.5)
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    points = np.column_stack([X.ravel(), Y.ravel(), np.zeros(X.size)])
    normals = np.tile([0.0, 0.0, 1.0], (X.size, 1))
    return points, normals, np.full(X.size, lx * ly / (nx * ny)), np.zeros(3)


def _cap(R, coverage, nr, ns):
    """Springs on a spherical socket below its centre (the origin), normals to the centre."""
    edges = np.radians(np.linspace(0.0, coverage, nr + 1))
    t0, t1 = edges[:-1], edges[1:]
    area = 2 * np.pi * R**2 * (np.cos(t0) - np.cos(t1)) / ns
    polar = np.arccos(0.5 * (np.cos(t0) + np.cos(t1)))
    phi = 2 * np.pi * (np.arange(ns) + 0.5) / ns
    P, F = np.meshgrid(polar, phi, indexing="ij")
    direction = np.column_stack(
        [(np.sin(P) * np.cos(F)).ravel(), (np.sin(P) * np.sin(F)).ravel(), (-np.cos(P)).ravel()]
    )
    return R * direction, -direction, np.repeat(area, ns), np.zeros(3)


def _trough(R, length, arc, nl, ns):
    """Springs on a cylindrical trough of axis x through the origin, normals to the axis."""
    xs = -length / 2 + length / nl * (np.arange(nl) + 0.5)
    th = np.radians(arc) * ((np.arange(ns) + 0.5) / ns - 0.5)
    X, T = np.meshgrid(xs, th, indexing="ij")
    X, T = X.ravel(), T.ravel()
    points = np.column_stack([X, R * np.sin(T), -R * np.cos(T)])
    normals = np.column_stack([np.zeros_like(T), -np.sin(T), np.cos(T)])
    return points, normals, np.full(X.size, R * np.radians(arc) / ns * length / nl), np.zeros(3)


def _bowl(a, b, c, coverage, nr, ns):
    """Springs on a triaxial ellipsoid below its centre, normals inward: resists all six dofs."""
    dphi = np.radians(coverage) / nr
    phi = dphi * (np.arange(nr) + 0.5)
    dpsi = 2 * np.pi / ns
    P, S = np.meshgrid(phi, dpsi * (np.arange(ns) + 0.5), indexing="ij")
    P, S = P.ravel(), S.ravel()
    points = np.column_stack([a * np.sin(P) * np.cos(S), b * np.sin(P) * np.sin(S), -c * np.cos(P)])
    grad = points / np.array([a * a, b * b, c * c])
    normals = -grad / np.linalg.norm(grad, axis=1)[:, None]
    dp = np.column_stack([a * np.cos(P) * np.cos(S), b * np.cos(P) * np.sin(S), c * np.sin(P)])
    ds = np.column_stack([-a * np.sin(P) * np.sin(S), b * np.sin(P) * np.cos(S), np.zeros_like(P)])
    area = np.linalg.norm(np.cross(dp, ds), axis=1) * dphi * dpsi
    return points, normals, area, np.zeros(3)


BUILDERS = {"plate": _grid_plate, "cap": _cap, "trough": _trough, "bowl": _bowl}


def make_layer(case: Case) -> tuple[d.SpringLayer, np.ndarray]:
    """The layer of ``case`` and its natural centre."""
    points, normals, cell, centre = BUILDERS[case.geometry](*case.shape)
    rng = np.random.default_rng(case.seed)
    n = len(points)
    areas = cell * 10.0 ** rng.uniform(-case.area_spread, case.area_spread, n)
    thickness = case.thickness * rng.uniform(1 - case.thickness_spread, 1 + case.thickness_spread, n)
    h = thickness
    if case.gap_kind == "bonded":
        gap = np.zeros(n)
    elif case.gap_kind == "uniform":
        gap = case.gap_level * h
    elif case.gap_kind == "random":
        gap = case.gap_level * h * rng.uniform(-1.0, 1.0, n) + 0.25 * case.gap_level * h
    else:  # curved: grows away from a random spring, negative (overlap) near it
        p0 = points[rng.integers(n)]
        dist2 = np.sum((points - p0) ** 2, axis=1)
        gap = h * (abs(case.gap_level) * dist2 / max(dist2.max(), 1e-300) - 0.3 * abs(case.gap_level))
    return d.SpringLayer(points, normals, areas, thickness, gap), centre


def _bodies(case: Case, reference, force=(0, 0, 0), moment=(0, 0, 0)):
    free = case.free + ((case.extra_dof,) if case.extra_dof else ())
    moving = d.Body(reference=tuple(reference), free=free, force=tuple(force), moment=tuple(moment))
    fixed = d.Body(reference=tuple(reference), free=())
    return (moving, fixed) if case.moving == 1 else (fixed, moving)


def cone_load(problem: d.ContactProblem, case: Case, scale: float = 1.0) -> np.ndarray:
    """``r = -A^T lambda`` over the free dofs, ``lambda >= 0`` random (force x thickness)."""
    system = problem.system()
    rng = np.random.default_rng(case.seed + 1)
    n = system.n_springs
    weight = rng.uniform(0.0, 2.0, n) * (rng.uniform(size=n) < case.sparsity)
    if not weight.any():
        weight[rng.integers(n)] = 1.0
    lam = system.volume * problem.law.modulus * case.strain * weight * scale
    r = -system.A.T @ lam
    if case.pull:
        r = -r
    if case.extra_dof:
        k = problem.free_names.index(f"body{case.moving}.{case.extra_dof}")
        r[k] += 0.5 * np.linalg.norm(r) * (1.0 if rng.uniform() < 0.5 else -1.0)
    return r


def with_free_load(problem: d.ContactProblem, r_free: np.ndarray) -> d.ContactProblem:
    """``problem`` carrying the generalized load ``r_free`` on its free dofs."""
    full = np.zeros(12)
    full[problem.free_indices] = r_free
    b1 = d.Body(reference=problem.body1.reference, free=problem.body1.free, force=full[0:3], moment=full[3:6])
    b2 = d.Body(reference=problem.body2.reference, free=problem.body2.free, force=full[6:9], moment=full[9:12])
    return d.ContactProblem(problem.layer, problem.law, body1=b1, body2=b2)


def make_problem(case: Case, *, moderate: bool = True) -> d.ContactProblem:
    """Build ``case``; with ``moderate``, halve the load until Newton's strains are < 0.5."""
    layer, centre = make_layer(case)
    b1, b2 = _bodies(case, centre + np.asarray(case.lever))
    bare = d.ContactProblem(layer, case.law, body1=b1, body2=b2)
    problem = with_free_load(bare, cone_load(bare, case))
    if not moderate or case.pull or case.extra_dof:
        return problem
    scale = 1.0
    for _ in range(12):
        try:
            s = quiet_solve(problem, "newton")
        except d.DeaError:
            return problem
        if s.max_compressive_strain < MAX_STRAIN:
            return problem
        scale *= 0.5
        problem = with_free_load(bare, cone_load(bare, case, scale))
    return problem


@st.composite
def shapes(draw, geometry):
    """Geometry parameters with 10 to 200 springs."""
    if geometry == "plate":
        nx, ny = draw(st.integers(2, 14)), draw(st.integers(2, 14))
        size = 10 ** draw(st.floats(-0.5, 1.7))
        aspect = draw(st.floats(0.3, 3.0))
        if nx * ny < 10:
            nx = 10 // ny + 1
        return (size, size * aspect, nx, ny)
    if geometry == "cap":
        R = 10 ** draw(st.floats(0.0, 1.7))
        coverage = draw(st.floats(25.0, 150.0))
        nr, ns = draw(st.integers(2, 8)), draw(st.integers(5, 20))
        return (R, coverage, nr, ns)
    if geometry == "trough":
        R = 10 ** draw(st.floats(0.0, 1.7))
        length = R * draw(st.floats(0.3, 3.0))
        arc = draw(st.floats(60.0, 300.0))
        nl, ns = draw(st.integers(2, 10)), draw(st.integers(5, 20))
        return (R, length, arc, nl, ns)
    a = 10 ** draw(st.floats(0.0, 1.5))
    b, c = a * draw(st.floats(0.4, 0.85)), a * draw(st.floats(1.15, 2.0))
    coverage = draw(st.floats(40.0, 120.0))
    nr, ns = draw(st.integers(2, 8)), draw(st.integers(5, 20))
    return (a, b, c, coverage, nr, ns)


def _size(geometry, shape) -> float:
    return max(shape[0], shape[1]) if geometry == "plate" else shape[0]


@st.composite
def laws(draw, linear=None):
    H = 10 ** draw(st.floats(-1.0, 2.0))
    kinds = ["linear", "ateshian", "ateshian0", "cubic", "polynomial", "blankevoort"]
    if linear is True:
        kinds = ["linear"]
    elif linear is False:
        kinds = kinds[1:]
    kind = draw(st.sampled_from(kinds))
    beta = draw(st.floats(0.0, 1.0))
    if kind == "linear":
        return d.LinearLaw(H)
    if kind == "ateshian":
        return d.AteshianLaw(H, beta)
    if kind == "ateshian0":
        return d.AteshianLaw(H, 0.0)
    if kind == "cubic":
        return d.CubicLaw(H, beta)
    if kind == "polynomial":
        return d.PolynomialLaw(H, beta, draw(st.sampled_from([1, 2, 3, 4, 5, 7, 9])))
    return d.BlankevoortLaw(H)


@st.composite
def cases(
    draw,
    *,
    geometry=None,
    law=None,
    linear=None,
    free="mixed",
    moving=None,
    gap_kind=None,
    pull=False,
    extra_dof=False,
    strain=(-3.0, -0.7),
):
    geometry = geometry or draw(st.sampled_from(sorted(RESISTED)))
    shape = draw(shapes(geometry))
    resisted = RESISTED[geometry]
    if free == "mixed" and extra_dof:
        free = "subset"  # the extra dof is the one unresisted free dof
    if free == "mixed":
        # mostly dofs the springs resist; sometimes all six, unresisted ones included
        # (in-plane motion of a plate, rotations of a ball about its centre), unloaded
        free = draw(st.sampled_from(["subset", "subset", "subset", "all"]))
    if free == "subset":
        chosen = draw(st.lists(st.sampled_from(resisted), min_size=1, max_size=len(resisted), unique=True))
        free_dofs = tuple(dof for dof in d.DOFS if dof in chosen)
    elif free == "all":
        free_dofs = d.DOFS
    else:
        free_dofs = resisted
    extra = None
    if extra_dof:
        unresisted = [dof for dof in d.DOFS if dof not in resisted]
        assume(unresisted)
        extra = draw(st.sampled_from(unresisted))
    size = _size(geometry, shape)
    lever_length = size * draw(st.sampled_from([0.0, 0.1, 1.0, 3.0]))
    direction = np.array(draw(st.tuples(*[st.floats(-1, 1)] * 3)))
    lever = tuple(direction * lever_length)
    return Case(
        geometry=geometry,
        shape=shape,
        law=law if law is not None else draw(laws(linear)),
        moving=moving or draw(st.sampled_from([1, 2, 2])),
        free=free_dofs,
        lever=lever,
        area_spread=draw(st.sampled_from([0.0, 0.5, 1.5])),
        thickness=10 ** draw(st.floats(-0.7, 0.7)),
        thickness_spread=draw(st.sampled_from([0.0, 0.5])),
        gap_kind=gap_kind or draw(st.sampled_from(["bonded", "uniform", "random", "curved"])),
        gap_level=draw(st.floats(-0.05, 0.15)),
        strain=10 ** draw(st.floats(*strain)),
        sparsity=draw(st.sampled_from([0.1, 0.5, 1.0])),
        seed=draw(st.integers(0, 2**31 - 1)),
        pull=pull,
        extra_dof=extra,
    )


# --- solving and comparing ------------------------------------------------------------


def applicable(law, methods=METHODS):
    """The methods that take ``law``, as the registry's capabilities say (``auto`` takes any)."""
    return tuple(m for m in methods if m == "auto" or d.formulations.takes(m, law))


def quiet_solve(problem, method, **options):
    """Solve with the tight test options; every warning but ValidityWarning is an error."""
    opts = dict(TIGHT.get(method, {}))
    opts.update(options)
    if method == "auto":
        opts = dict(options)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        warnings.simplefilter("ignore", d.ValidityWarning)
        return d.solve(problem, method, **opts)


def solve_all(problem, methods):
    """``{method: Solution or the DeaError it raised}``."""
    out = {}
    for method in methods:
        try:
            out[method] = quiet_solve(problem, method)
        except d.DeaError as exc:
            out[method] = exc
    return out


def _describe(outcomes) -> str:
    parts = []
    for method, o in outcomes.items():
        if isinstance(o, Exception):
            parts.append(f"{method}: {type(o).__name__}: {str(o)[:300]}")
        else:
            parts.append(f"{method}: success={o.success} status={o.status} worst={o.certificate.worst()}")
    return "\n".join(parts)


def determined_projector(problem, solution) -> np.ndarray:
    """Projector (m, m) onto the free-dof directions the compressed springs determine.

    ``u`` is unique along them; along the others (a direction no compressed spring
    resists) every value that keeps the open springs open is an equilibrium too.
    """
    return _determined(problem, solution)[0]


def _determined(problem, solution) -> tuple[np.ndarray, float]:
    """:func:`determined_projector` and the condition number of the compressed springs' strain rows
    (weighted by their stiffness) over those directions: how much a strain error (a pressure error)
    grows into an error of ``u`` there."""
    system = problem.system()
    eps = system.strain_at(solution.u[problem.free_indices])
    scale = max(np.abs(eps).max(initial=0.0), 1e-300)
    active = eps < -1e-9 * scale
    m = system.n_dofs
    if not active.any():
        return np.zeros((m, m)), 1.0
    rows = system.A[active] * np.sqrt(system.volume[active] * np.abs(problem.law.tangent(eps[active])))[:, None]
    _, s, vt = np.linalg.svd(rows, full_matrices=False)
    keep = s > 1e-7 * s.max()
    return vt[keep].T @ vt[keep], float(s.max() / s[keep].min()) if keep.any() else 1.0


def assert_agree(problem, solutions, rtol=1e-6):
    """Pressures agree everywhere, ``u`` along every direction the contact determines."""
    names = list(solutions)
    ref = solutions[names[0]]
    P = determined_projector(problem, ref)
    free = problem.free_indices
    peak = max(s.peak_pressure for s in solutions.values())
    umax = max(np.abs(P @ s.u[free]).max(initial=0.0) for s in solutions.values())
    for name in names[1:]:
        s = solutions[name]
        np.testing.assert_allclose(
            s.pressure,
            ref.pressure,
            rtol=0,
            atol=rtol * max(peak, 1e-300),
            err_msg=f"pressure: {names[0]} vs {name}",
        )
        np.testing.assert_allclose(
            P @ s.u[free],
            P @ ref.u[free],
            rtol=0,
            atol=rtol * max(umax, 1e-300),
            err_msg=f"displacement: {names[0]} vs {name}",
        )


def spring_resultants(problem, solution) -> np.ndarray:
    """The 12-vector of forces and moments the springs exert on each body about its
    reference, summed from the spring forces here (not from ``dea_opt``'s operators)."""
    layer = problem.layer
    f2 = (solution.pressure * layer.areas)[:, None] * layer.normals  # pushes body 2 along +n
    out = np.zeros(12)
    for k, body, f in ((0, problem.body1, -f2), (1, problem.body2, f2)):
        arm = layer.points - np.asarray(body.reference)
        out[6 * k : 6 * k + 3] = f.sum(axis=0)
        out[6 * k + 3 : 6 * k + 6] = np.cross(arm, f).sum(axis=0)
    return out


def assert_balanced(problem, solution, rtol=1e-8):
    """The springs balance the load on every free dof (moments over the layer's size)."""
    layer = problem.layer
    load = problem.load_vector
    total = float(solution.pressure @ layer.areas)
    length = np.ones(12)
    for k, body in enumerate((problem.body1, problem.body2)):
        arm = np.sqrt(np.mean(np.sum((layer.points - np.asarray(body.reference)) ** 2, axis=1)))
        length[6 * k + 3 : 6 * k + 6] = max(arm, 1e-300)
    resultant = spring_resultants(problem, solution)
    free = problem.free_indices
    scale = max(np.linalg.norm((load / length)[free]), total)
    residual = np.abs((resultant + load)[free] / length[free])
    assert residual.max() <= rtol * scale, (
        f"springs do not balance the load: residual {residual.max() / scale:.3g} (relative) on "
        f"{[problem.free_names[i] for i in np.flatnonzero(residual > rtol * scale)]}"
    )
    if problem.body2.free:
        # contact_force / contact_moment (dea_opt's own) equal minus the load on body 2's free dofs
        own = np.concatenate([solution.contact_force, solution.contact_moment])
        idx = [i for i, dof in enumerate(d.DOFS) if dof in problem.body2.free]
        np.testing.assert_allclose((own + problem.body2.load_vector)[idx] / length[6:][idx], 0.0, atol=rtol * scale)


def farkas_margin(problem) -> float:
    """``max r.d`` over ``A d >= 0``, ``|d|_inf <= 1``, relative to ``|r|``: 0 when the load
    is in the cone, > 0 (a motion that opens or keeps every spring and does positive work)
    when it is not. A linear program, independent of ``dea_opt``'s NNLS.

    Dofs are scaled by their column norms (never blowing a column of rounding noise up),
    and directions no spring resists beyond rounding (singular values below 1e-9 of the
    largest, e.g. rotations about the centre of a sphere) count as resisted by none: a load
    component along them is outside the cone by itself."""
    system = problem.system()
    norms = np.linalg.norm(system.A, axis=0)
    top = max(norms.max(initial=0.0), 1e-300)
    norms = np.where(norms < 1e-10 * top, top, norms)  # a noise column stays noise
    A, rs = system.A / norms, system.load / norms
    rnorm = max(np.linalg.norm(rs), 1e-300)
    U, sv, Vt = np.linalg.svd(A, full_matrices=False)
    keep = sv > 1e-9 * max(sv.max(initial=0.0), 1e-300)
    null_part = float(np.linalg.norm(rs - Vt[keep].T @ (Vt[keep] @ rs)))
    if null_part > 1e-9 * rnorm:
        return null_part / rnorm
    B = U[:, keep] * sv[keep]  # A d = B z with z = Vt[keep] d
    rz = Vt[keep] @ rs
    res = linprog(-rz, A_ub=-B, b_ub=np.zeros(len(B)), bounds=[(-1, 1)] * len(rz), method="highs")
    assert res.status == 0, res.message
    return float(-res.fun / rnorm)


# --- the properties ---------------------------------------------------------------------


def check_outcomes(problem, outcomes, *, inside: bool | None):
    note(_describe(outcomes))
    errors = {m: o for m, o in outcomes.items() if isinstance(o, Exception)}
    if len(errors) == len(outcomes) and all(_unresolved(o) for o in errors.values()):
        # a load float64 does not resolve against the layer (one of rounding's size, a moment on lever
        # arms that are rounding): no method certifies an answer, each says why
        return None
    if errors:
        classes = {type(o) for o in outcomes.values()}
        assert not (len(errors) < len(outcomes)), f"some methods succeed, some raise:\n{_describe(outcomes)}"
        assert len(classes) == 1, f"methods raise different errors:\n{_describe(outcomes)}"
        assert inside is not True, f"a load inside the cone was not solved:\n{_describe(outcomes)}"
        if inside is False:
            assert classes == {d.LoadNotSupportedError}, _describe(outcomes)
        return None
    assert inside is not False, f"a load outside the cone was 'solved':\n{_describe(outcomes)}"
    for s in outcomes.values():
        assert s.success and s.certificate.passed
        assert np.isfinite(s.u).all() and np.isfinite(s.pressure).all()
        assert (s.pressure >= 0).all()
        assert_balanced(problem, s, rtol=1e-6 if s.method != "newton" else 1e-8)
    assert_agree(problem, outcomes)
    return outcomes


def _unresolved(exc) -> bool:
    """Whether ``exc`` is a :class:`SolverError` whose answer the certificate could not accept for the
    strains' rounding (``Certificate.rounding`` above half its tolerance, as for
    :func:`dea_opt.solver.beyond_resolution`: a load float64 does not resolve against the layer there)."""
    solution = getattr(exc, "solution", None)
    if not isinstance(exc, d.SolverError) or solution is None:
        return False
    certificate = solution.certificate
    return bool(certificate.rounding > 0.5 * certificate.tolerance)


@budget("agree")
@SEEDED
@given(case=cases())
@pytest.mark.slow
def test_methods_agree_or_raise_the_same_error(case):
    """Inside the cone: all methods succeed, certified, and agree to 1e-6."""
    problem = make_problem(case)
    note(repr(problem))
    margin = farkas_margin(problem)
    # (HiGHS's own feasibility tolerances are about 1e-9 of the data: a lever arm of 1e-9 of the
    # layer's size, a reference 4e-9 mm off a trough's axis, leaves margins of a few 1e-9)
    assert margin <= 1e-7, f"a load built inside the cone has Farkas margin {margin}"
    check_outcomes(problem, solve_all(problem, applicable(case.law)), inside=True)


@budget("outside")
@SEEDED
@given(case=st.one_of(cases(pull=True), cases(extra_dof=True)), shift=st.floats(0.0, 1.0))
def test_loads_outside_the_cone_raise_load_not_supported_everywhere(case, shift):
    """Pulling the bodies apart, or loading a dof nothing resists: LoadNotSupportedError
    from every method when the Farkas LP proves it, the same outcome from all otherwise."""
    problem = make_problem(case)
    if case.pull and shift > 0:
        # tilt the pull toward the cone: part pull, part another push (often still outside)
        push = cone_load(problem, replace(case, pull=False, seed=case.seed + 7))
        r = problem.system().load
        problem = with_free_load(problem, (1 - shift) * r + shift * push)
    margin = farkas_margin(problem)
    note(f"Farkas margin {margin:.3g}")
    inside = True if margin <= 1e-12 else (False if margin > 1e-4 else None)
    check_outcomes(problem, solve_all(problem, applicable(case.law)), inside=inside)


# --- a manufactured equilibrium -------------------------------------------------------------


def independent_strain(layer, body1, body2, u) -> np.ndarray:
    """``eps = (gap + n . (delta2 - delta1)) / h`` with ``delta_k = t_k + w_k x (x - c_k)``."""
    delta = []
    for k, body in enumerate((body1, body2)):
        t, w = u[6 * k : 6 * k + 3], u[6 * k + 3 : 6 * k + 6]
        delta.append(t + np.cross(w, layer.points - np.asarray(body.reference)))
    return (layer.gap + np.sum(layer.normals * (delta[1] - delta[0]), axis=1)) / layer.thickness


@budget("manufactured")
@SEEDED
@given(case=cases(), target=st.floats(0.01, 0.4), pick=st.integers(0, 2**31 - 1), data=st.data())
def test_a_manufactured_equilibrium_is_found_again(case, target, pick, data):
    """Choose a displacement, load the body with what the springs exert there, solve."""
    method = data.draw(st.sampled_from(applicable(case.law)), label="method")
    layer, centre = make_layer(case)
    b1, b2 = _bodies(case, centre + np.asarray(case.lever))
    bare = d.ContactProblem(layer, case.law, body1=b1, body2=b2)
    system = bare.system()
    rng = np.random.default_rng(pick)
    # a random free motion, scaled so the most compressed spring reaches -target
    x = rng.normal(size=system.n_dofs)
    x /= np.linalg.norm(x)
    ax = system.A @ x
    if (system.e0 + ax).min() > 0 and ax.min() >= 0:
        x, ax = -x, -ax
    # smallest s >= 0 with min(e0 + s A x) = -target
    s_values = (-target - system.e0) / np.where(ax < 0, ax, -np.inf)
    s_values = s_values[(ax < 0) & (s_values >= 0)]
    assume(s_values.size)
    s = s_values.min()
    x = s * x
    u = bare.full_u(x)
    eps = independent_strain(layer, bare.body1, bare.body2, u)
    np.testing.assert_allclose(eps, system.strain_at(x), rtol=0, atol=1e-10 * max(1.0, np.abs(eps).max()))
    assume(eps.min() < -1e-3)
    pressure = -case.law.stress(np.minimum(eps, 0.0))
    problem = bare
    # load = minus the resultant the springs exert, computed here
    fake = type("S", (), {"pressure": pressure})()
    load = -spring_resultants(bare, fake)
    b1 = d.Body(reference=bare.body1.reference, free=bare.body1.free, force=load[0:3], moment=load[3:6])
    b2 = d.Body(reference=bare.body2.reference, free=bare.body2.free, force=load[6:9], moment=load[9:12])
    problem = d.ContactProblem(layer, case.law, body1=b1, body2=b2)
    note(f"manufactured x = {x.tolist()}, min strain {eps.min():.3g}")
    solution = quiet_solve(problem, method)
    assert solution.success and solution.certificate.passed
    assert_balanced(problem, solution, rtol=1e-6 if method != "newton" else 1e-8)
    peak = pressure.max()
    np.testing.assert_allclose(solution.pressure, pressure, rtol=0, atol=1e-6 * peak)
    # along the directions the manufactured contact determines (a solver's answer may hold a spring on
    # the edge of the contact compressed by its tolerance, which would add a direction it does not),
    # to the pressures' 1e-6 grown by the contact's condition (a far reference point makes the dofs
    # nearly dependent: a residual of 1e-13 moved IPOPT's answer by 2e-6 of it there, Newton's by 2e-8)
    P, condition = _determined(problem, type("S", (), {"u": u})())
    got = P @ solution.u[problem.free_indices]
    want = P @ x
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-6 * condition * max(np.abs(want).max(), 1e-300))


# --- invariants ---------------------------------------------------------------------------


def random_rotation(rng) -> np.ndarray:
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    if np.linalg.det(q) < 0:
        q[:, 0] = -q[:, 0]
    return q


def transformed(problem, Q, t) -> d.ContactProblem:
    """The problem moved by ``x -> Q x + t`` (``Q`` orthogonal; a mirror when det Q = -1).
    Forces are vectors; moments are pseudovectors (``det(Q) Q M``); gaps do not change."""
    layer = problem.layer
    det = float(np.linalg.det(Q))
    new_layer = d.SpringLayer(layer.points @ Q.T + t, layer.normals @ Q.T, layer.areas, layer.thickness, layer.gap)
    bodies = []
    for body in (problem.body1, problem.body2):
        bodies.append(
            d.Body(
                reference=tuple(Q @ np.asarray(body.reference) + t),
                free=body.free,
                force=tuple(Q @ np.asarray(body.force)),
                moment=tuple(det * Q @ np.asarray(body.moment)),
            )
        )
    return d.ContactProblem(new_layer, problem.law, body1=bodies[0], body2=bodies[1])


def transform_u(u, Q) -> np.ndarray:
    det = float(np.linalg.det(Q))
    out = np.empty(12)
    for k in range(2):
        out[6 * k : 6 * k + 3] = Q @ u[6 * k : 6 * k + 3]
        out[6 * k + 3 : 6 * k + 6] = det * Q @ u[6 * k + 3 : 6 * k + 6]
    return out


def _check_equivariant(case, Q, t, method):
    problem = make_problem(case)
    moved = transformed(problem, Q, t)
    try:
        base = quiet_solve(problem, method)
    except d.DeaError as exc:
        if _unresolved(exc):
            return
        with pytest.raises(type(exc)):
            quiet_solve(moved, method)
        return
    try:
        other = quiet_solve(moved, method)
    except d.SolverError as exc:
        if _unresolved(exc):
            # where the answer is not unique (a press fit in a shallow bowl under a tiny load), a
            # method may pick one far along a direction nothing determines (IPOPT: 355 m away),
            # whose strains float64 no longer resolves: not certified, and it says why
            return
        raise
    assert other.success
    peak = base.peak_pressure
    np.testing.assert_allclose(other.pressure, base.pressure, rtol=0, atol=1e-6 * max(peak, 1e-300))
    # compressive strains are unique; open springs' strains are not where u is not
    np.testing.assert_allclose(
        np.minimum(other.strain, 0),
        np.minimum(base.strain, 0),
        rtol=0,
        atol=1e-6 * max(np.abs(base.strain).max(), 1e-300),
    )
    # u: all six dofs of the moving body are free, so the free subspace maps onto itself.
    # Compare along the directions the contact determines (everywhere for a unique answer).
    P = determined_projector(problem, base)
    free = problem.free_indices
    want_full = np.zeros(12)
    want_full[free] = P @ base.u[free]
    want = transform_u(want_full, Q)[free]
    P2 = determined_projector(moved, other)
    got = P2 @ other.u[free]
    scale = max(np.abs(want).max(), 1e-300)
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-6 * scale)
    if method == "newton" and np.allclose(P, np.eye(len(free))):
        # A unique answer is equivariant in full. (Where the compressed springs leave a
        # direction free, Newton's answer has no part along what no spring resists at all,
        # but along directions only open springs resist it may be any point of a flat set.)
        np.testing.assert_allclose(
            other.u, transform_u(base.u, Q), rtol=0, atol=1e-6 * max(np.abs(base.u).max(), 1e-300)
        )
    for s, p in ((base, problem), (other, moved)):
        assert_balanced(p, s, rtol=1e-6 if method != "newton" else 1e-8)


@budget("rigid")
@SEEDED
@given(case=cases(free="all"), rot=st.integers(0, 2**31 - 1), shift=st.floats(-3.0, 3.0), data=st.data())
def test_rigid_motion_rotates_the_solution(case, rot, shift, data):
    """Points, normals, references and loads rotated and moved: ``u`` rotates (translations
    and rotations alike), pressures stay."""
    method = data.draw(st.sampled_from(applicable(case.law)), label="method")
    rng = np.random.default_rng(rot)
    Q = random_rotation(rng)
    t = rng.normal(size=3) * 10.0**shift
    _check_equivariant(case, Q, t, method)


@budget("mirror")
@SEEDED
@given(case=cases(free="all"), plane=st.integers(0, 2**31 - 1), data=st.data())
def test_mirroring_mirrors_the_solution(case, plane, data):
    """Reflected through a plane: forces and translations reflect, moments and rotations
    (pseudovectors) reflect and change sign, pressures stay."""
    method = data.draw(st.sampled_from(applicable(case.law)), label="method")
    rng = np.random.default_rng(plane)
    m = rng.normal(size=3)
    m /= np.linalg.norm(m)
    S = np.eye(3) - 2.0 * np.outer(m, m)
    t = 2.0 * rng.normal() * m  # reflect through a plane off the origin
    _check_equivariant(case, S, t, method)


@budget("superpose")
@SEEDED
@given(
    case=cases(law=d.LinearLaw(1.0), gap_kind="bonded"),
    H=st.floats(-1.0, 2.0),
    pick=st.integers(0, 2**31 - 1),
    method=st.sampled_from(("newton", "qp", "nlp")),
)
def test_linear_bonded_layer_in_full_compression_superposes_loads(case, H, pick, method):
    """``u(r1 + r2) = u(r1) + u(r2)`` while every spring stays compressed."""
    layer, centre = make_layer(case)
    b1, b2 = _bodies(case, centre + np.asarray(case.lever))
    bare = d.ContactProblem(layer, d.LinearLaw(10.0**H), body1=b1, body2=b2)
    system = bare.system()
    A = system.A
    # a motion compressing every spring: maximize the smallest compression (an LP)
    m = A.shape[1]
    res = linprog(
        np.r_[np.zeros(m), -1.0],
        A_ub=np.c_[A, np.ones(len(A))],
        b_ub=np.zeros(len(A)),
        bounds=[(-1, 1)] * m + [(0, 1)],
        method="highs",
    )
    assert res.status == 0
    x_star, margin = res.x[:m], res.x[m]
    assume(margin > 1e-3 * np.abs(A).max())
    rng = np.random.default_rng(pick)
    xs = []
    for _ in range(2):
        x = x_star + rng.uniform(-1, 1, size=m) * 0.5 * margin / max(np.abs(A).sum(axis=1).max(), 1e-300)
        assert (A @ x < 0).all()
        xs.append(x * 0.2 / max(-(A @ x).min(), 1e-300) * rng.uniform(0.05, 1.0))
    # only the directions the springs resist are determined (free="all" frees others too)
    _, sv, Vt = np.linalg.svd(A, full_matrices=False)
    Vk = Vt[sv > 1e-9 * sv.max()]
    P = Vk.T @ Vk
    xs = [P @ x for x in xs]
    loads = [A.T @ (system.volume * bare.law.stress(A @ x)) for x in xs]
    solve_x = []
    for r in (loads[0], loads[1], loads[0] + loads[1]):
        s = quiet_solve(with_free_load(bare, r), method)
        assert s.success and (s.strain < 0).all()
        assert_balanced(s.problem, s, rtol=1e-6 if method != "newton" else 1e-8)
        solve_x.append(P @ s.u[bare.free_indices])
    scale = np.abs(solve_x[2]).max()
    np.testing.assert_allclose(solve_x[0] + solve_x[1], solve_x[2], rtol=0, atol=1e-6 * scale)
    np.testing.assert_allclose(solve_x[2], xs[0] + xs[1], rtol=0, atol=1e-6 * scale)
