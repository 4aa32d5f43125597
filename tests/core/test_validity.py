"""A solved answer is not yet a valid one: the validity report of every result.

Each check is tested against a closed form or an independent computation written here: a
plate pressed to a known uniform strain (the law's range, crushing), a prescribed rotation
about a point at a known distance (the exact gap error ``y (sin t - t) + d (1 - cos t)``, and
scipy's rotation matrix for random motions), and the reported reproducers on the real knee
(meshes in metres, a 1e6 N load, six free dofs that rotate the femur about 21 deg) beside
the physiological case that must stay valid.
"""

from __future__ import annotations

import dataclasses
import json
import math
import warnings

import numpy as np
import pytest
from conftest import KNEE
from scipy.spatial.transform import Rotation

import dea_opt as d
from dea_opt.geometry import plate_layer
from dea_opt.validity import DEFAULT_LIMITS, Check, Validity, ValidityLimits, assess, rotation_gap_error

NAMES = (
    "strain",
    "rotation",
    "gap_error",
    "extent",
    "layer_area",
    "thickness",
    "peak_pressure",
    "dropped_springs",
    "lost_through_layer",
    "stability",
)


def solve_recording(problem, method="newton", **options):
    """Solve and return ``(solution, [ValidityWarning messages])``; any other warning fails."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        solution = d.solve(problem, method, **options)
    others = [w for w in caught if not issubclass(w.category, d.ValidityWarning)]
    assert not others, [str(w.message) for w in others]
    return solution, [str(w.message) for w in caught]


# --- the strain range of the law: a plate pressed to a known uniform strain ------------------

PLATE = plate_layer(40.0, 10.0, 40, 10, thickness=2.0)
PLATE_AREA = float(PLATE.areas.sum())


def pressed_plate(law, strain):
    """The plate under the centred force that gives every spring the compressive ``strain``."""
    pressure = -float(law.stress(np.array([-strain]))[0])
    return d.ContactProblem(PLATE, law, force=(0.0, 0.0, -pressure * PLATE_AREA), free=("uz",))


@pytest.mark.parametrize("strain, valid", [(0.05, True), (0.29, True), (0.31, False), (0.5, False)])
def test_linear_law_is_valid_up_to_thirty_percent(strain, valid):
    solution, messages = solve_recording(pressed_plate(d.LinearLaw(1.0), strain))
    check = solution.validity["strain"]
    np.testing.assert_allclose(solution.strain, -strain, rtol=1e-9)  # the closed form holds
    assert check.value == pytest.approx(strain, rel=1e-9)
    assert check.limit == 0.30 and check.passed is valid and solution.validity.valid is valid
    assert solution.success  # certified either way: solved is not valid
    if valid:
        assert messages == [] and check.advice == ""
    else:
        assert solution.validity.failed == (check,)
        assert len(messages) == 1 and "beyond the range of the linear law" in messages[0]
        assert f"strain {strain:.4g} > 0.3" in messages[0]


@pytest.mark.parametrize("strain", [0.35, 0.6, 0.79])
def test_ateshian_law_is_valid_past_thirty_percent(strain):
    solution, messages = solve_recording(pressed_plate(d.AteshianLaw(0.6, 0.05), strain))
    check = solution.validity["strain"]
    assert check.value == pytest.approx(strain, rel=1e-9)
    assert check.limit == DEFAULT_LIMITS.crushing == 0.8  # Ateshian states no range: crushing only
    assert check.passed and solution.validity.valid and messages == []


@pytest.mark.parametrize(
    "law", [d.AteshianLaw(0.6, 0.05), d.BlankevoortLaw(0.6), d.CubicLaw(0.6, 0.3)], ids=lambda law: law.name
)
def test_every_law_is_flagged_near_crushing(law):
    solution, messages = solve_recording(pressed_plate(law, 0.9))
    check = solution.validity["strain"]
    assert check.value == pytest.approx(0.9, rel=1e-9) and check.passed is False
    assert "nearly crushed" in check.advice and len(messages) == 1 and "nearly crushed" in messages[0]


def test_linear_law_crushed_through_its_thickness():
    solution, messages = solve_recording(pressed_plate(d.LinearLaw(1.0), 1.5))
    check = solution.validity["strain"]
    assert check.value == pytest.approx(1.5, rel=1e-9) and check.passed is False
    assert "crushed through its whole thickness" in check.advice
    assert len(messages) == 1 and "crushed through" in messages[0]


def test_a_law_of_your_own_states_its_range():
    class Cautious(d.LinearLaw):
        valid_compression = 0.1

    class Silent(d.LinearLaw):
        valid_compression = None  # like the base Law: no range, only crushing

    assert d.Law.valid_compression is None and d.LinearLaw.valid_compression == 0.30
    cautious, _ = solve_recording(pressed_plate(Cautious(1.0), 0.15))
    assert cautious.validity["strain"].limit == 0.1 and not cautious.validity.valid
    silent, messages = solve_recording(pressed_plate(Silent(1.0), 0.5))
    assert silent.validity["strain"].limit == 0.8 and silent.validity.valid and messages == []
    # The caller's limit overrides the law's
    mine = assess(silent.problem, silent.u, limits=ValidityLimits(compression=0.4))
    assert mine["strain"].limit == 0.4 and mine.failed == (mine["strain"],)
    relaxed = assess(cautious.problem, cautious.u, limits=ValidityLimits(compression=0.2))
    assert relaxed.valid


# --- rotation and the gap error of the linearised kinematics ---------------------------------

D = 30.0  # mm from body 2's reference down to the plate


def rotated_plate(angle, law=None):
    """The plate with body 2's reference at (0, 0, D) prescribed to rotate by ``angle`` about x."""
    body2 = d.Body(reference=(0.0, 0.0, D), free=(), prescribed={"rx": angle})
    return d.ContactProblem(PLATE.with_gap(1.0), law or d.LinearLaw(1.0), body2=body2)


def test_ten_degree_rotation_gap_error_is_the_exact_one():
    theta = math.radians(10.0)
    problem = rotated_plate(theta)
    solution, messages = solve_recording(problem)
    assert solution.status is d.Status.NO_FREE_DOFS
    y = PLATE.points[:, 1]
    # Exact: the z of R r is y sin t - D cos t; linear: the z of r + t e_x x r is theta y - D.
    expected = y * (math.sin(theta) - theta) + D * (1.0 - math.cos(theta))
    np.testing.assert_allclose(rotation_gap_error(problem, solution.u), expected, rtol=1e-12, atol=1e-15)
    # ... and the same from scipy's rotation matrix: |R p - (p + theta x p)| . n
    r = PLATE.points - np.array([0.0, 0.0, D])
    R = Rotation.from_rotvec([theta, 0.0, 0.0]).as_matrix()
    independent = ((r @ R.T) - r - np.cross([theta, 0.0, 0.0], r)) @ np.array([0.0, 0.0, 1.0])
    np.testing.assert_allclose(expected, independent, rtol=1e-12, atol=1e-14)

    rotation, gap = solution.validity["rotation"], solution.validity["gap_error"]
    assert rotation.value == pytest.approx(10.0, rel=1e-12) and rotation.limit == 3.0
    assert rotation.passed is False and "finite kinematics" in rotation.advice
    largest = np.abs(expected).max()
    assert dict(gap.details)["mm"] == pytest.approx(largest, rel=1e-12)
    assert gap.value == pytest.approx(largest / 2.0, rel=1e-12) and gap.passed is False
    assert len(messages) == 1 and "rotation 10 > 3 deg" in messages[0] and "gap_error" in messages[0]


@pytest.mark.parametrize("theta", [1e-9, 1e-7, 1e-5, 1e-4, 2e-4, 1e-2, 0.5])
def test_gap_error_straight_below_the_reference_is_d_one_minus_cos(theta):
    """At y = 0 only the second-order term is left, ``D (1 - cos t) = 2 D sin(t/2)^2``:
    exact to rounding at every angle, also where ``sin(t)/t - 1`` cancels."""
    problem = rotated_plate(theta)
    error = rotation_gap_error(problem, problem.prescribed_u)
    on_axis = np.flatnonzero(np.abs(PLATE.points[:, 1]) < 0.6)  # the rows next to y = 0
    y = PLATE.points[on_axis, 1]
    series_a = -(theta**3) / 6.0 + theta**5 / 120.0  # sin t - t, without cancellation
    expected = y * (series_a if theta < 1e-3 else math.sin(theta) - theta) + 2 * D * math.sin(theta / 2) ** 2
    np.testing.assert_allclose(error[on_axis], expected, rtol=1e-10)


@pytest.mark.parametrize("seed", range(6))
def test_gap_error_of_random_motions_matches_scipy(seed):
    """Both bodies rotated by random vectors of 1-40 deg about random references; springs with
    random normals. The error is n . ((R2 - I)r2 - theta2 x r2 - (R1 - I)r1 + theta1 x r1)."""
    rng = np.random.default_rng(seed)
    n = 200
    points = rng.normal(scale=20.0, size=(n, 3))
    normals = rng.normal(size=(n, 3))
    layer = d.SpringLayer(points, normals, rng.uniform(0.5, 2.0, n), rng.uniform(1.0, 4.0, n), gap=5.0)
    c1, c2 = rng.normal(scale=40.0, size=(2, 3))
    u = np.concatenate([rng.normal(size=3), rng.normal(size=3), rng.normal(size=3), rng.normal(size=3)])
    for k in (3, 9):
        u[k : k + 3] *= math.radians(rng.uniform(1.0, 40.0)) / np.linalg.norm(u[k : k + 3])
    problem = d.ContactProblem(
        layer, d.LinearLaw(1.0), body1=d.Body(reference=c1, free=()), body2=d.Body(reference=c2, free=())
    )
    unit = layer.normals
    expected = np.zeros(n)
    for sign, c, theta in ((-1.0, c1, u[3:6]), (1.0, c2, u[9:12])):
        r = points - c
        R = Rotation.from_rotvec(theta).as_matrix()
        expected += sign * np.einsum("ij,ij->i", unit, r @ R.T - r - np.cross(theta, r))
    np.testing.assert_allclose(rotation_gap_error(problem, u), expected, rtol=1e-10, atol=1e-12)
    validity = assess(problem, u)
    angles = [math.degrees(np.linalg.norm(u[3:6])), math.degrees(np.linalg.norm(u[9:12]))]
    assert validity["rotation"].value == pytest.approx(max(angles), rel=1e-12)
    assert validity["gap_error"].value == pytest.approx(np.max(np.abs(expected) / layer.thickness), rel=1e-9)


def test_small_rotation_is_valid_and_translations_leave_no_gap_error():
    problem = rotated_plate(math.radians(2.0))
    validity = assess(problem, problem.prescribed_u)
    assert validity["rotation"].passed and validity["gap_error"].passed  # 2 deg, 30 mm: 0.9 % of h
    u = np.zeros(12)
    u[6:9] = (3.0, -2.0, 0.5)
    assert not rotation_gap_error(problem, u).any()
    assert assess(problem, u)["rotation"].value == 0.0


# --- sizes and units ------------------------------------------------------------------------


def test_a_layer_in_micrometres_is_flagged():
    layer = plate_layer(40e3, 10e3, 20, 5, thickness=2e3)
    validity = assess(d.ContactProblem(layer, d.LinearLaw(1.0), force=(0, 0, -1.0)), np.zeros(12))
    assert {c.name for c in validity.failed} == {"extent", "layer_area", "thickness"}
    assert validity["extent"].value == pytest.approx(math.hypot(38e3, 8e3), rel=1e-12)
    assert "micrometres" in validity["extent"].advice and "scale=0.001" in validity["extent"].advice


def test_one_spring_stands_for_its_area():
    """A single spring spans nothing, but it stands for a patch of its area: not metres."""
    layer = d.SpringLayer([[0.0, 0.0, 0.0]], [[0.0, 0.0, 1.0]], 100.0, 2.0)
    validity = assess(d.ContactProblem(layer, d.LinearLaw(1.0)), np.zeros(12))
    assert validity["extent"].value == 10.0 and validity.valid


def test_a_layer_without_springs_is_not_assessed_for_size():
    empty = d.SpringLayer(np.zeros((0, 3)), np.zeros((0, 3)), 1.0, 1.0)
    validity = assess(d.ContactProblem(empty, d.LinearLaw(1.0)), np.zeros(12))
    assert all(validity[n].passed is None for n in ("extent", "layer_area", "thickness", "gap_error"))
    assert validity.valid and validity["strain"].value == 0.0 and validity["peak_pressure"].value == 0.0


# --- pressures ---------------------------------------------------------------------------------


def test_peak_pressure_above_what_cartilage_survives():
    # H = 100 MPa at 0.2 strain: 20 MPa, valid; at 0.4 (and with a range check switched off): 40 MPa
    ok, _ = solve_recording(pressed_plate(d.LinearLaw(100.0), 0.2))
    assert ok.validity["peak_pressure"].value == pytest.approx(20.0, rel=1e-9) and ok.validity.valid
    high, messages = solve_recording(pressed_plate(d.AteshianLaw(100.0, 0.0), 0.3))
    peak = -float(d.AteshianLaw(100.0, 0.0).stress(np.array([-0.3]))[0])
    assert peak > 35.0
    check = high.validity["peak_pressure"]
    assert check.value == pytest.approx(peak, rel=1e-9) and check.limit == 35.0 and check.passed is False
    assert high.validity.failed == (check,) and "check the load's units" in messages[0]
    lenient = assess(high.problem, high.u, high.strain, high.pressure, limits=ValidityLimits(peak_pressure=50.0))
    assert lenient.valid


# --- the springs the proximity window drops (a hook for the re-cast at the solved pose) -------


def test_dropped_springs_is_not_evaluated_unless_counted():
    solution, _ = solve_recording(pressed_plate(d.LinearLaw(1.0), 0.1))
    check = solution.validity["dropped_springs"]
    assert check.passed is None and check.status == "not evaluated" and math.isnan(check.value)
    assert solution.validity.valid
    assert "dropped_springs, stability not evaluated" in solution.validity.summary()
    args = (solution.problem, solution.u, solution.strain, solution.pressure)
    assert assess(*args, dropped=0)["dropped_springs"].passed is True
    counted = assess(*args, dropped=453)
    assert counted["dropped_springs"].value == 453 and not counted.valid
    assert "max_gap" in counted["dropped_springs"].advice
    assert assess(*args, dropped=5, limits=ValidityLimits(dropped_springs=10)).valid
    for bad in (-1, 2.5, "3", True):
        with pytest.raises(d.InputError, match="dropped must be a count"):
            assess(*args, dropped=bad)


# --- the object: immutable, JSON-ready, one row, one line -------------------------------------


def test_the_report_is_immutable_json_ready_and_flat():
    solution, _ = solve_recording(rotated_plate(math.radians(10.0)))
    validity = solution.validity
    assert isinstance(validity, Validity) and validity is solution.validity  # computed once
    assert validity.names == NAMES and all(isinstance(c, Check) for c in validity.checks)
    with pytest.raises(dataclasses.FrozenInstanceError):
        validity.checks = ()  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        validity.checks[0].value = 0.0  # type: ignore[misc]

    data = json.loads(json.dumps(validity.as_dict(), allow_nan=False))
    assert data["valid"] is False and set(data["failed"]) == {c.name for c in validity.failed}
    assert list(data["checks"]) == list(NAMES)
    assert data["checks"]["rotation"]["limit"] == 3.0 and data["checks"]["extent"]["limit"] == [1.0, 1000.0]
    assert data["checks"]["dropped_springs"]["value"] is None
    assert data["checks"]["dropped_springs"]["status"] == "not evaluated"
    assert json.loads(json.dumps(solution.summary()["validity"], allow_nan=False)) == data

    row = validity.columns()
    assert row["valid"] is False and row["validity_failed"].split(";") == [c.name for c in validity.failed]
    assert all(isinstance(v, (bool, float, str)) for v in row.values())
    assert row["validity_rotation_deg"] == pytest.approx(10.0) and "validity_gap_error_mm" in row
    assert {d.validity.check_column(n) for n in NAMES} <= set(row)
    assert {"validity_extent_mm", "validity_layer_area_mm2", "validity_peak_pressure_MPa"} <= set(row)

    line = validity.summary()
    assert "\n" not in line and line.startswith("NOT VALID") and "rotation 10 > 3 deg" in line
    assert "valid=False" in repr(solution)
    with pytest.raises(KeyError, match="no validity check named 'pressure'"):
        validity["pressure"]


def test_valid_only_if_every_evaluated_check_passed():
    def check(name, passed):
        return Check(name, 1.0, 2.0, "", passed)

    assert Validity((check("a", True), check("b", None))).valid
    assert not Validity((check("a", True), check("b", False))).valid
    assert Validity((check("a", None),)).valid
    assert Validity((check("a", True), check("b", None))).summary() == "valid (1 checks passed, b not evaluated)"


def test_a_failed_solution_is_not_valid():
    problem = pressed_plate(d.LinearLaw(1.0), 0.1)
    validity = assess(problem, np.full(12, np.nan))
    assert not validity.valid
    assert {c.name for c in validity.failed} >= {"strain", "rotation", "gap_error", "peak_pressure"}
    assert all("not finite" in c.advice for c in validity.failed)


@pytest.mark.parametrize(
    "kwargs, field",
    [
        ({"crushing": 0.0}, "crushing"),
        ({"crushing": 1.5}, "crushing"),
        ({"rotation": -1}, "rotation"),
        ({"rotation": "3 deg"}, "rotation"),
        ({"gap_error": math.nan}, "gap_error"),
        ({"compression": 2.0}, "compression"),
        ({"extent": (10.0, 1.0)}, "extent"),
        ({"layer_area": 5.0}, "layer_area"),
        ({"thickness": (0.1, math.nan)}, "thickness"),
        ({"extent": ("1", "2")}, "extent"),
        ({"crushing": True}, "crushing"),
        ({"peak_pressure": 0}, "peak_pressure"),
        ({"dropped_springs": -2}, "dropped_springs"),
        ({"dropped_springs": 1.5}, "dropped_springs"),
        ({"lost_through_layer": -1}, "lost_through_layer"),
        ({"lost_through_layer": True}, "lost_through_layer"),
    ],
)
def test_bad_limits_name_the_field(kwargs, field):
    with pytest.raises(d.InputError, match=rf"ValidityLimits\.{field}(\[\d\])? must be"):
        ValidityLimits(**kwargs)


def test_bad_arguments_to_assess():
    problem = pressed_plate(d.LinearLaw(1.0), 0.1)
    with pytest.raises(d.InputError, match=r"u must have shape \(12,\)"):
        assess(problem, np.zeros(6))
    with pytest.raises(d.InputError, match=r"strain must have shape \(400,\)"):
        assess(problem, np.zeros(12), strain=np.zeros(3))
    with pytest.raises(d.InputError, match="problem must be a ContactProblem, got SpringLayer"):
        assess(PLATE, np.zeros(12))
    with pytest.raises(d.InputError, match="limits must be a dea_opt.validity.ValidityLimits"):
        assess(problem, np.zeros(12), limits={"rotation": 5})
    with pytest.raises(
        d.InputError, match=r"lost_through_layer must be a count of springs \(an integer >= 0\) or None, got 2.5"
    ):
        assess(problem, np.zeros(12), lost_through_layer=2.5)
    # small kinematics keep their springs: nothing is lost through the layer
    check = assess(problem, np.zeros(12))["lost_through_layer"]
    assert check.passed and check.value == 0
    lost = assess(problem, np.zeros(12), lost_through_layer=3, limits=ValidityLimits(lost_through_layer=2))
    assert lost.failed[-1].name == "lost_through_layer" and "3 spring(s)" in lost.failed[-1].advice

    class Odd(d.LinearLaw):
        valid_compression = 30  # a percentage where a fraction is meant

    with pytest.raises(d.InputError, match=r"Odd.valid_compression must be a finite number > 0 and <= 1, got 30"):
        assess(problem.with_law(Odd(1.0)), np.zeros(12))


def test_the_guide_validity_example_runs(capsys):
    import re
    from pathlib import Path

    page = (Path(__file__).resolve().parents[2] / "docs" / "guide" / "concepts.md").read_text()
    blocks = [
        re.search(r"```python\n(.*?)```", page.split(title, 1)[1], re.DOTALL).group(1)
        for title in ("## Solving, and what a solution holds", "\n## Validity")
    ]
    namespace: dict = {}
    for code in blocks:
        exec(compile(code, "concepts.md", "exec"), namespace)
    line = capsys.readouterr().out.strip().splitlines()[-1]
    assert line == namespace["solution"].validity.summary() and line.startswith("valid (8 checks passed")
    assert namespace["loose"].limits.peak_pressure == 50.0 and namespace["loose"].valid


# --- the real knee: the reported reproducers and the physiological case -------------------------

FILES = ("femoral_cartilage.stl", "medial_tibial_cartilage.stl", "lateral_tibial_cartilage.stl")


def knee_problem(scale=1.0, law=None, free=("uz", "ry"), force=1000.0):
    """Tibial cartilage (body 1) and the femur (body 2) under ``force`` N along -z at the
    midpoint of the two tibial cartilages' centroids, as in ``tests/core/test_knee.py``."""
    from dea_opt import mesh as M

    if not all((KNEE / name).is_file() for name in FILES):
        pytest.skip(f"the knee meshes are not in {KNEE}")
    femur, medial, lateral = (M.load_mesh(KNEE / name, scale=scale) for name in FILES)
    tibia, labels = M.concatenate_meshes({"medial": medial, "lateral": lateral})
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # in metres a few thickness rays miss
        layer = M.cast_springs(tibia, femur, labels=labels, max_gap=2.0 * scale).layer
    centre = [(m.area_faces @ m.triangles_center) / m.area for m in (medial, lateral)]
    reference = tuple(0.5 * (centre[0] + centre[1]))
    return d.ContactProblem(layer, law or d.LinearLaw(10.0), force=(0.0, 0.0, -force), reference=reference, free=free)


@pytest.fixture(scope="module")
def knee():
    return knee_problem()


def test_knee_physiological_case_is_valid(knee):
    solution, messages = solve_recording(knee)
    assert solution.success and solution.validity.valid and messages == []
    v = solution.validity
    assert 0.0 < v["strain"].value < 0.3 and 0.0 < v["rotation"].value < 3.0
    assert 10.0 < v["extent"].value < 100.0 and 100.0 < v["layer_area"].value < 10_000.0
    assert 0.5 < v["thickness"].value < 12.0 and 1.0 < v["peak_pressure"].value < 20.0


def test_knee_in_metres_is_flagged_as_metres():
    problem = knee_problem(scale=1e-3)
    solution, messages = solve_recording(problem, strict=False)
    failed = {c.name for c in solution.validity.failed}
    assert {"extent", "layer_area", "thickness"} <= failed
    assert solution.validity["extent"].value < 0.1  # an 80 mm layer read as 0.08
    assert all("metres" in solution.validity[n].advice for n in ("extent", "layer_area"))
    assert len(messages) == 1 and "scale=1000" in messages[0]


def test_knee_under_a_million_newtons_is_flagged_for_pressure(knee):
    solution, messages = solve_recording(knee.with_load(force=(0.0, 0.0, -1e6)))
    assert solution.success  # the certificate passes: the equations are solved
    pressure = solution.validity["peak_pressure"]
    assert pressure.passed is False and pressure.value == pytest.approx(solution.peak_pressure)
    assert pressure.value > 1000.0 and solution.validity["strain"].passed is False
    assert len(messages) == 1
    # one warning naming every failed check with its value, limit and advice
    for check in solution.validity.failed:
        assert check.describe() in messages[0]
    assert "peak_pressure" in messages[0] and "> 35 MPa" in messages[0] and "load's units" in messages[0]


@pytest.mark.parametrize("offset", [(0.0, 0.0, 0.0), (10.0, 0.0, 0.0)], ids=["midpoint", "medial-10mm"])
def test_knee_with_six_free_dofs_rotates_out_of_the_small_rotation_model(knee, offset):
    """With the default six free dofs the femur slid about 17 mm and rotated about 21 deg."""
    point = tuple(np.add(knee.body2.reference, offset))
    problem = d.ContactProblem(
        knee.layer, knee.law, load=d.Load((0.0, 0.0, -1000.0), point=point), reference=knee.body2.reference, free=d.DOFS
    )
    solution, messages = solve_recording(problem)
    assert solution.success
    degrees = math.degrees(np.linalg.norm(solution.u[9:12]))
    assert degrees > 10.0
    rotation = solution.validity["rotation"]
    assert rotation.value == pytest.approx(degrees, rel=1e-12) and rotation.passed is False
    assert solution.validity["gap_error"].passed is False
    assert len(messages) == 1 and "small-rotation kinematics" in messages[0]
