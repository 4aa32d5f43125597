"""The package's layout: its subpackages in layers, no import cycle, small modules, one name per thing.

The import graph is read from the source with :mod:`ast` (nothing is imported to build it):
a node per module of ``dea_opt`` (a package is its ``__init__``), an edge per import of
another ``dea_opt`` module, at module level or inside a function (an import inside a function
runs later, but it is a dependency all the same). ``from . import x`` is an edge to the
submodule ``x`` when there is one, else to the package. Importing ``dea_opt.a.b`` runs
``dea_opt/a/__init__`` first, but that implicit edge to a parent package is left out: every
module would otherwise sit in a cycle with ``dea_opt/__init__``, which imports the public API
from its submodules.

Above the modules, the subpackages (and the top-level modules) stand in :data:`LAYERS`, from the
bottom up: each imports only from the layers below its own, so no two subpackages can depend on
each other, whichever way round.
"""

from __future__ import annotations

import ast
import graphlib
import tomllib
from pathlib import Path

import pytest

import dea_opt

PACKAGE = Path(dea_opt.__file__).resolve().parent
#: Modules stay under this many lines, formatted by ruff (the project's guide says "~500").
MAX_LINES = 520
#: The subpackages and top-level modules of dea_opt from the bottom up. A name imports (at module
#: level or inside a function) only from the layers below its own; ``dea_opt`` itself, the public
#: front, imports from any. A new subpackage takes its place here.
LAYERS = (
    ("_version", "errors"),  # the version; the one exception tree
    ("status", "_checks", "files", "units"),  # status vocabularies; checks; atomic files, locks; units in names
    ("laws", "kinematics", "anatomy", "progress", "gait"),  # spring laws; rigid motion; anatomical frames
    ("formulations",),  # arrays and a law: the registry and every formulation
    ("layer",),  # the spring layer
    ("mesh", "io"),  # meshes to springs (and the cast cache); file formats
    ("problem",),  # a contact problem: layer, law, bodies, kinematics
    ("certificate_sums",),  # the certificate's sums over a problem's springs, in one sweep
    ("certificate", "validity", "loadcheck", "agreement", "geometry"),  # judging an answer; embedded geometries
    ("solution",),  # an answer with its certificate and validity
    ("finite",),  # finite kinematics above the arrays: meshes re-cast at the pose
    ("joint",),  # several bodies, layers and ligaments
    ("solver",),  # solve and compare, by kinematics and method
    ("loadpath", "study"),  # load paths; comparison studies
    ("opensim",),  # OpenSim models and motions, read without OpenSim
    ("scenario",),  # scenario files: schema, parse, build, content keys
    ("report",),  # report.html of a run and of a sweep
    ("run",),  # running a scenario: outputs published together, pictures, init
    ("sensitivity", "sweep"),  # derivatives and calibration; sweeps over scenarios
    ("cli",),  # the command line
)
LEVEL = {name: level for level, names in enumerate(LAYERS) for name in names}
#: Modules stay under this many lines, formatted by ruff (the project's guide says "~500").
MAX_LINES = 520


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _target(name: str) -> str | None:
    """The dea_opt module ``name`` loads: itself, or the longest prefix that is a module."""
    while name:
        if name in MODULES:
            return name
        name = name.rpartition(".")[0]
    return None


class _Imports(ast.NodeVisitor):
    """Every intra-package import of one module, with whether it runs at import time."""

    def __init__(self, module: str, is_package: bool):
        self.package = module if is_package else module.rpartition(".")[0]
        self.depth = 0  # functions around the current node
        self.found: list[tuple[str, bool]] = []  # (target module, at import time)

    def _function(self, node):
        self.depth += 1
        self.generic_visit(node)
        self.depth -= 1

    visit_FunctionDef = visit_AsyncFunctionDef = visit_Lambda = _function

    def _add(self, name: str):
        target = _target(name) if name.startswith("dea_opt") else None
        if target is not None:
            self.found.append((target, self.depth == 0))

    def visit_Import(self, node):
        for alias in node.names:
            self._add(alias.name)

    def visit_ImportFrom(self, node):
        if node.level:
            parts = self.package.split(".")
            base = ".".join(parts[: len(parts) - node.level + 1])
            base = f"{base}.{node.module}" if node.module else base
        else:
            base = node.module or ""
        for alias in node.names:
            self._add(f"{base}.{alias.name}" if f"{base}.{alias.name}" in MODULES else base)


def import_edges() -> dict[tuple[str, str], bool]:
    """``{(importer, imported): True if some import of it runs at import time}``."""
    edges: dict[tuple[str, str], bool] = {}
    for name, path in MODULES.items():
        visitor = _Imports(name, path.name == "__init__.py")
        visitor.visit(ast.parse(path.read_text(encoding="utf-8"), filename=str(path)))
        for target, at_import in visitor.found:
            if target != name:
                edges[(name, target)] = edges.get((name, target), False) or at_import
    return edges


def _cycle(edges) -> list[str] | None:
    graph = {name: set() for name in MODULES}
    for importer, imported in edges:
        graph[importer].add(imported)
    try:
        tuple(graphlib.TopologicalSorter(graph).static_order())
    except graphlib.CycleError as exc:
        return exc.args[1]
    return None


@pytest.fixture(scope="module")
def edges() -> dict[tuple[str, str], bool]:
    """:func:`import_edges`, parsed once by the test process that runs these tests (every
    module of the package read and parsed: a second at collection in each test process otherwise)."""
    return import_edges()


def test_the_graph_sees_the_imports_it_must(edges):
    # a module-level import, a function-level one, and the package front
    assert edges[("dea_opt.mesh.springs", "dea_opt.layer")] is True
    assert edges[("dea_opt.study", "dea_opt.solver")] is False
    assert edges[("dea_opt", "dea_opt.loadpath")] is True
    assert ("dea_opt.scenario.build", "dea_opt.laws") in edges  # `from .. import laws`
    assert len(edges) > 100


def _unit(module: str) -> str:
    """The subpackage or top-level module of ``module`` (``dea_opt`` for the package itself)."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "dea_opt"


def test_every_subpackage_has_its_layer():
    units = {_unit(name) for name in MODULES} - {"dea_opt"}
    assert units == set(LEVEL), f"not in LAYERS: {sorted(units - set(LEVEL))}; gone: {sorted(set(LEVEL) - units)}"


def test_subpackages_import_only_from_the_layers_below(edges):
    """Counting the imports inside functions: no subpackage reaches up, or across its own layer."""
    wrong = sorted(
        (a, b)
        for a, b in edges
        if _unit(a) != "dea_opt" and _unit(a) != _unit(b) and LEVEL[_unit(a)] <= LEVEL[_unit(b)]
    )
    assert not wrong, "imports that break the layers: " + "; ".join(f"{a} -> {b}" for a, b in wrong)


def test_the_layer_rule_would_see_an_upward_import_inside_a_function():
    visitor = _Imports("dea_opt.layer", False)
    visitor.visit(ast.parse("def from_meshes():\n    from .mesh import springs_from_meshes\n"))
    assert visitor.found == [("dea_opt.mesh", False)]
    assert LEVEL[_unit("dea_opt.layer")] <= LEVEL[_unit("dea_opt.mesh")]  # would be reported


def test_no_import_cycle_at_import_time(edges):
    cycle = _cycle([edge for edge, at_import in edges.items() if at_import])
    assert cycle is None, " -> ".join(cycle)


def test_no_import_cycle_with_function_level_imports(edges):
    cycle = _cycle(list(edges))
    assert cycle is None, " -> ".join(cycle)


#: What the formulations never see (the guide: "Dependencies point one way: formulations code sees
#: arrays and a law, never meshes or files"): meshes, files, scenarios, load paths, problems,
#: layers, solutions, and the code that builds their arrays from those.
NEVER_SEEN_BY_FORMULATIONS = (
    "dea_opt.mesh",
    "dea_opt.io",
    "dea_opt.scenario",
    "dea_opt.loadpath",
    "dea_opt.problem",
    "dea_opt.layer",
    "dea_opt.solution",
    "dea_opt.finite",
    "dea_opt.solver",
)
#: What they may import besides each other: errors, statuses, input checks, tolerances, laws and
#: the kinematics' array helpers, and the loader of optional dependencies and compiled parts
#: (``dea_opt._checks.dependencies``).
SEEN_BY_FORMULATIONS = (
    "dea_opt.errors",
    "dea_opt.status",
    "dea_opt._checks.inputs",
    "dea_opt._checks.thresholds",
    "dea_opt.laws",
    "dea_opt.kinematics",
    "dea_opt._checks.dependencies",
    "dea_opt._checks.threads",
)


def _within(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


def test_formulations_see_arrays_and_a_law_only(edges):
    """No module under dea_opt/formulations/ imports, at module level or inside a function, from
    the packages that know meshes, files, problems or solutions."""
    imported = {(a, b) for a, b in edges if _within(a, "dea_opt.formulations")}
    assert imported, "the graph sees no import of the formulations"
    forbidden = sorted((a, b) for a, b in imported if any(_within(b, p) for p in NEVER_SEEN_BY_FORMULATIONS))
    assert not forbidden, f"formulations import what they must not see: {forbidden}"
    other = sorted(
        (a, b) for a, b in imported if not _within(b, "dea_opt.formulations") and b not in SEEN_BY_FORMULATIONS
    )
    assert not other, f"formulations import beyond arrays, laws and errors: {other}"


def test_the_rule_of_the_formulations_would_see_a_function_level_import(tmp_path):
    source = "def f():\n    from ..mesh.springs import cast_springs\n    import dea_opt.io\n"
    visitor = _Imports("dea_opt.formulations.example", False)
    visitor.visit(ast.parse(source))
    assert set(visitor.found) == {("dea_opt.mesh.springs", False), ("dea_opt.io", False)}


@pytest.mark.parametrize("name", sorted(MODULES))
def test_modules_are_small(name):
    lines = MODULES[name].read_text(encoding="utf-8").count("\n")
    assert lines <= MAX_LINES, f"{name} has {lines} lines; split it (the guide's limit is ~500)"


def test_version_is_the_projects():
    project = tomllib.loads((PACKAGE.parent / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    from dea_opt._version import __version__

    assert dea_opt.__version__ == __version__ == project["version"]


def test_one_name_per_thing_no_former_names():
    """Version 0.x keeps no aliases: no FORMER_* tables, and no module-level ``__getattr__`` (the
    way a former name is served)."""
    assert not [name for name in dir(dea_opt) if name.startswith("FORMER")]
    serving = [
        name
        for name, path in MODULES.items()
        if any(
            isinstance(node, ast.FunctionDef) and node.name == "__getattr__"
            for node in ast.parse(path.read_text(encoding="utf-8")).body
        )
    ]
    assert not serving, f"modules that serve names by __getattr__: {serving}"


def test_import_dea_opt_starts_no_picture_machinery_nor_matplotlib():
    import subprocess
    import sys

    code = (
        "import sys, dea_opt; "
        "print(sorted(m for m in sys.modules if m.startswith(('matplotlib', 'dea_opt.run', 'cvxpy', 'casadi'))))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]", out
