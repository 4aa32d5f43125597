"""The written math and the code name each other; the guide's error catalogue and status tables
(``docs/guide/errors.md``, ``docs/guide/concepts.md``) match the code.

Pages are ``formulations/*.md``. A page and every module it names (``dea_opt/....py``) link
both ways, and so do every module that cites a page and that page. Each page has a
``## Symbols`` table, and every identifier in the page's formulas is one of the symbols it
defines: a symbol with a subscript (``V_i``, ``c_hat_i``) counts as defined when the table
defines it or its stem (``V``, ``c_hat``). The formulas are the indented blocks, in the code's
notation, and the typeset display equations (``$$ ... $$``, rendered to MathML when the site is
built); each page typesets its key equations, and each typeset equation is followed by its twin
in the code's notation, which uses exactly the same symbols.
"""

from __future__ import annotations

import inspect
import re
from pathlib import Path

import pytest

import dea_opt
import dea_opt.errors
from dea_opt import Status, formulations

ROOT = Path(__file__).resolve().parents[2]
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
    source = Path(module.__file__).resolve().relative_to(ROOT).as_posix()  # finite: its package's __init__
    assert source in page.read_text(), f"the page must name its module, {source}"


def test_every_public_module_of_the_formulations_package_has_its_page():
    """A formulation's module has its page, formulations/<name>.md; the modules every formulation
    shares (the system, which directions resist, the scaling, the crushed verdict) are written in
    formulations/energy.md, the energy they all minimise."""
    base = (ROOT / "dea_opt" / "formulations").resolve()
    # a formulation is named by the registry (finite_nlp is dea_opt/formulations/finite/nlp.py), a
    # subpackage by its folder (dea_opt/formulations/finite/__init__.py is the formulation "finite")
    registered = {Path(formulations.get(n).__file__).resolve(): n for n in formulations.names()}
    paths = {*base.glob("*.py"), *base.glob("*/__init__.py"), *(p for p in registered if base in p.parents)}
    for path in sorted(paths):
        name = registered.get(path, path.parent.name if path.name == "__init__.py" else path.stem)
        if name.startswith("_") or path == base / "__init__.py":
            continue  # the registry (__init__) and the option declarations are not math
        page = ROOT / "formulations" / f"{name}.md"
        if name in formulations.FORMULATIONS:
            assert page.is_file(), f"{path.name} has no written math at formulations/{name}.md"
        elif not page.is_file():
            page = ROOT / "formulations" / "energy.md"
        source = path.relative_to(ROOT.resolve()).as_posix()
        assert f"formulations/{page.name}" in path.read_text(), f"{source} does not name its page"
        assert source in page.read_text(), f"{page.name} does not name {source}"


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


#: The LaTeX commands a typeset formula may use: those that stand for a symbol of the code's
#: notation (by its name there), the functions of :data:`VOCABULARY`, and layout that holds no
#: symbol. Any other command fails the check, so that no symbol can hide behind one.
LATEX_SYMBOLS = {
    "varepsilon": "eps",
    "epsilon": "eps",
    "sigma": "sigma",
    "Sigma": "Sigma",
    "phi": "phi",
    "varphi": "phi",
    "Phi": "Phi",
    "lambda": "lambda",
    "beta": "beta",
    "alpha": "alpha",
    "mu": "mu",
    "nu": "nu",
    "rho": "rho",
    "tau": "tau",
    "theta": "theta",
    "omega": "omega",
    "delta": "delta",
    "xi": "xi",
    "psi": "psi",
    "nabla": "grad",
}
LATEX_FUNCTIONS = {"sum", "min", "max", "sqrt", "exp", "ln", "log", "sin", "cos", "tan"}
LATEX_LAYOUT = {
    "frac",
    "dfrac",
    "tfrac",
    "left",
    "right",
    "big",
    "Big",
    "bigg",
    "quad",
    "qquad",
    "cdot",
    "times",
    "le",
    "ge",
    "leq",
    "geq",
    "ne",
    "in",
    "mid",
    "to",
    "infty",
    "ldots",
    "cdots",
    "lVert",
    "rVert",
    "lvert",
    "rvert",
    "leftarrow",
    "nonumber",
}
_IDENTIFIER = r"(?<![\w.])[A-Za-z][A-Za-z0-9]*(?:_[A-Za-z0-9]+)*'?"


def _typeset(text: str) -> list[tuple[str, list[str]]]:
    """Each display equation (``$$ ... $$``) of a page, with the indented block that follows it
    (its twin in the code's notation; empty when none follows)."""
    lines, out, i = text.splitlines(), [], 0
    while i < len(lines):
        if lines[i].strip().startswith("$$"):
            body, i = [lines[i].strip()[2:]], i + 1
            while not body[-1].rstrip().endswith("$$"):
                body.append(lines[i])
                i += 1
            latex = "\n".join(body).rstrip()[:-2]
            j = i
            while j < len(lines) and not lines[j].strip():
                j += 1
            twin = []
            while j < len(lines) and lines[j].startswith("    ") and lines[j].strip():
                twin.append(lines[j])
                j += 1
            out.append((latex, twin))
        else:
            i += 1
    return out


def _subscript(match: re.Match) -> str:
    """``_{t}`` is ``_t`` and ``_{2i}`` is ``_2i``, but digits alone join their symbol: ``e_{0}``
    is the code's ``e0`` (``c_1``, unbraced, stays ``c_1``)."""
    text = re.sub(r"\W+", "_", match[1]).strip("_")
    return text if text.isdigit() else "_" + text


def _latex_identifiers(latex: str) -> set[str]:
    """The symbols of a typeset formula, named as in the code's notation (``\\varepsilon_i`` is
    ``eps_i``, ``\\hat{c}_i`` is ``c_hat_i``, ``\\partial x`` and ``d\\xi`` are ``dx`` and
    ``dxi``, ``e_{0}`` is ``e0``); superscripts are not symbols (``A^\\top``), nor is prose
    (``\\text{...}``). An unknown command is an error."""
    s = re.sub(r"\\text\{[^{}]*\}", " ", latex)
    s = re.sub(r"\\begin\{array\}\{[lcr]*\}|\\(?:begin|end)\{[^{}]*\}", " ", s)  # and an array's columns
    s = re.sub(r"\\(?:mathrm|operatorname|mathbf|boldsymbol|mathit)\{([^{}]*)\}", r"\1", s)
    s = re.sub(r"\\(hat|dot)\{\\?([A-Za-z]+)\}", lambda m: LATEX_SYMBOLS.get(m[2], m[2]) + "_" + m[1], s)
    s = re.sub(r"\\partial\s*", "d", s)
    s = re.sub(r"(?<![A-Za-z\\])d\\([A-Za-z]+)", lambda m: "d" + LATEX_SYMBOLS.get(m[1], "\\" + m[1]), s)
    s = re.sub(r"\\[{}]", " ", s)
    while re.search(r"\^\{[^{}]*\}", s):
        s = re.sub(r"\^\{[^{}]*\}", "", s)
    s = re.sub(r"\^(?:\\[A-Za-z]+|[A-Za-z0-9])", "", s)

    def command(match: re.Match) -> str:
        name = match.group(1)
        if name in LATEX_SYMBOLS:
            return " " + LATEX_SYMBOLS[name]
        if name in LATEX_FUNCTIONS:
            return " " + name
        if name in LATEX_LAYOUT:
            return " "
        raise AssertionError(f"the typeset formula {latex!r} uses \\{name}, which the symbol check does not read")

    s = re.sub(r"\\([A-Za-z]+)", command, s)
    s = re.sub(r"\\.", " ", s)  # spacing and line breaks: \, \; \\
    while re.search(r"_\{[^{}]*\}", s):
        s = re.sub(r"_\{([^{}]*)\}", _subscript, s)
    s = re.sub(r"[{}&]", " ", s)
    s = re.sub(r"(?<![A-Za-z_\d])(\d+(?:\.\d+)?)(?=[A-Za-z])", r"\1 ", s)  # 2x is 2 x
    return set(re.findall(_IDENTIFIER, s))


def _stem(token: str, defined: set[str]) -> str | None:
    """The symbol of the table that defines ``token`` (its stem), or None for a word of the
    vocabulary or an undefined token."""
    token = token.rstrip("'")
    while True:
        if token in defined:
            return token
        if token in VOCABULARY or "_" not in token:
            return None
        token = token.rsplit("_", 1)[0]


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_every_symbol_of_a_page_s_formulas_is_defined_on_that_page(page):
    text = page.read_text()
    assert "## Symbols" in text, f"{page.name} has no Symbols table"
    defined = _defined(text)
    formulas = _formulas(text)
    assert formulas and defined
    undefined = sorted({t for line in formulas for t in _identifiers(line) if not _is_defined(t, defined)})
    assert not undefined, f"{page.name} uses {undefined} in its formulas without defining them in its Symbols table"
    for latex, _ in _typeset(text):
        undefined = sorted(t for t in _latex_identifiers(latex) if not _is_defined(t, defined))
        assert not undefined, f"{page.name}'s typeset {latex!r} uses {undefined} without defining them"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_each_page_typesets_its_key_equations_each_with_its_twin_in_the_code_s_notation(page):
    text = page.read_text()
    defined = _defined(text)
    typeset = _typeset(text)
    assert len(typeset) >= 2, f"{page.name} typesets {len(typeset)} equations: its key ones are to be typeset"
    for latex, twin in typeset:
        assert twin, (
            f"{page.name}: the typeset {latex!r} has no twin in the code's notation (an indented block after it)"
        )
        shown = {_stem(t, defined) for t in _latex_identifiers(latex)} - {None}
        written = {_stem(t, defined) for line in twin for t in _identifiers(line)} - {None}
        assert shown == written, (
            f"{page.name}: the typeset {latex!r} and its twin {twin} differ in their symbols: "
            f"only typeset {sorted(shown - written)}, only in the twin {sorted(written - shown)}"
        )


def test_the_symbol_check_catches_an_undefined_symbol():
    text = (
        "## Symbols\n\n| symbol | meaning |\n|---|---|\n| `x`, `V_i` | dofs, volumes |\n\n## Math\n\n"
        "    Phi(x) = sum_i V_i w(x_i)  (a remark with y)\n    K^T A^(-1/2)\n"
    )
    defined = _defined(text)
    tokens = {t for line in _formulas(text) for t in _identifiers(line)}
    assert tokens == {"Phi", "x", "sum_i", "V_i", "w", "x_i", "K", "A"}
    assert sorted(t for t in tokens if not _is_defined(t, defined)) == ["A", "K", "Phi", "w"]


def test_the_typeset_reading_names_symbols_as_the_code_does_and_refuses_what_it_cannot_read():
    latex = r"\Phi(x) = \sum_{i} V_i\, w\big(\min(\varepsilon_i(x), 0)\big) - r \cdot x + \hat{c}_i^{\top} + 2y"
    assert _latex_identifiers(latex) == {"Phi", "x", "sum_i", "V_i", "w", "min", "eps_i", "r", "c_hat_i", "y"}
    assert _latex_identifiers(r"K \frac{\partial x}{\partial p} = \frac{a}{b} \quad \text{(where k)}") == {
        "K",
        "dx",
        "dp",
        "a",
        "b",
    }
    assert _latex_identifiers(r"T^\top K\, d\xi = e_{0} + c_1 + r_{2i} + \dot{\varepsilon} + \nabla \Phi") == {
        "T",
        "K",
        "dxi",
        "e0",
        "c_1",
        "r_2i",
        "eps_dot",
        "grad",
        "Phi",
    }
    assert _latex_identifiers(
        r"\begin{array}{rll} \phi(\varepsilon) = & 0, & \varepsilon \le 0 \\ & \varepsilon_{\mathrm{t}} \end{array}"
    ) == {
        "phi",
        "eps",
        "eps_t",
    }
    with pytest.raises(AssertionError, match="vec"):
        _latex_identifiers(r"\vec{F} = 0")  # an unknown command could hide a symbol
    page = "Intro.\n\n$$\nq = A^\\top f\n$$\n\n    q = A^T f\n\n$$ g = q - r $$\n\nText.\n"
    assert _typeset(page) == [("\nq = A^\\top f\n", ["    q = A^T f"]), (" g = q - r ", [])]


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
