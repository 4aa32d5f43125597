"""``dea-opt calibrate``: a scenario's parameters fitted to a pressure map CSV, and the results written.

Written math: ``formulations/sensitivity.md`` ("Calibration", "Standard errors"). The fit is
:func:`~dea_opt.sensitivity.calibrate.calibrate`'s; this module checks that the scenario can be
fitted (:func:`check_scenario`), reads the map (its noise stated with ``--noise`` or not, its
correlation over ``--correlation-length``) and writes ``calibration.json``, ``residuals.csv`` and
``calibration.png`` (:func:`calibrate_scenario`).
"""

from __future__ import annotations

from ..errors import InputError
from .calibrate import calibrate
from .measurements import PressureMap

__all__ = ["calibrate_scenario", "check_scenario"]


def check_scenario(scenario) -> None:
    """An error unless ``dea-opt calibrate`` can fit ``scenario``: one load (``[load]``) and small
    kinematics (the fit's Jacobian is the small kinematics' sensitivities); the message names the key."""
    from ..scenario import ScenarioError, key_origin

    if scenario.solve.kinematics == "finite":
        origin = key_origin(scenario, "solve.kinematics")
        raise ScenarioError(
            f"{scenario.source or 'the scenario'}: calibrate fits with the sensitivities of the small kinematics "
            f'(Eq. (9)-(11)), and solve.kinematics = "finite"{f" ({origin})" if origin else ""}: set '
            f'solve.kinematics = "small" (in the file, or --set solve.kinematics=small)'
        )
    if scenario.load_path is not None:
        raise InputError(
            "calibrate needs a scenario with one load ([load]); this one has a [load_path]: "
            "calibrate against one frame written as a static scenario"
        )


def calibrate_scenario(
    scenario,
    data_path,
    folder,
    *,
    parameters=None,
    film=None,
    noise: float | None = None,
    max_distance=None,
    correlation_length: float | None = None,
    progress: bool = False,
) -> tuple:
    """``dea-opt calibrate``: fit a scenario's parameters to a pressure map CSV and write the results.

    ``noise`` None: not stated (the standard errors from the residuals' scatter);
    ``correlation_length`` (mm): the readings' noise correlated over that distance
    (:func:`~dea_opt.sensitivity.covariance.spatial_correlation`). Writes ``calibration.json``
    (the summary), ``residuals.csv`` (:meth:`Calibration.residual_map`) and ``calibration.png``
    (:meth:`Calibration.plot`) into ``folder`` (the command stages and publishes it like every
    run's folder). ``progress``: the stages (reading meshes, casting springs, fitting with its
    count of solves) on a terminal (:mod:`dea_opt.progress`). Returns ``(Calibration, {name:
    path})``.
    """
    from ..progress import showing, stage

    check_scenario(scenario)
    with showing(progress):
        return _calibrate_and_write(
            scenario, data_path, folder, parameters, film, noise, max_distance, correlation_length, progress, stage
        )


def _calibrate_and_write(
    scenario, data_path, folder, parameters, film, noise, max_distance, correlation_length, progress, stage
) -> tuple:
    """The body of :func:`calibrate_scenario`, inside its progress."""
    import dataclasses
    from pathlib import Path

    from ..files.atomic import write_atomic
    from ..io.summary import write_json
    from ..run import prepare_run
    from .covariance import spatial_correlation

    # read, cast and checked as a run's (the check before solving stops a unit or sign slip)
    problem, _, _, suspicions = prepare_run(scenario)
    stage("reading the pressure map")
    names = tuple(parameters) if parameters else problem.law.parameter_names
    data = PressureMap.from_csv(data_path, film=film, noise=noise, max_distance=max_distance)
    if correlation_length is not None:
        try:
            correlation = spatial_correlation(data.points, correlation_length)
        except InputError as exc:
            raise InputError(f"correlation_length: {exc}") from None
        data = dataclasses.replace(data, correlation=correlation)
    fit = calibrate(problem, data, names, progress=progress)
    if suspicions:
        fit = dataclasses.replace(fit, notes=(*fit.notes, *(f"suspicious input: {line}" for line in suspicions)))
    stage("writing outputs")
    folder = Path(folder)
    files = {
        "summary": folder / "calibration.json",
        "residuals": folder / "residuals.csv",
        "plot": folder / "calibration.png",
    }
    film_info = (
        None
        if data.film is None
        else {"name": data.film.name, "lower_MPa": data.film.lower, "upper_MPa": data.film.upper}
    )
    summary = {
        **fit.summary(),
        "scenario": scenario.source,
        "data": str(data_path),
        "film": film_info,
        "noise": data.noise,
        "correlation_length_mm": correlation_length,
        "points": len(data.pressure),
        "points_matched": int(fit.residuals.size),
    }
    write_json(summary, files["summary"])
    table = fit.residual_map()
    write_atomic(files["residuals"], lambda tmp: table.to_csv(tmp, index=False))
    fit.plot(files["plot"], title=scenario.title or None)
    return fit, files
