"""Property tests: layers whose free dofs include directions no spring resists.

Every example is a plate, a spherical socket or a closed spherical shell around a ball, with
the moving body's reference at the geometry's centre, so that the unresisted dofs are known
exactly (in-plane motion and spin of a plate; every rotation of a ball about its centre,
whose lever arms are zero only up to rounding), and a random subset of the six dofs free:
sometimes none unresisted, sometimes some, sometimes all. Loads are built here from a random
set of compressive spring forces (so they lie in the cone the springs can carry), plus, in
some examples, a part along the free unresisted dofs of any size from 1e-12 of the rest to
all of it. Gaps may be open, bonded or press-fitted.

The properties, checked for every method (``newton``, ``qp`` for a linear law, ``nlp``,
``auto``):

* a load with a part along an unresisted free dof raises ``LoadNotSupportedError`` from every
  method, and is never "solved": any part when no free dof is resisted, more than 1e-7 of the
  load otherwise (a part below 1e-9 is rounding, tolerated and held);
* otherwise every method succeeds, its answer passes an equilibrium check written here (spring
  forces ``p_i S_i n_i`` and their moments about the reference summed in plain numpy and
  compared with the load on every free dof, relative to the load, the total spring force and
  the force of the initial overlap), takes no motion along the unresisted dofs, and the
  methods agree on the pressures;
* zero load on a press-fitted layer is solved and certified by every method with one status.

The budget comes from the profiles of ``tests/properties/test_properties.py`` (``WEIGHTS``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from hypothesis import event, given, note
from hypothesis import strategies as st
from test_properties import (
    SEEDED,
    _cap,
    _grid_plate,
    applicable,
    assert_agree,
    budget,
    laws,
    quiet_solve,
)

import dea_opt as d

#: Dofs no spring resists, about the geometry's centre, exactly (not up to rounding).
UNRESISTED = {"plate": ("ux", "uy", "rz"), "socket": ("rx", "ry", "rz"), "shell": ("rx", "ry", "rz")}


def _shell(R, n):
    """A closed spherical shell of ``n`` springs around a ball of radius ``R`` centred at the
    origin (Fibonacci lattice), normals toward the centre: every translation is resisted,
    no rotation about the centre is."""
    k = np.arange(n) + 0.5
    polar = np.arccos(1 - 2 * k / n)
    azimuth = np.pi * (1 + 5**0.5) * k
    direction = np.column_stack([np.sin(polar) * np.cos(azimuth), np.sin(polar) * np.sin(azimuth), np.cos(polar)])
    return R * direction, -direction, np.full(n, 4 * np.pi * R**2 / n), np.zeros(3)


@dataclass(frozen=True)
class Case:
    geometry: str
    shape: tuple
    law: d.Law
    moving: int
    free: tuple
    area_spread: float
    thickness: float
    gap_kind: str  # open, bonded, press, mixed
    gap_level: float  # fraction of the thickness
    strain: float  # size of the compressive spring forces the load is built from
    extra: float  # size of the load along unresisted free dofs (0: none), relative
    seed: int


def make_layer(case: Case) -> d.SpringLayer:
    if case.geometry == "plate":
        points, normals, cell, _ = _grid_plate(*case.shape)
    elif case.geometry == "socket":
        points, normals, cell, _ = _cap(*case.shape)
    else:
        points, normals, cell, _ = _shell(*case.shape)
    rng = np.random.default_rng(case.seed)
    n = len(points)
    areas = cell * 10.0 ** rng.uniform(-case.area_spread, case.area_spread, n)
    h = case.thickness * rng.uniform(0.7, 1.3, n)
    level = case.gap_level * h
    gap = {"open": level, "bonded": 0.0 * h, "press": -level, "mixed": level * rng.uniform(-1.0, 1.0, n)}
    return d.SpringLayer(points, normals, areas, h, gap[case.gap_kind])


def bodies(case: Case, force=(0, 0, 0), moment=(0, 0, 0)):
    moving = d.Body(reference=(0, 0, 0), free=case.free, force=tuple(force), moment=tuple(moment))
    fixed = d.Body(reference=(0, 0, 0), free=())
    return (moving, fixed) if case.moving == 1 else (fixed, moving)


def resultant(layer, pressure, moving: int) -> np.ndarray:
    """Force and moment about the origin (the reference) the springs exert on the moving body,
    ``(Fx, Fy, Fz, Mx, My, Mz)``: spring ``i`` pushes body 2 along ``+n_i`` and body 1 along
    ``-n_i`` with ``p_i S_i``."""
    f = (pressure * layer.areas)[:, None] * layer.normals * (1.0 if moving == 2 else -1.0)
    return np.concatenate([f.sum(axis=0), np.cross(layer.points, f).sum(axis=0)])


def lengths(layer) -> np.ndarray:
    """1 for a translation, the layer's RMS radius about the reference for a rotation (mm)."""
    radius = np.sqrt(np.mean(np.sum(layer.points**2, axis=1)))
    return np.array([1.0, 1.0, 1.0, radius, radius, radius])


def rejected(case: Case) -> bool:
    """Whether the load must be rejected: any part along unresisted dofs when no free dof is
    resisted, else a part of more than 1e-7 of it (the documented bound; the examples stay
    far from it on either side)."""
    if not case.extra:
        return False
    return case.extra > 1e-7 or all(dof in UNRESISTED[case.geometry] for dof in case.free)


def make_problem(case: Case) -> tuple[d.ContactProblem, np.ndarray]:
    """The problem and its load on the moving body (6,), built from spring forces here."""
    layer = make_layer(case)
    rng = np.random.default_rng(case.seed + 1)
    n = len(layer)
    pressure = case.law.modulus * case.strain * rng.uniform(0.0, 2.0, n) * (rng.uniform(size=n) < 0.5)
    pressure[rng.integers(n)] += case.law.modulus * case.strain
    load = -resultant(layer, pressure, case.moving)
    unresisted = [i for i, dof in enumerate(d.DOFS) if dof in UNRESISTED[case.geometry]]
    load[unresisted] = 0.0  # exactly: these sums are rounding noise
    free = [i for i, dof in enumerate(d.DOFS) if dof in case.free]
    if case.extra:
        # in arc lengths (moments over the radius), relative to the largest free component
        length = lengths(layer)
        along = [i for i in unresisted if i in free]
        size = np.abs(load[free] / length[free]).max(initial=0.0)
        size = size or case.law.modulus * float(layer.areas.sum()) * case.strain
        load[along] = case.extra * size * length[along] * rng.choice([-1.0, 1.0], len(along))
    b1, b2 = bodies(case, load[:3], load[3:])
    return d.ContactProblem(layer, case.law, body1=b1, body2=b2), load


@st.composite
def cases(draw, *, zero_load=False):
    geometry = draw(st.sampled_from(sorted(UNRESISTED)))
    if geometry == "plate":
        nx, ny = draw(st.integers(3, 10)), draw(st.integers(3, 10))
        size = 10 ** draw(st.floats(0.0, 1.5))
        shape = (size, size * draw(st.floats(0.5, 2.0)), nx, ny)
    elif geometry == "socket":
        shape = (
            10 ** draw(st.floats(0.0, 1.5)),
            draw(st.floats(30.0, 150.0)),
            draw(st.integers(2, 6)),
            draw(st.integers(5, 14)),
        )
    else:
        shape = (10 ** draw(st.floats(0.0, 1.5)), draw(st.integers(12, 90)))
    unresisted = UNRESISTED[geometry]
    pool = draw(st.sampled_from([unresisted, d.DOFS, d.DOFS, tuple(x for x in d.DOFS if x not in unresisted)]))
    free = tuple(draw(st.lists(st.sampled_from(pool), min_size=1, max_size=len(pool), unique=True)))
    unresisted_free = [dof for dof in free if dof in UNRESISTED[geometry]]
    extra = 0.0
    if not zero_load and unresisted_free and draw(st.booleans()):
        # tolerated rounding (below 1e-9 of the load) or a real part (above 1e-5)
        extra = 10 ** draw(st.one_of(st.floats(-14.0, -9.0), st.floats(-5.0, 0.0)))
    return Case(
        geometry=geometry,
        shape=shape,
        law=draw(laws()),
        moving=draw(st.sampled_from([1, 2])),
        free=tuple(dof for dof in d.DOFS if dof in free),
        area_spread=draw(st.sampled_from([0.0, 0.5, 1.0])),
        thickness=10 ** draw(st.floats(-0.5, 0.5)),
        gap_kind="press" if zero_load else draw(st.sampled_from(["open", "bonded", "press", "mixed"])),
        gap_level=draw(st.floats(0.001, 0.1)),
        strain=10 ** draw(st.floats(-3.0, -1.5)),
        extra=extra,
        seed=draw(st.integers(0, 2**31 - 1)),
    )


def solve_all(problem, law):
    out = {}
    for method in applicable(law):
        try:
            out[method] = quiet_solve(problem, method)
        except d.DeaError as exc:
            out[method] = exc
    return out


def describe(outcomes) -> str:
    return "\n".join(
        f"{m}: {type(o).__name__}: {str(o)[:200]}"
        if isinstance(o, Exception)
        else f"{m}: success={o.success} status={o.status} worst={o.certificate.worst()}"
        for m, o in outcomes.items()
    )


def check_balanced(case: Case, problem, solution, load, rtol):
    """The equilibrium check of this file: spring forces and moments summed here, compared
    with the load on every free dof (moments over the layer's RMS radius), relative to the
    load, the total spring force and the force of the initial overlap at the law's modulus."""
    layer = problem.layer
    length = lengths(layer)
    free = [i for i, dof in enumerate(d.DOFS) if dof in case.free]
    pressure = solution.pressure
    overlap = np.maximum(-layer.gap / layer.thickness, 0.0)
    scale = max(
        np.abs(load / length).max(), float(pressure @ layer.areas), case.law.modulus * float(layer.areas @ overlap)
    )
    residual = np.abs((resultant(layer, pressure, case.moving) + load) / length)[free]
    assert residual.max(initial=0.0) <= rtol * scale, (
        f"{solution.method}: springs do not balance the load: residual {residual.max() / scale:.3g} on "
        f"{[d.DOFS[free[i]] for i in np.flatnonzero(residual > rtol * scale)]}"
    )
    # no motion along what nothing resists: the answer is the minimum-norm one
    u = solution.u[6 * (case.moving - 1) : 6 * case.moving] * length
    held = [i for i in free if d.DOFS[i] in UNRESISTED[case.geometry]]
    size = np.abs(u[free]).max(initial=0.0)
    assert np.abs(u[held]).max(initial=0.0) <= 1e-8 * size, f"motion along unresisted dofs: {u[held]}"


@budget("unresisted")
@SEEDED
@given(case=cases())
def test_unresisted_free_dofs_are_rejected_or_held(case):
    problem, load = make_problem(case)
    note(repr(case))
    outcomes = solve_all(problem, case.law)
    note(describe(outcomes))
    event(
        f"{case.geometry}: "
        + (
            "rejected"
            if rejected(case)
            else "held"
            if all(dof in UNRESISTED[case.geometry] for dof in case.free)
            else "some unresisted"
            if any(dof in UNRESISTED[case.geometry] for dof in case.free)
            else "all resisted"
        )
    )
    if rejected(case):
        for method, outcome in outcomes.items():
            assert isinstance(outcome, d.LoadNotSupportedError), (
                f"{method}: a load along an unresisted dof was not rejected:\n{describe(outcomes)}"
            )
            unresisted = [f"body{case.moving}.{dof}" for dof in case.free if dof in UNRESISTED[case.geometry]]
            assert any(outcome.direction.get(name, 0.0) != 0.0 for name in unresisted)
        return
    for method, outcome in outcomes.items():
        assert not isinstance(outcome, Exception), f"{method} raised on a load inside the cone:\n{describe(outcomes)}"
        assert outcome.success
        exact = method in ("newton", "auto") and not case.extra
        check_balanced(case, problem, outcome, load, rtol=1e-8 if exact else 1e-6)
    if all(dof in UNRESISTED[case.geometry] for dof in case.free):
        # nothing resisted: every dof held, the springs keep the strain of their gaps
        for outcome in outcomes.values():
            assert outcome.status is d.Status.HELD and not outcome.u.any()
            np.testing.assert_allclose(
                outcome.pressure,
                -case.law.stress(np.minimum(problem.layer.gap / problem.layer.thickness, 0.0)),
                rtol=1e-12,
                atol=0,
            )
    assert_agree(problem, outcomes)


@budget("preload")
@SEEDED
@given(case=cases(zero_load=True))
def test_zero_load_with_overlap_is_solved_by_every_method_with_one_status(case):
    layer = make_layer(case)
    b1, b2 = bodies(case)
    problem = d.ContactProblem(layer, case.law, body1=b1, body2=b2)
    note(repr(case))
    outcomes = solve_all(problem, case.law)
    note(describe(outcomes))
    event(f"{case.geometry}: " + " ".join(sorted({getattr(o, "status", type(o).__name__) for o in outcomes.values()})))
    for method, outcome in outcomes.items():
        assert not isinstance(outcome, Exception), f"{method} raised:\n{describe(outcomes)}"
        assert outcome.success
        check_balanced(case, problem, outcome, np.zeros(6), rtol=1e-8)
    assert len({o.status for o in outcomes.values()}) == 1
    assert next(iter(outcomes.values())).status in (d.Status.HELD, d.Status.PRELOADED)
    assert_agree(problem, outcomes)
