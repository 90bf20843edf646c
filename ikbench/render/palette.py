"""Colours of a figure's methods: one distinct colour each, however many there are."""

from __future__ import annotations


def distinct_colors(count: int) -> list[tuple[float, float, float, float]]:
    """``count`` RGBA colours, no two alike: tab10's for up to ten; then tab20b's five dark
    shades (navy, olive, brown, maroon, plum: unlike any of tab10's), for up to fifteen;
    beyond, evenly spaced hues of hsv. A figure that coloured method k by ``C{k % 10}`` drew
    the eleventh like the first."""
    from matplotlib import colormaps

    if count <= 15:
        first = [colormaps["tab10"](k) for k in range(10)]
        return (first + [colormaps["tab20b"](k) for k in (0, 4, 8, 12, 16)])[:count]
    return [colormaps["hsv"](k / count) for k in range(count)]
