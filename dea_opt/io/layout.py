"""Where a picture's axes go: margins measured from the texts around them, no layout engine.

Matplotlib's constrained layout measures every axes with all it draws, twice (each time making
and measuring every tick label), and ``savefig`` then draws the whole figure once more before the
picture itself: a third of the time of a map, a cycle plot or an exposure picture (0.05 to 0.09 s
of 0.15 to 0.23 s on Agg), for a run's three pictures and every picture the tests draw. These
pictures have a fixed arrangement (maps in a row, each with its colour bar; panels stacked over a
shared time axis), so the room each axes needs around it is the size of the texts that go
there: measured here once the figure holds them, in inches (any figure size or dpi keeps them
inside it). Headings, notes, axis labels and legends are measured as they are; tick labels are
the strings their axis' locator and formatter give for the axes where it stands (what the
drawing writes there, five-digit loads included), measured without making a tick.
``tests/outputs/test_figures.py`` checks that every text of every kind of picture lies inside it.
A figure resized after it was placed (``set_size_inches`` before ``savefig``) is placed again
when it is drawn (a layout engine, :func:`_placed`, that does nothing at the size it placed).
"""

from __future__ import annotations

__all__ = ["colorbar_axes", "place_maps", "place_panels"]

#: Inches between a text and the figure's edge or a neighbour (matplotlib's constrained layout: 3 pt).
PAD = 4.0 / 72.0
#: A colour bar's length as a fraction of its map's height, and its length over its width.
SHRINK, ASPECT = 0.85, 20.0
#: Inches between stacked panels (their inner tick labels are hidden).
GAP = 10.0 / 72.0
#: Inches between maps side by side: one's colour bar label and the next one's axis label.
COLUMN_GAP = 0.3


_ENGINE: list = []  # the layout engine's class, made at the first figure (matplotlib is imported then)


def _engine_class():
    """The class of :func:`_placed`'s layout engine (defined once matplotlib is wanted: importing
    dea_opt starts no picture machinery)."""
    if not _ENGINE:
        from matplotlib.layout_engine import LayoutEngine

        class Placed(LayoutEngine):
            """The placing of :func:`place_maps` or :func:`place_panels`, made again when the
            figure is drawn at another size (inches) than the one it was placed at: a figure a
            user resizes before saving it keeps its texts inside it. At the size it was placed
            at, drawing costs nothing more. ``after``: what is sized to the placed figure (a
            stamp's mark), done again after it."""

            _adjust_compatible = True
            _colorbar_gridspec = False

            def __init__(self, place, size):
                super().__init__()
                self.place, self.size, self.after = place, tuple(size), []

            def set(self, **kwargs):
                raise TypeError("a placed figure's layout has no parameters: it is placed again at its new size")

            def execute(self, fig):
                if tuple(fig.get_size_inches()) != self.size:
                    self.place()
                    for again in self.after:
                        again()

        _ENGINE.append(Placed)
    return _ENGINE[0]


def _placed(fig, place) -> None:
    """Keep ``place`` (a call placing ``fig`` again) as the figure's layout engine, at its size now."""
    engine, kind = fig.get_layout_engine(), _engine_class()
    if isinstance(engine, kind):
        engine.place, engine.size = place, tuple(fig.get_size_inches())
    else:
        fig.set_layout_engine(kind(place, fig.get_size_inches()))


def colorbar_axes(fig):
    """An axes for a colour bar, placed by :func:`place_maps` (``fig.colorbar(mappable, cax=...)``)."""
    return fig.add_axes((0.9, 0.1, 0.03, 0.8))


def _renderer(fig):
    return fig.canvas.get_renderer()


def _size(fig, artist, renderer) -> tuple[float, float]:
    """Width and height (inches) of a text or legend: zero for none, a hidden one or an empty text."""
    if artist is None or not artist.get_visible():
        return 0.0, 0.0
    if hasattr(artist, "get_text") and not artist.get_text().strip():
        return 0.0, 0.0
    box = artist.get_window_extent(renderer)
    return box.width / fig.dpi, box.height / fig.dpi


def _label(fig, axis, renderer) -> float:
    """Inches an axis label takes across its axis, with its pad (zero without a label)."""
    width, height = _size(fig, axis.label, renderer)
    across = width if axis.axis_name == "y" else height
    return across + axis.labelpad / 72.0 if across else 0.0


def _ticks(fig, axis, renderer) -> tuple[float, float, float]:
    """Inches the tick labels of ``axis`` take across it (with the ticks and their pad), the widest
    label along a horizontal axis, and the height of its offset text (``1e6``, ``+1e3``; zero
    without one): the labels its locator and formatter give for its axes where it stands."""
    from matplotlib.text import Text

    tick = axis.majorTicks[0]  # the one every tick of the axis copies its properties from
    label = tick.label1 if tick.label1.get_visible() else tick.label2
    if not axis.get_visible() or not label.get_visible():
        return 0.0, 0.0, 0.0
    low, high = sorted(axis.get_view_interval())
    slack = 1e-9 * (high - low)
    locs = [x for x in axis.get_major_locator()() if low - slack <= x <= high + slack]
    formatter = axis.get_major_formatter()
    text = Text()
    text.update_from(label)
    text.set_figure(fig)
    widest = tallest = 0.0
    strings = set(formatter.format_ticks(locs))
    longest = max(map(len, strings), default=0)
    for string in strings:  # a label two characters shorter than the longest is narrower
        if len(string) >= longest - 1:
            text.set_text(string)
            width, height = _size(fig, text, renderer)
            widest, tallest = max(widest, width), max(tallest, height)
    offset = formatter.get_offset()
    if offset:
        text.set_text(offset)
        offset_height = _size(fig, text, renderer)[1] + PAD
    else:
        offset_height = 0.0
    across = widest if axis.axis_name == "y" else tallest
    outside = (tick.get_tick_padding() + tick.get_pad()) / 72.0
    return (across + outside if across else outside), widest, offset_height


def _title(fig, ax, renderer) -> float:
    """Inches a map's title takes above it."""
    height = _size(fig, ax.title, renderer)[1]
    return height + ax.titleOffsetTrans.get_matrix()[1, 2] / fig.dpi if height else 0.0


def _rect(fig, left, bottom, width, height) -> tuple:
    """Inches to figure fractions, sizes kept positive (a figure too small for its texts still draws)."""
    figure_width, figure_height = fig.get_size_inches()
    return (
        left / figure_width,
        bottom / figure_height,
        max(width, 0.01) / figure_width,
        max(height, 0.01) / figure_height,
    )


def _fit(fig, text, renderer, centre: float = 0.5, right: float = 1.0) -> bool:
    """Wrap each line of ``text``, centred at ``centre`` (a fraction of the figure's width), that
    would stand out of the figure's left edge or past ``right`` (a fraction: a colour bar's left
    edge), at as many characters as fit (a scenario's title with its frame, "...: peak frame 36,
    0.432 s", can be that wide): whether a line was wrapped."""
    import textwrap

    from matplotlib.text import Text

    room = 2.0 * (min(centre, right - centre) * fig.bbox.width - PAD * fig.dpi)
    probe = Text()
    probe.update_from(text)
    probe.set_figure(fig)
    lines = text.get_text().split("\n")
    fitted = []
    for line in lines:
        probe.set_text(line)
        width = probe.get_window_extent(renderer).width if line.strip() else 0.0
        fitted.append(textwrap.fill(line, max(10, int(len(line) * room / width))) if width > room else line)
    text.set_text("\n".join(fitted))
    return fitted != lines


def _heading(fig, text) -> float:
    """Put the figure's heading ``text`` (``fig.suptitle``'s, or None) at the top edge, its lines
    fitted to the figure's width: inches it takes."""
    if text is None:
        return 0.0
    _fit(fig, text, _renderer(fig))
    text.set_y(1.0 - PAD / fig.get_size_inches()[1])
    text.set_verticalalignment("top")
    height = _size(fig, text, _renderer(fig))[1]
    return height + PAD if height else 0.0


def _note(fig, text) -> float:
    """Put the figure's note ``text`` (``fig.supxlabel``'s, or None) at the bottom edge, its lines
    fitted to the figure's width: inches it takes."""
    if text is None:
        return 0.0
    _fit(fig, text, _renderer(fig))
    text.set_y(PAD / fig.get_size_inches()[1])
    text.set_verticalalignment("bottom")
    height = _size(fig, text, _renderer(fig))[1]
    return height + PAD if height else 0.0


def _sides(fig, ax, right, renderer) -> tuple[float, float, float]:
    """Inches a map needs on its left (tick labels, axis label), between it and its colour bar (its
    last tick label may stand out of its right end), and ``right`` of that gap (its colour bar's),
    for the ticks its axes gives where it stands. A text or legend drawn on the map that stands
    out of its sides (a long region name near its edge) widens the side it stands out of. (Its
    title does not: a title wider than the map would shrink it and stand out further.)"""
    widest = _ticks(fig, ax.xaxis, renderer)[1]
    left = _ticks(fig, ax.yaxis, renderer)[0] + _label(fig, ax.yaxis, renderer)
    gap = max(0.15, 0.5 * widest + PAD)
    drawn = [a for a in (*ax.texts, ax.get_legend()) if _size(fig, a, renderer)[0]]
    if drawn:
        box = ax.get_window_extent(renderer)
        extents = [a.get_window_extent(renderer) for a in drawn]
        left = max(left, (box.x0 - min(e.x0 for e in extents)) / fig.dpi + PAD)
        gap = max(gap, (max(e.x1 for e in extents) - box.x1) / fig.dpi + PAD)
    return left, gap, right


def place_maps(fig, pairs, heading=None, note=None) -> None:
    """Place maps side by side in one row, each with its colour bar on its right.

    Above the maps: the heading and each map's title (a line that would stand out of the figure,
    or over the map's colour bar beside it, wrapped to fit); below: each map's tick labels and axis label, then the note. A colour bar is
    :data:`SHRINK` times its map's height, centred beside it. A map of equal scale shrinks inside
    its place (matplotlib keeps its aspect), and its locator may then give other ticks (``2.5``
    where the place gave ``2``): the margins are measured again at the shrunk map until they stop
    growing (at most three times), each the largest it was measured.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        Without a layout engine (it is given one that places it again at another size), on an
        Agg canvas, holding every text it will draw.
    pairs : list of (Axes, Colorbar)
        The maps from left to right, each colour bar drawn in an axes of :func:`colorbar_axes`.
    heading, note : matplotlib.text.Text, optional
        The figure's ``suptitle`` and ``supxlabel``, put at its top and bottom edges.
    """
    renderer = _renderer(fig)
    _placed(fig, lambda: place_maps(fig, pairs, heading, note))
    _maps(fig, pairs, heading, note, renderer)
    # a map's title is centred on it: a line that would stand out of the figure, or over the map's
    # colour bar where the title is beside it (a wide map's title is half way down the figure), is
    # wrapped (every title, hence the list), and the maps are placed again under the taller title
    fitted = []
    for ax, bar in pairs:
        box, beside = ax.get_position(), bar.ax.get_position()
        above = box.y1 + ax.titleOffsetTrans.get_matrix()[1, 2] / fig.bbox.height >= beside.y1
        fitted.append(_fit(fig, ax.title, renderer, 0.5 * (box.x0 + box.x1), 1.0 if above else beside.x0))
    if any(fitted):
        _maps(fig, pairs, heading, note, renderer)


def _maps(fig, pairs, heading, note, renderer) -> None:
    """:func:`place_maps`' placing, for the titles as they stand."""
    width, height = fig.get_size_inches()
    top = PAD + _heading(fig, heading) + max(_title(fig, ax, renderer) for ax, _ in pairs)
    bottom = PAD + _note(fig, note)
    bottom += max(_ticks(fig, ax.xaxis, renderer)[0] + _label(fig, ax.xaxis, renderer) for ax, _ in pairs)
    tall = height - top - bottom
    bar_length = SHRINK * tall
    bar_y = bottom + 0.5 * (tall - bar_length)
    bars = []  # each colour bar's width, tick labels and label, at its length (its ticks depend on it)
    for _, bar in pairs:
        bar.ax.set_position(_rect(fig, 0.0, bar_y, bar_length / ASPECT, bar_length))
        ticks, label = _ticks(fig, bar.ax.yaxis, renderer)[0], _label(fig, bar.ax.yaxis, renderer)
        bars.append(bar_length / ASPECT + ticks + label)
    sides: list[tuple[float, ...]] = [(0.0, 0.0, 0.0)] * len(pairs)
    for _ in range(3):
        measured = [_sides(fig, ax, right, renderer) for (ax, _), right in zip(pairs, bars)]
        grown = [tuple(map(max, old, new)) for old, new in zip(sides, measured)]
        if grown == sides:
            break
        sides = grown
        wide = (width - 2 * PAD - COLUMN_GAP * (len(pairs) - 1) - sum(map(sum, sides))) / len(pairs)
        x = PAD
        for (ax, bar), (left, gap, right) in zip(pairs, sides):
            ax.set_position(_rect(fig, x + left, bottom, wide, tall))
            ax.apply_aspect()  # where the drawing will put it
            bar.ax.set_position(_rect(fig, x + left + wide + gap, bar_y, bar_length / ASPECT, bar_length))
            x += left + wide + gap + right + COLUMN_GAP


def place_panels(fig, axes, heading=None) -> None:
    """Place panels stacked in one column over a shared x axis, each legend beside its panel.

    Above: the heading (a line wider than the figure wrapped to fit); on the left, each panel's
    tick labels and axis label; on the right, each panel's legend (anchored just right of its
    panel's upper corner); below: the bottom panel's tick labels and axis label. Panels are
    :data:`GAP` apart, more where a panel has an offset text (``1e6``) over it. The tick labels
    are measured at the panels' height, the one they are drawn at.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        Without a layout engine (it is given one that places it again at another size), on an
        Agg canvas, holding every text it will draw.
    axes : list of Axes
        The panels from top to bottom.
    heading : matplotlib.text.Text, optional
        The figure's ``suptitle``, put at its top edge.
    """
    renderer = _renderer(fig)
    _placed(fig, lambda: place_panels(fig, axes, heading))
    width, height = fig.get_size_inches()
    top = PAD + _heading(fig, heading)
    bottom = PAD + _ticks(fig, axes[-1].xaxis, renderer)[0] + _label(fig, axes[-1].xaxis, renderer)
    legend = max(_size(fig, ax.get_legend(), renderer)[0] for ax in axes)
    above = [PAD] + [GAP] * (len(axes) - 1)
    for _ in range(2):  # the offset texts, once the ticks are those of the panels' height
        tall = (height - top - bottom - sum(above)) / len(axes)
        y = height - top
        for ax, gap in zip(axes, above):
            y -= gap + tall
            ax.set_position(_rect(fig, PAD, y, width - 2 * PAD - legend, tall))
        ticks = [_ticks(fig, ax.yaxis, renderer) for ax in axes]
        above = [max(above[k], ticks[k][2]) for k in range(len(axes))]
    left = PAD + max(tick[0] + _label(fig, ax.yaxis, renderer) for ax, tick in zip(axes, ticks))
    wide = (width - left - legend - PAD) / 1.01  # a legend's anchor is 1 % of its panel's width right of it
    y = height - top
    for ax, gap in zip(axes, above):
        y -= gap + tall
        ax.set_position(_rect(fig, left, y, wide, tall))
