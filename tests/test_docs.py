"""The written math and the code name each other; the README's error catalogue matches the code."""

from __future__ import annotations

import inspect
import re
from pathlib import Path

import pytest

import dea_opt
import dea_opt.errors
from dea_opt import formulations

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("name", list(formulations.FORMULATIONS))
def test_each_formulation_module_and_page_link_both_ways(name):
    module = formulations.get(name)
    page = ROOT / module.PAGE
    assert page.is_file(), f"{module.__name__} names {module.PAGE}, which does not exist"
    assert module.PAGE in module.__doc__, "the module docstring must name its page"
    assert f"dea_opt/formulations/{name}.py" in page.read_text(), "the page must name its module"


def test_every_module_of_the_formulations_package_has_its_page():
    for path in sorted((ROOT / "dea_opt" / "formulations").glob("*.py")):
        if path.stem == "__init__":
            continue
        page = ROOT / "formulations" / f"{path.stem}.md"
        assert page.is_file(), f"{path.name} has no written math at formulations/{path.stem}.md"
        assert f"formulations/{path.stem}.md" in path.read_text(), f"{path.name} does not name its page"
        assert f"dea_opt/formulations/{path.stem}.py" in page.read_text(), f"{page.name} does not name {path.name}"


def test_every_page_names_an_existing_module():
    pages = sorted((ROOT / "formulations").glob("*.md"))
    assert {p.stem for p in pages} >= {"energy", "qp", "nlp", "newton"}
    for page in pages:
        for path in re.findall(r"`(dea_opt/[\w/]+\.py)`", page.read_text()):
            assert (ROOT / path).is_file(), f"{page.name} names {path}, which does not exist"


def test_error_catalogue_lists_every_error():
    readme = (ROOT / "README.md").read_text()
    catalogue = readme.split("## Error catalogue", 1)[1].split("\n## ", 1)[0]
    classes = [c for _, c in inspect.getmembers(dea_opt.errors, inspect.isclass)
               if issubclass(c, (dea_opt.DeaError, Warning)) and c.__module__ == "dea_opt.errors"]
    assert len(classes) >= 5
    for cls in classes:
        assert f"`{cls.__name__}`" in catalogue, f"{cls.__name__} is not in the README's error catalogue"
        assert getattr(dea_opt, cls.__name__) is cls
