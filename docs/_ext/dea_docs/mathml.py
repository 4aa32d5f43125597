"""Equations rendered to MathML when the site is built.

Sphinx's default renders LaTeX in the reader's browser with MathJax fetched from a CDN; the site
must load nothing from the network and must read the same from ``file://``. A browser renders
MathML itself (MathML Core: Chromium, Firefox and Safari), so each ``$...$`` and ``$$...$$`` of the
pages is converted here, once, by ``latex2mathml`` (pure Python): no script, no font, no request.
A formula it cannot convert fails the build with the formula in the message.
"""

from __future__ import annotations

from docutils import nodes
from latex2mathml.converter import convert
from sphinx.errors import ExtensionError


def _mathml(latex: str, display: str) -> str:
    try:
        return convert(latex, display=display)
    except Exception as error:  # latex2mathml raises its own exceptions for bad TeX
        raise ExtensionError(f"cannot render the formula {latex!r} as MathML: {error}") from error


def visit_inline(self, node) -> None:
    self.body.append(f'<span class="math notranslate">{_mathml(node.astext(), "inline")}</span>')
    raise nodes.SkipNode


def visit_block(self, node) -> None:
    if node.get("label"):
        self.body.append(f'<span class="eqno">({node["number"]})</span>')
    self.body.append(f'<div class="math notranslate">{_mathml(node.astext(), "block")}</div>')
    raise nodes.SkipNode


def setup(app) -> None:
    app.add_html_math_renderer("mathml", (visit_inline, None), (visit_block, None))
