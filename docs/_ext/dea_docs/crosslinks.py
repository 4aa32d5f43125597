"""Code names in the pages become links: math pages to code, code to math pages.

The written math (``formulations/*.md``) names its modules as ``dea_opt/formulations/qp.py``,
and the docstrings name their math page as ``formulations/qp.md``; the guide names objects as
``dea_opt.mesh.cast_springs``. After the references are resolved, every such inline literal
whose target the site documents becomes a link to it: a module path to the module's API page,
a page path to the rendered math page, a dotted name to its API page (or its module's). A
literal whose target is not documented stays as it is, so this never breaks the build.
"""

from __future__ import annotations

import functools
import re

from docutils import nodes

_MODULE_PATH = re.compile(r"(dea_opt(?:/\w+)*?)(?:/__init__)?\.py")  # lazy: a package's __init__.py is the package
_MATH_PAGE = re.compile(r"formulations/(\w+)\.md")
_DOTTED = re.compile(r"dea_opt(?:\.\w+)+")


def _python_objects(env) -> dict[str, tuple[str, str]]:
    """Fully qualified name -> (docname, anchor) of every Python object and module the site has."""
    domain = env.get_domain("py")
    return {name: (docname, anchor) for name, _, _, docname, anchor, _ in domain.get_objects()}


def _target(text: str, objects: dict, docnames: set[str]) -> tuple[str, str] | None:
    text = text.strip()
    match = _MODULE_PATH.fullmatch(text)
    if match:
        return objects.get(match.group(1).replace("/", "."))
    match = _MATH_PAGE.fullmatch(text)
    if match and f"math/pages/{match.group(1)}" in docnames:
        return (f"math/pages/{match.group(1)}", "")
    match = _DOTTED.fullmatch(text.removesuffix("()"))
    if match:
        name = match.group(0)
        while name.count("."):
            if name in objects:
                return objects[name]
            name = name.rsplit(".", 1)[0]  # an attribute of a documented object: link the object
    return None


def link_literals(app, doctree, docname: str) -> None:
    env = app.builder.env
    objects = _python_objects(env)
    for literal in list(doctree.findall(nodes.literal)):
        if isinstance(literal.parent, nodes.reference):
            continue
        target = _target(literal.astext(), objects, env.found_docs)
        if target is None or target == (docname, ""):
            continue
        todoc, anchor = target
        if todoc == docname and not anchor:
            continue
        uri = app.builder.get_relative_uri(docname, todoc) + (f"#{anchor}" if anchor else "")
        reference = nodes.reference("", "", internal=True, refuri=uri, classes=["dea-crosslink"])
        literal.replace_self(reference)
        reference.append(literal)


def _lookup(dotted: str):
    """The object a dotted path names (the longest importable module, then attributes, then a
    dataclass's or annotated class's fields), or a sentinel ``_MISSING``."""
    import importlib

    parts = dotted.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for i, attribute in enumerate(parts[cut:], start=cut):
            if hasattr(obj, attribute):
                obj = getattr(obj, attribute)
                continue
            fields = set(getattr(obj, "__dataclass_fields__", {})) | set(getattr(obj, "model_fields", {}))
            for klass in getattr(obj, "__mro__", ()):
                fields |= set(getattr(klass, "__annotations__", {}))
            return object() if attribute in fields and i == len(parts) - 1 else _MISSING
        return obj
    return _MISSING


_MISSING = object()


def _contexts(node) -> list[str]:
    """Where a reference stands: its module (and class), and the object whose docstring holds
    it (``docstring of dea_opt._checks.memory.check_memory``), each with their parents."""
    places = []
    module = node.get("py:module") or ""
    if module:
        places += [f"{module}.{node['py:class']}"] if node.get("py:class") else []
        places.append(module)
    match = re.search(r"docstring of ([\w.]+)", str(node.source or ""))
    if match:
        dotted = match.group(1).split(".")
        places += [".".join(dotted[:i]) for i in range(len(dotted), 0, -1)]
    return list(dict.fromkeys(places))


def _exists(target: str, node) -> bool:
    """Whether ``target`` names a real object of the package, seen from where the reference
    stands (an undocumented internal: a private constant, a dataclass field, a method of a class
    of the module): such a reference stays plain text. A name that exists nowhere is a broken
    reference and fails the build."""
    import importlib
    import inspect

    if _lookup(target) is not _MISSING and target.startswith("dea_opt"):
        return True
    for place in _contexts(node):
        if _lookup(f"{place}.{target}") is not _MISSING:
            return True
        try:
            module = importlib.import_module(place)
        except ImportError:
            continue
        for _, klass in inspect.getmembers(module, inspect.isclass):
            if klass.__module__ == place and _lookup(f"{place}.{klass.__name__}.{target}") is not _MISSING:
                return True
    return "." not in target and target in _members_anywhere()


@functools.cache
def _members_anywhere() -> frozenset[str]:
    """Every attribute name of every class the package defines, instance attributes included
    (``self.pose = ...``): a bare ``:meth:`tangent``` names one of them, on a class the
    docstring's parameter has."""
    import importlib
    import inspect
    import pkgutil

    import dea_opt

    names: set[str] = set()
    for info in pkgutil.walk_packages(dea_opt.__path__, "dea_opt."):
        if info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        for _, klass in inspect.getmembers(module, inspect.isclass):
            if klass.__module__ != info.name:
                continue
            names |= set(vars(klass)) | set(getattr(klass, "__dataclass_fields__", {}))
            try:
                names |= set(re.findall(r"self\.(\w+)\s*[:=]", inspect.getsource(klass)))
            except (OSError, TypeError):
                pass
    return frozenset(names)


def _example_defines(app, docname: str, target: str) -> bool:
    """A gallery page's reference to a function or class its own script defines."""
    from pathlib import Path

    if not docname.startswith(("gallery/", "tutorial/")):
        return False
    script = Path(app.srcdir) / (docname + ".py")
    if not script.is_file():
        return False
    return re.search(rf"^(def|class) {re.escape(target)}\b", script.read_text(), re.M) is not None


def resolve_missing(app, env, node, contnode):
    """A docstring's reference Sphinx could not resolve where it stands: a name exported by
    another module than the documented one (``dea_opt.laws.LAWS`` is documented as
    ``dea_opt.LAWS``), or a short name (``InputError``, ``Solution.u``) that one documented
    object ends with. Anything else stays unresolved, and the build fails on it."""
    from sphinx.util.nodes import make_refnode

    from .api import homes

    if node.get("refdomain") != "py":
        return None
    target = node["reftarget"].lstrip("~.")
    if _example_defines(app, node["refdoc"], target):
        return contnode
    objects = _python_objects(env)
    aliases = homes()
    name = aliases.get(target)
    if name is None:
        head, _, tail = target.partition(".")
        for full, home in aliases.items():  # an attribute of an exported object
            if tail and full == head:
                name = f"{home}.{tail}"
    if name is None or name not in objects:
        suffix = "." + target
        found = sorted({n for n in objects if n.endswith(suffix)})
        homes_found = [n for n in found if n in aliases.values() or n.rsplit(".", 1)[0] in aliases.values()]
        found = homes_found or found
        name = found[0] if len(found) == 1 else None
    if name is None or name not in objects:
        return contnode if _exists(target, node) else None
    docname, anchor = objects[name]
    return make_refnode(app.builder, node["refdoc"], docname, anchor, contnode, name)


def setup(app) -> None:
    app.connect("doctree-resolved", link_literals)
    app.connect("missing-reference", resolve_missing)
