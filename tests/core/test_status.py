"""One status vocabulary: the same situation gets the same status from every method, solved once
or frame by frame; the solver's own status is kept beside it; old string uses keep working."""

from __future__ import annotations

import io
import json
import warnings

import numpy as np
import pandas as pd
import pytest

import dea_opt as d
from dea_opt import Status, formulations
from dea_opt.geometry import plate_layer, sphere_on_bed_layer
from dea_opt.status import CERTIFIABLE

#: The formulations of the small kinematics (the finite ones solve kinematics="finite" problems only).
METHODS = tuple(n for n in formulations.names() if "small" in formulations.capabilities(n).kinematics)


def _plate(gap=0.0, H=20.0):
    """A plate on a bonded layer, its springs open by ``gap`` (mm; negative: a press fit)."""
    grid = plate_layer(40.0, 10.0, 40, 4, thickness=2.0)
    layer = d.SpringLayer(grid.points, grid.normals, grid.areas, grid.thickness, gap=gap)
    return d.ContactProblem(layer, d.LinearLaw(H), free=("uz", "rx", "ry"))


def _bed(law, force):
    layer = sphere_on_bed_layer(radius=25.0, thickness=2.0, extent=6.0, n_rings=30, n_sectors=16)
    return d.ContactProblem(layer, law, force=(0, 0, -force), reference=(0, 0, 25.0), free=("uz",))


def quiet(fn, *args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", d.ValidityWarning)
        return fn(*args, **kwargs)


def test_a_status_is_its_string():
    assert Status.CONVERGED == "converged" and f"{Status.MAX_ITERATIONS}" == "max_iterations"
    assert json.loads(json.dumps({"status": Status.PRELOADED})) == {"status": "preloaded"}
    buffer = io.StringIO()
    pd.DataFrame({"status": [Status.UNLOADED, Status.CRUSHED]}).to_csv(buffer, index=False)
    assert buffer.getvalue().split() == ["status", "unloaded", "crushed"]
    assert Status("held") is Status.HELD


def test_every_status_explains_itself():
    assert len({s.value for s in Status}) == len(Status)
    for status in Status:
        assert status.value == status.value.lower() and len(status.description) > 20, status
    assert CERTIFIABLE < set(Status)


@pytest.mark.parametrize(
    "exc, status",
    [
        (d.LoadNotSupportedError("no"), Status.NOT_SUPPORTED),
        (d.InputError("bad"), Status.INVALID_INPUT),
        (d.SolverError("failed", status=Status.NON_FINITE), Status.NON_FINITE),
        (d.SolverError("failed"), Status.SOLVER_ERROR),
        (d.SolverError("failed", status="not a status"), Status.SOLVER_ERROR),
        (d.MissingDependencyError("pip install x"), Status.SOLVER_ERROR),
    ],
)
def test_the_status_of_a_run_that_raised(exc, status):
    assert Status.of_error(exc) is status


@pytest.mark.parametrize("method, native", [("newton", "converged"), ("qp", "Solved"), ("nlp", "Solve_Succeeded")])
def test_each_method_keeps_its_solver_s_own_status(method, native):
    s = quiet(d.solve, _plate().with_load(force=(0, 0, -100.0)), method)
    assert s.success and s.status is Status.CONVERGED
    assert s.info["native_status"] == native and s.info["solver_success"]


@pytest.mark.parametrize("method", [*METHODS, "auto"])
def test_zero_load_frames_of_a_load_path_have_one_status_by_every_method(method):
    """Zero-load frames were ``stalled`` in one frame and ``unloaded`` in
    another, and failed their certificate with nlp. Every method now gives them one status and
    a certified answer: ``unloaded`` without overlap, ``preloaded`` with a press fit."""
    loads = [(0, 0, 0), (0, 0, -200.0), (0, 0, 0)]
    apart = quiet(d.solve_path, _plate(gap=0.05), loads, method=method)
    assert list(apart.table["status"]) == [Status.UNLOADED, Status.CONVERGED, Status.UNLOADED]
    assert apart.table["success"].all() and not apart.pressures[0].any() and not apart.pressures[2].any()
    fitted = quiet(d.solve_path, _plate(gap=-0.02), loads, method=method)
    assert list(fitted.table["status"]) == [Status.PRELOADED, Status.CONVERGED, Status.PRELOADED]
    assert fitted.table["success"].all()
    # the same answer as a single solve, by every method: the default formulation's
    single = quiet(d.solve, _plate(gap=-0.02), method)
    assert single.status is Status.PRELOADED and single.info["solved_by"] == formulations.DEFAULT
    np.testing.assert_allclose(fitted.pressures[0], single.pressure, rtol=0, atol=1e-9 * single.peak_pressure)


@pytest.mark.parametrize(
    "method, options",
    [("newton", {}), ("nlp", {"form": "constrained"}), ("nlp", {"form": "reduced", "max_iter": 300}), ("auto", {})],
)
def test_a_layer_crushed_by_its_load_is_crushed_by_every_method(method, options):
    """The log law's stress stays finite at eps = -1: 400 N is more than the bed can carry. Each
    method fails in its own way (Newton's line search, IPOPT's search direction or its iteration
    limit); the status is the situation's."""
    s = quiet(d.solve, _bed(d.BlankevoortLaw(0.6), 400.0), method, strict=False, **options)
    assert not s.success and s.status is Status.CRUSHED and "crushed" in s.message
    assert s.strain.min() < -1 + 1e-4 and s.info["native_status"]


@pytest.mark.parametrize("options", [{"form": "constrained"}, {"form": "reduced"}])
def test_a_certified_answer_is_converged_whatever_the_solver_doubted(options):
    """Ateshian's law near eps = -1 under 4000 N: an equilibrium exists, and IPOPT stops short of
    its own tolerance there (acceptable level, or a search direction too small); the answer
    passes the certificate and agrees with Newton, so its status is that of Newton's."""
    problem = _bed(d.AteshianLaw(0.6, 0.05), 4000.0)
    s = quiet(d.solve, problem, "nlp", **options)
    newton = quiet(d.solve, problem, "newton")
    assert s.success and s.status is Status.CONVERGED is newton.status
    assert s.info["native_status"] in ("Solved_To_Acceptable_Level", "Search_Direction_Becomes_Too_Small")
    np.testing.assert_allclose(s.pressure, newton.pressure, rtol=0, atol=1e-6 * newton.peak_pressure)


def test_a_claimed_answer_the_certificate_rejects_is_inaccurate():
    s = quiet(
        d.solve,
        _plate().with_load(force=(0, 0, -300.0), point=(10.0, 0, 0)),
        "newton",
        gtol=0.5,
        xtol=0.5,
        strict=False,
    )
    assert s.info["native_status"] == "converged" and s.info["solver_success"]
    assert not s.success and s.status is Status.INACCURATE and "fails dea-opt's certificate" in s.message


def test_a_solver_error_carries_a_status():
    with pytest.raises(d.SolverError) as info:
        quiet(d.solve, _plate().with_load(force=(0, 0, -300.0), point=(10.0, 0, 0)), "newton", max_iter=1)
    assert info.value.status is Status.MAX_ITERATIONS and info.value.native_status == "max_iter"
    assert info.value.solution.status is Status.MAX_ITERATIONS


# --- run statuses: one vocabulary for manifests, sweep rows and exit codes ----------------------


@pytest.mark.parametrize(
    "success, valid, failures, expected",
    [
        (True, True, (), "ok"),
        (True, None, (), "ok"),
        (True, False, (), "outside_validity"),
        (False, False, (), "certificate_failed"),  # a failure outranks validity
        (False, True, ("inaccurate",), "certificate_failed"),
        (False, True, ("load_not_supported", "load_not_supported"), "load_not_supported"),
        (False, True, ("pose_error", "load_not_supported"), "pose_error"),
        (False, True, ("load_not_supported", "solver_error"), "certificate_failed"),
    ],
)
def test_a_run_status_names_the_cause_of_its_failures(success, valid, failures, expected):
    from dea_opt.status import RunStatus

    status = RunStatus.of_run(success, valid, [Status(f) for f in failures])
    assert status is RunStatus(expected) and status == expected
    assert status.exit_code == {"ok": 0, "outside_validity": 3}.get(expected, 1)


def test_run_statuses_are_their_strings_with_an_exit_code_and_a_description():
    from dea_opt.status import RunStatus

    assert json.loads(json.dumps({"status": RunStatus.LOAD_NOT_SUPPORTED})) == {"status": "load_not_supported"}
    assert [s for s in RunStatus if s.failed] == [
        RunStatus.CERTIFICATE_FAILED,
        RunStatus.LOAD_NOT_SUPPORTED,
        RunStatus.POSE_ERROR,
        RunStatus.NOT_CONVERGED,
        RunStatus.ERROR,
    ]
    assert RunStatus.ERROR.exit_code == 2 and all(len(s.description) > 20 for s in RunStatus)
    # the frame statuses a run's status repeats are the same words
    assert RunStatus.of_frame(Status.NOT_SUPPORTED) == Status.NOT_SUPPORTED
    assert RunStatus.of_frame(Status.POSE_ERROR) == Status.POSE_ERROR
