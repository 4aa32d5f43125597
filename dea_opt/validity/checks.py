"""The validity checks, one function each (``formulations/validity.md``): the strain against the
law's range and crushing, the rotation and the gap error of the small kinematics, the layer's
sizes, the peak pressure, the springs the cast dropped or lost through the layer, and the
stability of a finite-kinematics equilibrium.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from ..formulations._parts.sweeps import BLOCK, blocks
from .report import Check, ValidityLimits, _limit

__all__ = ["rotation_gap_error"]


_NOT_FINITE = "the value is not finite: the solution failed (see its certificate)"


def _strain_check(law, strain, limits: ValidityLimits) -> Check:
    own = limits.compression if limits.compression is not None else getattr(law, "valid_compression", None)
    if own is not None:
        own = _limit(f"{type(law).__name__}.valid_compression", own, 1.0)
    limit = limits.crushing if own is None else min(own, limits.crushing)
    value = float(max(-np.min(strain), 0.0)) if len(strain) else 0.0
    if np.isnan(strain).any():
        value = math.nan
    if value <= limit:
        return Check("strain", value, limit, "", True)
    return Check("strain", value, limit, "", False, _strain_advice(law, value, limit, limits))


def _strain_advice(law, value, limit, limits) -> str:
    if not math.isfinite(value):
        return _NOT_FINITE
    if value >= 1.0:
        return (
            "a spring is crushed through its whole thickness (strain <= -1), which is not physical: "
            "use a bounded law such as AteshianLaw or a smaller load, and check H and the thickness"
        )
    if value > limits.crushing:
        return (
            f"the cartilage is nearly crushed: past {limits.crushing:.0%} compression only its solid "
            f"matrix would be left, which no law of a porous layer describes; check the load, H and the "
            f"thickness"
        )
    if getattr(law, "is_linear", False) and limits.compression is None:
        return (
            f"beyond the range of the linear law ({limit:.0%} compressive strain, where Volokh, Chao & "
            f"Armand find it valid): use AteshianLaw, or check the load and H"
        )
    return f"beyond the range of {law.describe()} ({limit:.0%} compressive strain): use a law valid there"


def _rotation_error_factors(angle: float) -> tuple[float, float]:
    """``(a, b)`` with ``R - I - W = a W + b W^2`` for the rotation by ``angle`` (rad).

    ``a = sin(t)/t - 1`` (its series below 1e-4, where the difference cancels), ``b =
    (1 - cos t)/t^2 = 2 sin(t/2)^2 / t^2`` (formulations/validity.md).
    """
    if angle == 0.0:
        return 0.0, 0.5
    a = -(angle**2) / 6.0 + angle**4 / 120.0 if angle < 1e-4 else math.sin(angle) / angle - 1.0
    b = 2.0 * (math.sin(0.5 * angle) / angle) ** 2
    return a, b


def rotation_gap_error(problem, u) -> np.ndarray:
    """Exact minus linearised motion along each spring's normal (mm), shape (N,).

    For body ``k`` rotated by the vector ``theta_k = u[3:6]`` (or ``u[9:12]``) about its
    reference ``c_k``, the exact motion of a point ``x`` is ``t_k + (R_k - I)(x - c_k)`` and
    the linearised one of Eq. (9) is ``t_k + theta_k x (x - c_k)``; the result is
    ``n_i . (e_2(x_i) - e_1(x_i))`` with ``e_k = (R_k - I - [theta_k]x)(x - c_k)``, the error
    in the spring's gap (formulations/validity.md).
    """
    layer = problem.layer
    u = np.asarray(u, dtype=float)
    error = np.zeros(len(layer))
    matrices, work = _gap_error_matrices(problem, u), _work(len(layer))
    for part in blocks(len(layer)):
        error[part] = _gap_error_block(problem, part, matrices, work)
    return error


def _gap_error_matrices(problem, u) -> list | None:
    """``[(M_k, c_k)]`` for each rotating body: ``R - I - W = a W + b W^2``
    (:func:`_rotation_error_factors`) signed by the body (body 1 -, body 2 +); None where a
    rotation is not finite."""
    matrices = []
    for sign, body, k in ((-1.0, problem.body1, 3), (1.0, problem.body2, 9)):
        theta = u[k : k + 3]
        angle = float(np.linalg.norm(theta))
        if not math.isfinite(angle):
            return None
        if angle == 0.0:
            continue
        a, b = _rotation_error_factors(angle)
        W = np.array([[0.0, -theta[2], theta[1]], [theta[2], 0.0, -theta[0]], [-theta[1], theta[0], 0.0]])
        # W^2 = theta theta^T - |theta|^2 I
        M = sign * (a * W + b * (np.outer(theta, theta) - angle**2 * np.eye(3)))
        matrices.append((M, np.asarray(body.reference, dtype=float)[:, None]))
    return matrices


def _work(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Two (3, min(BLOCK, n)) buffers for :func:`_gap_error_block`, made once per sweep: a fresh
    temporary of three values a spring per block is a fresh mapping of pages (``sweeps.BLOCK``)."""
    size = min(BLOCK, n)
    return np.empty((3, size)), np.empty((3, size))


def _gap_error_block(problem, part: slice, matrices, work) -> np.ndarray:
    """:func:`rotation_gap_error` over the springs ``part`` (``matrices`` from
    :func:`_gap_error_matrices`, ``work`` from :func:`_work`), from the springs' points and normals:
    ``n . sum_k M_k (x - c_k)``, one small product of the block's points per rotating body and a
    row-wise dot with its normals (its temporaries in cache: ``dea_opt/formulations/_parts/sweeps.py``)."""
    layer = problem.layer
    normals, points = layer.normals[part], layer.points[part]
    m = len(points)
    if matrices is None:
        return np.full(m, np.nan)
    if not matrices:
        return np.zeros(m)
    # Coordinates by rows of the buffers (3, m): arithmetic along rows of three values a spring
    # is several times slower.
    r, moved = work[0][:, :m], work[1][:, :m]
    for j, (M, reference) in enumerate(matrices):
        np.subtract(points.T, reference, out=r)
        if j == 0:
            np.matmul(M, r, out=moved)
        else:
            moved += M @ r
    error = normals[:, 0] * moved[0]
    error += normals[:, 1] * moved[1]
    error += normals[:, 2] * moved[2]
    return error


_KINEMATICS_ADVICE = (
    "outside the small-rotation kinematics of Eq. (9)-(11): use finite kinematics, "
    "ContactProblem(..., kinematics='finite') (exact rotations, gaps at the current pose; "
    "formulations/finite.md), fix the dofs the joint does not move, or reduce the load"
)
_FINITE = (
    "finite kinematics take rotations exactly: the small kinematics' error does not apply, and springs "
    "re-cast as body 2 moves (or closed-form targets) have no tangent planes' error"
)


#: deg: the rotation vector's principal range. Past it the vector has wound: the same pose has a
#: shorter one, and its components no longer turn body 2 about their own axes.
HALF_TURN = 180.0


def _turn_check(u) -> Check:
    """Finite kinematics: body 2's rotation vector within a half turn (body 1 does not move)."""
    degrees = math.degrees(float(np.linalg.norm(u[9:12])))
    if not math.isfinite(degrees):
        return Check("rotation", math.nan, HALF_TURN, "deg", False, _NOT_FINITE)
    if degrees <= HALF_TURN * (1 + 1e-12):
        return Check("rotation", degrees, HALF_TURN, "deg", True)
    advice = (
        f"body 2's rotation vector turns {degrees:.4g} deg, past a half turn: it has wound through whole "
        f"turns (the pose is {math.degrees(math.remainder(math.radians(degrees), 2 * math.pi)):+.4g} deg about "
        f"the same axis), so its components no longer turn body 2 about their axes and a free one can undo a "
        f"prescribed one; start from a rotation within a half turn (x0), prescribe large motions as a frame "
        f"(poses=, a pose column), or fix the rotations the joint does not make"
    )
    return Check("rotation", degrees, HALF_TURN, "deg", False, advice)


def _plane_check(plane_error, limits: ValidityLimits) -> Check:
    """Finite kinematics: the tangent planes of springs that were not re-cast, against mesh 2."""
    if plane_error is None:
        return Check("gap_error", math.nan, limits.gap_error, "of thickness", None, _FINITE, (("mm", math.nan),))
    relative, mm = plane_error
    passed = bool(relative <= limits.gap_error)
    advice = (
        ""
        if passed
        else _NOT_FINITE
        if math.isnan(relative)
        else f"the start cast's tangent planes, not re-cast as body 2 moved (recast=False), misplace a "
        f"spring's compression by {mm:.3g} mm against mesh 2 at the solved pose: solve with recast=True "
        f"(the default), which keeps the springs on mesh 2"
    )
    return Check("gap_error", relative, limits.gap_error, "of thickness", passed, advice, (("mm", mm),))


def _rotation_checks(problem, u, limits: ValidityLimits, plane_error=None) -> tuple[Check, Check]:
    u = np.asarray(u, dtype=float)
    degrees = math.degrees(max(float(np.linalg.norm(u[3:6])), float(np.linalg.norm(u[9:12]))))
    if getattr(problem, "kinematics", "small") == "finite":
        return _turn_check(u), _plane_check(plane_error, limits)
    if not np.isfinite(u).all():
        degrees = math.nan
    passed = degrees <= limits.rotation
    advice = "" if passed else _NOT_FINITE if math.isnan(degrees) else (f"the rotation is {_KINEMATICS_ADVICE}")
    rotation = Check("rotation", degrees, limits.rotation, "deg", passed, advice)
    layer = problem.layer
    if not len(layer):
        return rotation, Check(
            "gap_error",
            math.nan,
            limits.gap_error,
            "of thickness",
            None,
            "the layer has no springs",
            (("mm", math.nan),),
        )
    mm = relative = 0.0
    matrices, work = _gap_error_matrices(problem, u), _work(len(layer))
    for part in blocks(len(layer)):  # the largest error, without an array of N of it
        error = np.abs(_gap_error_block(problem, part, matrices, work))
        mm = float(np.max([mm, np.max(error)]))  # (NaN kept: a failed answer)
        relative = float(np.max([relative, np.max(error / layer.thickness[part])]))
    passed = relative <= limits.gap_error
    advice = (
        ""
        if passed
        else _NOT_FINITE
        if math.isnan(relative)
        else (f"the linearised rotation misplaces a spring by {mm:.3g} mm along its normal, {_KINEMATICS_ADVICE}")
    )
    return rotation, Check("gap_error", relative, limits.gap_error, "of thickness", passed, advice, (("mm", mm),))


def _range_check(name, value, limit, unit, small, large) -> Check:
    low, high = limit
    if low <= value <= high:
        return Check(name, value, limit, unit, True)
    return Check(name, value, limit, unit, False, small if value < low else large)


def _size_checks(layer, limits: ValidityLimits) -> tuple[Check, ...]:
    names = (
        ("extent", limits.extent, "mm"),
        ("layer_area", limits.layer_area, "mm^2"),
        ("thickness", limits.thickness, "mm"),
    )
    if not len(layer):
        return tuple(Check(n, math.nan, lim, unit, None, "the layer has no springs") for n, lim, unit in names)
    area = float(layer.areas.sum())
    # A layer is at least as large as its area says: springs at one point stand for a patch.
    # One strided pass per coordinate is 10x faster than np.ptp(axis=0) over (N, 3).
    span = [float(column.max() - column.min()) for column in layer.points.T]
    extent = max(math.hypot(*span), math.sqrt(area))
    # an elementwise sum, not BLAS's dot: a dot over 1e4 springs wakes a second BLAS thread, which
    # costs milliseconds when the other core is busy (this runs outside the solve's one-thread context)
    thickness = float(np.sum(layer.areas * layer.thickness) / area)
    metres = "the geometry looks like metres: load meshes with load_mesh(path, scale=1000)"
    microns = "the geometry looks like micrometres: load meshes with load_mesh(path, scale=0.001)"
    return (
        _range_check(
            "extent",
            extent,
            limits.extent,
            "mm",
            f"the springs span {extent:.3g} mm where a joint's layer spans 10-100 mm; {metres}",
            f"the springs span {extent:.3g} mm where a joint's layer spans 10-100 mm; {microns}",
        ),
        _range_check(
            "layer_area",
            area,
            limits.layer_area,
            "mm^2",
            f"the springs cover {area:.3g} mm^2 where a joint's layer covers 100-10000 mm^2; {metres}",
            f"the springs cover {area:.3g} mm^2 where a joint's layer covers 100-10000 mm^2; {microns}",
        ),
        _range_check(
            "thickness",
            thickness,
            limits.thickness,
            "mm",
            f"mean thickness {thickness:.3g} mm where cartilage is 0.5-6 mm thick: give it in mm",
            f"mean thickness {thickness:.3g} mm where cartilage is 0.5-6 mm thick: give it in mm",
        ),
    )


def _pressure_check(pressure, limits: ValidityLimits) -> Check:
    peak = float(np.max(pressure, initial=0.0))
    passed = peak <= limits.peak_pressure
    advice = (
        ""
        if passed
        else _NOT_FINITE
        if math.isnan(peak)
        else (
            f"a peak of {peak:.4g} MPa is above what cartilage survives (it fails at about 25-35 MPa; joints see "
            f"1-20 MPa): check the load's units (N, not body weights), H's (MPa, not kPa or Pa) and the mesh's (mm)"
        )
    )
    return Check("peak_pressure", peak, limits.peak_pressure, "MPa", passed, advice)


def _count_check(name, argument, count, limit, missing, advice) -> Check:
    """A check of a count of springs (``argument``: the name the caller gave it), not evaluated
    without one (``missing`` says why); ``advice(count)`` says what a count past ``limit`` means."""
    if count is None:
        return Check(name, math.nan, limit, "springs", None, missing)
    if isinstance(count, bool) or not isinstance(count, (int, np.integer)) or count < 0:
        raise InputError(f"{argument} must be a count of springs (an integer >= 0) or None, got {count!r}")
    passed = bool(count <= limit)
    return Check(name, float(count), limit, "springs", passed, "" if passed else advice(count))


def _dropped_check(dropped, limits: ValidityLimits) -> Check:
    return _count_check(
        "dropped_springs",
        "dropped",
        dropped,
        limits.dropped_springs,
        "no count of the springs the proximity window drops at the solved pose was given",
        lambda n: (
            f"{n} spring(s) that carry load at the solved pose lie outside the proximity window: "
            f"cast the springs with a larger max_gap or max_overlap"
        ),
    )


def _through_layer_check(problem, lost, limits: ValidityLimits) -> Check:
    if lost is None and getattr(problem, "kinematics", "small") != "finite":
        # the small kinematics keeps the springs of the start pose: the lumped layer carries
        # every overlap short of its whole thickness (the strain check sees the rest)
        lost = 0
    return _count_check(
        "lost_through_layer",
        "lost_through_layer",
        lost,
        limits.lost_through_layer,
        "no count of the springs lost through the layer at the solved pose was given",
        lambda n: (
            f"{n} spring(s) that carried load are compressed deeper than mesh 1's cartilage at the solved "
            f"pose (their rays meet mesh 2 behind mesh 1's far side), so the cast cannot place them and the "
            f"answer leaves their force out; the layer is nearly crushed there: check the load and its units, "
            f"H and the thicknesses"
        ),
    )


def _stability_check(problem, stability, softest, limits: ValidityLimits) -> Check:
    if stability is None:
        why = (
            "the small kinematics' energy is convex: each of its equilibria is stable"
            if getattr(problem, "kinematics", "small") != "finite"
            else "no certified equilibrium to test (the stability of an answer that is no equilibrium means nothing)"
        )
        return Check("stability", math.nan, limits.stability, "", None, why)
    value = float(stability)
    if value <= limits.stability:
        return Check("stability", value, limits.stability, "", True)
    if not math.isfinite(value):
        return Check("stability", value, limits.stability, "", False, _NOT_FINITE)
    where = f" along {softest}" if softest else ""
    return Check(
        "stability",
        value,
        limits.stability,
        "",
        False,
        f"the equilibrium is unstable: its stiffness{where} is negative ({value:.3g} of the stiffest "
        f"direction's), so body 2 leaves it at the smallest disturbance (the load tips it over the "
        f"contact, as a pencil on its point) and Newton, which descends the energy, does not stop "
        f"there; hold that dof, or give it the load that holds it (in a joint, the ligaments)",
    )
