"""A small, safe XML reader for OpenSim model files: elements with their line numbers.

A model from elsewhere is untrusted input. This reader is built on the standard library's
expat parser (:mod:`xml.parsers.expat`) and refuses any document type declaration
(``<!DOCTYPE ...>``) before expat reads a byte of it. Entities can only be declared inside
one, so nothing can be expanded: no "billion laughs" or quadratic blow-up, and no external
entity or DTD is ever fetched (expat fetches none by itself either; parameter-entity parsing
stays off). A reference to an undeclared entity (``&foo;``) is expat's own error. OpenSim
writes no DOCTYPE, so no model is lost by the refusal.

Why not :mod:`xml.etree.ElementTree`: it keeps no line numbers, and a bad model must be
reported at its line; the tree built here is the few fields the reader needs (tag,
attributes, text, children, line). ``defusedxml`` would give the same safety but is not among
the project's kept libraries; the refusal of DOCTYPE here is the part of it that matters.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from xml.parsers import expat

from ..errors import OpenSimModelError

__all__ = ["Element", "MAX_BYTES", "parse_file", "parse_text"]

#: The largest model file read (bytes): a model of the whole body with every muscle is a few MB.
MAX_BYTES = 200 * 1024 * 1024


@dataclass(eq=False)
class Element:
    """One XML element: ``tag``, ``attrib``, stripped ``text``, ``children`` and its ``line``."""

    tag: str
    attrib: dict
    line: int
    children: list = field(default_factory=list)
    text: str = ""
    parent: Element | None = field(default=None, repr=False)

    @property
    def name(self) -> str | None:
        """The ``name`` attribute (OpenSim's component name), or None."""
        return self.attrib.get("name")

    def child(self, tag: str) -> Element | None:
        """The first child element with ``tag``, or None."""
        for c in self.children:
            if c.tag == tag:
                return c
        return None

    def child_text(self, tag: str) -> str | None:
        """The text of the first child with ``tag`` (None when there is none)."""
        c = self.child(tag)
        return None if c is None else c.text

    def iter(self):
        """This element and every element below it, depth first in document order."""
        stack = [self]
        while stack:
            e = stack.pop()
            yield e
            stack.extend(reversed(e.children))


class _Refused(Exception):
    def __init__(self, message: str, line: int):
        super().__init__(message)
        self.line = line


def parse_text(data: bytes | str, source: str = "<text>") -> Element:
    """The root element of the XML document ``data``.

    Raises
    ------
    OpenSimModelError
        Malformed XML (the message gives expat's reason and the line and column), a document
        type declaration or entity declaration (refused, with its line), or no root element.
    """
    parser = expat.ParserCreate()
    parser.SetParamEntityParsing(expat.XML_PARAM_ENTITY_PARSING_NEVER)
    root: list[Element] = []
    stack: list[Element] = []
    texts: list[list[str]] = []

    def refuse_doctype(*_args):
        raise _Refused("it has a document type declaration (<!DOCTYPE ...>)", parser.CurrentLineNumber)

    def refuse_entity(*_args):
        raise _Refused("it declares an entity (<!ENTITY ...>)", parser.CurrentLineNumber)

    def start(tag, attrib):
        element = Element(tag, dict(attrib), parser.CurrentLineNumber, parent=stack[-1] if stack else None)
        if stack:
            stack[-1].children.append(element)
        else:
            root.append(element)
        stack.append(element)
        texts.append([])

    def end(_tag):
        element = stack.pop()
        element.text = "".join(texts.pop()).strip()

    def chars(data):
        if texts:
            texts[-1].append(data)

    parser.StartDoctypeDeclHandler = refuse_doctype
    parser.EntityDeclHandler = refuse_entity
    parser.UnparsedEntityDeclHandler = refuse_entity
    parser.ExternalEntityRefHandler = refuse_entity
    parser.StartElementHandler = start
    parser.EndElementHandler = end
    parser.CharacterDataHandler = chars
    try:
        parser.Parse(data, True)
    except _Refused as exc:
        raise OpenSimModelError(
            f"{source}, line {exc.line}: refused, {exc}: a model file is untrusted input and OpenSim "
            f"writes none, so dea-opt reads no document type or entity declarations"
        ) from None
    except expat.ExpatError as exc:
        raise OpenSimModelError(
            f"{source}, line {exc.lineno}, column {exc.offset + 1}: not well-formed XML "
            f"({expat.ErrorString(exc.code)}): is it an OpenSim model file (.osim)?"
        ) from None
    if not root:
        raise OpenSimModelError(f"{source}: holds no XML element: is it an OpenSim model file (.osim)?")
    return root[0]


def parse_file(path) -> Element:
    """The root element of the XML file ``path``, read safely (:func:`parse_text`).

    Raises
    ------
    OpenSimModelError
        The file is missing, a directory, larger than :data:`MAX_BYTES`, unreadable, or not
        well-formed XML (with its line).
    """
    path = Path(path)
    if "\0" in str(path):
        raise OpenSimModelError(f"model path {str(path)!r} holds a NUL byte")
    if not path.exists():
        raise OpenSimModelError(f"model file {path} does not exist")
    if path.is_dir():
        raise OpenSimModelError(f"model file {path} is a directory, not an OpenSim model file (.osim)")
    size = path.stat().st_size
    if size > MAX_BYTES:
        raise OpenSimModelError(
            f"model file {path} has {size} bytes, more than the {MAX_BYTES} dea-opt reads: is it a model file?"
        )
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise OpenSimModelError(f"model file {path} cannot be read: {exc.strerror or exc}") from None
    return parse_text(data, str(path))
