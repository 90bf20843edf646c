"""Labels beside a figure's points that do not overlap each other (issue 64: recommend's
``pareto.png`` printed ``eaik`` over ``ours-lm``).

:func:`label_points` places each label at the first of :data:`OFFSETS_PT` around its point
(right and above first) whose box overlaps no label placed before it and stays inside the
axes; a label with no free place keeps the first offset. The boxes are measured with the
figure's renderer, so the result depends on the figure's size and fonts, not on guesses.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

#: Where a label may go, relative to its point [typographic points]: right-above first, then
#: right-below, left-above, left-below, then further out.
OFFSETS_PT: tuple[tuple[float, float], ...] = (
    (4, 4), (4, -11), (-4, 4), (-4, -11), (4, 13), (4, -20), (-4, 13), (-4, -20),
    (10, -4), (-10, -4), (4, 22), (4, -29))


def label_points(ax: Any, points: Sequence[tuple[float, float]], texts: Sequence[str],
                 colors: Sequence[Any], fontsize: float = 7) -> list[Any]:
    """Annotate ``points`` (data coordinates) of ``ax`` with ``texts`` in ``colors``, no two
    labels overlapping where a free offset exists (see the module docstring); returns the
    annotations."""
    fig = ax.figure
    fig.canvas.draw()  # the transforms and the renderer, after the limits are set
    renderer = fig.canvas.get_renderer()
    inside = ax.get_window_extent(renderer)
    placed: list[Any] = []
    annotations = []
    for point, text, color in zip(points, texts, colors):
        chosen = None
        for dx, dy in OFFSETS_PT:
            label = ax.annotate(text, point, xytext=(dx, dy), textcoords="offset points",
                                fontsize=fontsize, color=color,
                                ha="left" if dx >= 0 else "right")
            box = label.get_window_extent(renderer)
            free = not any(box.overlaps(other) for other in placed)
            within = (inside.x0 <= box.x0 and box.x1 <= inside.x1 and inside.y0 <= box.y0
                      and box.y1 <= inside.y1)
            if free and within:
                chosen = label
                break
            label.remove()
        if chosen is None:  # crowded: the first place, overlapping
            dx, dy = OFFSETS_PT[0]
            chosen = ax.annotate(text, point, xytext=(dx, dy), textcoords="offset points",
                                 fontsize=fontsize, color=color)
        placed.append(chosen.get_window_extent(renderer))
        annotations.append(chosen)
    return annotations
