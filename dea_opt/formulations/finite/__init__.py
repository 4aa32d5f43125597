"""Finite kinematics as arrays: the formulation ``"finite"`` (Newton, exact rotation, gaps at the current pose).

Written math: ``formulations/finite.md``. This package is the formulations' side of finite
kinematics: like every formulation it sees arrays and a law, never meshes, files or problems.
It holds

- this module: the registry's formulation ``"finite"`` (:data:`OPTIONS`, :data:`CAPABILITIES`,
  :class:`Model`, :func:`solve`), the scaling of a solve (:func:`scale`, :func:`small_system`)
  and the status of its answer (:func:`status_of`);
- :mod:`~dea_opt.formulations.finite.geometry`: exact rotations, body 2's pose, each spring's
  target on body 2 (:class:`Targets`: a plane or a sphere) and its gap, with the gap's derivative;
- :mod:`~dea_opt.formulations.finite.system`: the arrays of one problem (:class:`FiniteSystem`)
  and everything at one pose of body 2 (:class:`State`: forces, residual, tangent);
- :mod:`~dea_opt.formulations.finite.newton`: Newton with the consistent tangent, and the raw
  answer every finite solve gives (:class:`InnerResult`);
- :mod:`~dea_opt.formulations.finite.motion`: which motions of body 2 change a gap at all (the
  load check's question);
- :mod:`~dea_opt.formulations.finite.nlp` with :mod:`~dea_opt.formulations.finite.ipopt`: the
  formulation ``"finite_nlp"``, IPOPT on a conservative surrogate, the independent cross-check;
- ``_finite.c``: the optional C kernel of the two passes over the springs (the gaps to plane
  targets and the tangent's sum), each with its numpy twin.

A solve takes a :class:`FiniteSystem`: the springs on body 1 (points and unit normals (N, 3),
areas (N,) mm^2, thicknesses (N,) mm), their targets, body 2's reference point (3,) mm, its free
and prescribed coordinates among ``(ux, uy, uz, rx, ry, rz)`` (mm, rad: ``u[6:12]`` of the
12-vector, the rotation vector taken as an exact rotation) and the load on body 2 (force (3,) N
at the reference, moment (3,) N mm). It returns an :class:`InnerResult`: body 2's free
coordinates at equilibrium (m,), the springs' :class:`State` there and the solver's status. These
two types are the registry's contract for finite kinematics
(``dea_opt.formulations.CONTRACTS["finite"]``).

:mod:`dea_opt.finite` is the other side: it builds these arrays from a
``ContactProblem(..., kinematics="finite")``, re-casts springs cast from meshes between solves and
certifies the answer at the solved pose; ``dea_opt.solve`` sends a finite problem there. The QP
is a small-kinematics method only.
"""

from __future__ import annotations

import numpy as np

from ...status import CERTIFIABLE, Status
from .._parts.options import Capabilities, Option, newton_tolerances
from .._parts.resistance import modulus_scale, resistance
from .._parts.system import SpringSystem, start_vector
from .geometry import Targets, evaluate
from .motion import motion
from .newton import InnerResult, escape_step
from .rotations import left_jacobian, pose_matrix, rotation
from .system import FiniteSystem, State, generalized

__all__ = [
    "CAPABILITIES",
    "OPTIONS",
    "RECAST_OPTIONS",
    "SHARED",
    "FiniteModel",
    "FiniteSystem",
    "InnerResult",
    "Model",
    "State",
    "Targets",
    "escape_step",
    "evaluate",
    "generalized",
    "left_jacobian",
    "pose_matrix",
    "rms_radius",
    "rotation",
    "scale",
    "small_system",
    "solve",
    "status_of",
]

PAGE = "formulations/finite.md"

#: The re-casting options of both finite formulations (formulations/finite.md, "Re-casting"):
#: declared here so that the registry checks them, used by :mod:`dea_opt.finite`.
RECAST_OPTIONS = (
    Option("recast", bool, True, "keep springs cast from meshes (targets= a SpringCast) up to date as body 2 moves"),
    Option(
        "recast_shift",
        float,
        0.01,
        "mm a spring's hit may move before its thickness is measured again",
        range=(0, float("inf")),
    ),
    Option(
        "full_shift",
        float,
        5.0,
        "mm the hits may move before the whole of mesh 1 is cast again",
        range=(0, float("inf")),
    ),
    Option("max_recasts", int, 10, "updates of the springs after converged solves, at most", range=(0, None)),
)
#: The re-casting options both finite formulations declare: under ``auto`` they go to both.
SHARED = tuple(option.name for option in RECAST_OPTIONS)
#: The options of :func:`solve` with ``method="finite"``.
OPTIONS = (
    *newton_tolerances("the contact set is"),
    Option("max_iter", int, 100, "Newton iterations per solve, at most", range=(1, None)),
    Option(
        "extended_start",
        bool,
        True,
        "treat every spring as active, tension included, in the first iteration of a cold start",
    ),
    *RECAST_OPTIONS,
)
CAPABILITIES = Capabilities(laws="any", warm_start=True, kinematics=("finite",), duals=False, checks_load_first=False)
EXTRA_OPTIONS = None
VARIANT = None
_NEWTON = ("xtol", "gtol", "max_iter", "extended_start")


def scale(T1, load, system: FiniteSystem, law, e0=None) -> tuple[np.ndarray, float]:
    """``(T, E0)``: the scaled directions ``T = T1 s`` of the small kinematics' scaling (see
    ``formulations/finite.md``, "Newton") and the energy scale ``E0 = s^2``, ``s`` the larger of the load's size ``|T1^T load|`` and
    the overlap of the springs' exact gaps at ``system.base``.

    Parameters
    ----------
    T1 : ndarray (m, k)
        The resisted directions, K0-orthonormal at unit scale (``SpringSystem.resistance.basis``).
    load : ndarray (m,)
        The load on the free coordinates (N, N mm).
    e0 : ndarray (N,), optional
        The springs' strains at ``system.base``, when already known (else evaluated).
    """
    s_load = float(np.linalg.norm(T1.T @ load)) if np.size(load) else 0.0
    e0 = system.state(system.base, law).eps if e0 is None else e0
    overlap = np.minimum(np.where(np.isfinite(e0), e0, 0.0), 0.0)
    volume = system.areas * system.thickness * modulus_scale(law.modulus)
    s = max(s_load, float(np.linalg.norm(np.sqrt(volume) * overlap)))
    if not (s > 0.0 and np.isfinite(s)):
        s = 1.0
    return T1 * s, s * s


def small_system(system: FiniteSystem, law) -> SpringSystem:
    """The small kinematics' :class:`~dea_opt.formulations.SpringSystem` of ``system`` at
    ``system.base``: the strain per unit free coordinate ``blockdiag(I, J)^T a_i / h_i``, the
    strains there, the load, and lengths (1 mm, the springs' RMS distance from the reference for
    a rotation), with its resisted directions decided, and, for targets not cast from meshes, as
    ``small.motion`` the :class:`~dea_opt.formulations.finite.motion.Motion` of the exact
    gaps there (which free motions change a gap at all: ``dea_opt.solve``'s load check)."""
    state = system.state(system.base, law)
    free = system.free
    AT = np.ascontiguousarray(generalized(state)[free] / system.thickness)
    volume = system.areas * system.thickness
    radius = rms_radius(system) if len(system) else 1.0
    lengths = np.where(free < 3, 1.0, max(radius, 1e-12))
    factor = np.asarray(np.linalg.qr((AT * np.sqrt(volume)).T, mode="r")) if AT.size else np.zeros((0, len(free)))
    e0 = np.where(np.isfinite(state.eps), state.eps, 1e300)
    small = SpringSystem(
        AT, e0, volume, state.load6[free], lengths, factor, float(np.sum(system.areas / system.thickness))
    )
    small.__dict__["resistance"] = resistance(small)
    # which free motions change a gap at all (the forces' directions above need not): the load
    # check's; not for targets cast from meshes, which a solve re-casts as body 2 moves (it does
    # not decide there, and every finite solve builds this system: no QR of the springs for nothing)
    if system.targets.faces is None:
        small.__dict__["motion"] = motion(system, state, small)
    return small


def rms_radius(system: FiniteSystem) -> float:
    """The springs' RMS distance from body 2's reference at zero displacement (mm)."""
    rows = system.points.T if system.planes is None else system.planes.pT
    c = system.reference
    squared = rows[0] * rows[0] + rows[1] * rows[1] + rows[2] * rows[2]
    mean = rows.mean(axis=1)
    return float(np.sqrt(max(float(squared.mean()) - 2.0 * float(c @ mean) + float(c @ c), 0.0)))


def status_of(native: str, success: bool, system: FiniteSystem, state) -> Status:
    """The answer's :class:`~dea_opt.status.Status`: the solver's, in dea-opt's vocabulary, with the
    statuses every method gives the same situation (no load: ``unloaded`` or ``preloaded``) and
    ``inaccurate`` for a convergence the certificate rejects."""
    try:
        status = Status(native)
    except ValueError:
        status = Status.SOLVER_ERROR
    if success and status not in CERTIFIABLE:  # certified where the solver doubted it (its word: native_status)
        status = Status.CONVERGED
    if status is Status.CONVERGED and success and not (system.force.any() or system.moment.any()):
        return Status.PRELOADED if (state.eps < 0).any() else Status.UNLOADED
    if status is Status.CONVERGED and not success:
        return Status.INACCURATE
    return status


def solve(
    system: FiniteSystem, law, T, energy_scale: float, *, x0=None, cold=None, start_state=None, **options
) -> InnerResult:
    """The equilibrium of ``system``'s free coordinates for its targets, by Newton.

    Parameters
    ----------
    system : FiniteSystem
    law : Law
    T : ndarray (m, k)
        The scaled directions (:func:`scale`): ``x = x0 + T xi``.
    energy_scale : float
        ``E0`` (N mm).
    x0 : array_like (m,), optional
        The start (mm, rad); zero by default.
    cold : bool, optional
        ``x0`` is no warm start (the first iteration may take the extended range); by default,
        whether ``x0`` was given.
    start_state : State, optional
        ``system.state(system.coordinates(x0), law)``, when the caller has it (not computed again).
    **options
        :data:`OPTIONS` (the re-casting ones are :mod:`dea_opt.finite`'s and ignored here).
    """
    from . import newton

    x = np.zeros(len(system.free)) if x0 is None else np.asarray(x0, dtype=float)
    cold = x0 is None if cold is None else cold
    if not len(system.free):
        state = system.state(system.base, law)
        return InnerResult(np.zeros(0), state, True, "no_free_dofs", "every dof is fixed or prescribed")
    defaults = {option.name: option.default for option in OPTIONS}
    chosen = {k: options.get(k, defaults[k]) for k in _NEWTON}
    start = start_state if x0 is not None else None
    return newton.solve(system, law, T, energy_scale, x0=x, cold=cold, start_state=start, **chosen)


class FiniteModel:
    """A :class:`FiniteSystem` and a law, re-solvable for new loads, warm-started from its last answer.

    ``Model(system, law, **options)`` as for every formulation (the system is a
    :class:`FiniteSystem`, built from a ``ContactProblem(..., kinematics="finite")`` by
    :mod:`dea_opt.finite`); ``solve(load=None, *, x0=None)`` returns the raw
    :class:`InnerResult` for the load ``(F, M)`` on body 2 (N, N mm; the system's own by
    default), scaled by :func:`small_system` at its base.
    """

    method = "finite"
    run = staticmethod(solve)  # the formulation's solve on the arrays (before the method of that name)

    def __init__(self, system, law, **options):
        from ...errors import InputError

        if not isinstance(system, FiniteSystem):
            raise InputError(
                f"the {self.method} formulation solves a FiniteSystem (the arrays of a problem with "
                f"kinematics='finite'; dea_opt.solve builds them from a ContactProblem), not "
                f"{type(system).__name__}"
            )
        self.system, self.law, self.options = system, law, options
        self.build_time = 0.0
        self._x = None

    def solve(self, load=None, *, x0=None) -> InnerResult:
        system = self.system if load is None else self.system.with_load(*load)
        small = small_system(system, self.law)
        T, E0 = scale(small.resistance.basis(self.law.modulus), small.load, system, self.law)
        start = start_vector(small, x0)
        start = self._x if start is None else start
        result = type(self).run(system, self.law, T, E0, x0=start, **self.options)
        if result.success:
            self._x = result.u_free
        return result


Model = FiniteModel
