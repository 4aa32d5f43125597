"""The API reference, generated from the package so that it cannot drift.

A *public module* is every module of ``dea_opt`` whose dotted path has no part starting with
``_`` (``dea_opt._checks`` and ``dea_opt.formulations._parts`` are private; ``__main__`` is a
script). Its *public names* are its ``__all__``; a module without one exports the classes and
functions it defines and the upper-case constants it assigns, none starting with ``_``.

An object exported by several modules (``dea_opt.LinearLaw`` is also ``dea_opt.laws.LinearLaw``
and ``dea_opt.laws.kinds.LinearLaw``) gets one page, at its *home*: the shortest public path that
exports it (the package itself first), ties broken alphabetically. Every other module that
exports it links to that page. ``write_api_pages`` writes the module pages and the object pages
(reStructuredText for autodoc and numpydoc) under ``docs/reference/api/``; the build calls it
every time, and ``tests/docs/test_site.py`` checks that every public name has its page.
"""

from __future__ import annotations

import ast
import enum
import functools
import importlib
import inspect
import pkgutil
import shutil
from dataclasses import dataclass
from pathlib import Path

PACKAGE = "dea_opt"


def public_modules() -> list[str]:
    """Every public module of the package, the package first, then in dotted order."""
    package = importlib.import_module(PACKAGE)
    names = [PACKAGE]
    for info in pkgutil.walk_packages(package.__path__, PACKAGE + "."):
        parts = info.name.split(".")[1:]
        if any(part.startswith("_") for part in parts):
            continue
        names.append(info.name)
    return [PACKAGE, *sorted(names[1:])]


def public_names(module_name: str) -> list[str]:
    """The public names of one module (its ``__all__``, or what it defines)."""
    module = importlib.import_module(module_name)
    names = getattr(module, "__all__", None)
    if names is not None:
        return [n for n in names if n != "__version__"] + (["__version__"] if "__version__" in names else [])
    found = []
    for name, value in vars(module).items():
        if name.startswith("_"):
            continue
        if (inspect.isclass(value) or inspect.isfunction(value)) and value.__module__ == module_name:
            found.append(name)
    source = inspect.getsource(module)
    for node in ast.parse(source).body:
        targets = (
            node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(node, ast.AnnAssign) else []
        )
        for target in targets:
            if isinstance(target, ast.Name) and target.id.isupper() and not target.id.startswith("_"):
                found.append(target.id)
    return sorted(set(found), key=found.index)


@dataclass(frozen=True)
class Entry:
    """One public name of one module, and where its page is."""

    module: str
    name: str
    home: str  #: the fully qualified name the page documents

    @property
    def qualified(self) -> str:
        return f"{self.module}.{self.name}"

    @property
    def is_home(self) -> bool:
        return self.qualified == self.home


def _identity(value) -> int:
    """What makes two exports the same object: the object itself (a re-export binds it)."""
    return id(value)


@functools.cache
def entries() -> tuple[Entry, ...]:
    """Every (module, public name), with the page that documents it."""
    pairs = []
    for module_name in public_modules():
        module = importlib.import_module(module_name)
        for name in public_names(module_name):
            pairs.append((module_name, name, getattr(module, name)))
    exporters: dict[object, list[str]] = {}
    for module_name, name, value in pairs:
        exporters.setdefault(_identity(value), []).append(f"{module_name}.{name}")
    modules = set(public_modules())
    out = []
    for module_name, name, value in pairs:
        # the same object under another name (an alias) keeps a page of its own
        candidates = [c for c in exporters[_identity(value)] if c.rsplit(".", 1)[1] == name]
        # a function named like a module of its package (``dea_opt.mesh.recast`` is both) is
        # documented at its longer path, so that the two pages do not share a name
        candidates = [c for c in candidates if c not in modules or inspect.ismodule(value)] or candidates
        home = min(candidates, key=lambda q: (q.count("."), q))
        out.append(Entry(module_name, name, home))
    return tuple(out)


def _kind(value) -> str:
    if inspect.isclass(value):
        if issubclass(value, BaseException):
            return "exception"
        return "class"
    if inspect.isfunction(value) or inspect.isbuiltin(value):
        return "function"
    if inspect.ismodule(value):
        return "module"
    return "data"


def _object(qualified: str):
    module_name, name = qualified.rsplit(".", 1)
    return getattr(importlib.import_module(module_name), name)


def _title(text: str, char: str = "=") -> str:
    return f"{text}\n{char * len(text)}\n"


def _attribute_doc(qualified: str) -> list[str]:
    """The ``#:`` comment documenting a constant where it is assigned (any module that exports
    it under this name), or nothing."""
    from sphinx.pycode import ModuleAnalyzer

    value = _object(qualified)
    name = qualified.rsplit(".", 1)[1]
    for module_name in public_modules() + _private_modules():
        module = importlib.import_module(module_name)
        if getattr(module, name, None) is not value:
            continue
        try:
            docs = ModuleAnalyzer.for_module(module_name).find_attr_docs()
        except Exception:  # a module without source
            continue
        if ("", name) in docs:
            return list(docs[("", name)])
    return []


def _private_modules() -> list[str]:
    package = importlib.import_module(PACKAGE)
    # not ``__main__``: importing it runs the command line
    found = pkgutil.walk_packages(package.__path__, PACKAGE + ".")
    return [info.name for info in found if not info.name.endswith(".__main__")]


def _data_directive(qualified: str, value) -> list[str]:
    """A constant: its type, its value when short, and its ``#:`` comment. Written by hand, not
    by autodata, which would show the docstring of the value's class (a Typer app's, a dict's)."""
    name = qualified.rsplit(".", 1)[1]
    lines = [f".. py:data:: {name}"]
    text = repr(value)
    if len(text) <= 160 and "\n" not in text and " at 0x" not in text:
        lines.append(f"   :value: {text}")
    lines += ["", f"   A ``{type(value).__name__}``.", ""]
    lines += [f"   {line}" for line in _attribute_doc(qualified)]
    return lines


def _object_page(qualified: str) -> str:
    value = _object(qualified)
    kind = _kind(value)
    module_name, name = qualified.rsplit(".", 1)
    lines = [_title(qualified), f".. currentmodule:: {module_name}", ""]
    if kind == "class":
        lines += [f".. autoclass:: {name}", "   :members:", "   :show-inheritance:"]
        if issubclass(value, enum.Enum):
            lines.append("   :undoc-members:")
    elif kind == "exception":
        lines += [f".. autoexception:: {name}", "   :show-inheritance:"]
    elif kind == "function":
        lines += [f".. autofunction:: {name}"]
    elif kind == "module":
        lines += [f"``{qualified}`` is the module :py:mod:`{value.__name__}`."]
    else:
        lines += _data_directive(qualified, value)
    return "\n".join(lines) + "\n"


def summary(value) -> str:
    """The first sentence of an object's own docstring, safe to put in a table cell."""
    doc = value.__doc__ if (inspect.isclass(value) or callable(value) or inspect.ismodule(value)) else None
    if not doc or (not inspect.ismodule(value) and type(value).__doc__ == doc and not inspect.isclass(value)):
        return " "
    first = " ".join(inspect.cleandoc(doc).split("\n\n", 1)[0].split())
    cut = first.find(". ")
    if cut > 0:
        first = first[: cut + 1]
    if first.count("``") % 2 or first.count("`") % 2:
        first = first.replace("`", "")
    return first or " "


def _module_page(module_name: str, module_entries: list[Entry]) -> str:
    lines = [_title(f"``{module_name}``"), f".. automodule:: {module_name}", ""]
    own = [e for e in module_entries if e.is_home]
    others = [e for e in module_entries if not e.is_home]
    if own:
        lines += [".. rubric:: Documented here", "", ".. list-table::", "   :class: dea-api-summary", ""]
        for e in own:
            lines += [f"   * - :py:obj:`{e.name} <{e.home}>`", f"     - {summary(_object(e.home))}"]
        lines += ["", ".. toctree::", "   :hidden:", ""] + [f"   generated/{e.home}" for e in own] + [""]
    if others:
        lines += [
            ".. rubric:: Also exported here",
            "",
            "The same objects as these, documented where they are exported first:",
            "",
            ".. list-table::",
            "   :header-rows: 1",
            "",
            "   * - name here",
            "     - documented as",
        ]
        for e in others:
            lines += [f"   * - ``{e.qualified}``", f"     - :py:obj:`{e.home}`"]
        lines.append("")
    if not module_entries:
        lines += ["This module exports no names of its own."]
    return "\n".join(lines) + "\n"


def homes() -> dict[str, str]:
    """Every exported path (``dea_opt.laws.LinearLaw``) -> the path its page documents."""
    return {e.qualified: e.home for e in entries()}


def write_api_pages(outdir: Path) -> tuple[Entry, ...]:
    """Write ``index.rst``, one page per public module and one per documented object into
    ``outdir`` (replacing what an earlier build left), and return the entries."""
    everything = entries()
    outdir = Path(outdir)
    if outdir.exists():
        shutil.rmtree(outdir)
    (outdir / "generated").mkdir(parents=True)
    modules = public_modules()
    by_module: dict[str, list[Entry]] = {m: [] for m in modules}
    for e in everything:
        by_module[e.module].append(e)
    for module_name in modules:
        (outdir / f"{module_name}.rst").write_text(_module_page(module_name, by_module[module_name]))
    for home in sorted({e.home for e in everything}):
        (outdir / "generated" / f"{home}.rst").write_text(_object_page(home))
    index = [
        _title("Python API"),
        "Every public module of ``dea_opt`` and every name it exports, generated from the package "
        "(its ``__all__``) at each build. An object exported by several modules is documented once, "
        "where it is exported first (``dea_opt.LinearLaw``, not ``dea_opt.laws.kinds.LinearLaw``); "
        "the other modules' pages link to it.",
        "",
        ".. toctree::",
        "   :maxdepth: 1",
        "",
    ]
    index += [f"   {m}" for m in modules]
    (outdir / "index.rst").write_text("\n".join(index) + "\n")
    return everything
