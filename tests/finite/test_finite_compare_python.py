"""``dea.compare`` on finite kinematics, as ``dea-opt compare`` does: ``newton`` and ``nlp`` run as
``finite`` and ``finite_nlp``, ``qp`` is skipped saying it is a small-kinematics method, and ``qp``
alone is an InputError naming the method and the kinematics.

The problem is the flat punch tilted in full contact (``tests/finite/test_finite.py``), whose finite
answer is closed: ``tan(theta) = M / (k I)`` and ``w = -F / (k A)``.
"""

from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np
import pytest

import dea_opt as d
from dea_opt.agreement import disagreement
from dea_opt.geometry import plate_layer

H, THICK, SIDE = 10.0, 10.0, 6.0  # MPa, mm, mm
K = H / THICK  # N/mm^3: a spring's stiffness per area


def quiet(function, *args, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        return function(*args, **kw)


@pytest.fixture(scope="module")
def punch():
    """The punch, its load and its closed form: ``(problem, w, theta, force, moment)``."""
    layer = plate_layer(SIDE, SIDE, 30, 6, thickness=THICK)
    area, second = float(layer.areas.sum()), float(layer.areas @ layer.points[:, 0] ** 2)
    force = 1.6 * K * area * (SIDE / 2) * np.tan(np.radians(25.0))  # every spring stays compressed
    theta = np.radians(15.0)
    moment = K * second * np.tan(theta)
    problem = d.ContactProblem(
        layer,
        d.LinearLaw(H),
        force=(0.0, 0.0, -force),
        moment=(0.0, moment, 0.0),
        reference=(0.0, 0.0, 0.0),
        free=("uz", "ry"),
        kinematics="finite",
    )
    return problem, -force / (K * area), theta, force, moment


def springs_on_body2(solution):
    """Force and moment about body 2's reference at the solved pose the springs exert, summed here."""
    layer = solution.problem.layer
    push = (solution.pressure * layer.areas)[:, None] * layer.normals
    centre = np.asarray(solution.problem.body2.reference) + solution.u[6:9]
    return push.sum(axis=0), np.cross(layer.points - centre, push).sum(axis=0)


def test_compare_runs_newton_and_nlp_as_the_finite_formulations_and_they_agree(punch):
    problem, w, theta, force, moment = punch
    out = quiet(d.compare, problem, methods=("newton", "nlp"))
    assert list(out.solutions) == ["finite", "finite_nlp"] and out.skipped == {}
    assert out.notes == (
        "newton stands for finite with finite kinematics",
        "nlp stands for finite_nlp with finite kinematics",
    )
    newton, ipopt = out.solutions["finite"], out.solutions["finite_nlp"]
    for solution, method in ((newton, "finite"), (ipopt, "finite_nlp")):
        assert solution.success and solution.method == method
        assert (solution.strain < 0).all()  # full contact: the closed form holds
        assert solution.u[8] == pytest.approx(w, rel=1e-8)
        assert solution.u[10] == pytest.approx(theta, rel=1e-8)
        resultant, about = springs_on_body2(solution)  # our own sums, not the certificate
        assert np.allclose(resultant, [0.0, 0.0, force], rtol=0, atol=1e-8 * force)
        assert abs(about[1] + moment) <= 1e-8 * moment
    # the two answers agree, and compare says by how much: the same numbers as ours
    scale = max(np.abs(newton.u).max(), np.abs(ipopt.u).max())
    du = np.abs(newton.u - ipopt.u).max() / scale
    dp = np.abs(newton.pressure - ipopt.pressure).max() / max(newton.peak_pressure, ipopt.peak_pressure)
    assert du <= 1e-6 and dp <= 1e-6
    assert out.displacement == pytest.approx(du, rel=1e-12, abs=1e-300)
    assert out.pressure == pytest.approx(dp, rel=1e-12, abs=1e-300)


def test_compare_by_default_runs_the_finite_formulations_and_says_why_qp_is_not_run(punch):
    problem, w, theta, *_ = punch
    out = quiet(d.compare, problem)
    assert list(out.solutions) == ["finite", "finite_nlp"] and out.notes == ()
    assert list(out.skipped) == ["qp"]
    assert out.skipped["qp"].startswith("qp is a small-kinematics method and this problem has kinematics='finite'")
    assert "'newton' and 'nlp', which stand for 'finite' and 'finite_nlp'" in out.skipped["qp"]
    assert out.displacement <= 1e-6 and out.pressure <= 1e-6
    assert all(s.u[10] == pytest.approx(theta, rel=1e-8) for s in out.solutions.values())
    # qp named beside newton: newton runs as finite, qp is skipped with the same reason
    out = quiet(d.compare, problem, methods=("qp", "newton"))
    assert list(out.solutions) == ["finite"] and list(out.skipped) == ["qp"]
    assert out.displacement == 0.0 and out.pressure == 0.0  # one answer: nothing to disagree


def test_qp_alone_on_a_finite_problem_is_an_input_error_naming_method_and_kinematics(punch):
    problem = punch[0]
    for methods in (("qp",), "qp", ["qp", "qp"]):
        with pytest.raises(d.InputError) as error:
            d.compare(problem, methods=methods)
        assert isinstance(error.value, d.DeaError)
        text = str(error.value)
        assert text.startswith("no method in methods solves this problem: qp is a small-kinematics method")
        assert "kinematics='finite'" in text and "use 'finite' or 'finite_nlp'" in text
    with pytest.raises(d.InputError, match="methods must be taken from newton, qp, nlp, finite, finite_nlp, got auto"):
        d.compare(problem, methods=("auto",))
    with pytest.raises(d.InputError, match="problem must be a ContactProblem, got dict"):
        d.compare({}, methods=("newton",))


def test_options_given_for_nlp_reach_finite_nlp(punch):
    problem = punch[0]
    # finite_nlp declares max_outer (the small nlp does not): its range check is what answers
    with pytest.raises(d.InputError, match="max_outer must be an integer >= 1, got 0"):
        d.compare(problem, methods=("nlp",), nlp={"max_outer": 0})
    with pytest.raises(d.InputError, match="method 'finite_nlp' takes the options .* got unknown option 'bogus'"):
        d.compare(problem, methods=("nlp",), nlp={"bogus": 1})


def test_a_small_problem_whose_named_methods_all_skip_is_an_input_error():
    layer = plate_layer(SIDE, SIDE, 6, 6, thickness=THICK)
    problem = d.ContactProblem(layer, d.AteshianLaw(H, 0.3), force=(0, 0, -50.0), reference=(0, 0, 0), free=("uz",))
    with pytest.raises(d.InputError, match="no method in methods solves this problem: qp needs a linear law"):
        d.compare(problem, methods=("qp",))
    out = quiet(d.compare, problem, methods=("qp", "newton"))
    assert list(out.solutions) == ["newton"] and out.skipped == {"qp": "qp needs a linear law"}


def test_disagreement_matches_springs_by_face_and_never_reads_nan_as_agreement():
    def answer(faces, pressure, u):
        layer = SimpleNamespace(source_face=None if faces is None else np.array(faces))
        pressure = np.array(pressure, dtype=float)
        return SimpleNamespace(
            pressure=pressure, peak_pressure=pressure.max(), u=np.array(u, float), problem=SimpleNamespace(layer=layer)
        )

    a = answer([1, 2, 3], [1.0, 2.0, 4.0], [0.0, 2.0])
    moved = answer([2, 3, 7], [2.0, 4.0, 0.5], [0.0, 1.0])
    assert disagreement([a, moved]) == (0.5, 0.25)  # face 1 (1 MPa) lost, face 7 gained; u: 1 of 2
    assert disagreement([a]) == (0.0, 0.0)
    unmatched = answer(None, [1.0, 2.0], [0.0, 2.0])  # two springs against three, no faces to match
    du, dp = disagreement([a, unmatched])
    assert du == 0.0 and np.isnan(dp)
