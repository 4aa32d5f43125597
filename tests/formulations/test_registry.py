"""The formulation registry: a formulation written here, in the test, runs like a built-in one.

The toy formulation minimises the same energy ``Phi(x) = sum_i V_i w(min(e0 + A x, 0)) - r . x``
with :func:`scipy.optimize.minimize` (BFGS on the exact gradient), in the scaled variables every
formulation solves in. Registered, it runs through ``solve``, ``solve_path``, ``compare`` and a
comparison study; its options are checked by the registry, and its capabilities decide where it
applies and which formulation ``auto`` falls back to.
"""

from __future__ import annotations

import types
import warnings

import numpy as np
import pytest
from conftest import scenario_text
from scipy.optimize import minimize

import dea_opt as d
from dea_opt import Status, formulations
from dea_opt.formulations import Capabilities, FormulationResult, Option, Variant, scaling, start_vector, trivial_result
from dea_opt.geometry import plate_layer
from dea_opt.run import solve_options
from dea_opt.study import run_study

#: scipy's BFGS statuses in dea-opt's vocabulary (0 converged, 1 iteration limit, 2 precision
#: loss in the line search, 3 NaN).
SCIPY_STATUS = {0: Status.CONVERGED, 1: Status.MAX_ITERATIONS, 2: Status.INACCURATE, 3: Status.NON_FINITE}


class MinimizeModel:
    """``Phi`` minimised by BFGS; nothing is built, a re-solve starts from the last answer."""

    def __init__(self, system, law, gtol=1e-10, maxiter=2000):
        self.system, self.law, self.gtol, self.maxiter = system, law, gtol, maxiter
        self.build_time = 0.0
        self.last = None
        self.calls = 0

    def solve(self, load=None, *, x0=None):
        self.calls += 1
        system = self.system if load is None else self.system.with_load(load)
        start = start_vector(system, x0)
        start = self.last if start is None else start
        trivial = trivial_result(system, self.law)
        if trivial is not None:
            return trivial
        sc = scaling(system, self.law.modulus)
        r = sc.load(system.load)

        def phi(xi):
            eps = np.minimum(system.e0 + xi @ sc.AT, 0.0)
            return float(sc.volume @ self.law.energy(eps) - r @ xi), sc.AT @ (sc.volume * self.law.stress(eps)) - r

        xi0 = np.zeros(sc.n_dofs) if start is None else sc.to_xi(start)
        out = minimize(phi, xi0, jac=True, method="BFGS", options={"gtol": self.gtol, "maxiter": self.maxiter})
        u_free = sc.to_u_free(out.x)
        if out.success:
            self.last = u_free
        return FormulationResult(
            u_free=u_free,
            stress=self.law.stress(np.minimum(system.strain_at(u_free), 0.0)),
            success=bool(out.success),
            status=SCIPY_STATUS.get(out.status, Status.SOLVER_ERROR),
            message=f"BFGS: {out.message}",
            iterations=int(out.nit),
            info={"native_status": int(out.status)},
        )


def toy_module(laws="any", warm_start=True):
    return types.SimpleNamespace(
        Model=MinimizeModel,
        OPTIONS=(
            Option("gtol", float, 1e-10, "BFGS's gradient tolerance (scaled)", range=(0, 1), tolerance=True),
            Option("maxiter", int, 2000, "BFGS's iteration limit", range=(1, None)),
        ),
        CAPABILITIES=Capabilities(laws=laws, warm_start=warm_start, duals=False, checks_load_first=False),
        VARIANT=None,
    )


@pytest.fixture
def toy():
    formulations.register("toy", toy_module())
    try:
        yield "toy"
    finally:
        formulations.unregister("toy")


def plate(law=None, e=10.0, force=-500.0):
    """A plate under an eccentric load: lift-off, so the contact set is a real unknown."""
    layer = plate_layer(40.0, 10.0, 80, 4, thickness=2.0)
    return d.ContactProblem(
        layer, law or d.LinearLaw(20.0), load=d.Load((0, 0, force), point=(e, 0, 0)), free=("uz", "rx", "ry")
    )


def own_balance(solution, problem):
    """The springs' force and moment on body 2 (about its reference point), from the
    pressures, areas, normals and points: summed here, not by the certificate."""
    layer = problem.layer
    f = (solution.pressure * layer.areas)[:, None] * layer.normals
    arm = layer.points - np.asarray(problem.body2.reference)
    return f.sum(axis=0), np.cross(arm, f).sum(axis=0)


def test_a_registered_formulation_is_solved_and_certified(toy):
    problem = plate()
    assert "toy" in formulations.names() and formulations.takes("toy", problem.law)
    s = d.solve(problem, "toy")
    assert s.success and s.method == "toy" and s.status is Status.CONVERGED
    force, moment = own_balance(s, problem)
    load_moment = np.cross(np.subtract((10.0, 0, 0), problem.body2.reference), (0, 0, -500.0))
    np.testing.assert_allclose(force, [0, 0, 500.0], rtol=0, atol=1e-6 * 500)
    np.testing.assert_allclose(moment, -load_moment, rtol=0, atol=1e-6 * 5000)
    reference = d.solve(problem, "newton")
    np.testing.assert_allclose(s.pressure, reference.pressure, rtol=0, atol=1e-6 * reference.peak_pressure)
    assert 0 < s.contact_area < problem.layer.areas.sum()


def test_a_registered_formulation_through_solve_path_warm_starts(toy, monkeypatch):
    problem = plate(d.AteshianLaw(10.0, 0.3))
    loads = [(0, 0, -100.0 * k) for k in (1, 2, 3, 4)]
    built = []
    original = MinimizeModel.__init__

    def counting(self, *args, **kwargs):
        built.append(self)
        original(self, *args, **kwargs)

    monkeypatch.setattr(MinimizeModel, "__init__", counting)
    path = d.solve_path(problem, loads, method="toy")
    newton = d.solve_path(problem, loads, method="newton")
    assert path.success and (path.table["status"] == Status.CONVERGED).all()
    assert len(built) == 1 and built[0].calls == 4  # one model, re-solved frame after frame
    for k, (pressure, reference) in enumerate(zip(path.pressures, newton.pressures)):
        assert np.abs(pressure - reference).max() <= 1e-6 * reference.max()
        force, _ = own_balance(path.solutions[k], problem)
        assert force[2] == pytest.approx(100.0 * (k + 1), rel=1e-6)


def test_a_registered_formulation_in_compare_and_a_study(toy):
    problem = plate()
    out = d.compare(problem, methods=("newton", "toy"))
    assert set(out.solutions) == {"newton", "toy"} and out.skipped == {}
    assert out.pressure <= 1e-6 and out.displacement <= 1e-6
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        study = run_study(problem, methods=("newton", "toy"), accuracy=("low", "default"))
    rows = study.table[study.table["method"] == "toy"].set_index("accuracy")
    assert list(rows["solver"]) == ["-", "-"] and (rows["status"] == Status.CONVERGED).all()
    assert rows.loc["default", "success"] and rows.loc["default", "d_pressure"] <= 1e-6
    # the study's accuracy reached the toy's tolerance option: a looser gtol, fewer iterations
    assert rows.loc["low", "solver_tol"] == 1e-3 and rows.loc["low", "iterations"] < rows.loc["default", "iterations"]


PLATE_SCENARIO = scenario_text(nx=80, H=20.0, point=(10.0, 0.0, 0.0), formats=("json",)) + "[solve]\n"


def test_a_registered_formulation_is_a_scenario_s_method(toy, tmp_path):
    from dea_opt.run import run_scenario
    from dea_opt.scenario import method_names, parse_scenario

    assert method_names() == ("auto", *formulations.names()) and "toy" in method_names()
    scenario = parse_scenario(PLATE_SCENARIO + 'method = "toy"\nmethods = ["newton", "toy"]\n')
    assert scenario.solve.method == "toy" and scenario.solve.methods == ["newton", "toy"]
    outcome = run_scenario(scenario, tmp_path / "out")
    solution = outcome.result
    assert outcome.exit_code == 0 and solution.method == "toy" and solution.success
    force, _ = own_balance(solution, solution.problem)
    assert force[2] == pytest.approx(500.0, rel=1e-6)
    # a name nobody registered is an error naming the key and the registered names
    with pytest.raises(d.ScenarioError, match=r"solve\.method.*must be one of auto, newton, .*toy.*got 'bfgs'"):
        parse_scenario(PLATE_SCENARIO + 'method = "bfgs"\n')
    with pytest.raises(d.ScenarioError, match=r"solve\.methods.*got 'auto'"):
        parse_scenario(PLATE_SCENARIO + 'methods = ["auto"]\n')


def test_an_unregistered_formulation_is_no_longer_a_scenario_s_method():
    from dea_opt.scenario import parse_scenario

    formulations.register("toy2", toy_module())
    try:
        assert parse_scenario(PLATE_SCENARIO + 'method = "toy2"\n').solve.method == "toy2"
    finally:
        formulations.unregister("toy2")
    with pytest.raises(d.ScenarioError, match="got 'toy2'"):
        parse_scenario(PLATE_SCENARIO + 'method = "toy2"\n')


def test_its_options_are_checked_by_the_registry(toy):
    problem = plate()
    with pytest.raises(
        d.InputError,
        match=r"method 'toy' takes the options \['gtol', 'maxiter', 'x0'\], "
        r"got unknown option 'tol'",
    ):
        d.solve(problem, "toy", tol=1e-8)
    with pytest.raises(d.InputError, match=r"gtol must be a number in \(0, 1\), got 2"):
        d.solve(problem, "toy", gtol=2)
    with pytest.raises(d.InputError, match="maxiter must be an integer >= 1, got 0"):
        d.solve_path(problem, [(0, 0, -1.0)], method="toy", maxiter=0)
    # One accuracy setting sets the options it marks as tolerances; [solve] keys pass by name.
    section = types.SimpleNamespace(tol=1e-7, solver="CLARABEL", form="constrained", maxiter=50)
    assert formulations.tolerance_options("toy", 1e-7) == {"gtol": 1e-7}
    assert solve_options(section, "toy", problem.law) == {"gtol": 1e-7, "maxiter": 50}


def test_its_status_maps_the_native_one(toy):
    s = d.solve(plate(), "toy", maxiter=1, strict=False)
    assert not s.success and s.status is Status.MAX_ITERATIONS and s.info["native_status"] == 1


def test_capabilities_decide_where_it_applies():
    formulations.register("toy_linear", toy_module(laws="linear"))
    try:
        nonlinear = plate(d.AteshianLaw(10.0, 0.3))
        with pytest.raises(
            d.InputError, match="method 'toy_linear' needs a LinearLaw.*method='newton' or method='nlp'"
        ):
            d.solve(nonlinear, "toy_linear")
        with pytest.raises(d.InputError, match="method 'toy_linear' needs a LinearLaw"):
            d.solve_path(nonlinear, [(0, 0, -1.0)], method="toy_linear")
        out = d.compare(nonlinear, methods=("newton", "toy_linear"))
        assert out.skipped == {"toy_linear": "toy_linear needs a linear law"}
        assert d.solve(plate(), "toy_linear").success
    finally:
        formulations.unregister("toy_linear")


def test_auto_falls_back_by_capability(monkeypatch):
    """With only Newton and two toys registered, ``auto`` falls back to the first that takes
    the law: the linear-only toy for a linear law, the other for a nonlinear one."""
    registry = {"newton": formulations.get("newton"), "toy_linear": toy_module(laws="linear"), "toy_any": toy_module()}
    monkeypatch.setattr(formulations, "FORMULATIONS", registry)
    linear, nonlinear = d.LinearLaw(20.0), d.AteshianLaw(10.0, 0.3)
    assert formulations.fallback_for(linear) == "toy_linear" and formulations.fallback_for(nonlinear) == "toy_any"

    def fails(self, load=None, *, x0=None):
        return FormulationResult(
            u_free=np.zeros(self.system.n_dofs),
            stress=np.zeros(self.system.n_springs),
            success=False,
            status=Status.LINE_SEARCH_FAILED,
            message="forced",
        )

    monkeypatch.setattr(formulations.get("newton").NewtonModel, "solve", fails)
    for law, expected in ((linear, "toy_linear"), (nonlinear, "toy_any")):
        s = d.solve(plate(law), "auto")
        assert s.success and s.method == expected and "line_search_failed" in s.info["fallback"]


def test_only_newton_takes_a_law_nothing_else_takes(monkeypatch):
    monkeypatch.setattr(
        formulations, "FORMULATIONS", {"newton": formulations.get("newton"), "toy_linear": toy_module(laws="linear")}
    )
    assert formulations.fallback_for(d.AteshianLaw(10.0, 0.3)) is None
    s = d.solve(plate(d.AteshianLaw(10.0, 0.3)), "auto")
    assert s.method == "newton" and s.info["fallback"] is None


@pytest.mark.parametrize(
    "name, module, match",
    [
        ("newton", toy_module(), "already registered"),
        ("auto", toy_module(), "other than 'auto'"),
        ("no-dash", toy_module(), "identifier"),
        ("bare", types.SimpleNamespace(Model=MinimizeModel), "lacks OPTIONS, CAPABILITIES"),
        (
            "caps",
            types.SimpleNamespace(Model=MinimizeModel, OPTIONS=(), CAPABILITIES={"laws": "any"}),
            "CAPABILITIES must be a Capabilities",
        ),
    ],
)
def test_a_bad_registration_is_refused(name, module, match):
    with pytest.raises(d.InputError, match=match):
        formulations.register(name, module)
    assert formulations.names()[:3] == ("newton", "qp", "nlp")


def test_unknown_names_and_bad_capabilities():
    with pytest.raises(
        d.InputError,
        match=r"method must be one of \('auto', 'newton', 'qp', 'nlp', 'finite', 'finite_nlp'\), "
        r"got 'simplex'",
    ):
        formulations.get("simplex")
    with pytest.raises(d.InputError, match="Capabilities.laws must be 'linear' or 'any'"):
        Capabilities(laws="cubic")


@pytest.mark.parametrize("name", ["newton", "qp", "nlp"])
def test_each_built_in_formulation_declares_itself(name):
    module = formulations.get(name)
    assert isinstance(module.CAPABILITIES, Capabilities) and module.CAPABILITIES.kinematics == ("small",)
    assert all(isinstance(o, Option) for o in module.OPTIONS)
    assert all(isinstance(status, Status) for status in module.NATIVE_STATUS.values())
    variant = formulations.variant(name)
    assert variant is None or isinstance(variant, Variant)
    assert formulations.tolerance_options(name, 1e-8) and set(formulations.tolerance_options(name, 1e-8).values()) == {
        1e-8
    }
    # every option's default passes its own check
    for option in module.OPTIONS:
        if not callable(option.choices):
            option.check(option.default)


def test_the_built_in_fallbacks_are_capability_answers():
    assert formulations.fallback_for(d.LinearLaw(1.0)) == "qp"
    for law in (d.AteshianLaw(1.0, 0.1), d.CubicLaw(1.0, 0.1), d.BlankevoortLaw(1.0)):
        assert formulations.fallback_for(law) == "nlp"


def test_the_guide_example_of_a_formulation_runs(capsys):
    import re
    from pathlib import Path

    page = (Path(__file__).resolve().parents[2] / "docs" / "guide" / "laws.md").read_text()
    section = page.split("## Adding a formulation", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, re.DOTALL).group(1)
    namespace: dict = {}
    try:
        exec(compile(code, "laws.md", "exec"), namespace)  # noqa: S102 - the guide's own example
        solution = namespace["solution"]
        assert solution.success and solution.method == "bfgs" and solution.status is Status.CONVERGED
        reference = d.solve(namespace["problem"], "newton")
        assert abs(solution.u[8] - reference.u[8]) <= 1e-6 * abs(reference.u[8])
        assert capsys.readouterr().out.startswith("converged ")
    finally:
        if "bfgs" in formulations.names():
            formulations.unregister("bfgs")


def test_the_guide_tables_of_options_and_capabilities_are_made_from_the_registry():
    """The guide and the reference do not copy the registry's tables: they are made from it when
    the site is built (the directives of ``docs/_ext/dea_docs/reference.py``), row by row."""
    import importlib.util
    import sys
    from pathlib import Path

    from conftest import docs_unavailable

    if importlib.util.find_spec("docutils") is None:  # the directives are docutils' (the docs extra)
        docs_unavailable("docutils (the docs extra) is not installed")
    root = Path(__file__).resolve().parents[2]
    for page in ("guide/laws.md", "reference/formulations.md"):
        text = (root / "docs" / page).read_text()
        assert ".. dea-formulation-options::" in text and ".. dea-formulation-capabilities::" in text, page
    sys.path.insert(0, str(root / "docs" / "_ext"))
    try:
        from dea_docs.reference import FormulationCapabilitiesDirective, FormulationOptionsDirective
    finally:
        sys.path.remove(str(root / "docs" / "_ext"))
    options = "\n".join(FormulationOptionsDirective.lines(None))
    capabilities = "\n".join(FormulationCapabilitiesDirective.lines(None))
    for name in formulations.names():
        for o in formulations.options(name):
            assert f"   * - ``{name}``\n     - ``{o.name}``\n     - {o.kind()}\n" in options, (name, o.name)
            assert f"     - {' '.join(o.doc.split())}" in options, (name, o.name)
        c = formulations.capabilities(name)
        assert f"   * - ``{name}``\n     - {c.laws}\n     - {'yes' if c.warm_start else 'no'}\n" in capabilities, name
