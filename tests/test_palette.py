"""Every method of a figure gets its own colour, however many methods there are."""

from __future__ import annotations

import pandas as pd
import pytest

from ikbench.render.ik_report import method_colors
from ikbench.render.palette import distinct_colors


@pytest.mark.parametrize("count", [1, 10, 11, 12, 15, 16, 30])
def test_no_two_methods_share_a_colour(count):
    colors = distinct_colors(count)
    assert len(colors) == count
    assert len({tuple(round(c, 6) for c in color) for color in colors}) == count


def test_a_method_keeps_its_colour_in_every_panel():
    table = pd.DataFrame({"method": ["eaik", "ours-lm", "rtb-lm", "ours-lm", "eaik"] +
                          [f"m{k}" for k in range(10)]})
    colors = method_colors(table)
    assert list(colors) == ["eaik", "ours-lm", "rtb-lm"] + [f"m{k}" for k in range(10)]
    assert colors["m9"] != colors["ours-lm"]  # the 11th method was drawn like the 2nd
    assert len(set(colors.values())) == 13
