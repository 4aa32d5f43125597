"""Sensitivities (formulations/sensitivity.md): closed forms, finite differences for every law and
parameter, CasADi's parametric sensitivities of the IPOPT solution, and the one-sided cases."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest

import dea_opt as d
from dea_opt.geometry import plate_layer, socket_layer, sphere_on_bed_layer
from dea_opt.sensitivity import sensitivities
from dea_opt.sensitivity.parametric import nlp_sensitivities

LAWS = (
    d.LinearLaw(0.6),
    d.AteshianLaw(0.6, 0.3),
    d.CubicLaw(0.6, 0.3),
    d.PolynomialLaw(0.6, 0.3, 5),
    d.BlankevoortLaw(0.6),
)
IDS = [type(law).__name__ for law in LAWS]
BED = sphere_on_bed_layer(radius=25.0, thickness=2.0, extent=7.0, n_rings=24, n_sectors=16)
LOAD = {"force": (0.0, 0.0, -10.0), "moment": (4.0, -3.0, 0.0)}


def solve(problem):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        solution = d.solve(problem, "newton")
    assert solution.success
    return solution


def bed_problem(law, layer=BED, force=LOAD["force"], moment=LOAD["moment"]):
    return d.ContactProblem(layer, law, force=force, moment=moment, reference=(0.0, 0.0, 25.0), free=("uz", "rx", "ry"))


def prescribed_problem(law, uz=-0.3, layer=BED):
    body = d.Body(reference=(0.0, 0.0, 25.0), free=("rx", "ry"), moment=(4.0, -3.0, 0.0), prescribed={"uz": uz})
    return d.ContactProblem(layer, law, body2=body)


def with_thickness(layer, thickness):
    return d.SpringLayer(layer.points, layer.normals, layer.areas, thickness, layer.gap)


def perturbed(law, name, t):
    """The problem with parameter ``name`` moved by ``t`` (absolute), built from scratch."""
    if name in law.parameter_names:
        return bed_problem(dataclasses.replace(law, **{name: getattr(law, name) + t}))
    if name == "thickness_scale":
        return bed_problem(law, with_thickness(BED, BED.thickness * (1 + t)))
    if name in ("Fz", "Mx", "My"):
        force, moment = np.array(LOAD["force"]), np.array(LOAD["moment"])
        if name == "Fz":
            force[2] += t
        else:
            moment["xy".index(name[1])] += t
        return bed_problem(law, force=force, moment=moment)
    if name == "uz":
        return prescribed_problem(law, -0.3 + t)
    raise AssertionError(name)


def outputs(s):
    return {
        "u": s.u,
        "strain": s.strain,
        "pressure": s.pressure,
        "peak_pressure": s.peak_pressure,
        "contact_force": s.contact_force,
        "contact_moment": s.contact_moment,
        "center_of_pressure": s.center_of_pressure,
        "W": float(s.pressure @ s.problem.layer.areas),
    }


def check_close(analytic, fd, scale, what):
    analytic, fd = np.asarray(analytic, dtype=float), np.asarray(fd, dtype=float)
    bound = 1e-5 * max(float(np.abs(fd).max(initial=0.0)), scale)
    assert np.abs(analytic - fd).max(initial=0.0) <= bound, f"{what}: {analytic} vs {fd}"


@pytest.mark.parametrize("law", LAWS, ids=IDS)
def test_law_parameter_derivatives_are_exact(law):
    eps = -np.linspace(0.0, 0.6, 13)
    complex_step = law.stress_derivatives(eps)
    symbolic = law.stress_derivatives(eps, method="casadi")
    assert set(complex_step) == set(law.parameter_names) == set(symbolic)
    for name, value in complex_step.items():
        np.testing.assert_allclose(value, symbolic[name], rtol=1e-12, atol=1e-14)
        v = getattr(law, name)
        step = 1e-6 * v
        fd = (
            dataclasses.replace(law, **{name: v + step}).stress(eps)
            - dataclasses.replace(law, **{name: v - step}).stress(eps)
        ) / (2 * step)
        np.testing.assert_allclose(value, fd, rtol=1e-7, atol=1e-9)
    # H scales every law: d sigma / d H = sigma / H
    np.testing.assert_allclose(complex_step["H"], law.stress(eps) / law.H, rtol=1e-13)


def test_law_parameter_derivatives_of_ateshian_in_closed_form():
    law = d.AteshianLaw(0.5, 0.2)
    eps = -np.linspace(0.05, 0.5, 10)
    lam = 1 + eps
    g = lam**2 - 1
    # sigma = H g / (2 lam^(2b+1)) exp(b g): d/db = sigma (g - 2 ln lam)
    sigma = 0.5 * 0.5 * g / lam**1.4 * np.exp(0.2 * g)
    np.testing.assert_allclose(law.stress_derivatives(eps)["beta"], sigma * (g - 2 * np.log(lam)), rtol=1e-12)
    assert law.stress_derivatives(eps[:0])["H"].shape == (0,)
    assert np.isnan(law.stress_derivatives(np.array([-1.0]))["H"]).all()
    with pytest.raises(d.InputError, match="method"):
        law.stress_derivatives(eps, method="fd")


def test_plate_in_closed_form():
    """A rigid plate on a bonded linear layer, uz free: uz = F h / (H S)."""
    layer = plate_layer(40.0, 10.0, 40, 10, thickness=2.0)
    H, F = 0.8, -30.0
    s = solve(d.ContactProblem(layer, d.LinearLaw(H), force=(0, 0, F), reference=(0, 0, 0), free=("uz",)))
    total = layer.areas.sum()
    sen = sensitivities(s, ("H", "Fz", "thickness_scale"))
    assert sen.u["Fz"][8] == pytest.approx(2.0 / (H * total), rel=1e-12)
    assert sen.u["H"][8] == pytest.approx(-s.u[8] / H, rel=1e-12)
    assert sen.u["thickness_scale"][8] == pytest.approx(s.u[8], rel=1e-12)
    np.testing.assert_allclose(sen.pressure["Fz"], -1.0 / total, rtol=1e-12)  # uniform p = -F / S
    np.testing.assert_allclose(sen.pressure["H"], 0.0, atol=1e-15)
    np.testing.assert_allclose(sen.contact_force["Fz"], [0.0, 0.0, -1.0], atol=1e-12)
    assert sen.units == {"H": "MPa", "Fz": "N", "thickness_scale": "1"}
    assert sen.unit("pressure", "Fz") == "MPa/N"
    assert not sen.one_sided and sen.decreasing is sen and sen.edge.size == 0 and sen.notes == ()


@pytest.mark.parametrize("law", LAWS, ids=IDS)
def test_central_differences_for_every_law_and_parameter(law):
    problem = bed_problem(law)
    s = solve(problem)
    names = (*law.parameter_names, "thickness_scale", "Fz", "Mx", "My")
    sen = sensitivities(s, names)
    assert sen.edge.size == 0 and sen.notes == ()
    nominal = outputs(s)
    for name in names:
        value = (
            getattr(law, name)
            if name in law.parameter_names
            else {"thickness_scale": 1.0, "Fz": 10.0, "Mx": 4.0, "My": 3.0}[name]
        )
        t = 1e-6 * value
        plus, minus = solve(perturbed(law, name, t)), solve(perturbed(law, name, -t))
        # away from changes of the contact set
        assert np.array_equal(plus.in_contact, s.in_contact) and np.array_equal(minus.in_contact, s.in_contact)
        a, b = outputs(plus), outputs(minus)
        for key, base in nominal.items():
            fd = (np.asarray(a[key]) - np.asarray(b[key])) / (2 * t)
            scale = float(np.abs(base).max()) / abs(value)
            if key == "W":  # total normal force = mean pressure times area, with the area rate
                analytic = sen.mean_pressure[name] * s.contact_area + s.mean_pressure * sen.contact_area[name]
            else:
                analytic = getattr(sen, key)[name]
            check_close(analytic, fd, scale, f"{type(law).__name__} d{key}/d{name}")


@pytest.mark.parametrize("law", LAWS[:2], ids=IDS[:2])
def test_central_differences_for_a_prescribed_dof_and_per_spring_parameters(law):
    s = solve(prescribed_problem(law))
    sen = sensitivities(s, ("uz", "gap", "thickness"))
    t = 1e-6
    plus, minus = solve(prescribed_problem(law, -0.3 + t)), solve(prescribed_problem(law, -0.3 - t))
    check_close(sen.u["uz"], (plus.u - minus.u) / (2 * t), 1.0, "du/duz")
    assert sen.u["uz"][8] == 1.0
    check_close(sen.pressure["uz"], (plus.pressure - minus.pressure) / (2 * t), s.peak_pressure, "dp/duz")
    assert sen.pressure["gap"].shape == (len(BED), len(BED)) and sen.u["gap"].shape == (12, len(BED))
    for j in np.flatnonzero(s.in_contact)[::97]:
        for name in ("gap", "thickness"):
            values = {}
            for sign in (+1, -1):
                gap, thickness = BED.gap.copy(), np.array(BED.thickness, dtype=float).copy()
                (gap if name == "gap" else thickness)[j] += sign * t
                layer = d.SpringLayer(BED.points, BED.normals, BED.areas, thickness, gap)
                values[sign] = solve(prescribed_problem(law, layer=layer))
            for key in ("u", "pressure", "center_of_pressure"):
                fd = (np.asarray(getattr(values[1], key)) - np.asarray(getattr(values[-1], key))) / (2 * t)
                check_close(np.asarray(getattr(sen, key)[name])[..., j], fd, 1e-3, f"d{key}/d{name}[{j}]")
            fd = (values[1].peak_pressure - values[-1].peak_pressure) / (2 * t)
            check_close(sen.peak_pressure[name][j], fd, 1e-3, f"dpeak/d{name}[{j}]")


@pytest.mark.parametrize("law", LAWS, ids=IDS)
def test_casadi_parametric_sensitivities_of_the_ipopt_solution_agree(law):
    layer = sphere_on_bed_layer(radius=25.0, thickness=2.0, extent=7.0, n_rings=12, n_sectors=12)
    problem = bed_problem(law, layer)
    s = solve(problem)
    names = (*law.parameter_names, "Fz", "Mx", "thickness_scale", "gap", "thickness")
    sen = sensitivities(s, names)
    ref = nlp_sensitivities(problem, names)
    np.testing.assert_allclose(ref["x"], s.u[problem.free_indices], rtol=1e-8, atol=1e-12)
    for name in names:
        for key in ("u", "pressure"):
            expected = ref[name][key]
            np.testing.assert_allclose(
                getattr(sen, key)[name], expected, rtol=0, atol=1e-9 * np.abs(expected).max(), err_msg=f"d{key}/d{name}"
            )


def test_random_problems_against_the_independent_nlp_check():
    rng = np.random.default_rng(7)
    for _ in range(4):
        n = 60
        points = np.column_stack([rng.uniform(-10, 10, n), rng.uniform(-10, 10, n), np.zeros(n)])
        normals = np.column_stack([rng.normal(0, 0.1, (n, 2)), np.ones(n)])
        layer = d.SpringLayer(
            points, normals, rng.uniform(0.5, 2.0, n), rng.uniform(1.0, 3.0, n), rng.uniform(0.0, 0.05, n)
        )
        law = LAWS[rng.integers(len(LAWS))]
        problem = d.ContactProblem(
            layer,
            law,
            force=(rng.normal(0, 1), rng.normal(0, 1), -20.0),
            moment=rng.normal(0, 10, 3),
            reference=(0, 0, 10.0),
        )
        s = solve(problem)
        names = (*law.parameter_names, "Fx", "Fz", "Mz", "thickness_scale")
        sen = sensitivities(s, names)
        if sen.edge.size:  # a spring that came to rest at zero strain: the two-sided check does not apply
            continue
        ref = nlp_sensitivities(problem, names, x0=s.u[problem.free_indices])
        for name in names:
            scale = np.abs(ref[name]["u"]).max()
            np.testing.assert_allclose(sen.u[name], ref[name]["u"], rtol=0, atol=1e-8 * scale)


def test_contact_area_rate_of_a_sphere_in_closed_form():
    """Area pi (2 R d - d^2) of a sphere at approach d: dA/dp = pi (2R - 2d) dd/dp."""
    R = 25.0
    layer = sphere_on_bed_layer(radius=R, thickness=2.0, extent=7.0, n_rings=60, n_sectors=32)
    for law in (d.LinearLaw(0.6), d.AteshianLaw(0.6, 0.3)):
        s = solve(d.ContactProblem(layer, law, force=(0, 0, -10.0), reference=(0, 0, R), free=("uz",)))
        sen = sensitivities(s, ("Fz", "H"))
        approach = -s.u[8]
        for name in ("Fz", "H"):
            expected = np.pi * (2 * R - 2 * approach) * (-sen.u[name][8])
            assert sen.contact_area[name] == pytest.approx(expected, rel=0.01)
    # The rate integrates to the change of the (stepwise) area over a wide range of loads.
    fine = sphere_on_bed_layer(radius=R, thickness=2.0, extent=7.0, n_rings=300, n_sectors=32)
    loads = np.linspace(-15.0, -5.0, 11)
    solutions = [
        solve(d.ContactProblem(fine, d.AteshianLaw(0.6, 0.3), force=(0, 0, f), reference=(0, 0, R), free=("uz",)))
        for f in loads
    ]
    rates = [sensitivities(s, ("Fz",)).contact_area["Fz"] for s in solutions]
    change = solutions[-1].contact_area - solutions[0].contact_area
    assert np.trapezoid(rates, loads) == pytest.approx(change, rel=0.03)


def edge_problem(law, F=-20.0):
    """100 bonded springs under a plate, and one spring whose gap is the plate's approach: it sits
    exactly at zero strain at equilibrium."""
    xs = np.arange(10) - 4.5
    X, Y = np.meshgrid(xs, xs)
    points = np.column_stack([X.ravel(), Y.ravel(), np.zeros(100)])
    base = d.SpringLayer(points, np.tile([0, 0, 1.0], (100, 1)), 1.0, 2.0, 0.0)
    approach = -solve(d.ContactProblem(base, law, force=(0, 0, F), reference=(0, 0, 0), free=("uz",))).u[8]
    layer = d.SpringLayer(
        np.vstack([points, [[8.0, 0.0, 0.0]]]), np.tile([0, 0, 1.0], (101, 1)), 1.0, 2.0, np.r_[np.zeros(100), approach]
    )
    return d.ContactProblem(layer, law, force=(0, 0, F), reference=(0, 0, 0), free=("uz",))


@pytest.mark.parametrize("law", (d.LinearLaw(1.0), d.AteshianLaw(1.0, 0.3)), ids=("linear", "ateshian"))
def test_one_sided_derivatives_at_a_spring_on_the_edge(law):
    problem = edge_problem(law)
    s = solve(problem)
    assert abs(s.strain[100]) < 1e-12
    sen = sensitivities(s, ("Fz", "H"))
    assert sen.one_sided and sen.edge.tolist() == [100]
    up, down = sen, sen.decreasing
    # Fz increasing lifts the plate: the edge spring stays out; decreasing pushes it in.
    assert up.edge_state["Fz"].tolist() == [False] and down.edge_state["Fz"].tolist() == [True]
    assert up.edge_state["H"].tolist() == [False] and down.edge_state["H"].tolist() == [True]
    t = 1e-4

    def moved(name, k):
        if name == "Fz":
            return solve(problem.with_load(force=(0.0, 0.0, -20.0 + k * t)))
        return solve(problem.with_law(dataclasses.replace(law, H=law.H + k * t)))

    for name in ("Fz", "H"):
        # second-order one-sided differences, each staying on its side of the kink
        f = {k: moved(name, k) for k in (-2, -1, 1, 2)}
        f[0] = s
        for key in ("u", "pressure"):
            forward = (-3 * getattr(f[0], key) + 4 * getattr(f[1], key) - getattr(f[2], key)) / (2 * t)
            backward = (3 * getattr(f[0], key) - 4 * getattr(f[-1], key) + getattr(f[-2], key)) / (2 * t)
            np.testing.assert_allclose(getattr(up, key)[name], forward, rtol=1e-5, atol=1e-8)
            np.testing.assert_allclose(getattr(down, key)[name], backward, rtol=1e-5, atol=1e-8)
        assert abs(up.u[name][8] - down.u[name][8]) > 1e-3 * abs(up.u[name][8])  # truly one-sided
        assert up.pressure[name][100] == 0.0 and down.pressure[name][100] != 0.0
    if law.is_linear:  # the closed forms: 100 springs, or 101
        assert up.u["Fz"][8] == pytest.approx(2.0 / (1.0 * 100), rel=1e-12)
        assert down.u["Fz"][8] == pytest.approx(2.0 / (1.0 * 101), rel=1e-12)
    # forced states give the two one-sided values
    assert sensitivities(s, ("Fz",), edge="out").u["Fz"][8] == pytest.approx(up.u["Fz"][8], rel=1e-12)
    assert sensitivities(s, ("Fz",), edge="in").u["Fz"][8] == pytest.approx(down.u["Fz"][8], rel=1e-12)


def test_unloaded_bonded_layer_is_one_sided_everywhere():
    layer = plate_layer(10.0, 10.0, 10, 10, thickness=2.0)
    s = solve(d.ContactProblem(layer, d.LinearLaw(1.0), force=(0, 0, 0), reference=(0, 0, 0), free=("uz",)))
    assert s.status == "unloaded"
    sen = sensitivities(s, ("Fz",))
    assert sen.edge.size == 100 and sen.one_sided
    # pushing (Fz decreasing) brings every spring in: uz = F h / (H S)
    assert sen.decreasing.u["Fz"][8] == pytest.approx(2.0 / 100.0, rel=1e-12)
    assert sen.decreasing.edge_state["Fz"].all()
    # pulling has no equilibrium: no derivative, and a note says so
    assert np.isnan(sen.u["Fz"][8]) and sen.notes


def test_a_load_along_an_unresisted_direction_has_no_derivative():
    layer = socket_layer(radius=25.0, thickness=2.0, coverage=90.0, n_rings=10, n_sectors=24)
    s = solve(d.ContactProblem(layer, d.LinearLaw(1.0), force=(0, 0, -100.0), reference=(0, 0, 0)))
    sen = sensitivities(s, ("Fz", "Mz"))
    assert np.isfinite(sen.u["Fz"]).all()
    assert np.isnan(sen.u["Mz"][6:]).all() and not sen.u["Mz"][:6].any()  # body 1 is fixed
    assert any("Mz" in note for note in sen.notes)


def test_per_spring_operator_beyond_the_dense_limit(monkeypatch):
    import dea_opt.sensitivity.derivatives as S

    s = solve(bed_problem(LAWS[1]))
    dense = sensitivities(s, ("thickness", "gap"))
    monkeypatch.setattr(S, "DENSE_LIMIT", 10)
    operator = sensitivities(s, ("thickness", "gap"))
    v = np.random.default_rng(0).normal(size=len(BED))
    for name in ("thickness", "gap"):
        for key in ("pressure", "strain"):
            np.testing.assert_allclose(getattr(operator, key)[name] @ v, getattr(dense, key)[name] @ v, atol=1e-12)
            np.testing.assert_allclose(getattr(operator, key)[name].T @ v, getattr(dense, key)[name].T @ v, atol=1e-12)


def test_path_frames_are_differentiated_one_by_one():
    problem = bed_problem(LAWS[0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        path = d.solve_path(problem, [(0, 0, -5.0), (0, 0, -10.0), (0, 0, -15.0)], method="newton")
    from dea_opt.sensitivity import path_sensitivities

    frames = path_sensitivities(path, ("Fz", "H"))
    assert len(frames) == 3
    for frame, solution in zip(frames, path.solutions):
        np.testing.assert_allclose(frame.u["Fz"], sensitivities(solution, ("Fz", "H")).u["Fz"])


def test_bad_requests_are_named_errors():
    s = solve(bed_problem(LAWS[0]))
    with pytest.raises(d.InputError, match="'beta'"):
        sensitivities(s, ("beta",))  # the linear law has no beta
    with pytest.raises(d.InputError, match="not prescribed"):
        sensitivities(s, ("body2.uz",))
    with pytest.raises(d.InputError, match="at least one"):
        sensitivities(s, ())
    with pytest.raises(d.InputError, match="edge"):
        sensitivities(s, ("H",), edge="maybe")
    with pytest.raises(d.InputError, match="area_band"):
        sensitivities(s, ("H",), area_band=-1.0)
    failed = dataclasses.replace(s, success=False, status="max_iter")
    with pytest.raises(d.InputError, match="certified"):
        sensitivities(failed, ("H",))
    # body 1 loads are parameters too: body 1 is fixed, so its load goes to the support
    sen = sensitivities(s, ("body1.Fz", "H"))
    assert not sen.u["body1.Fz"].any()
    table = sen.table()
    assert set(table) == {"body1.Fz", "H"} and table["H"]["peak_pressure"] == sen.peak_pressure["H"]


def test_page_and_modules_name_each_other():
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    page = (root / "formulations" / "sensitivity.md").read_text()
    for module in ("derivatives", "onesided", "parametric", "calibrate", "measurements", "uncertainty"):
        path = root / "dea_opt" / "sensitivity" / f"{module}.py"
        assert f"`dea_opt/sensitivity/{module}.py`" in page, f"the page does not name dea_opt/sensitivity/{module}.py"
        assert "formulations/sensitivity.md" in path.read_text(), f"{path} does not name its page"
    assert d.sensitivities is sensitivities and d.calibrate.__module__ == "dea_opt.sensitivity.calibrate"
    assert d.propagate.__module__ == "dea_opt.sensitivity.uncertainty"


def test_the_guide_snippet_runs_on_the_short_example():
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[2]
    pages = (
        ((root / "README.md").read_text(), "## A short example"),
        ((root / "docs" / "guide" / "sensitivities.md").read_text(), "## Sensitivities"),
    )
    namespace: dict = {}
    for text, title in pages:
        code = re.search(r"```python\n(.*?)```", text.split(title, 1)[1], re.S).group(1)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", d.ValidityWarning)
            exec(compile(code, title, "exec"), namespace)
    sens = namespace["sens"]
    assert set(sens.wrt) == {"H", "beta", "Fz", "thickness_scale", "gap"}
    assert sens.unit("peak_pressure", "H") == "MPa/MPa"
    assert sens.pressure["gap"].shape == (len(namespace["layer"]),) * 2
