"""One self-contained HTML page: its parts (headings, tables, pictures, notes), its style and scripts.

Written with the standard library's :func:`html.escape` rather than a template engine: a report is
a few sections of tables and pictures, and none of the kept libraries renders HTML (Jinja2 comes
with Sphinx, a documentation dependency only). Everything the page needs is inside it: the style,
the scripts, the pictures (PNG as ``data:`` URIs) and Plotly's JavaScript, which is gzipped and
unpacked by the browser (``DecompressionStream``): 4.8 MB of JavaScript weigh 2 MB in the page,
so that a report with its 3-D view stays under 5 MB. Nothing is loaded from the network, and the
page opens from ``file://``.
"""

from __future__ import annotations

import base64
import functools
import gzip
import html
import json
import math
from pathlib import Path

__all__ = ["Page", "Raw", "cell", "escape", "plotly_script", "table"]


def escape(text) -> str:
    """``text`` as HTML text (quotes included)."""
    return html.escape(str(text), quote=True)


def cell(value) -> str:
    """A table cell's text: numbers to four significant digits, NaN and None as a dash."""
    if value is None:
        return "–"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, float):
        if not math.isfinite(value):
            return "–"
        return f"{value:.4g}"
    return escape(value)


def table(header, rows, *, sortable: bool = False, classes=None, numbers=None) -> str:
    """A ``<table>``: ``header`` (texts), ``rows`` (lists of values, formatted by :func:`cell`);
    ``classes`` a class per row (e.g. ``"failed"``); ``sortable`` adds click-to-sort headers. A
    cell's raw number goes into ``data-value`` so that sorting is by number."""
    kind = ' class="sortable"' if sortable else ""
    out = [f"<table{kind}>"]
    if any(header):  # a table of names and values needs no header row
        out += ["<thead><tr>", *(f"<th>{escape(h)}</th>" for h in header), "</tr></thead>"]
    out.append("<tbody>")
    for k, row in enumerate(rows):
        style = f' class="{escape(classes[k])}"' if classes and classes[k] else ""
        out.append(f"<tr{style}>")
        for value in row:
            raw = ""
            if isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value):
                raw = f' data-value="{float(value)!r}"'
            out.append(f"<td{raw}>{value if isinstance(value, Raw) else cell(value)}</td>")
        out.append("</tr>")
    out.append("</tbody></table>")
    return "".join(out)


class Raw(str):
    """HTML that :func:`table` puts into a cell as it is (a link, a bold word)."""


_STYLE = """
:root { --ok: #1a7f37; --bad: #c62828; --warn: #b26a00; --grey: #5f6368; }
body { font-family: system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; margin: 0 auto; max-width: 1180px;
       padding: 1.2em 2em 3em; color: #202124; line-height: 1.45; }
h1 { font-size: 1.7em; margin: 0.2em 0 0.1em; } h2 { font-size: 1.25em; margin-top: 1.8em;
  border-bottom: 1px solid #dadce0; padding-bottom: 0.2em; } h3 { font-size: 1.05em; }
.sub { color: var(--grey); margin: 0 0 1em; }
.verdict { font-size: 1.15em; padding: 0.7em 1em; border-radius: 6px; margin: 1em 0; border: 2px solid; }
.verdict.ok { border-color: var(--ok); background: #e6f4ea; } .verdict.bad { border-color: var(--bad); background: #fce8e6; }
.verdict.warn { border-color: var(--warn); background: #fef7e0; }
.verdict b { font-size: 1.1em; }
table { border-collapse: collapse; margin: 0.6em 0 1em; font-size: 0.92em; }
th, td { border: 1px solid #dadce0; padding: 0.25em 0.6em; text-align: left; vertical-align: top; }
td[data-value] { text-align: right; font-variant-numeric: tabular-nums; }
th { background: #f1f3f4; } tr.failed td { background: #fce8e6; } tr.skipped td { color: var(--grey); }
table.sortable th { cursor: pointer; user-select: none; } table.sortable th:hover { background: #e8eaed; }
table.sortable th.up::after { content: " ▲"; } table.sortable th.down::after { content: " ▼"; }
.scroll { overflow-x: auto; max-height: 36em; overflow-y: auto; }
figure { margin: 1em 0; } figure img { max-width: 100%; border: 1px solid #dadce0; }
figcaption { color: var(--grey); font-size: 0.9em; }
.view { width: 100%; height: 620px; border: 1px solid #dadce0; }
.plot { width: 100%; height: 480px; border: 1px solid #dadce0; }
.note { color: var(--grey); font-size: 0.9em; } code { background: #f1f3f4; padding: 0 0.2em; border-radius: 3px; }
pre { background: #f8f9fa; border: 1px solid #dadce0; padding: 0.6em; overflow-x: auto; font-size: 0.85em; }
nav a { margin-right: 1em; } label { margin-right: 1em; }
"""

#: Click a header of a ``table.sortable`` to sort by it (numbers by ``data-value``), again to reverse.
_SORT = """
document.querySelectorAll('table.sortable').forEach(function (table) {
  table.querySelectorAll('th').forEach(function (th, column) {
    th.addEventListener('click', function () {
      var body = table.tBodies[0], rows = Array.from(body.rows);
      var up = !th.classList.contains('up');
      table.querySelectorAll('th').forEach(function (h) { h.classList.remove('up', 'down'); });
      th.classList.add(up ? 'up' : 'down');
      rows.sort(function (a, b) {
        var x = a.cells[column], y = b.cells[column];
        var u = x.dataset.value, v = y.dataset.value, r;
        if (u !== undefined && v !== undefined) { r = parseFloat(u) - parseFloat(v); }
        else if (u !== undefined) { r = -1; } else if (v !== undefined) { r = 1; }
        else { r = x.textContent.localeCompare(y.textContent); }
        return up ? r : -r;
      });
      rows.forEach(function (row) { body.appendChild(row); });
    });
  });
});
"""

#: Unpacks Plotly (gzipped, base64 in ``#plotly-gz``) and then draws every figure the page queued.
_PLOTLY_LOADER = """
window.deaFigures = window.deaFigures || [];
(async function () {
  var notice = function (text) {
    document.querySelectorAll('.view, .plot').forEach(function (d) { d.textContent = text; });
  };
  if (typeof DecompressionStream === 'undefined') {
    notice('This browser cannot unpack the interactive views (it lacks DecompressionStream): open the report ' +
           'in a current Firefox, Chrome, Edge or Safari.');
    return;
  }
  var text = document.getElementById('plotly-gz').textContent.trim();
  var bytes = Uint8Array.from(atob(text), function (c) { return c.charCodeAt(0); });
  var stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream('gzip'));
  var code = await new Response(stream).text();
  var script = document.createElement('script');
  script.textContent = code;
  document.head.appendChild(script);
  window.deaFigures.forEach(function (draw) { draw(window.Plotly); });
  document.body.dataset.plotly = 'ready';
})();
"""


@functools.lru_cache(maxsize=1)
def _plotly_gzipped() -> str | None:
    """Plotly's JavaScript, gzipped and base64-encoded (once per process); None without plotly."""
    try:
        from plotly.offline import get_plotlyjs
    except ImportError:
        return None
    return base64.b64encode(gzip.compress(get_plotlyjs().encode("utf-8"), 6)).decode("ascii")


def plotly_script() -> str | None:
    """The ``<script>`` elements that bring Plotly into the page, or None when plotly is not installed."""
    packed = _plotly_gzipped()
    if packed is None:
        return None
    return (
        f'<script id="plotly-gz" type="application/octet-stream">{packed}</script>\n<script>{_PLOTLY_LOADER}</script>'
    )


def _json(data) -> str:
    """JSON safe inside a ``<script>`` (no ``</`` can end it)."""
    return json.dumps(data, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")


class Page:
    """A report being written: sections of HTML, then :meth:`html` gives the whole page."""

    def __init__(self, title: str, subtitle: str = ""):
        self.title = title
        self.subtitle = subtitle
        self.parts: list[str] = []
        self.figures: list[str] = []  # JavaScript drawing each Plotly figure

    def add(self, markup: str) -> None:
        self.parts.append(markup)

    def heading(self, text: str, anchor: str) -> None:
        self.parts.append(f'<h2 id="{escape(anchor)}">{escape(text)}</h2>')

    def paragraph(self, text: str, css: str = "") -> None:
        style = f' class="{css}"' if css else ""
        self.parts.append(f"<p{style}>{escape(text)}</p>")

    def picture(self, path, caption: str) -> None:
        """Embed a PNG file (as a ``data:`` URI) with its caption; nothing when it is missing."""
        path = Path(path)
        if not path.is_file():
            return
        data = base64.b64encode(path.read_bytes()).decode("ascii")
        self.parts.append(
            f'<figure><img alt="{escape(caption)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{escape(caption)}</figcaption></figure>"
        )

    def plotly(self, element: str, figure: dict, css: str = "view", script: str = "") -> None:
        """A ``<div>`` where the Plotly ``figure`` (``{"data", "layout"}``) is drawn once Plotly is
        unpacked; ``script`` is more JavaScript run then, with ``Plotly`` and ``figure`` in scope."""
        self.parts.append(f'<div id="{escape(element)}" class="{css}">Loading the interactive view…</div>')
        self.figures.append(
            f"window.deaFigures.push(function (Plotly) {{ var figure = {_json(figure)};"
            f" var div = document.getElementById({_json(element)}); div.textContent = '';"
            f" Plotly.newPlot(div, figure.data, figure.layout, {{responsive: true, displaylogo: false}})"
            f".then(function () {{ div.dataset.drawn = 'yes'; }}); {script} }});"
        )

    def html(self) -> str:
        """The whole page."""
        plotly = plotly_script() if self.figures else None
        scripts = ""
        if self.figures and plotly is not None:
            scripts = f"<script>window.deaFigures = [];{''.join(self.figures)}</script>\n{plotly}"
        elif self.figures:
            scripts = (
                "<script>document.querySelectorAll('.view, .plot').forEach(function (d) { d.textContent = "
                "'The interactive views need Plotly, which is not installed: pip install plotly, then run again.'; "
                "});</script>"
            )
        subtitle = f'<p class="sub">{escape(self.subtitle)}</p>' if self.subtitle else ""
        return (
            '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
            '<meta name="viewport" content="width=device-width, initial-scale=1">'
            f"<title>{escape(self.title)}</title><style>{_STYLE}</style></head>\n<body>"
            f"<h1>{escape(self.title)}</h1>{subtitle}\n"
            + "\n".join(self.parts)
            + f"\n<script>{_SORT}</script>\n{scripts}\n</body></html>\n"
        )
