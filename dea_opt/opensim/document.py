"""The parsed XML of a model as OpenSim sees it: components by path, sockets, numbers with lines.

OpenSim names a component by its path from the model: the names of the components that own
it (``/bodyset/femur_r/femur_implant``, ``/jointset/knee_r/femur_r_offset``). Here every XML
element with a ``name`` is a component and its path is made of the named elements above it
(the ``<defaults>`` section is left out: it holds templates, not parts of the model). A socket
(``socket_parent_frame``, ``socket_frame``, ...) holds a path, absolute or relative to the
component that owns the socket (``..`` its owner); a bare name that names nothing there is
looked up as OpenSim 4.0 did for older files: a unique component of that name anywhere.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import OpenSimModelError
from .safexml import Element

__all__ = ["Document"]


@dataclass
class Document:
    """The components of one model file: ``paths`` (element -> path), ``by_path`` and
    ``by_name`` (name -> elements), and the file ``source`` for messages."""

    source: str
    model: Element
    paths: dict = field(default_factory=dict)
    by_path: dict = field(default_factory=dict)
    by_name: dict = field(default_factory=dict)

    @classmethod
    def of(cls, root: Element, source: str) -> Document:
        if root.tag != "OpenSimDocument":
            raise OpenSimModelError(
                f"{source}, line {root.line}: its root element is <{root.tag}>, not <OpenSimDocument>: is it an "
                f"OpenSim model file (.osim)?"
            )
        version = root.attrib.get("Version", "")
        if not version.isdigit():
            raise OpenSimModelError(f"{source}, line {root.line}: <OpenSimDocument> has no numeric Version")
        if int(version) < 40000:
            raise OpenSimModelError(
                f"{source}: written in OpenSim's format {version} (OpenSim 3); dea-opt reads the OpenSim 4 format "
                f"(40000 and later): open the model in OpenSim 4 and save it"
            )
        model = root.child("Model")
        if model is None:
            raise OpenSimModelError(f"{source}, line {root.line}: <OpenSimDocument> holds no <Model>")
        doc = cls(source, model)
        doc.paths[id(model)] = ""
        stack = [(c, "") for c in reversed(model.children)]
        while stack:
            element, owner = stack.pop()
            if element.tag == "defaults":
                continue
            path = owner
            if element.name is not None:
                path = f"{owner}/{element.name}"
                doc.paths[id(element)] = path
                doc.by_path.setdefault(path, element)
                doc.by_name.setdefault(element.name, []).append(element)
            stack.extend((c, path) for c in reversed(element.children))
        return doc

    # --- paths and sockets ----------------------------------------------------------------------

    def path(self, element: Element) -> str:
        """The component path of ``element`` (the nearest named element at or above it)."""
        e: Element | None = element
        while e is not None and id(e) not in self.paths:
            e = e.parent
        return self.paths[id(e)] if e is not None else ""

    def where(self, element: Element) -> str:
        """``"<file>, <path> (line N)"`` for messages."""
        return f"{self.source}, {self.path(element) or '/'} (line {element.line})"

    def socket(self, owner: Element, tag: str, kinds=None) -> Element:
        """The component the socket ``tag`` of ``owner`` connects to (``kinds``: allowed tags)."""
        value = owner.child_text(tag)
        if not value:
            raise OpenSimModelError(f"{self.where(owner)}: has no <{tag}> (the component it connects to)")
        target = self._resolve(value, self.path(owner))
        if target is None and "/" not in value:
            named = [e for e in self.by_name.get(value, []) if kinds is None or e.tag in kinds]
            target = named[0] if len(named) == 1 else None
        if target is None:
            raise OpenSimModelError(f"{self.where(owner)}: its <{tag}> {value!r} names no component of the model")
        if kinds is not None and target.tag not in kinds:
            raise OpenSimModelError(
                f"{self.where(owner)}: its <{tag}> {value!r} is a {target.tag}, expected one of {', '.join(kinds)}"
            )
        return target

    def _resolve(self, value: str, owner_path: str) -> Element | None:
        parts = value.split("/")
        if value.startswith("/"):
            current: list[str] = []
            parts = parts[1:]
        else:
            current = [p for p in owner_path.split("/") if p]
        for part in parts:
            if part in ("", "."):
                continue
            if part == "..":
                if not current:
                    return None
                current.pop()
            else:
                current.append(part)
        if not current:
            return self.model
        return self.by_path.get("/" + "/".join(current))

    # --- numbers ------------------------------------------------------------------------------

    def floats(self, element: Element, tag: str, n: int, default=None) -> np.ndarray:
        """The ``n`` numbers of the child ``tag`` of ``element`` (``default`` when it is absent)."""
        child = element.child(tag)
        if child is None:
            if default is None:
                raise OpenSimModelError(f"{self.where(element)}: has no <{tag}>")
            return np.array(default, dtype=float).reshape(n)
        fields = child.text.split()
        try:
            values = np.array([float(f) for f in fields], dtype=float)
        except ValueError:
            values = np.array([])
        if values.size != n or not np.isfinite(values).all():
            raise OpenSimModelError(
                f"{self.source}, line {child.line}: <{tag}> of {self.path(element) or '/'} must hold {n} finite "
                f"number{'s' if n > 1 else ''}, got {child.text[:80]!r}"
            )
        return values

    def number(self, element: Element, tag: str, default: float | None = None) -> float:
        """The one number of the child ``tag`` (``default`` when absent)."""
        return float(self.floats(element, tag, 1, None if default is None else [default])[0])

    def flag(self, element: Element, tag: str, default: bool) -> bool:
        """The boolean child ``tag`` (true/false, 1/0), ``default`` when absent."""
        text = element.child_text(tag)
        if text is None or text == "":
            return default
        value = {"true": True, "1": True, "false": False, "0": False}.get(text.lower())
        if value is None:
            child = element.child(tag)
            line = child.line if child is not None else element.line
            raise OpenSimModelError(
                f"{self.source}, line {line}: <{tag}> of {self.path(element)} must be true or false, got {text!r}"
            )
        return value

    def objects(self, set_tag: str) -> list:
        """The elements of the model's set ``set_tag`` (``<BodySet><objects>...``), in order."""
        found = self.model.child(set_tag)
        if found is None:
            return []
        objects = found.child("objects")
        return [] if objects is None else list(objects.children)
