"""Figures whose labels do not hide each other or the curves (issue 64): recommend's
``pareto.png`` wrote ``eaik`` over ``ours-lm``; the legibility summary's legend covered the
pointing panel's curves."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from ikbench.render.labels import label_points  # noqa: E402
from ikbench.render.legibility_plots import plot_legibility_summary  # noqa: E402


def _boxes(fig, artists):
    renderer = fig.canvas.get_renderer()
    return [a.get_window_extent(renderer) for a in artists]


def test_labels_of_crowded_points_do_not_overlap():
    """Four methods within a hair of each other at 100 % (UR5's eaik, ours-lm): the labels
    take free places around their points."""
    fig, ax = plt.subplots(figsize=(6, 4))
    points = [(0.0141, 100.0), (0.0158, 100.0), (0.0150, 99.9), (0.0146, 99.95)]
    ax.plot(*zip(*points), "o")
    ax.set_xscale("log")
    ax.set_xlim(0.005, 100)
    ax.set_ylim(85, 100.7)
    labels = label_points(ax, points, ["eaik", "ours-lm", "rtb-lm", "trac-ik"], ["k"] * 4)
    boxes = _boxes(fig, labels)
    assert len(boxes) == 4
    for i, a in enumerate(boxes):
        for b in boxes[i + 1:]:
            assert not a.overlaps(b), (a, b)
    plt.close(fig)


def test_the_one_place_is_kept_when_it_is_free():
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.set_xlim(0, 10)
    ax.set_ylim(0, 10)
    (label,) = label_points(ax, [(5.0, 5.0)], ["alone"], ["k"])
    assert label.xyann == (4, 4)
    plt.close(fig)


def test_the_legibility_summary_keeps_its_legend_off_the_panels():
    times = np.linspace(0, 2, 21)
    curves = {f"method-{k}": {"1": {"times_s": times, "position": times / 2,
                                    "pointing": times / 2}} for k in range(15)}
    fig = plot_legibility_summary(curves, 7)
    fig.canvas.draw()
    assert all(ax.get_legend() is None for ax in fig.axes)
    (legend,) = fig.legends
    (box,) = _boxes(fig, [legend])
    for panel in _boxes(fig, fig.axes):
        assert not box.overlaps(panel)
    colours = [tuple(line.get_color()) for line in fig.axes[0].get_lines()
               if line.get_label().startswith("method-")]
    assert len(set(colours)) == 15  # one colour each: tab10 repeated after ten
    plt.close(fig)
