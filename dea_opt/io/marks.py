"""What every picture of a result says about it: its verdict stamped on it, and the colours of its regions.

A result outside the model's validity, or without a certified answer, must not look like a clean
success on a slide: :func:`stamp` writes the verdict across the figure (a large diagonal mark
and a red border) and the figures put its reason under their title (:func:`verdict_lines`).
"""

from __future__ import annotations

import textwrap

__all__ = [
    "CLEAN",
    "REGION_COLOURS",
    "path_verdict",
    "region_colours",
    "solution_verdict",
    "stamp",
    "verdict_lines",
]

#: The verdict of a clean success, for a caller that has judged it (nothing is stamped).
CLEAN = ("", "")

#: Colours of the regions' contact edges and centres of pressure: they stand out on viridis
#: (dark blue to yellow), on the grey of the surface out of contact and on each other.
REGION_COLOURS = ("#e4172b", "#ff8c00", "#ff4fd8", "#00e5ff", "#8b4513", "#ffffff")


def region_colours(names) -> dict:
    """``{name: colour}`` for the regions ``names``, in order (the colours repeat past six)."""
    return {name: REGION_COLOURS[k % len(REGION_COLOURS)] for k, name in enumerate(names)}


def solution_verdict(solution) -> tuple[str, str] | None:
    """``(mark, reason)`` for a solution that is not a clean success: ``("NO CERTIFIED ANSWER",
    why)`` or ``("OUTSIDE VALIDITY", the failed checks)``; None for a certified answer inside
    validity."""
    if not solution.success:
        return "NO CERTIFIED ANSWER", f"{solution.method}: status {solution.status}"
    validity = solution.validity
    if not validity.valid:
        return "OUTSIDE VALIDITY", "; ".join(c.describe().split(": ", 1)[0] for c in validity.failed)
    return None


def path_verdict(table) -> tuple[str, str] | None:
    """``(mark, reason)`` for a load path's table (one row per frame) when a frame is not a clean
    success: the frames outside validity and their checks, or the frames without a certified
    answer; None when every frame is certified and valid."""
    success = table["success"].to_numpy(dtype=bool)
    valid = table["valid"].to_numpy(dtype=bool)
    outside = success & ~valid
    if outside.any():
        checks = sorted({c for text in table.loc[outside, "validity_failed"] for c in str(text).split(";") if c})
        return (
            "OUTSIDE VALIDITY",
            f"{int(outside.sum())} of {len(table)} frames outside validity ({', '.join(checks) or 'see frames.csv'})",
        )
    if not success.all():
        return "NO CERTIFIED ANSWER", f"{int((~success).sum())} of {len(table)} frames without a certified answer"
    return None


def verdict_lines(verdict, width: int = 90) -> str:
    """The verdict as lines under a title (empty when there is none, or it is :data:`CLEAN`)."""
    if not verdict or not verdict[0]:
        return ""
    mark, reason = verdict
    return "\n" + textwrap.fill(f"{mark}: {reason}", width)


def _size_mark(fig, text) -> None:
    """The mark's letters as large as the figure allows (at most 48 pt), shrunk until it lies well
    inside the figure (its size depends on the font)."""
    width, height = fig.get_size_inches() * 72.0  # points
    mark = text.get_text()
    text.set_fontsize(max(10.0, min(48.0, 1.1 * min(width, 2.0 * height) / max(len(mark), 1))))
    renderer = fig.canvas.get_renderer()
    box, figure = text.get_window_extent(renderer), fig.bbox
    scale = min(0.85 * figure.width / max(box.width, 1.0), 0.85 * figure.height / max(box.height, 1.0), 1.0)
    if scale < 1.0:
        text.set_fontsize(text.get_fontsize() * scale)


def stamp(fig, verdict) -> None:
    """Stamp ``verdict`` (``(mark, reason)`` or None) on ``fig``: the mark in large red letters
    across the figure, and a red border. Call it once the figure is laid out; the mark is sized
    to stay inside the figure."""
    if not verdict or not verdict[0]:
        return
    from matplotlib.patches import Rectangle

    mark = verdict[0]
    text = fig.text(
        0.5, 0.5, mark, ha="center", va="center", rotation=20, fontweight="bold", color="#d00000", alpha=0.35,
        zorder=100,
    )  # fmt: skip
    _size_mark(fig, text)
    after = getattr(fig.get_layout_engine(), "after", None)  # (dea_opt.io.layout's engine)
    if after is not None:  # a figure placed again at another size sizes its mark again
        after.append(lambda: _size_mark(fig, text))
    fig.add_artist(
        Rectangle((0.0, 0.0), 1.0, 1.0, transform=fig.transFigure, fill=False, edgecolor="#d00000", linewidth=6)
    )
