"""The written math and the code name each other; the guide's error catalogue and status tables
(``docs/guide/errors.md``, ``docs/guide/concepts.md``) match the code.

Pages are ``formulations/*.md``. A page and every module it names (``dea_opt/....py``) link
both ways, and so do every module that cites a page and that page. Each page has a
``## Symbols`` table, and every identifier in the page's formulas (its indented blocks) is one
of the symbols it defines: a symbol with a subscript (``V_i``, ``c_hat_i``) counts as defined
when the table defines it or its stem (``V``, ``c_hat``).
"""

from __future__ import annotations

import inspect
import re
from pathlib import Path

import pytest

import dea_opt
import dea_opt.errors
from dea_opt import Status, formulations

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted((ROOT / "formulations").glob("*.md"))
SOURCES = sorted((ROOT / "dea_opt").rglob("*.py"))

#: Words in formulas that are not symbols: functions, the words of an optimisation problem,
#: and the index letters every page uses (i over springs, j over dofs, k over bodies, b over
#: blocks).
VOCABULARY = {
    "sum",
    "min",
    "max",
    "sqrt",
    "diag",
    "exp",
    "ln",
    "sin",
    "cos",
    "int",
    "inf",
    "minimize",
    "subject",
    "to",
    "i",
    "j",
    "k",
    "b",
    "active",
}


@pytest.mark.parametrize("name", formulations.names())
def test_each_formulation_module_and_page_link_both_ways(name):
    module = formulations.get(name)
    page = ROOT / module.PAGE
    assert page.is_file(), f"{module.__name__} names {module.PAGE}, which does not exist"
    assert module.PAGE in module.__doc__, "the module docstring must name its page"
    assert f"dea_opt/formulations/{name}.py" in page.read_text(), "the page must name its module"


def test_every_public_module_of_the_formulations_package_has_its_page():
    """A formulation's module has its page, formulations/<name>.md; the modules every formulation
    shares (the system, which directions resist, the scaling, the crushed verdict) are written in
    formulations/energy.md, the energy they all minimise."""
    for path in sorted((ROOT / "dea_opt" / "formulations").glob("*.py")):
        if path.stem.startswith("_"):
            continue  # the registry (__init__) and the option declarations are not math
        page = ROOT / "formulations" / f"{path.stem}.md"
        if path.stem in formulations.FORMULATIONS:
            assert page.is_file(), f"{path.name} has no written math at formulations/{path.stem}.md"
        elif not page.is_file():
            page = ROOT / "formulations" / "energy.md"
        assert f"formulations/{page.name}" in path.read_text(), f"{path.name} does not name its page"
        assert f"dea_opt/formulations/{path.stem}.py" in page.read_text(), f"{page.name} does not name {path.name}"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_every_module_a_page_names_exists_and_links_back(page):
    assert {p.stem for p in PAGES} >= {"energy", "qp", "nlp", "newton"}
    named = set(re.findall(r"`(dea_opt/[\w/]+\.py)`", page.read_text()))
    assert named, f"{page.name} names no module"
    for path in sorted(named):
        assert (ROOT / path).is_file(), f"{page.name} names {path}, which does not exist"
        assert f"formulations/{page.name}" in (ROOT / path).read_text(), f"{path} does not link back to {page.name}"


@pytest.mark.parametrize("source", SOURCES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_page_a_module_cites_exists_and_names_it(source):
    module = str(source.relative_to(ROOT))
    for cited in sorted(set(re.findall(r"formulations/(\w+)\.md", source.read_text()))):
        page = ROOT / "formulations" / f"{cited}.md"
        assert page.is_file(), f"{module} cites formulations/{cited}.md, which does not exist"
        assert f"`{module}`" in page.read_text(), f"formulations/{cited}.md does not name {module}"


@pytest.mark.parametrize("source", SOURCES, ids=lambda p: str(p.relative_to(ROOT)))
def test_every_test_file_the_code_cites_exists(source):
    for cited in sorted(set(re.findall(r"tests/\w+\.py", source.read_text()))):
        assert (ROOT / cited).is_file(), f"{source.relative_to(ROOT)} cites {cited}, which does not exist"


def _formulas(text: str) -> list[str]:
    """The lines of the page's indented formula blocks (outside fenced code)."""
    lines, out, fence = text.splitlines(), [], False
    for i, line in enumerate(lines):
        if line.startswith("```"):
            fence = not fence
        elif (
            not fence
            and line.startswith("    ")
            and line.strip()
            and (i == 0 or not lines[i - 1].strip() or lines[i - 1].startswith("    "))
        ):
            out.append(line)
    return out


def _identifiers(line: str) -> set[str]:
    """Identifiers of one formula line: a trailing parenthesised remark (after two spaces) is
    prose, superscripts (``^T``, ``^rep``, ``^(-1/2)``) are not symbols, nor are numbers."""
    line = re.sub(r"\s{2,}\((?:[^()]|\([^()]*\))*\)\s*$", "", line)
    line = re.sub(r"\^(?:\([^)]*\)|[A-Za-z0-9+]+)", "", line)
    return set(re.findall(r"(?<![\w.])[A-Za-z][A-Za-z0-9]*(?:_[A-Za-z0-9]+)*'?", line))


def _defined(text: str) -> set[str]:
    """The symbols of the page's ``## Symbols`` table (first column)."""
    section = text.split("## Symbols", 1)[1].split("\n## ", 1)[0]
    rows = [row for row in section.splitlines() if row.startswith("| `")]
    return {symbol for row in rows for symbol in re.findall(r"`([^`]+)`", row.split("|")[1])}


def _is_defined(token: str, defined: set[str]) -> bool:
    token = token.rstrip("'")
    while True:
        if token in defined or token in VOCABULARY:
            return True
        if "_" not in token:
            return False
        token = token.rsplit("_", 1)[0]  # a subscript: V_i is V's


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_every_symbol_of_a_page_s_formulas_is_defined_on_that_page(page):
    text = page.read_text()
    assert "## Symbols" in text, f"{page.name} has no Symbols table"
    defined = _defined(text)
    formulas = _formulas(text)
    assert formulas and defined
    undefined = sorted({t for line in formulas for t in _identifiers(line) if not _is_defined(t, defined)})
    assert not undefined, f"{page.name} uses {undefined} in its formulas without defining them in its Symbols table"


def test_the_symbol_check_catches_an_undefined_symbol():
    text = (
        "## Symbols\n\n| symbol | meaning |\n|---|---|\n| `x`, `V_i` | dofs, volumes |\n\n## Math\n\n"
        "    Phi(x) = sum_i V_i w(x_i)  (a remark with y)\n    K^T A^(-1/2)\n"
    )
    defined = _defined(text)
    tokens = {t for line in _formulas(text) for t in _identifiers(line)}
    assert tokens == {"Phi", "x", "sum_i", "V_i", "w", "x_i", "K", "A"}
    assert sorted(t for t in tokens if not _is_defined(t, defined)) == ["A", "K", "Phi", "w"]


GUIDE = ROOT / "docs" / "guide"


def test_error_catalogue_lists_every_error():
    page = (GUIDE / "errors.md").read_text()
    catalogue = page.split("## The error catalogue", 1)[1].split("\n## ", 1)[0]
    classes = [
        c
        for _, c in inspect.getmembers(dea_opt.errors, inspect.isclass)
        if issubclass(c, (dea_opt.DeaError, Warning)) and c.__module__ == "dea_opt.errors"
    ]
    assert len(classes) >= 5
    for cls in classes:
        assert f"`{cls.__name__}`" in catalogue, f"{cls.__name__} is not in the guide's error catalogue"
        assert getattr(dea_opt, cls.__name__) is cls


def test_the_guide_status_table_lists_every_status_with_its_description():
    page = (GUIDE / "concepts.md").read_text()
    table = page.split("## Statuses", 1)[1].split("\n#", 1)[0]
    rows = {m.group(1): m.group(2).strip() for m in re.finditer(r"^\| `(\w+)` \| (.+?) \|$", table, re.MULTILINE)}
    assert set(rows) == {status.value for status in Status}
    for status in Status:
        assert rows[status.value] == status.description.replace("|", "\\|"), status


def test_the_guide_run_status_table_lists_every_run_status_with_its_exit_code_and_description():
    from dea_opt.status import RunStatus

    page = (GUIDE / "concepts.md").read_text()
    table = page.split("## Run statuses", 1)[1].split("\n#", 1)[0]
    rows = {
        m.group(1): (int(m.group(2)), m.group(3).strip())
        for m in re.finditer(r"^\| `(\w+)` \| (\d+) \| (.+?) \|$", table, re.MULTILINE)
    }
    assert set(rows) == {status.value for status in RunStatus}
    for status in RunStatus:
        assert rows[status.value] == (status.exit_code, status.description.replace("|", "\\|")), status
