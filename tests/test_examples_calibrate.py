"""examples/calibrate_from_film.py on its coarse setting: the film it writes, the fit it makes and the
uncertainty it reports, checked against the truth it was made from and against the film's rules."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

pytestmark = pytest.mark.slow

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def _load(name):
    spec = importlib.util.spec_from_file_location(f"example_{name}", EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_calibrate_from_film_coarse(tmp_path):
    example = _load("calibrate_from_film")
    summary = example.main(["--coarse", "--out", str(tmp_path)])
    assert summary["geometry"] == "hip"
    written = json.loads((tmp_path / "calibration.json").read_text())
    assert written["fit"]["values"] == pytest.approx(summary["fit"]["values"])
    film = pd.read_csv(tmp_path / "film.csv")
    assert list(film.columns) == ["x", "y", "z", "p"] and len(film) == summary["springs"] == 30 * 80
    # the film's rules: readings at or below 0.5 MPa say "below", at or above 2.5 "saturated"
    counts = summary["readings"]
    assert counts["below"] == int((film.p <= 0.5).sum()) and counts["saturated"] == int((film.p >= 2.5).sum())
    fit = summary["fit"]
    assert fit["success"] and fit["start"] == {"H_MPa": 10.0, "beta": 1.2}  # each named with its unit
    for name, true in example.TRUE.items():
        # a coarse layer (2400 springs) still brings the fit near the truth, within 3 standard errors
        key = {"H": "H_MPa"}.get(name, name)
        assert abs(fit["values"][key] - true) < 3 * fit["standard_errors"][key] + 1e-3 * true
    residuals = pd.read_csv(tmp_path / "residuals.csv")
    assert set(residuals.state) <= {"below", "measured", "saturated"} and len(residuals) == len(film)
    within = residuals.state == "measured"
    # a reading within the range: (log predicted - log measured) / noise
    np.testing.assert_allclose(
        residuals.residual[within],
        np.log(np.hypot(residuals.predicted_MPa[within], 5e-4) / residuals.measured_MPa[within]) / 0.05,
        rtol=1e-9,
    )
    unc = summary["uncertainty"]
    assert unc["failed_draws"] == 0 and unc["draws"] == 24
    assert unc["first_order"]["peak_pressure"] > 0 and unc["monte_carlo"]["peak_pressure"] > 0
    assert (tmp_path / "calibration.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
