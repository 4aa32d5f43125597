"""Finite kinematics: which negative verdicts on a load are proved, and how an unproved one is said.

Written math: ``formulations/finite.md`` ("What the layer can carry"). A failed solve proves
nothing about the problem: Newton's iterates may have crushed springs, run away, or lost springs
through the layer from one start where another start, a load continuation or IPOPT finds an
equilibrium. A verdict about the load itself stands only where :func:`prove` finds it from the
problem: along the balances of body 2 that do not depend on its pose (:func:`balances`), no
compression of the springs the layer can ever have (:func:`candidates`), each at most its stress
at strain -1 (:func:`stress_limit`), carries the load. :func:`prove` looks for a direction ``y``
of those balances along which the load asks more than every spring can give (Farkas' lemma;
cutting planes, each a small LP for scipy's HiGHS) and checks it itself. Otherwise the answer is a solve
that did not converge (:func:`judge`). Used by :mod:`~dea_opt.finite.driver` and
:mod:`~dea_opt.finite.means`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Proof", "balances", "candidates", "judge", "prove", "raise_unsupported", "stress_limit"]

#: The load must exceed what the springs carry along ``y`` by this fraction for a proof: far above
#: the rounding of sums over 1e5 springs, and of HiGHS's tolerances (whose ``y`` is checked here).
_MARGIN = 1e-6
_AXES = ("x", "y", "z")


@dataclass(frozen=True)
class Proof:
    """A verdict on the load proved from the problem.

    Attributes
    ----------
    kind : str
        ``"unsupported"`` (no compression of any spring the layer can have pushes along ``y``, however
        large) or ``"crushed"`` (they push along it, but less than the load asks, even with every
        spring at strain -1).
    direction : str
        ``y`` in words (the balances and their weights).
    demand, capacity : float
        What the load asks along ``y``, and the most the springs give along it (N; moments over the
        springs' radius ``length``).
    n_springs : int
        The springs the layer can have (the bound sums over them).
    limit : float
        The law's compressive stress at strain -1 (MPa; inf for a law unbounded there).
    length : float
        The radius moments were divided by (mm).
    parts : dict
        The load's part along ``y`` on the free dofs of its balances (``{"body2.uz": N, ...}``, N and
        N mm): what no compression of the springs balances.
    """

    kind: str
    direction: str
    demand: float
    capacity: float
    n_springs: int
    limit: float
    length: float
    parts: dict

    def message(self) -> str:
        where = f"along {self.direction}"
        springs = f"{self.n_springs} springs the layer can have"
        if self.kind == "unsupported":
            return (
                f"compression-only springs cannot carry this load at any pose: {where} the load asks "
                f"{self.demand:.4g} N, and none of the {springs} pushes body 2 that way (a balance of body 2 "
                f"that holds at every pose; formulations/finite.md, 'What the layer can carry')"
            )
        return (
            f"proved: {where} the load asks {self.demand:.4g} N, more than the {springs} carry there with "
            f"every one crushed to strain -1 ({self.capacity:.4g} N at the law's {self.limit:.4g} MPa; a balance "
            f"of body 2 that holds at every pose, formulations/finite.md, 'What the layer can carry')"
        )


def stress_limit(law) -> float:
    """The law's compressive stress at strain -1 (MPa, > 0): the most a spring carries inside the model
    (past it body 2 passes through body 1); inf for a law that stiffens without bound there."""
    if law.bounded_strain:
        return np.inf
    with np.errstate(all="ignore"):
        value = -float(law.stress(np.array([-1.0]))[0])
    return value if np.isfinite(value) and value > 0 else np.inf


def candidates(problem, cast) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(points, normals, areas)`` (N, 3), (N, 3), (N,): every spring the layer can have, on body 1
    (which does not move): the layer's own springs, or for springs cast from meshes (``cast``, a
    :class:`~dea_opt.mesh.SpringCast`) one on every face of mesh 1, as a cast at some pose makes
    them (the face's centroid, its normal, its area)."""
    if cast is None:
        layer = problem.layer
        return np.asarray(layer.points), np.asarray(layer.normals), np.asarray(layer.areas)
    mesh = cast.mesh1
    normals = np.asarray(mesh.face_normals, dtype=float)
    if cast.options.get("flip"):
        normals = -normals
    return np.asarray(mesh.triangles_center, dtype=float), normals, np.asarray(mesh.area_faces, dtype=float)


def balances(problem, points, normals) -> tuple[np.ndarray, np.ndarray, list[tuple]]:
    """``(A, b, names)``: the balances of body 2 that hold at every pose, ``A c = b`` for the
    compressive forces ``c >= 0`` (N) of springs at ``points`` along ``normals`` (rows (k, N),
    moments in N mm), and for each its name in words and the free dof it balances (``"body2.uz"``;
    None for an axis along no coordinate).

    A free translation ``t_k`` balances the springs' force along ``e_k``, whatever the pose (the
    springs push along their own directions, fixed on body 1). A moment about an axis ``e`` through
    the base position ``q`` of body 2's reference balances when the rotation coordinates give it at
    every pose (all three rotations free, or only the one along ``e``, the others held at zero) and
    no free translation moves the reference in a way the balance sees (``e x t`` along free
    translations, doing no work against the load's force: ``F . (e x t) = 0``).
    """
    body = problem.body2
    free = set(body.free)
    force = np.asarray(body.force, dtype=float)
    moment = np.asarray(body.moment, dtype=float)
    base = np.zeros(6)
    for i, name in enumerate(("ux", "uy", "uz", "rx", "ry", "rz")):
        base[i] = body.prescribed.get(name, 0.0)
    q = np.asarray(body.reference, dtype=float) + base[:3]
    rows: list = []
    rhs: list = []
    names: list[tuple[str, str | None]] = []
    moved = [k for k in range(3) if f"u{_AXES[k]}" in free]
    for k in moved:
        rows.append(-normals[:, k])
        rhs.append(force[k])
        names.append((f"the force along {_AXES[k]}", f"body2.u{_AXES[k]}"))
    turning = [k for k in range(3) if f"r{_AXES[k]}" in free]
    axes: list[np.ndarray] = []
    if len(turning) == 3:
        axes = [np.eye(3)[k] for k in range(3)]
        if np.linalg.norm(force) > 0:
            axes.append(force / np.linalg.norm(force))
    elif len(turning) == 1 and not np.any(base[3:]):
        axes = [np.eye(3)[turning[0]]]
    kept: list[np.ndarray] = []
    for e in axes:
        if _sees_no_translation(e, moved, force) and all(abs(e @ other) < 1 - 1e-12 for other in kept):
            kept.append(e)
    arms = np.cross(points - q, normals)
    for e in kept:
        rows.append(-(arms @ e))
        rhs.append(float(e @ moment))
        axis = next((_AXES[k] for k in range(3) if abs(e[k]) == 1.0), None)
        names.append((_moment_name(e, q), None if axis is None else f"body2.r{axis}"))
    if not rows:
        return np.zeros((0, len(points))), np.zeros(0), []
    return np.array(rows), np.array(rhs), names


def _sees_no_translation(e, moved, force) -> bool:
    for k in moved:
        turned = np.cross(e, np.eye(3)[k])
        outside = [j for j in range(3) if j not in moved]
        scale = max(float(np.linalg.norm(force)), 1.0)
        if np.abs(turned[outside]).max(initial=0.0) > 1e-12 or abs(float(force @ turned)) > 1e-12 * scale:
            return False
    return True


def _moment_name(e, q) -> str:
    axis = next((_AXES[k] for k in range(3) if abs(e[k]) == 1.0), None)
    point = ", ".join(f"{c:.4g}" for c in q)
    along = f"{axis}" if axis else "(" + ", ".join(f"{c:.3g}" for c in e) + ")"
    return f"the moment along {along} about ({point}) mm"


def prove(problem, cast=None) -> Proof | None:
    """A :class:`Proof` that no equilibrium inside the model carries ``problem``'s load, or None.

    ``cast``: the :class:`~dea_opt.mesh.SpringCast` springs are re-cast from (None: the layer's
    springs are all there is). The forces the springs can give on the balances, ``A c`` over
    ``0 <= c_i <= U_i = S_i sigma_-1`` (:func:`balances`, :func:`candidates`, :func:`stress_limit`),
    fill a zonotope whose support function along ``y`` is ``h(y) = sum_i U_i max(a_i . y, 0)``; the
    load ``b`` lies outside it exactly where some ``y`` has ``b . y > h(y)`` (Farkas' lemma).
    :func:`_farkas` looks for that ``y`` (Kelley's cutting planes on the concave ``b . y - h(y)``,
    ``k <= 6`` unknowns), and :func:`_check` checks it.
    """
    points, normals, areas = candidates(problem, cast)
    A, b, names = balances(problem, points, normals)
    if not len(b) or not np.any(b) or not len(areas):
        return None
    q = np.asarray(problem.body2.reference, dtype=float)
    length = max(float(np.sqrt(np.mean(np.sum((points - q) ** 2, axis=1)))), 1.0)
    scale = np.array([1.0 if text.startswith("the force") else 1.0 / length for text, _ in names])
    A, b = A * scale[:, None], b * scale  # moments as forces at the springs' radius
    limit = stress_limit(problem.law)
    upper = areas * limit
    y = _farkas(A, b, upper)
    return None if y is None else _check(A, b, upper, y, names, scale, limit, length)


#: Cutting planes :func:`_farkas` adds at most before it leaves the load undecided (no proof).
_CUTS = 200


def _farkas(A, b, upper) -> np.ndarray | None:
    """A ``y`` (k,) in the box ``|y| <= 1`` with ``b . y > h(y) = sum_i upper_i max(a_i . y, 0)``
    (``A`` (k, n): the columns ``a_i``; ``upper`` (n,), inf allowed), or None where none is found.

    ``phi(y) = b . y - h(y)`` is concave, piecewise linear and positively homogeneous: at any ``y_j``
    it is ``s_j . y_j`` with the supergradient ``s_j = b - sum_{a_i . y_j > 0} upper_i a_i``, and
    ``phi <= s_j . y`` everywhere. Each round maximises ``t`` over ``t <= s_j . y`` for the cuts so
    far (and ``a_i . y <= 0`` for the springs of unbounded stress met so far) in the box: a small
    LP (HiGHS) whose optimum bounds ``max phi`` from above. It stops where ``phi`` at the LP's
    ``y`` proves (``_MARGIN``), or where the bound shows that nothing can."""
    from scipy.optimize import linprog

    k, n = A.shape
    finite = np.isfinite(upper)
    weights = np.where(finite, upper, 0.0)
    size = float(np.abs(b).sum())
    rows: list[np.ndarray] = [np.concatenate([-b, [1.0]])]  # t <= b . y: the cut at y = 0
    bounds = [(-1.0, 1.0)] * k + [(None, None)]
    cost = np.zeros(k + 1)
    cost[-1] = -1.0
    for _ in range(_CUTS):
        result = linprog(cost, A_ub=np.array(rows), b_ub=np.zeros(len(rows)), bounds=bounds, method="highs")
        if result.status != 0 or result.x is None:
            return None
        y, bound = result.x[:k], float(result.x[-1])
        if not bound > _MARGIN * size:
            return None  # max phi is no more than rounding: the load lies in the zonotope
        push = A.T @ y
        blocked = ~finite & (push > 0)
        if blocked.any():  # a spring of unbounded stress pushes along y: no y with it counts
            worst = int(np.argmax(np.where(blocked, push, -np.inf)))
            rows.append(np.concatenate([A[:, worst], [0.0]]))
            continue
        reaching = push > 0
        supergradient = b - A[:, reaching] @ weights[reaching]
        if float(supergradient @ y) > _MARGIN * float(b @ y) and float(b @ y) > 0:
            return y
        rows.append(np.concatenate([-supergradient, [1.0]]))
    return None


def _check(A, b, upper, y, names, scale, limit, length) -> Proof | None:
    """The proof along ``y`` (k,), checked in numpy: the load's ``b . y`` against the most the springs
    give along it. None where it does not prove."""
    if not np.isfinite(y).all() or not np.any(y):
        return None
    y = y / np.abs(y).max()
    push = A.T @ y  # each spring's force per unit compression, along y
    demand = float(b @ y)
    if not demand > 0:
        return None
    reaching = push > 0
    if reaching.any() and not np.isfinite(upper[reaching]).all():
        return None  # a spring pushing along y whose stress has no bound: no proof
    capacity = float(np.sum(upper[reaching] * push[reaching])) if reaching.any() else 0.0
    if not capacity < (1.0 - _MARGIN) * demand:
        return None
    terms = [f"{w:+.3g} x {text}" for w, (text, _) in zip(y, names) if abs(w) > 1e-9]
    direction = " ".join(terms) + (f" (moments over {length:.4g} mm)" if any(s != 1 for s in scale) else "")
    kind = "unsupported" if not reaching.any() else "crushed"
    # the load's part along y, on the dofs of its balances (N, N mm): what is left unbalanced
    along = (demand / float(y @ y)) * y / scale
    parts = {dof: float(value) for value, (_, dof) in zip(along, names) if dof is not None and abs(value) > 0}
    return Proof(kind, direction, demand, capacity, int(len(push)), limit, length, parts)


def raise_unsupported(proof: Proof | None, problem) -> None:
    """Raise :class:`~dea_opt.errors.LoadNotSupportedError` where ``proof`` shows that no spring the
    layer can have pushes along the load (``problem``'s), at any pose."""
    from ..errors import LoadNotSupportedError

    if proof is not None and proof.kind == "unsupported":
        raise LoadNotSupportedError(
            f"{proof.message()}. Check the load's sign (body 2 is pushed toward body 1 by a load along -normal) "
            f"and its units (N, N mm), fix those dofs, or add springs",
            direction=dict(proof.parts),
        )


def judge(solution, proof: Proof | None, problem) -> None:
    """The last word on a failed ``solution`` (a :class:`~dea_opt.finite.solution.FiniteSolution`,
    changed in place): ``crushed`` where ``proof`` (:func:`prove`) proves it, a
    :class:`~dea_opt.errors.LoadNotSupportedError` where it proves that no spring the layer can have
    pushes along the load; else a ``crushed`` or ``unbounded`` the solve gave (what its iterates
    met) is what it is, a solve that did not converge (``max_iterations``, ``info["unproved"]``
    keeping the solve's word), its message keeping what the iterates did."""
    from ..status import Status

    if solution.success:
        return
    raise_unsupported(proof, problem)
    if proof is not None:
        solution.info["proved"] = proof.kind
        if solution.status is not Status.CRUSHED or proof.message() not in solution.message:
            message = f"{proof.message()}: the load is beyond what this layer can bear; {solution.message}"
            object.__setattr__(solution, "message", message)
        object.__setattr__(solution, "status", Status.CRUSHED)
        solution.info["failure"] = "the layer is crushed: the load is beyond what it can bear (proved)"
        return
    if solution.status not in (Status.CRUSHED, Status.UNBOUNDED):
        return
    was = solution.status.value
    solution.info["unproved"] = was
    solution.info.pop("failure", None)
    object.__setattr__(solution, "status", Status.MAX_ITERATIONS)
    object.__setattr__(
        solution,
        "message",
        f"did not converge: {solution.message} (not a verdict on the load: {was!r} is not proved, as along every "
        f"balance of body 2 that holds at every pose the springs the layer can have carry it inside the "
        f"model; formulations/finite.md, 'What the layer can carry')",
    )
