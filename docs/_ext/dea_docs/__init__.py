"""Sphinx extensions of the dea-opt site: equations as MathML, code names as links, reference
pages made from the code, and the gallery's scraper (see each module)."""

from __future__ import annotations

from . import crosslinks, mathml, reference


def setup(app) -> dict:
    mathml.setup(app)
    crosslinks.setup(app)
    reference.setup(app)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
