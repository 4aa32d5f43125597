"""report.html: one self-contained page per run and per sweep, read in headless Chromium.

The page is opened from ``file://`` in Debian's Chromium, driven over its DevTools pipe
(:mod:`docs_browser`): it must load without a console error and without a request leaving
``file://``, its 3-D view must draw (a screenshot of it holds the pressure's colours, not a blank
box), and it must weigh at most 5 MB. Its content is read back from the page: the verdict
first, every validity check, each compartment's share; a sweep's table sorts by a click and its
plot follows its menus.
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import KNEE
from typer.testing import CliRunner

import dea_opt as d
from dea_opt.cli import app

HERE = Path(__file__).resolve().parents[1]
KNEE_EXAMPLE = HERE.parents[0] / "examples" / "scenarios" / "knee" / "knee.toml"
runner = CliRunner()
MEGABYTES = 5 * 1024 * 1024

PLATE = """
title = "A plate in two halves"
[geometry]
kind = "plate"
nx = 30
ny = 6
[law]
kind = "linear"
H = {H}
[body2]
free = ["uz", "ry"]
[regions]
split = "x"
[load]
force = [0.0, 0.0, -600.0]
point = [4.0, 0.0, 0.0]
"""


@pytest.fixture(scope="module")
def browser():
    sys.path.insert(0, str(HERE))
    from docs_browser import Browser, find_chromium

    executable = find_chromium()
    if executable is None:
        pytest.skip("Chromium is not installed (apt-get install chromium)")
    with Browser(executable) as opened:
        yield opened


def run(*args) -> object:
    return runner.invoke(app, [str(a) for a in args])


def offline(html: str) -> list[str]:
    """Scripts, styles, pictures or frames the page would fetch: none may have a source of its own."""
    return re.findall(r"<(?:script|img|link|iframe)[^>]*\s(?:src|href)=\"(?!data:)[^\"]*\"", html)


def not_blank(png: Path) -> tuple[int, float]:
    """``(colours, share of coloured pixels)`` of a screenshot: a blank box has one colour."""
    import matplotlib.image

    pixels = (matplotlib.image.imread(png)[..., :3] * 255).round().astype(int).reshape(-1, 3)
    colours = len(np.unique(pixels[:, 0] * 65536 + pixels[:, 1] * 256 + pixels[:, 2]))
    saturated = (pixels.max(axis=1) - pixels.min(axis=1)) > 40  # viridis, not grey or white
    return colours, float(saturated.mean())


def read_page(browser, page: Path, tmp_path: Path, view: str = "#view3d") -> dict:
    """Open ``page`` in Chromium; its problems, the 3-D view's screenshot numbers and its text."""
    report = browser.open(page.as_uri(), settle=2.0)
    shot = tmp_path / "view.png"
    browser.element_screenshot(page.as_uri(), view, shot, "document.querySelectorAll('[data-drawn]').length > 0")
    text = browser.evaluate(
        page.as_uri(), "document.body.innerText", "document.body && document.body.dataset.plotly === 'ready'"
    )
    colours, coloured = not_blank(shot)
    return {"problems": report.problems(), "colours": colours, "coloured": coloured, "text": text}


def hover_pressure(browser, page: Path):
    """Move the mouse over the 3-D view until a face in contact answers: ``(MPa, (x, y, z) mm)``
    read from the hover label, or None."""
    target = browser.call("Target.createTarget", {"url": page.as_uri()})["targetId"]
    session = browser.call("Target.attachToTarget", {"targetId": target, "flatten": True})["sessionId"]

    def evaluate(expression):
        answer = browser.call("Runtime.evaluate", {"expression": expression, "returnByValue": True}, session=session)
        return answer["result"].get("value")

    try:
        for _ in range(240):
            if evaluate("!!document.querySelector('#view3d[data-drawn]')"):
                break
            browser._pump(0.25)
        browser._pump(1.0)
        x0, y0, width, height = evaluate(
            "(() => { const e = document.getElementById('view3d'); e.scrollIntoView();"
            " const r = e.getBoundingClientRect(); return [r.x, r.y, r.width, r.height]; })()"
        )
        browser._pump(0.5)
        for fx in (0.5, 0.4, 0.6, 0.3, 0.7):
            for fy in (0.5, 0.4, 0.6, 0.3, 0.7):
                point = {"type": "mouseMoved", "x": x0 + width * fx, "y": y0 + height * fy}
                browser.call("Input.dispatchMouseEvent", point, session=session)
                browser._pump(0.4)
                text = evaluate("Array.from(document.querySelectorAll('#view3d .hovertext')).map(e => e.textContent)")
                found = re.search(r"([\d.eE+-]+) MPax ([\d.-]+), y ([\d.-]+), z ([\d.-]+) mm", " ".join(text or []))
                if found:
                    return float(found[1]), np.array([float(found[k]) for k in (2, 3, 4)])
        return None
    finally:
        browser.call("Target.closeTarget", {"targetId": target})


@pytest.mark.slow
def test_a_run_writes_its_report_with_its_other_outputs_and_it_reads_in_chromium(browser, tmp_path):
    (tmp_path / "plate.toml").write_text(PLATE.format(H=10.0))
    result = run("run", tmp_path / "plate.toml", "-o", tmp_path / "out")
    assert result.exit_code == 0, result.stdout + result.stderr
    page = tmp_path / "out" / "report.html"
    manifest = json.loads((tmp_path / "out" / "manifest.json").read_text())
    assert manifest["files"]["report.html"]["size_bytes"] == page.stat().st_size  # published with the others
    assert "report        report.html" in result.stdout
    html = page.read_text()
    assert page.stat().st_size <= MEGABYTES and offline(html) == []
    # the verdict first, then the checks, the compartments, the 3-D view, the certificate, inputs, software
    order = [html.index(f'id="{a}"') for a in ("verdict", "validity", "compartments", "view", "certificate")]
    order += [html.index(f'id="{a}"') for a in ("inputs", "software")]
    assert order == sorted(order)
    seen = read_page(browser, page, tmp_path)
    assert seen["problems"] == []
    assert seen["colours"] > 100 and seen["coloured"] > 0.2, seen  # the pressure's colours, drawn
    text = seen["text"]
    assert text.index("VALID") < text.index("Validity")
    for check in ("strain", "rotation", "gap_error", "peak_pressure", "dropped_springs"):
        assert check in text
    solution = d.solve(d.scenario.build_problem(d.scenario.load_scenario(tmp_path / "plate.toml")))
    for name, stats in solution.regions().items():  # each compartment's share, as the run computed it
        assert re.search(rf"{name}\s+{100 * stats.share:.4g}\s", text), name
    digest = manifest["scenario_sha256"]
    assert digest in text and "numpy" in text and d.__version__ in text
    # hovering a face shows its pressure: on springs without a mesh a face joins three springs and
    # shows their mean, within the pressures of the springs around that corner of it (3 digits)
    pressure, where = hover_pressure(browser, page)
    near = solution.pressure[np.linalg.norm(solution.problem.layer.points - where, axis=1) < 2.0]
    assert near.min() * (1 - 5e-3) <= pressure <= near.max() * (1 + 5e-3), (pressure, where, near)


def test_a_result_outside_validity_says_so_first(browser, tmp_path):
    (tmp_path / "soft.toml").write_text(PLATE.format(H=1.0))
    result = run("run", tmp_path / "soft.toml", "-o", tmp_path / "out")
    assert result.exit_code == 3
    html = (tmp_path / "out" / "report.html").read_text()
    banner = html[html.index('id="verdict"') - 40 : html.index('id="verdict"') + 400]
    assert 'class="verdict bad"' in banner and "OUTSIDE VALIDITY" in banner and "strain" in banner
    assert '<tr class="failed"><td>strain</td>' in html


@pytest.mark.slow
def test_the_demo_report_has_the_cycle_the_peak_frame_and_the_comparison(browser, tmp_path):
    result = run("demo", "--coarse", "--frames", "5", "-o", tmp_path / "demo")
    assert result.exit_code == 0, result.stdout + result.stderr
    page = tmp_path / "demo" / "report.html"
    html = page.read_text()
    assert page.stat().st_size <= MEGABYTES and offline(html) == []
    assert html.count("data:image/png;base64,") == 3  # cycle, exposure and the peak frame's map
    for anchor in ("figures", "frames", "comparison", "compartments"):
        assert f'id="{anchor}"' in html
    seen = read_page(browser, page, tmp_path)
    assert seen["problems"] == [] and seen["colours"] > 100 and seen["coloured"] > 0.2, seen
    assert "superior" in seen["text"] and "The peak frame's checks (frame" in seen["text"]


def test_without_plotly_the_report_says_how_to_get_its_views(monkeypatch, tmp_path):
    from dea_opt.report import page

    monkeypatch.setattr(page, "_plotly_gzipped", lambda: None)
    (tmp_path / "plate.toml").write_text(PLATE.format(H=10.0))
    assert run("run", tmp_path / "plate.toml", "-o", tmp_path / "out").exit_code == 0
    html = (tmp_path / "out" / "report.html").read_text()
    assert "plotly-gz" not in html and "pip install plotly" in html and "VALID" in html


@pytest.mark.slow
def test_a_sweep_report_sorts_its_table_and_plots_any_output_against_any_swept_value(browser, tmp_path):
    (tmp_path / "plate.toml").write_text(PLATE.format(H=10.0))
    sets = ["--set", "law.H=3,8,12", "--set", "load.scale=0.5,1"]
    result = run("sweep", tmp_path / "plate.toml", *sets, "--scheduler", "synchronous", "-o", tmp_path / "s")
    assert result.exit_code in (0, 3), result.stdout + result.stderr
    page = tmp_path / "s" / "report.html"
    assert f"report: {page}" in result.stdout
    html = page.read_text()
    assert page.stat().st_size <= MEGABYTES and offline(html) == []
    assert browser.open(page.as_uri(), settle=2.0).problems() == []
    uri = page.as_uri()
    ready = "document.querySelectorAll('[data-drawn]').length > 0"
    # a click on a header sorts the cases by it, a second click the other way
    column = """(() => { const t = document.querySelector('#cases ~ .scroll table');
        const h = Array.from(t.tHead.rows[0].cells).findIndex(c => c.textContent === 'peak_pressure_MPa');
        const read = () => Array.from(t.tBodies[0].rows).map(r => parseFloat(r.cells[h].dataset.value));
        t.tHead.rows[0].cells[h].click(); const up = read(); t.tHead.rows[0].cells[h].click();
        return [up, read()]; })()"""
    up, down = browser.evaluate(uri, column, ready)
    assert up == sorted(up) and down == sorted(up, reverse=True) and len(up) == 6
    # the plot follows its menus: the output chosen against the swept value chosen
    plot = """(() => { const x = document.getElementById('x-menu'), y = document.getElementById('y-menu');
        y.value = 'contact_area_mm2'; x.value = 'load.scale';
        x.dispatchEvent(new Event('change')); const div = document.getElementById('sweep-plot');
        return div.data.map(t => [t.name, t.x, t.y]); })()"""
    traces = browser.evaluate(uri, plot, ready)
    import pandas as pd

    table = pd.read_csv(tmp_path / "s" / "sweep.csv")
    drawn = sorted((x, y) for _, xs, ys in traces for x, y in zip(xs, ys))
    assert drawn == sorted(zip(table["load.scale"], table["contact_area_mm2"]))
    assert {name for name, _, _ in traces} == set(table["status"])
    shot = tmp_path / "plot.png"
    browser.element_screenshot(uri, "#sweep-plot", shot, ready)
    assert not_blank(shot)[0] > 20


@pytest.mark.slow
@pytest.mark.skipif(not KNEE.is_dir(), reason="needs the real knee in ../shared/data/knee")
def test_the_real_knee_s_report_weighs_under_5_mb_and_draws(browser, tmp_path):
    result = run("run", KNEE_EXAMPLE, "-o", tmp_path / "knee")
    assert result.exit_code == 0, result.stdout + result.stderr
    page = tmp_path / "knee" / "report.html"
    assert page.stat().st_size <= MEGABYTES and offline(page.read_text()) == []
    seen = read_page(browser, page, tmp_path)
    assert seen["problems"] == [] and seen["colours"] > 100 and seen["coloured"] > 0.1, seen
    assert "medial" in seen["text"] and "lateral" in seen["text"] and "femoral_cartilage.stl" in seen["text"]
    # on springs cast from a mesh a face is a spring: the hover shows that spring's own pressure
    springs = __import__("pandas").read_csv(tmp_path / "knee" / "contact.csv")
    pressure, where = hover_pressure(browser, page)
    near = np.linalg.norm(springs[["x_mm", "y_mm", "z_mm"]].to_numpy() - where, axis=1) < 1.5
    assert np.isclose(springs["pressure_MPa"][near], pressure, rtol=5e-3).any(), (pressure, where)
