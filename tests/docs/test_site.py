"""The documentation site, built: every public name has its page, every internal link and anchor
resolves, the index reaches the newcomer's six tasks directly, no page mentions an issue number
or a date, nothing is loaded from the network, and pages render in headless Chromium (no console
error, no request leaving ``file://``, no missing image, every equation rendered; a screenshot of
each under the test's ``tmp_path``), search included.

The site is the one ``DEA_OPT_DOCS_HTML`` names (``.ci/run`` builds it first), else it is built
here once, with warnings as errors. Without the ``docs`` extra, or without Chromium, these tests
skip; with ``DEA_OPT_REQUIRE_DOCS=1`` (``.ci/run`` sets it) they fail instead.
"""

from __future__ import annotations

import fcntl
import html
import importlib.util
import os
import re
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest
from conftest import docs_unavailable

ROOT = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.slow


@pytest.fixture(scope="session")
def site(tmp_path_factory) -> Path:
    given = os.environ.get("DEA_OPT_DOCS_HTML")
    if given:
        path = Path(given).resolve()
        assert (path / "index.html").is_file(), f"DEA_OPT_DOCS_HTML={given} holds no built site"
        return path
    if importlib.util.find_spec("sphinx") is None or importlib.util.find_spec("sphinx_gallery") is None:
        docs_unavailable('the docs extra is not installed (pip install -e ".[docs]")')
    shared = tmp_path_factory.getbasetemp().parent  # one build for every xdist worker
    out = shared / "dea-opt-site"
    with open(shared / "dea-opt-site.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        if not (out / "index.html").is_file():
            command = [sys.executable, "-m", "sphinx", "-W", "-n", "-q", "-b", "html", str(ROOT / "docs"), str(out)]
            built = subprocess.run(command, capture_output=True, text=True, env={**os.environ, "MPLBACKEND": "Agg"})
            assert built.returncode == 0, f"the site does not build:\n{built.stdout[-3000:]}\n{built.stderr[-5000:]}"
    return out


class _Links(HTMLParser):
    def __init__(self):
        super().__init__()
        self.links: list[str] = []
        self.ids: set[str] = set()
        self.loads: list[str] = []  # what the page itself loads: scripts, styles, images

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if "id" in attrs:
            self.ids.add(attrs["id"])
        if tag == "a" and attrs.get("name"):
            self.ids.add(attrs["name"])
        if tag == "a" and attrs.get("href"):
            self.links.append(attrs["href"])
        if tag in ("script", "img", "iframe", "source") and attrs.get("src"):
            self.loads.append(attrs["src"])
        if tag == "link" and attrs.get("href") and attrs.get("rel") not in (None, "canonical"):
            self.loads.append(attrs["href"])


def _parse(page: Path) -> _Links:
    parser = _Links()
    parser.feed(page.read_text(encoding="utf-8"))
    return parser


def _pages(site: Path) -> list[Path]:
    return [p for p in site.rglob("*.html") if not p.relative_to(site).parts[0].startswith("_")]


def test_every_public_name_has_its_page(site):
    from sphinx.util.inventory import InventoryFile

    sys.path.insert(0, str(ROOT / "docs" / "_ext"))
    try:
        from dea_docs.api import entries, public_modules
    finally:
        sys.path.remove(str(ROOT / "docs" / "_ext"))
    with open(site / "objects.inv", "rb") as handle:
        inventory = InventoryFile.load(handle, "", lambda base, uri: uri)
    documented = {
        name: where for kind, objects in inventory.items() if kind.startswith("py:") for name, where in objects.items()
    }
    everything = entries()
    assert len(everything) > 500 and {e.module for e in everything} >= {"dea_opt", "dea_opt.mesh", "dea_opt.scenario"}
    missing = sorted({e.home for e in everything if e.home not in documented})
    assert not missing, f"public names without a page: {missing[:20]}"
    for e in everything:
        page = site / "reference" / "api" / "generated" / f"{e.home}.html"
        assert page.is_file(), f"{e.qualified} has no page {page.name}"
    for module in public_modules():
        page = site / "reference" / "api" / f"{module}.html"
        links = set(_parse(page).links)
        for e in (e for e in everything if e.module == module):
            assert any(f"generated/{e.home}.html" in link for link in links), f"{module}'s page does not link {e.name}"


def test_every_internal_link_and_anchor_resolves(site):
    parsed = {page: _parse(page) for page in _pages(site)}
    broken = []
    for page, links in parsed.items():
        for href in links.links:
            parts = urlsplit(href)
            if parts.scheme or parts.netloc or href.startswith("mailto:"):
                continue
            target = (page.parent / unquote(parts.path)).resolve() if parts.path else page
            if target.is_dir():
                target = target / "index.html"
            if not target.exists():
                broken.append(f"{page.relative_to(site)} -> {href}")
                continue
            if parts.fragment and target.suffix == ".html" and not target.relative_to(site).parts[0].startswith("_"):
                ids = parsed[target].ids if target in parsed else _parse(target).ids
                if parts.fragment not in ids:
                    broken.append(f"{page.relative_to(site)} -> {href} (no such anchor)")
    assert len(parsed) > 500 and not broken, "\n".join(broken[:30])


def test_the_math_and_the_code_link_both_ways(site):
    """Every formulation's math page links its module's API page, and that page links back."""
    from dea_opt import formulations

    for name in formulations.names():
        module = formulations.get(name).__name__
        math_links = _parse(site / "math" / "pages" / f"{name}.html").links
        assert any(f"reference/api/{module}.html" in link for link in math_links), f"math/{name} -> {module}"
        api_links = _parse(site / "reference" / "api" / f"{module}.html").links
        assert any(f"math/pages/{name}.html" in link for link in api_links), f"{module} -> math/{name}"


def test_every_math_page_shows_its_typeset_equations_as_mathml(site):
    """Each display equation (``$$``) of ``formulations/*.md`` is MathML in its built page (made
    at build time: no script renders it), and no TeX is left in the page's text."""
    for source in sorted((ROOT / "formulations").glob("*.md")):
        displays = sum(1 for line in source.read_text().splitlines() if line.strip() == "$$") // 2
        page = (site / "math" / "pages" / f"{source.stem}.html").read_text(encoding="utf-8")
        blocks = len(re.findall(r'<math[^>]*display="block"', page))
        text = html.unescape(re.sub(r"<math.*?</math>|<[^>]+>", " ", page, flags=re.S))
        assert displays >= 2 and blocks >= displays, f"{source.name}: {displays} displays, {blocks} rendered"
        assert not re.search(r"\$\$|\\(frac|begin|varepsilon|sum)\b", text), f"{source.name} shows TeX"


def test_the_index_reaches_the_six_tasks_in_one_click(site):
    links = set(_parse(site / "index.html").links)
    for task, target in {
        "set up your own joint": "tutorial/your_own_joint.html",
        "choose H": "tutorial/your_own_joint.html#which-modulus",
        "read the validity verdict": "guide/concepts.html#validity",
        "run a gait from an OpenSim file": "guide/loadpaths.html#opensim-load-paths",
        "run a sweep on a cluster": "guide/sweeps.html#sweeps-on-a-cluster",
        "calibrate to film": "guide/sensitivities.html#calibration",
    }.items():
        assert target in links, f"the index does not link '{task}' ({target})"


def test_no_page_mentions_an_issue_number_or_a_date(site):
    found = []
    for page in _pages(site):
        text = html.unescape(re.sub(r"<[^>]+>", " ", page.read_text(encoding="utf-8")))
        for pattern in (r"\bissues?\s*#?\d+", r"#\d{2,}\b(?![\w-])", r"\b20\d\d-[01]\d-[0-3]\d\b"):
            found += [f"{page.relative_to(site)}: {m.group(0)}" for m in re.finditer(pattern, text, re.I)]
    assert not found, "\n".join(found[:20])


def test_no_page_loads_anything_from_the_network(site):
    remote = []
    for page in _pages(site):
        for src in _parse(page).loads:
            if urlsplit(src).scheme not in ("", "file", "data"):
                remote.append(f"{page.relative_to(site)}: {src}")
    css = [
        p for p in (site / "_static").rglob("*.css") if re.search(r"url\((['\"]?)https?:", p.read_text(errors="ignore"))
    ]
    assert not remote and not css, (remote[:10], css[:5])


@pytest.fixture(scope="module")
def browser():
    sys.path.insert(0, str(Path(__file__).parents[1]))
    from docs_browser import Browser, find_chromium

    executable = find_chromium()
    if executable is None:
        docs_unavailable("Chromium is not installed (apt-get install chromium)")
    with Browser(executable) as opened:
        yield opened


#: A page of each kind: the index, a guide page with equations, an API page, a gallery example
#: with its figures, the tutorial and a math page.
PAGES = (
    "index.html",
    "guide/concepts.html",
    "reference/api/generated/dea_opt.solve.html",
    "gallery/hip_gait.html",
    "tutorial/your_own_joint.html",
    "math/pages/energy.html",
    "math/pages/joint.html",
)


@pytest.mark.parametrize("page", PAGES)
def test_a_page_renders_in_chromium(site, browser, page, tmp_path):
    import matplotlib.image

    shot = tmp_path / (page.replace("/", "_") + ".png")
    report = browser.open((site / page).as_uri(), screenshot=shot)
    assert not report.problems(), f"{page}: {report.problems()}"
    assert report.title and report.text_length > 1000
    pixels = matplotlib.image.imread(shot)
    assert pixels.shape[0] >= 600 and float(pixels[..., :3].std()) > 0.02, "the screenshot is blank"
    if page == "guide/concepts.html":
        assert report.maths >= 10  # the model's equations, rendered as MathML with a size
    if page.startswith("math/pages/"):
        assert report.maths >= 5  # the page's key equations, typeset, each with a size


def test_search_works_from_file(site, browser):
    count = browser.evaluate(
        (site / "search.html").as_uri() + "?q=validity",
        "document.querySelectorAll('#search-results li').length",
        "document.querySelectorAll('#search-results li').length > 0",
    )
    assert count and count > 0, "search found nothing for 'validity' from file://"
