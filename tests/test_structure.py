"""The package's layout: no import cycle, small modules.

The import graph is read from the source with :mod:`ast` (nothing is imported to build it):
a node per module of ``dea_opt`` (a package is its ``__init__``), an edge per import of
another ``dea_opt`` module. ``from . import x`` is an edge to the submodule ``x`` when there
is one, else to the package. Importing ``dea_opt.a.b`` runs ``dea_opt/a/__init__`` first,
but that implicit edge to a parent package is left out: every module would otherwise sit in
a cycle with ``dea_opt/__init__``, which imports the public API from its submodules.

Two graphs are checked. The imports that run when a module is imported (module level, class
bodies) must have no cycle at all. Adding the imports inside functions, which run only when
the function is called (after every module has loaded, so they cannot fail half-initialised),
the graph must have no cycle either, except through the edges of ``CALL_TIME_FRONTS``: methods
that are thin fronts to a subpackage which itself builds the front's class.
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
#: Function-level imports allowed to close a cycle, and why.
CALL_TIME_FRONTS = {
    # SpringLayer.from_meshes is a front to dea_opt.mesh, which builds SpringLayer objects.
    ("dea_opt.layer", "dea_opt.mesh"),
}


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


EDGES = import_edges()


def test_the_graph_sees_the_imports_it_must():
    # a module-level import, a function-level one, and the package front
    assert EDGES[("dea_opt.mesh.springs", "dea_opt.layer")] is True
    assert EDGES[("dea_opt.study", "dea_opt.solver")] is False
    assert EDGES[("dea_opt", "dea_opt.loadpath")] is True
    assert ("dea_opt.scenario.build", "dea_opt.laws") in EDGES  # `from .. import laws`
    assert len(EDGES) > 100


def test_no_import_cycle_at_import_time():
    cycle = _cycle([edge for edge, at_import in EDGES.items() if at_import])
    assert cycle is None, " -> ".join(cycle)


def test_no_import_cycle_with_function_level_imports():
    cycle = _cycle([edge for edge in EDGES if edge not in CALL_TIME_FRONTS])
    assert cycle is None, " -> ".join(cycle)


@pytest.mark.parametrize("front", sorted(CALL_TIME_FRONTS))
def test_each_allowed_front_is_real_and_only_a_call_time_import(front):
    """An entry of CALL_TIME_FRONTS that no longer closes a cycle must be removed from it."""
    assert EDGES.get(front) is False, f"{front} is not a function-level import"
    assert _cycle([edge for edge in EDGES if edge not in CALL_TIME_FRONTS - {front}]) is not None


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
    "dea_opt.largemotion",
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


def test_formulations_see_arrays_and_a_law_only():
    """No module under dea_opt/formulations/ imports, at module level or inside a function, from
    the packages that know meshes, files, problems or solutions."""
    imported = {(a, b) for a, b in EDGES if _within(a, "dea_opt.formulations")}
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
