"""CONTRIBUTING.md cannot rot: every file, module, name and test it mentions in backticks exists,
and its worked example of a law runs."""

from __future__ import annotations

import importlib
import re
from pathlib import Path

import pytest

import dea_opt as d

ROOT = Path(__file__).resolve().parents[2]
TEXT = (ROOT / "CONTRIBUTING.md").read_text(encoding="utf-8")
#: Inline code spans (not the fenced blocks, which are checked by running them).
SPANS = sorted(set(re.findall(r"(?<!`)`([^`\n]+)`(?!`)", re.sub(r"```.*?```", "", TEXT, flags=re.S))))
PATHS = [s for s in SPANS if re.fullmatch(r"[\w./-]+(\.(py|md|toml)(::\w+)?|/)", s)]
DOTTED = [s for s in SPANS if re.fullmatch(r"dea_opt(\.\w+)+", s)]


def resolve(dotted: str):
    """The object ``dotted`` names: the longest importable module prefix, then attributes."""
    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for name in parts[cut:]:
            obj = getattr(obj, name)
        return obj
    raise ImportError(dotted)


def test_the_guide_mentions_what_it_should():
    assert len(PATHS) >= 20 and len(DOTTED) >= 20
    for topic in ("## Adding a law", "## Adding a formulation", "## Adding a mesh format", "## Adding an output"):
        assert topic in TEXT


@pytest.mark.parametrize("path", PATHS)
def test_every_path_it_names_exists(path):
    file, _, test = path.partition("::")
    target = ROOT / file
    assert target.exists(), f"CONTRIBUTING.md names {file}, which does not exist"
    if test:
        assert re.search(rf"^def {test}\(", target.read_text(encoding="utf-8"), flags=re.M), f"{path} not found"


@pytest.mark.parametrize("dotted", DOTTED)
def test_every_dotted_name_it_names_imports(dotted):
    assert resolve(dotted) is not None


def test_the_test_lists_it_says_to_extend_exist():
    assert re.search(r"^LAWS = ", (ROOT / "tests/core/test_laws.py").read_text(), flags=re.M)
    assert re.search(r"^LAWS = ", (ROOT / "tests/sensitivity/test_sensitivity.py").read_text(), flags=re.M)
    assert re.search(r"^BED_LAWS = ", (ROOT / "tests/core/test_reference.py").read_text(), flags=re.M)
    assert re.search(r"^BAD_FILES = ", (ROOT / "tests/mesh/test_mesh_errors.py").read_text(), flags=re.M)
    conftest = (ROOT / "tests/conftest.py").read_text()
    assert re.search(r"^METHODS = ", conftest, flags=re.M) and re.search(r"^TIGHT = ", conftest, flags=re.M)


def test_the_law_example_registers_a_law_that_solves():
    """The guide's example, run as written, adds a law a problem solves with; the answer is
    checked here by the plate's own closed form (uniform strain, force balance)."""
    block = re.search(r"```python\n(.*?)```", TEXT, flags=re.S).group(1)
    namespace: dict = {}
    exec(compile(block, "CONTRIBUTING.md", "exec"), namespace)
    try:
        law = namespace["ToyLaw"](k=10.0, c=50.0)
        assert d.LAWS.kind_of(law) == "toy"
        from dea_opt.geometry import plate_layer

        layer = plate_layer(nx=8, ny=8)
        force = 40.0
        solution = d.solve(d.ContactProblem(layer, law, force=(0.0, 0.0, -force), free=["uz"]), "newton")
        # a flat punch on a bed: one strain everywhere, and the springs' forces carry the load
        strain = solution.strain
        assert solution.success and strain.max() - strain.min() < 1e-9
        eps = strain[0]
        assert float((layer.areas * -(10.0 * eps + 50.0 * eps**3)).sum()) == pytest.approx(force, rel=1e-9)
    finally:
        d.LAWS.unregister("toy")
